"""A face's change of light carried over a clip's frames (``relight.temporal``), on synthetic layers with known
levels: a jittering level comes out steadier, a real change is followed, the face's grid moves with the eyes, the
frame's fine texture stays its own, and the photo past the layer's reach stays the photo; a change the photo itself
shows (a light moved) is the frame's own at once, its overall level (an exposure) is not such a change."""
from __future__ import annotations

import numpy as np
from shadowflow.nodes.relight import temporal as T
from shadowflow.nodes.relight.compose import FaceLayer, compose

H = W = 200
EYES = np.array([[80.0, 90.0], [120.0, 90.0]])
YY, XX = np.mgrid[:H, :W]


def photo(seed: int = 0) -> np.ndarray:
    """(H, W, 3) a textured grey photo in linear light."""
    rng = np.random.default_rng(seed)
    return (0.25 + 0.05 * rng.random((H, W, 1))).repeat(3, axis=2).astype(np.float32)


def layer(image: np.ndarray, k, dx: float = 0.0, fine: np.ndarray | None = None) -> FaceLayer:
    """A face (a disc below the eyes, moved ``dx`` pixels) brightened ``k`` times (a number, or (H, W, 1) per pixel),
    its gain fading to 1 around it (0 change beyond 80 pixels from its centre); ``fine``: (H, W) a fine factor on the
    relit face."""
    r = np.hypot(XX - 100 - dx, YY - 110)
    inside = r < 50
    fade = np.clip((80 - r) / 30, 0, 1)[..., None]
    gain = np.where(inside[..., None], k, 1.0 + fade * (k - 1.0)).astype(np.float32)
    relit = image * k * (1.0 if fine is None else fine[..., None])
    return FaceLayer((0, H, 0, W), inside, relit.astype(np.float32), gain)


def centre_level(lay: FaceLayer, image: np.ndarray, dx: float = 0.0, x: float = 100.0, reach: float = 20.0) -> float:
    """The mean factor of the relit face over the photo near its centre (or near ``x``, within ``reach`` pixels)."""
    r = np.hypot(XX - x - dx, YY - 110) < reach
    return float(np.mean(lay.relit[r] / image[r]))


def run(levels, dxs=None, image=None) -> list[float]:
    image = photo() if image is None else image
    dxs = [0.0] * len(levels) if dxs is None else dxs
    carried, out = None, []
    for k, dx in zip(levels, dxs):
        steadied, carried = T.steady_layer(layer(image, k, dx), image, EYES + [dx, 0.0], carried)
        out.append(centre_level(steadied, image, dx))
    return out


def test_a_jittering_level_comes_out_steadier():
    levels = [2.0 * (1.1 if i % 2 else 1 / 1.1) for i in range(20)]
    out = run(levels)
    step_in = np.abs(np.diff(np.log(levels[10:]))).mean()
    step_out = np.abs(np.diff(np.log(out[10:]))).mean()
    # an exponential average with a frame's share 0.3 leaves 0.3 / 1.7 of an alternating step
    assert step_out < 0.3 * step_in
    assert abs(np.mean(np.log(out[10:])) - np.log(2.0)) < 0.02  # about the level the frames share


def test_a_real_change_is_followed_within_a_few_frames():
    out = run([1.0] * 5 + [3.0] * 10)
    assert out[0] == np.float32(1.0) or abs(out[0] - 1.0) < 1e-5  # the first frame as it came
    assert abs(out[5] - 3.0) > 0.5  # the change is averaged in, not taken at once
    assert abs(np.log(out[5 + 8]) - np.log(3.0)) < 0.05  # ... and followed within eight frames


def test_the_grid_moves_with_the_face():
    """A face moving across the frame under a steady light needs no correction: the carried change moves with it."""
    dxs = [3.0 * i for i in range(10)]
    out = run([2.0] * 10, dxs)
    assert max(abs(v - 2.0) for v in out) < 0.02
    grid = T.FaceGrid.from_eyes(EYES + [12.0, 0.0])
    field = np.exp(-((XX - 112.0) ** 2 + (YY - 110.0) ** 2) / 800.0).astype(np.float32)
    values, known = T.to_grid(field, grid, (0, H, 0, W))
    back, weight = T.from_grid(values, known, grid, (0, H, 0, W))
    on = weight > 0.99
    assert on[110, 112] and np.abs(back - field)[on].max() < 0.02
    moved = T.FaceGrid.from_eyes(EYES)
    shifted, _ = T.to_grid(field, moved, (0, H, 0, W))
    assert np.abs(shifted - values)[known].max() > 0.2  # the grid is the face's, not the photo's


def test_the_frames_fine_texture_stays_its_own():
    image = photo()
    rng = np.random.default_rng(5)
    carried = None
    for k in [2.0, 2.6, 1.5]:
        fine = (1.0 + 0.2 * rng.standard_normal((H, W))).astype(np.float32)
        lay = layer(image, k, fine=fine)
        steadied, carried = T.steady_layer(lay, image, EYES, carried)
    factor = np.log(steadied.relit[..., 0] / lay.relit[..., 0])[lay.inside]
    fine_log = np.log(fine)[lay.inside]
    # the correction is smooth: it does not follow the frame's fine pattern
    assert abs(np.corrcoef(factor, fine_log)[0, 1]) < 0.25
    assert factor.std() < 0.1 * fine_log.std() + 0.02


def test_the_photo_past_the_layers_reach_is_untouched():
    image = photo()
    carried = None
    for k in [2.0, 1.2, 2.8]:
        steadied, carried = T.steady_layer(layer(image, k), image, EYES, carried)
    before, after = compose(image, [layer(image, 2.8)]), compose(image, [steadied])
    beyond = np.hypot(XX - 100, YY - 110) >= 80 + 5 * T.COARSE * 40  # the change's reach and its blur's
    assert np.array_equal(after[beyond], image[beyond])
    assert np.array_equal(before[beyond], after[beyond])
    assert not np.allclose(after[~beyond], before[~beyond])  # (within it, the change was steadied)


def test_a_change_the_photo_shows_is_the_frames_own_at_once():
    """A light moved: the face's image-left half is half as bright as before, and the relighting lifts it twice as
    much (its change 4 there, 2 on the right). The first frame under the new light is relit as its own change says;
    averaged with the change made for the photo before, its left half would come back a fifth too dark."""
    lit = photo()
    dark = lit.copy()
    dark[:, :100] *= 0.5
    carried = None
    for _ in range(6):
        _, carried = T.steady_layer(layer(lit, 2.0), lit, EYES, carried)
    k = np.where(XX < 100, 4.0, 2.0)[..., None]
    changed = T.light_shown_changed(T.photo_on_grid(lit[..., 0], EYES), T.photo_on_grid(dark[..., 0], EYES))
    assert changed
    steadied, carried = T.steady_layer(layer(dark, k), dark, EYES, carried, light_changed=changed)
    assert abs(centre_level(steadied, dark, x=75.0, reach=8.0) - 4.0) < 0.2
    assert abs(centre_level(steadied, dark, x=125.0, reach=8.0) - 2.0) < 0.1
    # the relit face is as it was under the light before: the half lifted as far as the photo darkened
    left = np.hypot(XX - 75, YY - 110) < 8
    assert abs(float(np.mean(steadied.relit[left])) / float(np.mean(2.0 * lit[left])) - 1.0) < 0.05


def test_a_frame_relit_under_its_own_light_is_its_own_and_the_carry_passes_it_by():
    """A frame fitted under its own estimate, which left the clip's running light (``alone``: a departure not yet
    confirmed), keeps its own change (3, where the running change is 2), and the frames after it are steadied by the
    running change from before it, untouched by its own: the next frame at 2 comes back at 2 (carried through it, it
    would come back 0.3 of the way to 3)."""
    image = photo()
    carried = None
    for _ in range(6):
        _, carried = T.steady_layer(layer(image, 2.0), image, EYES, carried)
    alone, kept = T.steady_layer(layer(image, 3.0), image, EYES, carried, alone=True)
    assert kept is carried
    assert abs(centre_level(alone, image) - 3.0) < 0.02
    after, _ = T.steady_layer(layer(image, 2.0), image, EYES, kept)
    assert abs(centre_level(after, image) - 2.0) < 0.02


def test_an_exposure_is_not_a_change_of_light():
    """The photo's overall level steps by 10 % from frame to frame (a camera's exposure) while the fit's change
    jitters: the jitter is still averaged (the photo shows no change of light), and the relit face follows the
    photo's level as the photo does."""
    image = photo()
    carried, out, levels, before = None, [], [], None
    for i in range(20):
        frame_image = image * np.float32(0.9 if i % 2 else 1.0)
        k = 2.0 * (1.1 if i % 2 else 1 / 1.1)
        now = T.photo_on_grid(frame_image[..., 0], EYES)
        changed = before is not None and T.light_shown_changed(before, now)
        steadied, carried = T.steady_layer(layer(frame_image, k), frame_image, EYES, carried, light_changed=changed)
        before = now
        out.append(centre_level(steadied, frame_image))
        levels.append(k)
    step_in = np.abs(np.diff(np.log(levels[10:]))).mean()
    step_out = np.abs(np.diff(np.log(out[10:]))).mean()
    assert step_out < 0.3 * step_in
