"""The lit eye's detail put into an eye in a shadow as deep as the noise floor (``relight/eyes.py``)."""
import numpy as np
from shadowflow.nodes.relight.eyes import EyeDetail

H, W = 100, 120
EYES = np.array([[40.0, 50.0], [80.0, 50.0]])  # [x, y], 40 px apart


def _photo():
    """An even skin (0.5) whose left eye, lit, has an iris (0.1, 3 px) with a darker dot toward the nose (0.05, at
    +5 px); the right half of the face in a shadow 0.05 as bright (as the fitted shading there says)."""
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    albedo = np.full((H, W, 3), 0.5, np.float32)
    albedo[np.hypot(yy - 50, xx - 40) <= 3] = 0.1
    albedo[np.hypot(yy - 50, xx - 45) <= 1.5] = 0.05
    shading = np.where(xx < 60, 1.0, 0.05).astype(np.float32)
    return albedo * shading[..., None], shading, xx


def test_an_untrusted_eye_takes_the_lit_eyes_pattern_mirrored_across_the_face():
    """Into an even fill (0.5) whose right eye is not trusted, the lit eye's pattern goes as its ratio to the skin
    around it: an iris at 0.1 and, mirrored across the face, its dot on the nose's side (x = 75, not 85); the
    trusted left half is left exactly as it was, and at contrast 0 nothing is."""
    photo, shading, xx = _photo()
    fill = np.full((H, W, 3), 0.5, np.float32)
    trust = np.where(xx < 60, 1.0, 0.0).astype(np.float32)
    out = EyeDetail(photo, shading, EYES).apply(fill, trust)
    np.testing.assert_allclose(out[50, 80], 0.1, atol=0.01)
    np.testing.assert_allclose(out[50, 75], 0.05, atol=0.01)
    np.testing.assert_allclose(out[50, 85], 0.5, atol=0.01)
    np.testing.assert_allclose(out[50, 95], 0.5, atol=1e-6)  # the skin beyond the eye
    np.testing.assert_array_equal(out[:, :60], fill[:, :60])
    np.testing.assert_array_equal(EyeDetail(photo, shading, EYES, contrast=0.0).apply(fill, trust), fill)


def test_an_eye_is_deep_by_its_own_opening_not_the_shade_around_it():
    """Two eyes in a band of shade at the noise floor (``precision`` 0.4, past ``DEEP_EYE``): the one whose opening
    holds signal (0.06, its iris and white seen) is not painted, however dark the band around it (its grown region's
    median is the band's); the one whose opening is as deep as the band is, all of its region."""
    from shadowflow.nodes.relight.paint import DEEP_EYE, deep_eyes

    yy, xx = np.mgrid[:60, :120]
    relative = np.full((60, 120), 0.4, np.float32)
    seen_opening = np.hypot((xx - 30) / 10.0, (yy - 30) / 4.0) < 1.0
    deep_opening = np.hypot((xx - 90) / 10.0, (yy - 30) / 4.0) < 1.0
    relative[seen_opening] = 0.06
    regions = [np.hypot((xx - c) / 18.0, (yy - 30) / 12.0) < 1.0 for c in (30, 90)]
    assert np.median(relative[regions[0]]) > DEEP_EYE  # (judged by its region, the seen eye was deep)
    deep = deep_eyes(relative, regions, [seen_opening, deep_opening])
    assert not deep[regions[0]].any() and deep[regions[1]].all() and deep.sum() == regions[1].sum()
    # an opening too small to judge: its region says
    tiny = np.zeros_like(seen_opening)
    tiny[30, 30] = True
    assert deep_eyes(relative, regions[:1], [tiny])[regions[0]].all()
