"""A relit face put back into its photo (``relight/compose.py``): beyond the feather the photo is its own bit
for bit, the face's change of light runs on into the photo around it and fades out, held within
``RATIO_OUTSIDE`` and to the person, and the relit face fades into the photo with no outline."""
import numpy as np
from shadowflow.nodes.relight.compose import RATIO_OUTSIDE, FaceLayer, compose, composite, inner_alpha, outside_gain
from shadowflow.nodes.relight.fields import distance_inside, distance_to

H, W = 100, 120


def _face(radius: float = 25.0) -> np.ndarray:
    yy, xx = np.mgrid[0:H, 0:W]
    return np.hypot(yy - 50, xx - 60) <= radius


def test_beyond_the_feather_the_photo_is_its_own_bit_for_bit():
    """A face relit twice as bright in a textured photo: every pixel more than the feather (12 px) from the face
    is the photo's exact value; the face is the relit face; between, the photo follows the face's change of light
    (2x at the face's edge) falling steadily to 1."""
    rng = np.random.default_rng(0)
    photo = rng.uniform(0.1, 0.4, (H, W, 3)).astype(np.float32)
    face = _face()
    relit = np.where(face[..., None], 2.0 * photo, 0.0).astype(np.float32)
    out = composite(photo, relit, face, 12.0)
    away = distance_to(face)
    np.testing.assert_array_equal(out[away > 12.0], photo[away > 12.0])
    np.testing.assert_array_equal(out[face], relit[face])
    ring = (out / photo)[50, 86:98].mean(axis=-1)  # from just outside the face to the feather's end
    assert ring[0] > 1.9 and ring[-1] < 1.05
    assert np.all(np.diff(ring) <= 1e-6)


def test_the_change_around_the_face_is_held_within_its_range_and_to_the_person():
    """A face relit 10x brighter lifts the photo beside it at most 4x (a dark wall would glow), one relit 50x
    darker darkens it at most to 0.15x; where the segmentation says it is not the person, the photo keeps its
    light exactly."""
    photo = np.full((H, W, 3), 0.05, np.float32)
    face = _face()
    beside = ~face & (distance_to(face) <= 1.0)
    lo, hi = RATIO_OUTSIDE
    brighter = outside_gain(photo, np.where(face[..., None], 10.0 * photo, 0.0), face, 12.0)
    assert brighter[~face].max() <= hi + 1e-5
    assert brighter[beside].min() > 3.5  # it does brighten, as far as it may
    darker = outside_gain(photo, np.where(face[..., None], 0.02 * photo, 0.0), face, 12.0)
    assert darker[~face].min() >= lo - 1e-5
    assert darker[beside].max() < 0.2  # it does darken, as far as it may
    person = np.ones((H, W), np.float32)
    person[:, 60:] = 0.0
    gain = outside_gain(photo, np.where(face[..., None], 3.0 * photo, 0.0), face, 12.0, person=person)
    assert np.all(gain[~face & (person == 0)] == 1.0)
    assert gain[beside & (person == 1)].min() > 2.5


def test_the_relit_face_fades_in_from_its_border_without_a_step():
    """``inner_alpha``: 0 off the face, 1 from 0.4 of the feather (8 px of 20) inside it, and between a ramp
    with no step between neighbours larger than a smooth ramp over 8 px has (1.5 / 8 at its steepest)."""
    face = _face()
    alpha = inner_alpha(face, 20.0)
    inside = distance_inside(face)
    assert np.all(alpha[~face] == 0.0)
    assert np.all(alpha[inside >= 8.0] == 1.0)
    assert 0.0 < alpha[face & (inside < 8.0)].min() and alpha[face & (inside < 8.0)].max() < 1.0
    steps = max(np.abs(np.diff(alpha, axis=0)).max(), np.abs(np.diff(alpha, axis=1)).max())
    assert steps < 0.25


def test_a_relit_face_meets_the_photo_with_no_outline_whatever_its_own_border():
    """A face whose relit pixels are blotchy (twice the photo, +-50 % from pixel to pixel) put back with its
    fade: across the face's outline the image steps by no more than a few per cent of a pixel's own blotch
    (it meets the photo times the face's change of light there); put back without the fade it steps by the
    blotches themselves."""
    rng = np.random.default_rng(3)
    photo = np.full((H, W, 3), 0.3, np.float32)
    face = _face()
    relit = np.where(face[..., None], 0.6 * (1.0 + 0.5 * rng.uniform(-1, 1, (H, W, 1))), 0.0).astype(np.float32)
    gain = outside_gain(photo, relit, face, 20.0)
    faded = compose(photo, [FaceLayer((0, H, 0, W), face, relit, gain, inner_alpha(face, 20.0))])
    cut = compose(photo, [FaceLayer((0, H, 0, W), face, relit, gain, None)])

    def outline_step(image):
        grey = image[..., 0]
        across = np.concatenate([np.abs(np.diff(grey, axis=a))[np.diff(face, axis=a)] for a in (0, 1)])
        return across.max()

    assert outline_step(faded) < 0.05
    assert outline_step(cut) > 0.15
