"""One face relit in its photo (``relight/face.py``, ``FaceRelight``) and the node's honesty about it
(``relight/nodes.py``), on a rendered face whose truth is known: an ICT-FaceKit identity, skin-coloured, lit from
40 degrees right with a room's light of 0.2, its cast and attached shadows traced, in a coloured frame (a linear
8-bit file). The fit is taken as exact (its normals, depth and shadows the render's), so what is checked is the
relighting alone: the photo comes back under its own light, and a new light gives the face the render under it. The
same face lit by a warm lamp in a blue room (``LAMP``, ``ROOM``) checks the colour of the light a relighting adds.
The scene is ``conftest.side_lit_face``."""
from types import SimpleNamespace

import cv2
import numpy as np
import pytest
from conftest import FRAME, LAMP, LEFT, NEW_LIGHT, PHOTO_LIGHT, ROOM, TOP, side_lit_face
from shadowflow.flow.frame import Frame
from shadowflow.nodes.photo.align import Alignment
from shadowflow.nodes.relight.compose import FaceLayer, compose, outside_gain
from shadowflow.nodes.relight.face import FaceRelight
from shadowflow.nodes.relight.fields import distance_to
from shadowflow.nodes.relight.live import FACE, render_live
from shadowflow.nodes.relight.nodes import PhotoRelightNode


@pytest.fixture(scope="module")
def rendered():
    return side_lit_face()


@pytest.fixture(scope="module")
def blue_room():
    return side_lit_face(LAMP, ROOM)


def _log_chroma(rgb: np.ndarray) -> np.ndarray:
    """(..., 2) ln R/G and ln B/G of (..., 3) linear RGB."""
    x = np.maximum(rgb, 1e-4)
    return np.stack([np.log(x[..., 0] / x[..., 1]), np.log(x[..., 2] / x[..., 1])], axis=-1)


def _box(values, face):
    y0, y1, x0, x1 = face.box
    return values[y0:y1, x0:x1]


def test_relit_by_its_own_light_the_face_comes_back_as_the_photo(rendered):
    """Under the photo's own light the relit face is the photo (to a tenth of a level of 255), nothing is painted,
    the exposure is 1, and the layer put back into the photo leaves it as it was."""
    face = rendered.face
    relit = face.relit(PHOTO_LIGHT)
    assert np.abs(relit - _box(rendered.photo, face))[face.face].max() < 0.1 / 255
    assert face.report["painted"] == 0.0 and face.report["exposure"] == pytest.approx(1.0, abs=1e-3)
    assert np.abs(compose(rendered.photo, [face.layer(PHOTO_LIGHT)]) - rendered.photo).max() < 0.1 / 255


def test_relit_by_a_new_light_the_face_is_the_render_under_it(rendered):
    """Lit from the other side, the relit face is the face rendered under that light (up to the one exposure gain):
    within 4 % at the median pixel and 15 % at the 90th percentile (the cast shadows' edges, the fill of the far
    side's attached shadow), where the photo differs from it by over 50 % at the median pixel, and within 20 % in
    the new light's own cast shadow (the nose's), traced on the fitted surface; the side toward the new light is
    brightened, the other darkened; beyond the feather the photo is untouched."""
    face = rendered.face
    relit = face.relit(NEW_LIGHT)
    f = face.face
    truth, photo = _box(rendered.truth, face)[f].mean(axis=-1), _box(rendered.photo, face)[f].mean(axis=-1)
    got = relit[f].mean(axis=-1)
    scale = np.median(got / truth)
    error = np.abs(got - scale * truth) / (scale * truth)
    assert np.median(error) < 0.04 and np.percentile(error, 90) < 0.15
    cast = _box(rendered.new_cast, face)[f]  # the new light's cast shadow falls where the render has it
    assert cast.sum() > 100 and np.median(got[cast] / (scale * truth[cast])) == pytest.approx(1.0, abs=0.2)
    assert np.median(np.abs(photo - truth) / truth) > 0.5
    cols = np.nonzero(f.any(axis=0))[0]
    middle = (cols.min() + cols.max()) // 2
    change = got / photo
    x = np.nonzero(f)[1]
    assert np.median(change[x < middle - 10]) > 1.5 and np.median(change[x > middle + 10]) < 0.8
    out = compose(rendered.photo, [face.layer(NEW_LIGHT)])
    y0, y1, x0, x1 = face.layer_box
    whole = np.zeros(rendered.photo.shape[:2], bool)
    whole[y0:y1, x0:x1] = face.layer_face
    far = distance_to(whole) > face.feather
    np.testing.assert_array_equal(out[far], rendered.photo[far])


def test_the_light_a_new_light_adds_is_the_lamps_colour_not_the_rooms(blue_room):
    """Lit by a warm lamp in a blue room, the side turned from the lamp is blue. Relit toward that side, the skin
    brightened over 1.5 x takes the lamp's colour as the render under the new light has it: its chromaticity within
    0.11 of the truth's at the median pixel (with the room's colour kept, 0.14; the photo's own, 0.41); under the
    photo's own light the face is the photo (to a level of 255: the 8-bit render's bluest shade pulled a little)."""
    face = blue_room.face
    relit = face.relit(NEW_LIGHT)
    truth, photo = _box(blue_room.truth, face), _box(blue_room.photo, face)
    brightened = face.face & (relit.mean(axis=-1) > 1.5 * photo.mean(axis=-1))
    assert brightened.sum() > 2000
    error = np.linalg.norm(_log_chroma(relit[brightened]) - _log_chroma(truth[brightened]), axis=-1)
    assert np.median(error) < 0.11, np.median(error)
    assert np.median(np.linalg.norm(_log_chroma(photo[brightened]) - _log_chroma(truth[brightened]), axis=-1)) > 0.3
    assert np.abs(face.relit(PHOTO_LIGHT) - photo)[face.face].max() < 1.0 / 255


def test_the_live_face_takes_the_lamps_colour_as_the_product_does(blue_room):
    """The live page's relighting (``render_live``) of the face in the blue room, relit toward the side turned from
    the lamp and from the front, differs from the product's relit photo by under 3 grey levels on average inside the
    face (the lamp's colour left out, 4.2 and 5.3)."""
    face = blue_room.face
    live = face.live_data()
    y0, y1, x0, x1 = live.box
    h, w = live.size
    inside = (live.alpha8 == 255) & ((live.flags & FACE) > 0)
    assert inside.sum() > 5000
    for light in (NEW_LIGHT, np.array([0.0, 0.0, 1.0])):
        product = compose(blue_room.photo, [face.layer(light)])[y0:y1, x0:x1]
        theirs = cv2.resize(product, (w, h), interpolation=cv2.INTER_AREA)
        levels = np.abs(render_live(live, light) - theirs).max(axis=-1)[inside] * 255
        assert levels.mean() < 3.0, (light, levels.mean())


def test_what_the_hair_matte_calls_hair_is_not_skin(rendered):
    """A hair matte (``hair_matte``: the face's box -> how sure it is of hair) over the face's upper third takes that
    third out of the skin whose darkness may be a shadow's; the rest of the skin stays as it was without a matte."""
    face = rendered.face
    y0, y1, x0, x1 = face.box
    third = y0 + (y1 - y0) // 3
    asked = []

    def matte(box):
        asked.append(tuple(box))
        share = np.zeros((box[1] - box[0], box[3] - box[2]), np.float32)
        share[:third - box[0]] = 1.0
        return share

    haired = FaceRelight(photo=rendered.photo, alignment=Alignment(np.array([[1.0, 0, LEFT], [0, 1.0, TOP]]), "test"),
                         mask=face.mask, normals=rendered.normals,
                         lit=rendered.lit, albedo=np.where(face.mask, 0.6, np.nan), depth=face.depth,
                         light=PHOTO_LIGHT, iod_px=face.iod, hair_matte=matte)
    assert asked == [tuple(face.box)]
    before, after = face.shown_light.skin, haired.shown_light.skin
    assert before[:third - y0].sum() > 500 and not after[:third - y0].any()
    np.testing.assert_array_equal(after[third - y0:], before[third - y0:])


def test_each_light_carries_its_own_change_of_light_around_the_face(rendered):
    """The part of the gain around the face no light changes is made once for all of a face's lights; each layer's
    gain is still its own light's: equal to the gain made from nothing for that relit face, the photo's own light
    leaving the surround untouched (1 within a thousandth) and the new light changing it by over 5 % on average."""
    face = rendered.face
    at = face.at
    gains = []
    for light in (NEW_LIGHT, PHOTO_LIGHT):
        layer = face.layer(light)
        fresh = outside_gain(at.layer_photo, layer.relit, at.layer_face, face.feather, at.layer_beyond,
                             at.layer_person)
        np.testing.assert_array_equal(layer.gain, fresh)
        gains.append(layer.gain)
    around = ~at.layer_face & np.any(gains[0] != 1.0, axis=-1)
    assert around.sum() > 500
    assert np.abs(gains[1][around] - 1.0).max() < 1e-3
    assert np.abs(gains[0][around] - 1.0).mean() > 0.05


def test_the_node_flags_a_face_mostly_painted_and_gives_back_an_evenly_lit_face_it_would_harm(rendered):
    """``PhotoRelightNode._honest``: a face more than half painted is flagged and its score halved; an evenly lit
    face whose relit layer would change it at a fine scale (blotches of +-30 %) comes back as the photo, bit for
    bit, flagged too (score quartered with both); a face neither (an evenly lit one relit by its own light among
    them) is left alone."""
    face = rendered.face
    frame = Frame(0, "rendered", data={"placement": SimpleNamespace(eyes=rendered.eyes)})
    layer = face.layer(NEW_LIGHT)
    quality = {"score": 0.8, "flags": []}
    layers = PhotoRelightNode._honest(frame, face, [(NEW_LIGHT, layer)], {"painted": 0.1}, quality)
    assert layers[0][1] is layer and quality == {"score": 0.8, "flags": []}
    own = face.layer(PHOTO_LIGHT)  # evenly lit, and relit as it was: no harm done
    quality, report = {"score": 0.8, "flags": [], "even": True}, {"painted": 0.0}
    layers = PhotoRelightNode._honest(frame, face, [(PHOTO_LIGHT, own)], report, quality)
    assert layers[0][1] is own and report["harm"] < 1.0 and quality["flags"] == []
    quality = {"score": 0.8, "flags": []}
    PhotoRelightNode._honest(frame, face, [(NEW_LIGHT, layer)], {"painted": 0.6}, quality)
    assert quality["score"] == pytest.approx(0.4) and len(quality["flags"]) == 1
    blotchy = layer.relit * (1.0 + 0.3 * np.random.default_rng(0).uniform(-1, 1, layer.relit.shape[:2] + (1,)))
    harmful = FaceLayer(layer.box, layer.inside, blotchy.astype(np.float32), layer.gain, layer.alpha)
    quality = {"score": 0.8, "flags": [], "even": True}
    report = {"painted": 0.6}
    layers = PhotoRelightNode._honest(frame, face, [(NEW_LIGHT, harmful)], report, quality)
    assert report["harm"] > 8.0 and quality["score"] == pytest.approx(0.2) and len(quality["flags"]) == 2
    np.testing.assert_array_equal(compose(rendered.photo, [layers[0][1]]), rendered.photo)


def test_a_head_turned_past_the_measures_reach_is_not_judged_by_it(rendered):
    """The honesty check's ellipse from the eyes is a frontal face's: the same blotchy layer that sends an evenly lit
    frontal face back as it was is left to a head read as turned 40 degrees (its eyes' ellipse reaches the
    background, and a head turned toward its light looks evenly lit whatever the light); at 20 degrees it is
    judged."""
    face = rendered.face
    layer = face.layer(NEW_LIGHT)
    blotchy = layer.relit * (1.0 + 0.3 * np.random.default_rng(0).uniform(-1, 1, layer.relit.shape[:2] + (1,)))
    harmful = FaceLayer(layer.box, layer.inside, blotchy.astype(np.float32), layer.gain, layer.alpha)
    for yaw, judged in ((40.0, False), (-40.0, False), (20.0, True)):
        pose = SimpleNamespace(view=(yaw, 0.0))
        frame = Frame(0, "rendered", data={"placement": SimpleNamespace(eyes=rendered.eyes, pose=pose)})
        quality = {"score": 0.8, "flags": [], "even": True}
        layers = PhotoRelightNode._honest(frame, face, [(NEW_LIGHT, harmful)], {"painted": 0.0}, quality)
        assert (layers[0][1] is not harmful) == judged and bool(quality["flags"]) == judged, (yaw, quality)


def test_under_any_light_a_relit_face_with_pasted_patches_comes_back_as_it_was(rendered):
    """``harm_flag`` judges a face lit from the side too: the face relit rightly toward the other side (its new
    terminator and nose shadow are the new light's edges) is kept, its figures reported; the same layer with flat
    patches pasted over it (a hard rim each) is given back as the photo, bit for bit, ``doubtful`` with why, its
    relit layers kept for a clip."""
    face = rendered.face
    frame = Frame(0, "rendered", data={"placement": SimpleNamespace(eyes=rendered.eyes)})
    layer = face.layer(NEW_LIGHT)
    quality, report = {"score": 0.8, "flags": []}, {"painted": 0.0}
    layers = PhotoRelightNode._honest(frame, face, [(NEW_LIGHT, layer)], report, quality)
    assert layers[0][1] is layer and quality["flags"] == []
    assert report["added_edges"] < 2.0 and report["colour_blotches"] < 2.0
    patched = layer.relit.copy()
    yy, xx = np.mgrid[0:patched.shape[0], 0:patched.shape[1]]
    cx, cy = (rendered.eyes.mean(axis=0) - [layer.box[2], layer.box[0]])
    for dx in (-24, -8, 8, 24):
        for dy in (-10, 15, 40):
            patched[np.hypot(xx - cx - dx, yy - cy - dy) < 6] = [0.9, 0.5, 0.45]
    harmful = FaceLayer(layer.box, layer.inside, patched, layer.gain, layer.alpha)
    quality, report = {"score": 0.8, "flags": []}, {"painted": 0.0}
    layers = PhotoRelightNode._honest(frame, face, [(NEW_LIGHT, harmful)], report, quality)
    assert report["added_edges"] > 7.2 and quality["score"] == pytest.approx(0.4)
    assert quality["flags"][0].startswith("relit it would add edges") and quality["flags"][0].endswith("as it was")
    np.testing.assert_array_equal(compose(rendered.photo, [layers[0][1]]), rendered.photo)
    assert frame.data["photo_layers_relit"][0][1] is harmful


def test_a_face_whose_relit_face_would_darken_what_its_file_clipped_comes_back_as_it_was(rendered):
    """A cheek the file cut at its top says only that it was at least that bright: relit toward the other side,
    which darkens that cheek, it would be one flat tone. The face comes back as the photo, bit for bit, ``doubtful``
    with why (``harm.flattened`` over 5 % of the face); the same face unclipped is relit, nothing flattened."""
    face = rendered.face
    frame = Frame(0, "rendered", data={"placement": SimpleNamespace(eyes=rendered.eyes)})
    report = {"painted": 0.0}
    PhotoRelightNode._honest(frame, face, [(NEW_LIGHT, face.layer(NEW_LIGHT))], report, {"score": 0.8, "flags": []})
    assert report["flattened"] == 0.0
    photo = rendered.photo.copy()
    y0, y1, x0, x1 = face.box
    cheek = np.zeros(FRAME, bool)  # the lit (image-right) cheek, below the eyes
    cheek[y0:y1, x0:x1] = face.face
    cx, cy = rendered.eyes.mean(axis=0)
    cheek[:int(cy) + 8] = False
    cheek[:, :int(cx) + 12] = False
    photo[cheek] = 1.0
    clipped = FaceRelight(photo=photo, alignment=Alignment(np.array([[1.0, 0, LEFT], [0, 1.0, TOP]]), "test"),
                          mask=face.mask,
                          normals=rendered.normals, lit=rendered.lit, albedo=np.where(face.mask, 0.6, np.nan),
                          depth=face.depth, light=PHOTO_LIGHT, iod_px=face.iod)
    layer = clipped.layer(NEW_LIGHT)
    quality, report = {"score": 0.8, "flags": []}, {"painted": 0.0}
    layers = PhotoRelightNode._honest(frame, clipped, [(NEW_LIGHT, layer)], report, quality)
    assert report["flattened"] > 5.0 and quality["score"] == pytest.approx(0.4)
    assert quality["flags"][0].startswith("relit it would darken") and quality["flags"][0].endswith("as it was")
    np.testing.assert_array_equal(compose(photo, [layers[0][1]]), photo)


def test_a_fit_that_explains_little_is_no_doubt_when_the_relit_face_shows_no_harm(rendered):
    """``_unharmed_fit``: a face whose fit explains little is doubtful for it only while its relit face shows harm.
    Relit by its own light (no change at all) the flag is taken off and the score raised to 0.7, and so it is for a
    head read as turned 40 degrees; relit with blotches of +-30 % (H above 8 %) it stays, and with soft tinted blobs,
    turned or not; so it does for a head turned past the views' 50 degrees. Soft dim blobs (H, no edge, no colour)
    keep it on a frontal face only: H does not judge a turned one, whose ellipse is no frontal face's."""
    face = rendered.face
    unexplained = "the fitted face explains 12 % of the image's shading"
    own = face.layer(PHOTO_LIGHT)
    blotchy = own.relit * (1.0 + 0.3 * np.random.default_rng(0).uniform(-1, 1, own.relit.shape[:2] + (1,)))
    harmful = FaceLayer(own.box, own.inside, blotchy.astype(np.float32), own.gain, own.alpha)
    # soft dim blobs (H, no edge, no colour) and tinted ones of the same level (colour, no H)
    yy, xx = np.mgrid[0:own.relit.shape[0], 0:own.relit.shape[1]].astype(np.float32)
    cx, cy = rendered.eyes.mean(axis=0) - [own.box[2], own.box[0]]
    blobs = sum(np.exp(-((xx - cx - dx) ** 2 + (yy - cy - dy) ** 2) / (2 * 4.5**2))
                for dx in (-20, 0, 20) for dy in (0, 25, 50))
    dimmed = FaceLayer(own.box, own.inside, (own.relit * (1.0 - 0.5 * blobs)[..., None]).astype(np.float32),
                       own.gain, own.alpha)
    tint = 1.0 + 0.6 * blobs[..., None] * np.array([1.0, -0.376, -0.376], np.float32)  # the skin's level kept
    tinted = FaceLayer(own.box, own.inside, (own.relit * tint).astype(np.float32), own.gain, own.alpha)
    for layer, yaw, cleared in ((own, 0.0, True), (harmful, 0.0, False), (own, 40.0, True), (own, 55.0, False),
                                (dimmed, 0.0, False), (dimmed, 40.0, True), (tinted, 0.0, False),
                                (tinted, 40.0, False)):
        pose = SimpleNamespace(view=(yaw, 0.0))
        frame = Frame(0, "rendered", data={"placement": SimpleNamespace(eyes=rendered.eyes, pose=pose)})
        quality = {"score": 0.06, "flags": [unexplained]}
        report = {"painted": 0.0}
        PhotoRelightNode._honest(frame, face, [(PHOTO_LIGHT, layer)], report, quality)
        if cleared:
            assert quality == {"score": 0.7, "flags": []}, (yaw, report)
            assert ("harm" in report) == (yaw <= 25.0) and report.get("harm", 0.0) < (1.0 if layer is own else 99.0)
        else:
            assert quality == {"score": 0.06, "flags": [unexplained]}, (yaw, report)
            assert layer is not dimmed or (report["harm"] > 8.0 and report["added_edges"] / 7.2 < 0.5), report
            assert layer is not tinted or (report.get("harm", 0.0) < 8.0 and report["colour_blotches"] > 8.0), report
