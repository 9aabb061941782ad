"""The change of light and where the photo holds signal for it (``relight/lift.py``): ``relit = I x G``, kept
under the photo's own light, painted only where a pixel at the noise floor is to be lifted, what is not skin
held to the skin around it, and the exposure of the photo's lit skin."""
import numpy as np
import pytest
from shadowflow.nodes.geometry.reflectance import light_from_angles
from shadowflow.nodes.photo.encoding import srgb_to_linear
from shadowflow.nodes.relight.fields import brightness
from shadowflow.nodes.relight.lift import (
    FILE_NOISE,
    MAX_GAIN,
    brightened,
    exposure,
    fill_weight,
    held_to_skin,
    precision,
    relit_face,
    shadows_kept,
    signal,
    smooth_change,
    usable,
)


def test_shadows_are_kept_under_the_photos_own_light_and_let_go_30_degrees_away():
    """All of the photo is kept under its own light (and within 5 degrees), none from 30 degrees on, and
    between it lets go steadily, half way (17.5 degrees) at a half."""
    photo = light_from_angles(20.0, 10.0)
    assert shadows_kept(photo, photo) == 1.0
    assert shadows_kept(photo, light_from_angles(24.0, 10.0)) == 1.0
    for apart in (30.0, 45.0, 90.0):
        assert shadows_kept(photo, light_from_angles(20.0 + apart, 10.0)) == 0.0
        assert shadows_kept(photo, light_from_angles(20.0 - apart, 10.0)) == 0.0
    between = [shadows_kept(photo, light_from_angles(20.0 + a, 10.0)) for a in (6.0, 10.0, 17.5, 25.0, 29.0)]
    assert np.all(np.diff(between) < 0) and 0.0 < between[-1] and between[0] < 1.0
    assert between[2] == pytest.approx(0.5, abs=1e-4)


def test_an_elevation_counts_half_as_much_as_an_azimuth():
    """Faces lit evenly from the front read lit from above: 35 degrees of elevation away from the photo's
    light keep as much of it as 17.5 degrees of azimuth (a half), and 50 degrees of elevation still keep some."""
    photo = light_from_angles(0.0, 0.0)
    by_azimuth = shadows_kept(photo, light_from_angles(17.5, 0.0))
    by_elevation = shadows_kept(photo, light_from_angles(0.0, 35.0))
    assert by_elevation == pytest.approx(by_azimuth, abs=1e-4)
    assert by_azimuth == pytest.approx(0.5, abs=1e-4)
    assert shadows_kept(photo, light_from_angles(0.0, 50.0)) > 0.0


def test_precision_is_the_files_noise_as_a_share_of_the_light_in_either_encoding():
    """1.5 levels of 255 in the file are ``1.5 / 255 / v`` of a linear file's light at value ``v``; in an sRGB
    file they are that times d ln(light) / d ln(v), taken here from the sRGB decoding itself (numerically),
    on the curve's linear toe as above it."""
    v = np.array([0.01, 0.03, 0.1, 0.3, 0.6, 0.9], np.float32)
    np.testing.assert_allclose(precision(v, "linear"), FILE_NOISE / v, rtol=1e-6)
    h = 1e-4
    v64 = v.astype(np.float64)
    d_log_light = (np.log(srgb_to_linear(v64 + h).astype(np.float64))
                   - np.log(srgb_to_linear(v64 - h).astype(np.float64))) / (2 * h)
    np.testing.assert_allclose(precision(v, "srgb"), FILE_NOISE * d_log_light, rtol=2e-3)
    # a well-exposed pixel's texture is the photo's, one at the noise floor is noise
    assert signal(precision(np.float32(0.5)))[()] == 1.0
    assert signal(precision(np.float32(1.0 / 255.0)))[()] == 0.0


def test_a_pixel_at_the_noise_floor_lifted_is_not_usable_a_well_exposed_one_is():
    """Lifted twice, a well-exposed pixel (0.5) is shown, one at the noise floor (2 levels of 255) is not;
    the same dark pixel left as it is (a pupil, a nostril) is kept however dark; lifted 1.5x or less, its
    relative noise does not matter yet."""
    well, floor = precision(np.float32(0.5)), precision(np.float32(2.0 / 255.0))
    relative = np.array([well, floor, floor, floor, floor], np.float32)
    lift = np.array([2.0, 2.0, 1.0, 0.5, 1.5], np.float32)
    np.testing.assert_array_equal(usable(relative, lift), [1.0, 0.0, 1.0, 1.0, 1.0])


def test_the_noise_a_lift_raises_is_raised_less_in_an_srgb_file():
    """Lifted 6x, a linear file's 1.5 levels of noise become 9, past what may show (usable 0); an sRGB file's
    curve spends its levels on the dark, and the same lift raises them by 6^(1/2.4) = 2.1x only (usable 1)."""
    relative = np.array([0.01], np.float32)  # the light well known
    lift = np.array([6.0], np.float32)
    assert usable(relative, lift, "linear")[0] == 0.0
    assert usable(relative, lift, "srgb")[0] == 1.0


def test_only_a_paintable_pixel_that_cannot_be_lifted_is_painted():
    """The fill weight is how far a pixel cannot be lifted, on what may be painted, and nothing elsewhere."""
    u = np.array([1.0, 0.0, 0.25, 0.0], np.float32)
    paintable = np.array([True, True, True, False])
    np.testing.assert_allclose(fill_weight(u, paintable), [0.0, 1.0, 0.75, 0.0])


def _disc(shape, centre, radius):
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]]
    return (yy - centre[0]) ** 2 + (xx - centre[1]) ** 2 <= radius**2


def test_what_is_not_skin_is_lifted_at_most_a_quarter_more_than_the_skin_around_it():
    """A brow (not skin) the fitted socket's dark shading would lift 6x among skin lifted 2x is held to
    1.25 x 2 = 2.5x; lifted 2.2x it is left alone; the skin itself is never held, even a patch of it lifted 6x
    as the brow is; with no skin near, nothing is."""
    shape = (60, 60)
    brow = _disc(shape, (30, 30), 4)
    patch = _disc(shape, (12, 12), 4)  # skin
    photo = np.full(shape + (3,), 0.3, np.float32)
    lift = np.where(brow | patch, 6.0, 2.0).astype(np.float32)
    held = held_to_skin(lift, photo, ~brow, 3.0)
    np.testing.assert_allclose((held * lift)[brow], 2.5, rtol=1e-3)
    assert np.all(held[~brow] == 1.0)
    mild = np.where(brow, 2.2, 2.0).astype(np.float32)
    np.testing.assert_allclose(held_to_skin(mild, photo, ~brow, 3.0)[brow], 1.0, rtol=1e-4)
    np.testing.assert_array_equal(held_to_skin(lift, photo, np.zeros(shape, bool), 3.0), 1.0)


def test_what_is_bright_in_a_shadow_is_relit_no_brighter_than_the_photo_has_it():
    """Teeth (0.8) in a shadowed mouth whose skin (0.05) is lifted 4x: relit skin around is 0.2, so the teeth
    may not pass 1.25 x 0.2 = 0.25, but are never made darker than the photo: they keep their 0.8 (gain 1),
    instead of shining at 3.2."""
    shape = (60, 60)
    teeth = _disc(shape, (30, 30), 4)
    photo = np.where(teeth, 0.8, 0.05).astype(np.float32)[..., None] * np.ones(3, np.float32)
    lift = np.full(shape, 4.0, np.float32)
    held = held_to_skin(lift, photo, ~teeth, 3.0)
    np.testing.assert_allclose((held * lift)[teeth], 1.0, rtol=1e-4)


def test_relit_face_is_the_photo_times_the_gain_where_nothing_is_painted():
    """With no fill weight the relit face is ``I x G`` exactly (the painted values, even NaN, do not leak
    in), a full weight gives the painted values, and a gain past ``MAX_GAIN`` is held there."""
    rng = np.random.default_rng(1)
    photo = rng.uniform(0.05, 0.6, (20, 30, 3)).astype(np.float32)
    gain = rng.uniform(0.3, 5.0, (20, 30, 3)).astype(np.float32)
    painted = rng.uniform(0.0, 1.0, (20, 30, 3)).astype(np.float32)
    painted[0, 0] = np.nan
    none = np.zeros((20, 30), np.float32)
    np.testing.assert_array_equal(relit_face(photo, gain, painted, none), photo * gain)
    full = relit_face(photo, gain, painted, np.ones((20, 30), np.float32))
    np.testing.assert_allclose(full[1:], painted[1:], atol=1e-6)
    huge = np.full_like(gain, 40.0)
    np.testing.assert_allclose(relit_face(photo, huge, painted, none), photo * MAX_GAIN, rtol=1e-6)


def test_the_photos_shine_is_not_lifted_with_the_skin_but_kept_as_the_new_light_says():
    """``(I - sh) G + sh k``: a highlight on a cheek lifted 3x stays its own size when the new light keeps it
    (k = 1) and is gone when it does not (k = 0); the skin under it is lifted."""
    skin = np.full((4, 4, 3), 0.2, np.float32)
    shine = np.zeros_like(skin)
    shine[1, 1] = 0.3
    photo = skin + shine
    gain = np.full_like(skin, 3.0)
    none = np.zeros((4, 4), np.float32)
    kept = relit_face(photo, gain, photo, none, shine, np.ones((4, 4), np.float32))
    gone = relit_face(photo, gain, photo, none, shine, np.zeros((4, 4), np.float32))
    np.testing.assert_allclose(kept, 3.0 * skin + shine, rtol=1e-6)
    np.testing.assert_allclose(gone, 3.0 * skin, rtol=1e-6)


def test_a_deeply_lifted_pixel_takes_the_fills_colour_and_keeps_its_brightness():
    """Lifted 12x (past ``CHROMA_LIFT``) a teal-tinted shadow pixel takes the fill's skin colour at its own
    lifted brightness; lifted 2x it keeps its own colour."""
    photo = np.array([[[0.02, 0.04, 0.04], [0.02, 0.04, 0.04]]], np.float32)
    gain = np.array([[[12.0] * 3, [2.0] * 3]], np.float32)
    colour = np.array([[[0.6, 0.45, 0.35], [0.6, 0.45, 0.35]]], np.float32)
    out = relit_face(photo, gain, photo, np.zeros((1, 2), np.float32), colour=colour)
    np.testing.assert_allclose(brightness(out), brightness(photo * gain), rtol=1e-5)
    np.testing.assert_allclose(out[0, 0] / out[0, 0].sum(), colour[0, 0] / colour[0, 0].sum(), atol=1e-5)
    np.testing.assert_allclose(out[0, 1], photo[0, 1] * 2.0, rtol=1e-5)


def test_the_exposure_brings_the_relit_skin_to_the_photos_lit_skin():
    """The relit face's lit skin, 2.5x the photo's (a highlight or two among it), is brought back: the gain is
    1 / 2.5, by the median, which the highlights do not move; with too little lit skin to tell, 1."""
    rng = np.random.default_rng(2)
    photo = rng.uniform(0.3, 0.5, (40, 40, 3)).astype(np.float32)
    photo[:3] = 1.0  # highlights on the lit skin
    lit = np.zeros((40, 40), bool)
    lit[:, :20] = True
    relit = 2.5 * photo
    assert exposure(photo, relit, lit, lit) == pytest.approx(0.4, rel=1e-5)
    few = np.zeros((40, 40), bool)
    few[:5, :5] = True
    assert exposure(photo, relit, few, lit) == 1.0
    assert exposure(photo, relit, lit, few) == 1.0


def test_a_change_of_light_is_smoothed_as_a_ratio_and_is_1_off_the_face():
    """A change alternating 2x and 0.5x pixel by pixel averages to 1 (geometrically, as ratios do; not to
    1.25), a constant change stays itself, and off the face the change is 1."""
    face = np.zeros((40, 40), bool)
    face[5:35, 5:35] = True
    yy, xx = np.mgrid[0:40, 0:40]
    checker = np.where((yy + xx) % 2 == 0, 2.0, 0.5).astype(np.float32)[..., None] * np.ones(3, np.float32)
    smooth = smooth_change(checker, face, 3.0)
    np.testing.assert_allclose(smooth[12:28, 12:28], 1.0, atol=0.01)
    assert np.all(smooth[~face] == 1.0)
    constant = smooth_change(np.full((40, 40, 3), 1.7, np.float32), face, 3.0)
    np.testing.assert_allclose(constant[face], 1.7, rtol=1e-4)


def test_a_new_light_adds_the_room_light_the_photo_showed_but_not_its_shadows():
    """``L' + L_fit max(c - 1, 0)``: where the skin showed 1.5x the fitted shading (0.4) the new light's 0.2
    gains 0.2 of room light; where it showed less (a shadow, c = 0.5) nothing is taken off."""
    new = np.array([[0.2, 0.2]], np.float32)
    fitted = np.array([[0.4, 0.4]], np.float32)
    correction = np.array([[[1.5], [0.5]]], np.float32)
    np.testing.assert_allclose(brightened(new, fitted, correction)[..., 0], [[0.4, 0.2]], rtol=1e-6)
