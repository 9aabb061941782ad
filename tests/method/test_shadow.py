"""Cast and attached shadows, traced and confirmed by the image."""
import numpy as np
import pytest
from shadowflow.nodes.geometry.normals import normals_from_depth
from shadowflow.nodes.geometry.reflectance import light_from_angles
from shadowflow.nodes.method.shadow import cast_margin, cast_shadow, confirm_with_image, shadow_maps, soft_cast


@pytest.mark.parametrize("elev_deg", [30.0, 45.0, 60.0])
def test_shadow_of_a_step_has_the_right_length(elev_deg):
    # a wall of height 10 px at columns 20..21; light from the image's left, elev_deg above the ground plane
    z = np.zeros((20, 80))
    z[:, 20:22] = 10.0
    az = 90.0 - elev_deg  # angle from the view axis
    s = light_from_angles(az)  # toward the image's left: shadows fall to the right
    cast = cast_shadow(z, s)
    length = 10.0 / np.tan(np.radians(elev_deg))
    row = cast[10]
    shadowed = np.flatnonzero(row)
    assert shadowed.min() == 22  # starts right behind the wall
    # heights are bilinear between pixel centres, so the wall top is at column 21 and the
    # shadow reaches up to (not including) column 21 + length
    assert length - 1.0 - 1e-9 <= shadowed.max() - 21 < length
    assert np.array_equal(shadowed, np.arange(22, shadowed.max() + 1))  # one solid run
    assert not row[:20].any()  # nothing on the lit side


def test_a_sphere_has_its_attached_shadow_beyond_the_terminator_and_casts_none():
    """Frontal light: no shadow at all. Light 70 deg from the view axis on a hemisphere (convex,
    so nothing is cast): the attached shadow from the numerically differentiated depth is the
    analytic one, the side beyond the terminator ``n . s = 0``, to within its boundary pixels."""
    r, size = 40.0, 96
    rows, cols = np.mgrid[0:size, 0:size].astype(float)
    x, y = cols - size / 2 + 0.5, -(rows - size / 2 + 0.5)
    inside = x**2 + y**2 < (0.97 * r) ** 2
    z = np.where(inside, np.sqrt(np.clip(r**2 - x**2 - y**2, 0, None)), np.nan)
    n = normals_from_depth(z)
    maps = shadow_maps(z, n, np.array([0, 0, 1.0]))
    assert not maps.cast.any() and not maps.attached.any()
    s = light_from_angles(70)  # toward the image's left: the right side is dark
    maps = shadow_maps(z, n, s)
    analytic = inside & (np.stack([x, y, np.nan_to_num(z)], -1) @ s <= 0)
    assert analytic.sum() > 0.2 * inside.sum()
    assert not maps.cast.any()
    assert np.count_nonzero(maps.attached ^ analytic) < 0.03 * analytic.sum()
    assert not maps.attached[:, : size // 2].any()  # nothing on the lit side


def test_confirmation_removes_lit_pixels_and_grows_into_connected_dark_ones():
    from shadowflow.nodes.method.shadow import ShadowMaps

    traced = np.zeros((10, 10), bool)
    traced[2:5, 2:5] = True
    image = np.ones((10, 10))
    image[2:6, 2:6] = 0.0  # the real shadow is a little larger
    image[2, 2] = 0.5  # ...and this pixel is visibly lit
    image[8, 8] = 0.0  # dark albedo far from any shadow
    out = confirm_with_image(ShadowMaps(traced, np.zeros_like(traced)), image, 0.02)
    expect = image <= 0.02
    expect[8, 8] = False
    assert np.array_equal(out.cast, expect)


def _edge_columns(field: np.ndarray, k: int, rows: range) -> tuple[np.ndarray, np.ndarray]:
    """(rows, columns) in the original pixels of the far edge of ``field`` >= 0.5 brought to a grid ``k`` x
    finer by bilinear interpolation (as the relit photo brings the model grid's shadow to its pixels)."""
    import cv2

    up = cv2.resize(field.astype(np.float32), None, fx=k, fy=k, interpolation=cv2.INTER_LINEAR)
    fine = range(k * rows.start, k * rows.stop)
    cols = [(np.flatnonzero(up[r] >= 0.5).max() + 0.5) / k - 0.5 for r in fine]
    return (np.array(fine) + 0.5) / k - 0.5, np.array(cols)


def test_the_margin_of_a_cast_shadow_is_its_yes_or_no_and_gives_a_straight_edge_between_pixels():
    """A ridge like a nose's along a tilted line, lit 45 degrees from the image's left, casts a shadow whose
    far edge is a tilted straight line. The margin is > 0 exactly where ``cast_shadow`` says shadowed; brought
    4x finer and thresholded (``soft_cast``) its edge follows the line within a fifth of a pixel, where the
    yes-or-no shadow brought the same way is a staircase of whole pixels (measured: within 0.21 against 0.49,
    0.11 against 0.25 px rms)."""
    h, w = 40, 80
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    z = 10.0 * np.exp(-((xx - 20 - 0.3 * yy) / np.hypot(1.0, 0.3)) ** 2 / (2 * 3.0**2))
    z[:, -2:] = np.nan  # off the surface: no margin
    s = light_from_angles(45.0)
    margin, cast = cast_margin(z, s), cast_shadow(z, s)
    assert np.array_equal(margin > 0, cast) and cast.sum() > 300
    assert np.isnan(margin[:, -2:]).all() and np.nanmax(np.abs(margin)) <= 0.5
    assert np.array_equal(soft_cast(margin) > 0.5, cast) and soft_cast(margin)[:, -2:].max() == 0.0
    for field, worst in ((soft_cast(margin), 0.25), (cast.astype(np.float32), None)):
        ys, xs = _edge_columns(field, 4, range(5, h - 5))
        off = np.abs(xs - np.polyval(np.polyfit(ys, xs, 1), ys))
        if worst is None:
            assert off.max() > 0.45  # the staircase the margin is there to avoid
        else:
            assert off.max() < worst, off.max()
    # a light on the view axis casts nothing; from behind the face plane everything is in shadow
    assert (cast_margin(z, np.array([0.0, 0.0, 1.0]))[:, :-2] == -0.5).all()
    assert (cast_margin(z, light_from_angles(95.0))[:, :-2] == 0.5).all()


def test_a_narrow_shadow_beside_a_ridge_too_low_to_cast_it_is_found_and_a_dark_feature_beside_it_is_not():
    """A light 25 degrees from the view axis and a fitted ridge (the nose) 1.8 px high: the ray from the pixel
    beside it clears it by 0.4 px of height, so no cast shadow is traced there, yet the photo is dark in a band
    beside it (the real nose is higher). The band is found from that near miss (given alone as ``near``); a dark
    feature touching the band (an eye, given as a feature) is not, nor a dark region over 2 % of the face (a
    beard); a light on the view axis finds nothing."""
    from shadowflow.nodes.method.shadow import near_cast

    z = np.zeros((80, 120))  # the face: 9,600 px; the band 100 (1 %)
    z[:, 30:34] = 1.8
    s = light_from_angles(25)  # toward the image's left: shadows fall to the right
    intensity = np.full(z.shape, 0.8)
    intensity[10:30, 34:39] = 0.1  # the shadow the real, higher ridge casts
    intensity[10:30, 39:43] = 0.15  # an eye beside it: dark by its albedo
    eye = np.zeros(z.shape, bool)
    eye[10:30, 40:42] = True  # its outline, a pixel inside its dark edge (the feature is grown by one)
    none = np.zeros(z.shape, bool)
    normals = np.dstack([np.zeros_like(z), np.zeros_like(z), np.ones_like(z)])
    traced = confirm_with_image(shadow_maps(z, normals, s), intensity, 0.3, none)
    assert not traced.cast.any()  # the fitted ridge casts nothing
    maps = near_cast(traced, z, s, intensity, 0.3, none, eye)
    band = np.zeros(z.shape, bool)
    band[10:30, 34:39] = True
    assert np.array_equal(maps.cast, band) and np.array_equal(maps.near, band)
    beard = intensity.copy()
    beard[30:70, 34:50] = 0.12  # the band runs on into a dark region of 8 % of the face
    assert not near_cast(traced, z, s, beard, 0.3, none, eye).cast.any()
    # without the feature the eye is taken for the shadow it touches: the reason features are left out
    assert near_cast(traced, z, s, intensity, 0.3, none).cast[10:30, 39:43].all()
    # a frontal light casts no shadow, near or not
    assert not near_cast(traced, z, np.array([0.0, 0.0, 1.0]), intensity, 0.3, none, eye).cast.any()
    # nor does a ridge that the ray clears by more than the near miss's travel (0.5 px: 1.07 px of height here)
    z[:, 30:34] = 1.0
    assert not near_cast(traced, z, s, intensity, 0.3, none, eye).cast.any()


def test_a_near_miss_is_kept_off_the_eyes_brows_mouth_and_beard_and_hair_of_a_real_face():
    """The astronaut's landmarks on the model grid: her eyes and brows, her lips and what lies within 0.2 eye
    distances of them (a moustache's, a goatee's place) are kept out of the near shadows, and so is hair over the
    face; her cheeks and the nose's side are not."""
    from skimage import data
    from shadowflow.nodes.method.nodes import near_cast_kept_out
    from shadowflow.nodes.model.default_model import default_model
    from shadowflow.nodes.photo.placement import features_on_grid, place_faces

    model = default_model()
    placement = place_faces(model, np.ascontiguousarray(data.astronaut()))[0]
    grid = model.grid
    covered = np.zeros(grid, bool)
    covered[5:12, 40:90] = True  # a fringe
    out = near_cast_kept_out(placement, covered, grid, model.iod)
    assert out[features_on_grid(placement, grid, ("eyes", "brows", "lips"))].all() and out[covered].all()
    lips = features_on_grid(placement, grid, ("lips",))
    rows, cols = np.nonzero(lips)
    iod = model.iod
    below, centre = int(rows.max()), int(round(cols.mean()))
    assert out[below + int(0.15 * iod), centre] and not out[below + int(0.3 * iod), centre]
    eye_row = int(round(model.eyes[:, 1].mean()))
    cheek = (eye_row + int(0.5 * iod), int(round(model.eyes[0, 0])))
    assert not out[cheek]
    assert near_cast_kept_out(None, None, grid, iod) is None and near_cast_kept_out(None, covered, grid, iod) is covered
