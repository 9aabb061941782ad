"""The photo's own shadows told from dark albedo (``relight/evidence.py``), on a flat synthetic face lit from
its left whose fitted shading is known exactly: a soft cast shadow on its right (dimmer, the skin's colour kept)
is found and its light read; a beard there (darker and browner) and a darker patch of skin on the lit cheek are
not shadows."""
from types import SimpleNamespace

import numpy as np
import pytest
from shadowflow.nodes.photo.skin import MAX_CHROMA_DISTANCE, skin_distance
from shadowflow.nodes.relight.evidence import shadow_evidence, shadow_gate

H, W, IOD = 96, 160, 60.0
SKIN = np.array([0.62, 0.45, 0.34], np.float32)
BEARD = np.array([0.20, 0.12, 0.04], np.float32)  # darker and browner than the skin


@pytest.fixture(scope="module")
def scene():
    """The face (all of the box), the fitted shape's direct light falling from 1 on the left to 0.1 on the right,
    a shadow cast on the right (a disc, 3 px of penumbra, 0.3 of the light left), a beard in the terminator's
    band away from it, a patch of skin at 0.4 of the skin's albedo on the lit cheek."""
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    face = np.ones((H, W), bool)
    direct = np.clip(1.05 - 0.95 * xx / W, 0.0, 1.0).astype(np.float32)
    lighting = (0.15 + 0.85 * direct).astype(np.float32)
    from_centre = np.hypot(yy - 62, xx - 138)
    cast = (1.0 - 0.7 * np.clip((14.0 - from_centre) / 3.0, 0.0, 1.0)).astype(np.float32)
    beard = (yy > 6) & (yy < 28) & (xx > 122) & (xx < 152)
    patch = (yy > 40) & (yy < 60) & (xx > 20) & (xx < 45)
    albedo = np.where(beard[..., None], BEARD, SKIN) * np.where(patch, 0.4, 1.0)[..., None]
    light = lighting * cast  # the light the photo really shows
    photo = (albedo * light[..., None]).astype(np.float32)
    gate = shadow_gate(np.zeros((H, W), bool), direct, face, IOD)
    # the skin as the relighting tells it: of the lit skin's colour, in its shade too
    skin = skin_distance(photo, face, shade=True, reference=face & (direct >= 0.5)) < MAX_CHROMA_DISTANCE
    expected = np.broadcast_to(SKIN, (H, W, 3)).astype(np.float32)
    return SimpleNamespace(face=face, direct=direct, lighting=lighting, light=light, photo=photo, gate=gate,
                           skin=skin, expected=expected, beard=beard, patch=patch, core=from_centre < 10,
                           far=~beard & ~patch & (from_centre > 22))


def _evidence(s, skin=None, gate=None):
    return shadow_evidence(s.photo, s.expected, s.lighting, s.direct, s.skin if skin is None else skin,
                           s.gate if gate is None else gate, s.face, IOD)


def test_the_gate_is_the_terminators_band_and_the_fits_shadows_grown_by_a_tenth_of_the_eyes_distance():
    """Direct light under 0.35 from column 118 on; grown by 0.1 x 60 = 6 px the gate starts at column 112. A
    pixel of the fit's own shadow on the lit side opens a disc of 6 px around it, and nothing off the face is
    in it."""
    xx = np.mgrid[0:H, 0:W][1]
    direct = np.clip(1.05 - 0.95 * xx / W, 0.0, 1.0).astype(np.float32)
    face = np.ones((H, W), bool)
    assert np.nonzero(direct[0] < 0.35)[0].min() == 118
    gate = shadow_gate(np.zeros((H, W), bool), direct, face, IOD)
    assert np.all(gate[:, 112:]) and not gate[:, :112].any()
    spot = np.zeros((H, W), bool)
    spot[48, 40] = True
    face[:, :38] = False
    gate = shadow_gate(spot, direct, face, IOD)
    assert gate[48, 46] and gate[42, 40] and not gate[48, 47] and not gate[48, 34]
    assert not gate[:, :38].any()


def test_a_soft_cast_shadow_that_keeps_the_skins_colour_is_found_and_its_light_read(scene):
    """The shadow is skin (its colour kept), so its core is fully in the photo's shadows and the light read
    there is the light it really gets (0.3 of the fitted shading, to 10 %: the fitted shading would be 3.3x
    too bright); the lit skin away from it is in no shadow and its light is the fitted shading."""
    assert scene.skin[scene.core].all()
    ev = _evidence(scene)
    assert ev.found
    assert ev.membership[scene.core].min() > 0.9
    light = ev.lighting(scene.lighting).mean(axis=-1)
    assert np.median(light[scene.core] / scene.light[scene.core]) == pytest.approx(1.0, abs=0.1)
    assert np.all(ev.membership[scene.far] == 0.0)
    np.testing.assert_allclose(light[scene.far], scene.lighting[scene.far], rtol=1e-4)


def test_a_beard_darker_and_browner_in_the_gate_is_not_a_shadow(scene):
    """The beard is a quarter to a tenth of the skin's albedo, in the terminator's band where a shadow may fall.
    Its colour is not the skin's, so it is not read: it is in no shadow and takes the skin's light around it (the
    fitted shading there), and is lifted as the skin is. Read as skin it would be taken for a shadow (the scene
    tells them apart only by colour)."""
    assert not scene.skin[scene.beard].any()
    ev = _evidence(scene)
    assert ev.membership[scene.beard].max() < 0.05
    light = ev.lighting(scene.lighting).mean(axis=-1)
    np.testing.assert_allclose(light[scene.beard], scene.lighting[scene.beard], rtol=0.02)
    as_skin = _evidence(scene, skin=scene.face)
    assert np.median(as_skin.membership[scene.beard]) > 0.9


def test_a_darker_patch_of_skin_on_the_lit_cheek_is_not_a_shadow(scene):
    """Out of the gate (where the fitted shape lets no shadow fall) a patch of skin 0.4 as bright as the skin
    around it is the person's: no shadow, its light the fitted shading exactly. Were the whole face the gate,
    the same patch would be taken for one."""
    assert scene.skin[scene.patch].all() and not scene.gate[scene.patch].any()
    ev = _evidence(scene)
    assert np.all(ev.membership[scene.patch] == 0.0)
    np.testing.assert_allclose(ev.lighting(scene.lighting).mean(axis=-1)[scene.patch],
                               scene.lighting[scene.patch], rtol=1e-5)
    everywhere = _evidence(scene, gate=scene.face)
    assert np.median(everywhere.membership[scene.patch]) > 0.9
