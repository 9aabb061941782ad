"""Shadows the face does not cast (``relight/foreign.py``, their light in ``relight/evidence.py``, their lift in
``relight/face.py``), on a rendered face whose truth is known: an ICT-FaceKit identity, skin-coloured with a fine
texture, lit from 20 degrees with a room's light of 0.2, a hat's brim's shadow laid over its brow and eyes (0.35 of
the light left, a penumbra of 2 px), a darker patch of skin (0.7) on a cheek. The fit is taken as exact, so what is
checked is the shadow's finding and lifting: relit by its own light, the face comes back as the photo without the
brim; without looking for such shadows it keeps it."""
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import ndimage
from shadowflow.nodes.evaluation.occluders import KINDS, brim, lay_shadow, occluder
from shadowflow.nodes.evaluation.scenes import draw_face
from shadowflow.nodes.geometry.integrate import fill_holes
from shadowflow.nodes.geometry.normals import normals_from_depth
from shadowflow.nodes.geometry.reflectance import light_from_angles
from shadowflow.nodes.method.shadow import shadow_maps
from shadowflow.nodes.model.canonical import canonical_eyes
from shadowflow.nodes.photo.align import Alignment
from shadowflow.nodes.photo.evenness import face_ellipse, halves_ratio
from shadowflow.nodes.relight.face import FaceRelight
from shadowflow.nodes.relight.face_box import Features
from shadowflow.nodes.relight.foreign import found as shadows_found

GRID = (256, 256)  # the eyes 72 px apart: a face large enough to tell skin from a beard (``SKIN_MIN_IOD``)
TOP, LEFT = 40, 50  # the model grid's corner in the photo
FRAME = (340, 360)
SKIN = np.array([0.75, 0.55, 0.42], np.float32)
AMBIENT = 0.2
LIGHT = light_from_angles(-20.0)
LEFT_IN_SHADE = 0.35


def _in_photo(values: np.ndarray, fill=False) -> np.ndarray:
    out = np.full(FRAME, fill, values.dtype)
    out[TOP:TOP + GRID[0], LEFT:LEFT + GRID[1]] = values
    return out


@pytest.fixture(scope="module")
def scene():
    depth, mask, _ = draw_face(np.random.default_rng(3), GRID, "ict")
    depth = fill_holes(depth, mask)
    normals = normals_from_depth(depth)
    shadows = shadow_maps(depth, normals, LIGHT)
    shading = AMBIENT + (1 - AMBIENT) * np.clip(np.nan_to_num(normals) @ LIGHT, 0.0, None) * shadows.lit
    yy, xx = np.mgrid[0:FRAME[0], 0:FRAME[1]] / 200.0
    texture = 1.0 + 0.06 * np.random.default_rng(5).standard_normal(GRID)  # pores: the skin's own, kept when lifted
    eyes = canonical_eyes(GRID) + [LEFT, TOP]
    iod = float(eyes[1, 0] - eyes[0, 0])
    patch = _in_photo(np.zeros(GRID, bool))
    patch[TOP + 168:TOP + 198, LEFT + 50:LEFT + 88] = True
    albedo = SKIN * _in_photo(texture.astype(np.float32), 1.0)[..., None] * np.where(patch, 0.7, 1.0)[..., None]
    image = np.dstack([0.2 + 0.2 * xx, 0.3 - 0.1 * yy, np.full_like(xx, 0.25)]).astype(np.float32)
    face_px = _in_photo(mask)
    image[face_px] = (albedo * _in_photo(shading.astype(np.float32), 0.0)[..., None])[face_px]
    blocked = brim(FRAME, eyes, np.random.default_rng(1))  # the first draw: its edge 0.36 iod below the eyes
    clean = np.round(image * 255) / 255
    photo = (np.round(lay_shadow(image, blocked, LEFT_IN_SHADE, 2.0) * 255) / 255).astype(np.float32)

    def relight(looked_for: bool) -> FaceRelight:
        return FaceRelight(photo=photo, alignment=Alignment(np.array([[1.0, 0, LEFT], [0, 1.0, TOP]]), "test"),
                           mask=mask, normals=normals, lit=shadows.lit, albedo=np.where(mask, 0.6, np.nan),
                           depth=depth, light=LIGHT, iod_px=iod, model_normals=normals if looked_for else None)

    def relight_photo(photo: np.ndarray, features: Features | None = None) -> FaceRelight:
        return FaceRelight(photo=photo, alignment=Alignment(np.array([[1.0, 0, LEFT], [0, 1.0, TOP]]), "test"),
                           mask=mask, normals=normals, lit=shadows.lit, albedo=np.where(mask, 0.6, np.nan),
                           depth=depth, light=LIGHT, iod_px=iod, model_normals=normals, features=features)

    # a shadow over the lit half of the face from a line beside its midline, as far out as evens the halves
    ellipse = face_ellipse(eyes, FRAME)
    toward = 1.0 if np.mean(clean.mean(axis=-1)[TOP:, :int(eyes[:, 0].mean())]) > np.mean(
        clean.mean(axis=-1)[TOP:, int(eyes[:, 0].mean()):]) else -1.0  # image-left lit: +1
    columns = np.broadcast_to(np.arange(FRAME[1], dtype=float), FRAME)
    evened = []
    for d in np.arange(0.0, 0.8, 0.02) * iod:
        half = toward * (eyes[:, 0].mean() - columns) > d
        laid = (np.round(lay_shadow(image, half, LEFT_IN_SHADE, 2.0) * 255) / 255).astype(np.float32)
        evened.append((halves_ratio(laid, ellipse), d, half, laid))
    _, _, lit_half, half_shaded = min(evened, key=lambda e: e[0])
    return SimpleNamespace(photo=photo, clean=clean.astype(np.float32), blocked=blocked, face=face_px, eyes=eyes,
                           iod=iod, patch=patch, relit=relight(True), plain=relight(False), lit_half=lit_half,
                           half_shaded_photo=half_shaded, half_shaded=relight_photo(half_shaded), image=image,
                           relight_photo=relight_photo)


def _box(values, face: FaceRelight):
    y0, y1, x0, x1 = face.box
    return values[y0:y1, x0:x1]


def test_a_brims_shadow_is_found_where_it_falls_and_nowhere_else(scene):
    """The shadow found covers the brim's shade where the fitted shape is lit (out of its own shadows' gate), and
    leaves the lit skin, the darker patch of skin (0.7 of the skin) among it, alone: a third to two thirds of the
    face."""
    face = scene.relit
    foreign = face.shown_light.evidence.foreign
    core = _box(scene.blocked > 0.5, face) & face.at.face & (face.shown_light.evidence.gate < 0.01)
    lit = _box(scene.blocked < 0.01, face) & face.at.face
    assert np.mean(foreign[core] > 0.9) > 0.9
    assert np.mean(foreign[lit] > 0.1) < 0.02
    assert foreign[_box(scene.patch, face)].max() < 0.1
    found = shadows_found(face.shown_light.evidence.foreign, face.at.face, face.iod)
    assert 1 <= found["count"] <= 3 and 0.3 < found["area"] < 0.7  # the brim's, and its slivers the gate cuts off


def test_not_looked_for_none_is_found(scene):
    assert not scene.plain.shown_light.evidence.foreign.any()
    assert scene.plain.foreign_lift() is None


def test_relit_by_its_own_light_the_face_comes_back_without_the_shadow_its_texture_kept(scene):
    """Under the photo's own light the face is kept as it was but for the shadow: its shaded skin comes back to
    within 10 % of the photo without the brim (median), its pores the photo's (their fine detail, a high-pass of the
    log, 90 % of the clean photo's or more, and the ratio to it varying by under 2 %), and the lit skin is left to
    1 %. Not looked for, the shadow stays (under 40 % of the light)."""
    face = scene.relit
    relit = face.relit(LIGHT)
    clean, photo = _box(scene.clean, face), _box(scene.photo, face)
    core = _box(scene.blocked > 0.5, face) & face.at.face & (face.shown_light.evidence.gate < 0.01)
    core = ndimage.binary_erosion(core, iterations=4) & face.shown_light.skin  # past the penumbra
    ratio = relit.mean(axis=-1)[core] / clean.mean(axis=-1)[core]
    assert np.median(ratio) == pytest.approx(1.0, abs=0.1)
    assert np.std(np.log(ratio)) < 0.02

    def fine(image):
        log = np.log(image.mean(axis=-1) + 1e-4)
        return (log - ndimage.gaussian_filter(log, 3.0))[core]
    assert np.sum(fine(relit) * fine(clean)) / np.sum(fine(clean) ** 2) > 0.9
    lit = _box(scene.blocked < 0.01, face) & face.at.face & face.shown_light.skin
    np.testing.assert_allclose(np.median(relit.mean(axis=-1)[lit] / photo.mean(axis=-1)[lit]), 1.0, atol=0.01)
    kept = scene.plain.relit(LIGHT)
    assert np.median(kept.mean(axis=-1)[core] / clean.mean(axis=-1)[core]) < 0.4


def test_the_lift_of_the_shadow_is_what_the_harm_measure_leaves_out(scene):
    """``foreign_lift``: the shadow's core raised by about the inverse of what it keeps (1 / 0.35), the lit skin
    by nothing, 1 around the face."""
    face = scene.relit
    lift = face.foreign_lift()
    y0, y1, x0, x1 = face.layer_box
    core = (scene.blocked[y0:y1, x0:x1] > 0.99) & face.layer_face
    assert np.median(lift[core].mean(axis=-1)) == pytest.approx(1.0 / LEFT_IN_SHADE, rel=0.15)
    assert np.all(lift[~face.layer_face] == 1.0)


def test_occluders_keep_their_share_of_the_light_in_their_core_and_all_of_it_outside():
    """Each kind of shadow drawn from the eyes covers part of the photo, not all of it; laid over it, its core keeps
    ``ambient`` of the light (cooler in colour, the blue raised over the red), its outside all of it, and its
    penumbra between; an unknown kind is named in the error."""
    eyes = np.array([[80.0, 90.0], [140.0, 90.0]])
    photo = np.full((200, 220, 3), 0.5, np.float32)
    for kind in KINDS:
        blocked = occluder(kind, photo.shape[:2], eyes, np.random.default_rng(0)) > 0.5
        assert 0.02 < blocked.mean() < 0.9, kind
        laid = lay_shadow(photo, blocked, 0.3, 3.0)
        inner = ndimage.binary_erosion(blocked, iterations=15, border_value=1)
        outer = ndimage.binary_erosion(~blocked, iterations=15, border_value=1)
        assert inner.any() and outer.any()
        np.testing.assert_allclose(laid[inner].mean(axis=-1), 0.5 * 0.3, rtol=0.02)
        assert np.all(laid[inner][:, 2] > laid[inner][:, 0])
        np.testing.assert_allclose(laid[outer], 0.5, atol=1e-4)
        edge = blocked & ~ndimage.binary_erosion(blocked, border_value=1)
        assert np.all((laid[edge].mean(axis=-1) > 0.16) & (laid[edge].mean(axis=-1) < 0.49))
    with pytest.raises(ValueError, match="unknown shadow kind 'cloud'"):
        occluder("cloud", (10, 10), eyes, np.random.default_rng(0))


def test_a_shadow_that_evens_a_side_lit_face_is_judged_on_the_face_without_it(scene):
    """A shadow from elsewhere over the lit half of a face lit from the side (a hand's at 25 deg on Yale B) can even
    its halves: the photo reads lit evenly, and relit frontally the light's change read as harm (Yale B's hands at
    +-25 deg were given back, 28 % of them removed; judged without them, 56 %). Judged on the photo without the
    shadows it lifts, the face is lit from the side, as it is; without such shadows, the photo's own reading
    stands."""
    from shadowflow.nodes.relight.nodes import layer_pair, lit_evenly

    eyes, lit_half = scene.eyes, scene.lit_half
    ellipse = face_ellipse(eyes, FRAME)
    assert halves_ratio(scene.clean, ellipse) > 1.3  # lit from the side
    assert halves_ratio(scene.half_shaded_photo, ellipse) < 1.15  # yet the shadow evens its halves
    face = scene.half_shaded
    assert face.foreign_lift() is not None and lit_half[face.at.box[0]:face.at.box[1]].any()
    layer = face.layer(LIGHT)
    pair = layer_pair(face, layer)
    assert not lit_evenly(face, layer, pair, eyes, {"even": True})
    assert lit_evenly(scene.plain, scene.plain.layer(LIGHT), layer_pair(scene.plain, scene.plain.layer(LIGHT)), eyes,
                      {"even": True})


def test_a_lit_gap_in_a_shadow_over_an_eye_is_not_lifted(scene):
    """Leaves' shadow over the eyes with a gap of light on one of them: the eye and the lid around it are not skin
    (the face mesh's outline), and are in the shadow as far as the skin around them is, but not where they show the
    lit light themselves: lifted with the shadow, the gap came out white (a Yale B subject under laid-over leaves;
    1 / 0.35 of its light). The rest of the eyes in the shadow are lifted as it is."""
    iod, eyes = scene.iod, scene.eyes
    t = np.linspace(0.0, 2.0 * np.pi, 24, endpoint=False)
    outline = [e + np.column_stack([0.25 * iod * np.cos(t), 0.1 * iod * np.sin(t)]) for e in eyes]
    rows, cols = np.mgrid[0:FRAME[0], 0:FRAME[1]]
    gap = np.hypot(cols - eyes[0, 0], rows - eyes[0, 1] - 0.05 * iod) < 0.15 * iod
    shaded = (rows < eyes[0, 1] + 0.6 * iod) & ~gap
    photo = (np.round(lay_shadow(scene.image, shaded, LEFT_IN_SHADE, 1.0) * 255) / 255).astype(np.float32)
    face = scene.relight_photo(photo, Features(eyes=outline, brows=[], lips=[]))
    lift = face.foreign_lift()
    assert lift is not None
    y0, y1, x0, x1 = face.layer_box
    in_box = (slice(y0, y1), slice(x0, x1))
    core = ndimage.binary_erosion(gap, iterations=2)[in_box] & face.layer_face
    other_eye = (np.hypot(cols - eyes[1, 0], rows - eyes[1, 1]) < 0.1 * iod)[in_box] & face.layer_face
    assert np.median(lift[core].mean(axis=-1)) < 1.2
    assert np.median(lift[other_eye].mean(axis=-1)) == pytest.approx(1.0 / LEFT_IN_SHADE, rel=0.2)


def test_a_shadow_across_the_side_the_light_reaches_less_is_found_all_across(scene):
    """A band of shade across the lower face runs from skin the fitted shape lights into the band where it turns
    from the light (its own shadows' margin, where no shadow from elsewhere is seeded): found from the lit side, it
    is found all across, over skin as dark, short of the face's rim (it stopped at that margin: half of the shade of
    leaves and brims at 25 deg on Yale B was left)."""
    eyes, iod = scene.eyes, scene.iod
    rows = np.mgrid[0:FRAME[0], 0:FRAME[1]][0]
    band = (rows > eyes[0, 1] + 0.45 * iod) & (rows < eyes[0, 1] + 0.95 * iod)
    photo = (np.round(lay_shadow(scene.image, band, LEFT_IN_SHADE, 2.0) * 255) / 255).astype(np.float32)
    face = scene.relight_photo(photo)
    evidence = face.shown_light.evidence
    inside = ndimage.distance_transform_edt(face.at.face) > 0.2 * iod  # (not followed along the rim)
    core = _box(ndimage.binary_erosion(band, iterations=3), face) & inside & face.shown_light.skin
    margin = core & (evidence.gate > 0.01)
    assert margin.sum() > 0.5 * core.sum()  # most of it is in the margin
    assert np.mean(evidence.foreign[margin] > 0.5) > 0.9
    assert np.mean(evidence.foreign[core] > 0.5) > 0.9


def test_a_face_with_shade_left_unfound_takes_the_exposure_of_its_skin_without_the_shade_found():
    """The relit face's exposure is the photo's lit skin's level; a shade left unfound pulls it down (a face under
    leaves at 25 deg came back a fifth darker than without them). With the shadows found lifted, the level is read on
    the photo without them as well, and the brighter taken: here 0.5, the skin's, where the lit skin alone (more of
    it in the unfound shade than out) reads 0.175."""
    from shadowflow.nodes.relight.lift import exposure_target, precision
    from shadowflow.nodes.relight.shown_light import exposure_wanted

    rows = np.arange(100)[:, None] * np.ones((1, 80))
    found, unfound = rows < 40, (rows >= 40) & (rows < 75)
    photo = np.where(found | unfound, 0.5 * 0.35, 0.5).astype(np.float32)[..., None] * np.ones(3, np.float32)
    lift = np.where(found, 1.0 / 0.35, 1.0).astype(np.float32)[..., None] * np.ones(3, np.float32)
    skin = np.ones(rows.shape, bool)
    shown = SimpleNamespace(at=SimpleNamespace(photo=photo), lit_skin=skin & ~found, foreign_lift=lift, skin=skin,
                            relative=precision(photo.mean(axis=-1)), encoding="linear")
    assert exposure_target(photo, shown.lit_skin) == pytest.approx(0.175, rel=1e-3)
    assert exposure_wanted(shown, np.ones(rows.shape, np.float32)) == pytest.approx(0.5, rel=1e-3)
    shown.foreign_lift = None  # none found: the lit skin's
    assert exposure_wanted(shown, np.ones(rows.shape, np.float32)) == pytest.approx(0.175, rel=1e-3)
