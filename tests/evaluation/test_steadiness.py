"""The steadiness of a relit clip (``evaluation.steadiness``) on frames with known flicker: a relit face whose level
steps by a known amount from frame to frame, one that shimmers about a steady mean, and one that is steady."""
from __future__ import annotations

import numpy as np
import pytest

from shadowflow.nodes.evaluation.steadiness import Steadiness, luma8
from shadowflow.nodes.photo.evenness import face_ellipse

H = W = 160
EYES = np.array([[60.0, 60.0], [100.0, 60.0]])


def frames(n: int, seed: int = 0):
    """``n`` input frames: a textured face whose light drifts slowly (the input's own change)."""
    rng = np.random.default_rng(seed)
    texture = rng.uniform(-20, 20, (H, W, 1))
    for i in range(n):
        yield np.clip(110 + 2.0 * i + texture, 0, 255).repeat(3, axis=2).astype(np.uint8)


def measure(relit_of, n: int = 12, eyes=EYES) -> dict:
    steady = Steadiness()
    for i, before in enumerate(frames(n)):
        steady.add(before, relit_of(i, before), eyes)
    return steady.figures()


def test_a_relit_face_that_follows_its_input_adds_no_flicker():
    got = measure(lambda i, b: np.clip(b.astype(np.int16) + 30, 0, 255).astype(np.uint8))
    assert got["pairs"] == 11 and got["with_face"] == 12
    assert got["flicker"] < 0.05 and abs(got["excess_change"]) < 0.05


def test_a_level_stepping_up_and_down_is_its_flicker():
    # +-3 levels about the input's own change, alternating: each step 6 levels beyond the input's
    got = measure(lambda i, b: np.clip(b.astype(np.int16) + 30 + (3 if i % 2 else -3), 0, 255).astype(np.uint8))
    assert got["flicker"] == pytest.approx(6.0, abs=0.1)
    assert got["excess_change"] == pytest.approx(6.0 - 2.0, abs=0.3)  # |relit steps| 8 or 4, the input's 2


def test_a_shimmer_about_a_steady_mean_is_excess_change_not_flicker():
    rng = np.random.default_rng(3)

    def shimmer(i, b):
        noise = rng.choice([-4, 4], size=(H, W, 1))
        return np.clip(b.astype(np.int16) + 30 + noise, 0, 255).astype(np.uint8)

    got = measure(shimmer)
    assert got["flicker"] < 0.5
    assert got["excess_change"] > 2.0


def test_h_is_measured_on_the_face_and_a_frame_without_one_breaks_the_pairs():
    blotched = lambda i, b: np.where(((np.indices((H, W)).sum(0) // 6) % 2)[..., None] == 1,  # noqa: E731
                                     np.clip(b.astype(np.int16) * 1.5, 0, 255), b).astype(np.uint8)
    steady = Steadiness()
    for i, before in enumerate(frames(6)):
        steady.add(before, blotched(i, before), None if i == 3 else EYES)
    got = steady.figures()
    assert got["with_face"] == 5 and got["pairs"] == 3  # 0-1, 1-2, 4-5
    assert got["h_median"] > 10.0
    plain = measure(lambda i, b: b)
    assert plain["h_median"] < 0.5 and plain["flicker"] == 0.0


def test_the_mean_is_taken_over_the_face_ellipse():
    """A change outside the face's ellipse is not the face's."""
    ellipse = face_ellipse(EYES, (H, W), 0.0)
    y0, y1, x0, x1 = ellipse.box
    outside = np.ones((H, W), bool)
    outside[y0:y1, x0:x1] &= ~ellipse.mask

    def background(i, b):
        out = b.copy()
        out[outside] = 255 if i % 2 else 0
        return out

    assert measure(background)["flicker"] < 0.05
    assert luma8(np.full((2, 2, 3), 200, np.uint8))[0, 0] == pytest.approx(200.0)


def test_a_relit_face_moving_across_the_frame_adds_no_flicker():
    """The face's region follows it: a face relit brighter by a steady factor while it moves adds no flicker, though
    a fixed set of pixels sees its bright face come and go."""
    rng = np.random.default_rng(4)
    texture = rng.uniform(-30, 30, (H, W + 60, 1))
    steady = Steadiness()
    for i in range(10):
        eyes = EYES + [4.0 * i, 0.0]
        before = np.clip(110 + texture[:, 4 * i:4 * i + W], 0, 255).repeat(3, axis=2).astype(np.uint8)
        after = before.copy()
        ellipse = face_ellipse(eyes, (H, W), 0.0)
        y0, y1, x0, x1 = ellipse.box
        region = after[y0:y1, x0:x1]
        region[ellipse.mask] = np.clip(region[ellipse.mask].astype(np.int16) * 1.3, 0, 255).astype(np.uint8)
        steady.add(before, after, eyes)
    assert steady.figures()["flicker"] < 0.3
