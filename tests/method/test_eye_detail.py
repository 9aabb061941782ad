"""The lit eye's detail put into a filled eye (nodes/method/eye_detail.py), on a synthetic photo
whose eyes and light are known."""
import numpy as np
from shadowflow.nodes.method.eye_detail import EYE_AXES, EyeDetail

H, W = 120, 200
EYES = np.array([[60.0, 50.0], [140.0, 50.0]])  # image-left eye first; 80 px apart
SKIN = 0.6


def _photo(iris_offset: float = 6.0):
    """A side-lit face patch: the skin's brightness falls from right to left (the light is on the
    right), both eyes have a dark iris (albedo 0.3 of the skin's), each moved toward the nose by
    ``iris_offset`` pixels, as eyes that converge a little. Returns (photo (H, W, 1), albedo,
    shading)."""
    yy, xx = np.mgrid[0:H, 0:W].astype(float)
    shading = 0.2 + 0.8 * xx / W
    albedo = np.full((H, W), SKIN)
    for (ex, ey), toward_nose in zip(EYES, (1.0, -1.0)):
        albedo[np.hypot(xx - ex - toward_nose * iris_offset, yy - ey) < 7] = 0.3 * SKIN
    return (albedo * shading)[..., None], albedo, shading


def test_a_filled_eye_gets_the_lit_eyes_iris_mirrored_and_nothing_else_moves():
    photo, true_albedo, shading = _photo()
    filled = np.full((H, W, 1), SKIN, np.float32)  # the fill: smooth skin, no eyes
    trust = np.ones((H, W))
    yy, xx = np.mgrid[0:H, 0:W].astype(float)
    left = ((xx - EYES[0, 0]) / (EYE_AXES[0] * 80)) ** 2 + ((yy - EYES[0, 1]) / (EYE_AXES[1] * 80)) ** 2 < 1.6**2
    trust[left] = 0.0  # the left eye is in shadow: its albedo was filled
    filled[~left] = true_albedo[~left, None]  # measured elsewhere, the right eye's iris included
    trust[48:53, 45:49] = 1.0  # a few pixels inside the filled eye were measured: they must stay
    filled[48:53, 45:49] = 0.123
    out = EyeDetail(photo, shading, EYES, 1.0).apply(filled, trust)
    assert np.all(out[48:53, 45:49] == np.float32(0.123))
    # the left eye's iris comes back where the mirror of the right eye's puts it: toward the nose (+x)
    iris = (60 + 6, 50)
    assert out[iris[1], iris[0], 0] < 0.45 * SKIN, out[iris[1], iris[0], 0]
    away = (60 - 6, 50)  # where the iris is not: skin
    assert out[away[1], away[0], 0] > 0.85 * SKIN, out[away[1], away[0], 0]
    # dark where the truth is dark, across the eye's opening
    opening = (((xx - EYES[0, 0]) / (EYE_AXES[0] * 80)) ** 2 + ((yy - EYES[0, 1]) / (EYE_AXES[1] * 80)) ** 2) < 0.5
    err_after = np.abs(out[..., 0] - true_albedo)[opening].mean()
    err_before = np.abs(filled[..., 0] - true_albedo)[opening].mean()
    assert err_after < 0.35 * err_before, (err_after, err_before)
    # trusted albedo (the right eye, everything outside the filled eye) is left as it was
    assert np.array_equal(out[trust == 1], filled[trust == 1])


def test_eye_detail_is_off_at_zero_contrast():
    photo, _, shading = _photo()
    filled = np.full((H, W, 1), SKIN, np.float32)
    assert np.array_equal(EyeDetail(photo, shading, EYES, 0.0).apply(filled, np.zeros((H, W))), filled)


def test_both_eyes_filled_take_the_brighter_eyes_pattern_not_flat_skin():
    """Both eyes' albedo filled (a dark photo, both eyes in the fit's shadow): the brighter eye (the right, the
    light's side) is the source of both, its iris back where it is and mirrored into the left, toward the nose;
    beside the irises, skin. Without a source both came back as flat skin (the iris at 1.0 of it)."""
    photo, _, shading = _photo()
    filled = np.full((H, W, 1), SKIN, np.float32)
    out = EyeDetail(photo, shading, EYES).apply(filled, np.zeros((H, W)))
    for iris, away in (((134, 50), (146, 50)), ((66, 50), (54, 50))):
        assert out[iris[1], iris[0], 0] < 0.45 * SKIN, (iris, out[iris[1], iris[0], 0])
        assert out[away[1], away[0], 0] > 0.85 * SKIN, (away, out[away[1], away[0], 0])


def test_the_sockets_own_shading_is_not_taken_for_the_eyes_albedo():
    """A face with no eye texture (a render): the lit eye's socket is darker only by its shading,
    which the fitted shading knows. The filled eye must stay skin, not get a dark blot."""
    yy, xx = np.mgrid[0:H, 0:W].astype(float)
    shading = 0.2 + 0.8 * xx / W
    for ex, ey in EYES:
        shading = shading * (1.0 - 0.6 * np.exp(-((xx - ex) ** 2 / 200.0 + (yy - ey) ** 2 / 60.0)))
    photo = (SKIN * shading)[..., None]
    filled = np.full((H, W, 1), SKIN, np.float32)
    trust = np.where(xx < 100, 0.0, 1.0)
    out = EyeDetail(photo, shading, EYES, 1.0).apply(filled, trust)
    eye = ((xx - EYES[0, 0]) / (EYE_AXES[0] * 80)) ** 2 + ((yy - EYES[0, 1]) / (EYE_AXES[1] * 80)) ** 2 < 1
    assert np.abs(out[eye, 0] - SKIN).max() < 0.05 * SKIN, out[eye, 0].min()


def test_a_colour_photos_eye_comes_back_in_its_own_colour():
    """Skin-coloured skin, blue irises: the mirrored iris must come back blue, the skin keep its colour."""
    photo, true_albedo, shading = _photo()
    skin_tint, iris_tint = np.array([1.0, 0.8, 0.65]), np.array([0.5, 0.7, 1.0])
    iris = true_albedo < SKIN
    photo3 = photo * np.where(iris[..., None], iris_tint, skin_tint)
    yy, xx = np.mgrid[0:H, 0:W].astype(float)
    left = ((xx - EYES[0, 0]) / (EYE_AXES[0] * 80)) ** 2 + ((yy - EYES[0, 1]) / (EYE_AXES[1] * 80)) ** 2 < 1.6**2
    filled = np.where(left[..., None], SKIN * skin_tint, photo3 / shading[..., None]).astype(np.float32)
    trust = np.where(left, 0.0, 1.0)
    out = EyeDetail(photo3, shading, EYES, 1.0).apply(filled, trust)
    assert out.shape == (H, W, 3)
    # the iris over the skin around it, per channel, as the lit eye shows it: 0.3 x iris / skin colour
    assert np.allclose(out[50, 66], 0.3 * SKIN * iris_tint, rtol=0.15), (out[50, 66], 0.3 * SKIN * iris_tint)
    assert np.allclose(out[50, 54], SKIN * skin_tint, rtol=0.1), out[50, 54]


def test_a_ring_half_hair_gives_the_filled_eye_the_skins_colour_not_a_blend_of_channels():
    """Dark brown hair over the lower outer part of the filled eye's ring of skin (a held-out portrait): the eye's
    skin comes back in the ring's skin colour. Fitted channel by channel, each channel's level bent its own way
    toward the hair and the eye came back red (chromaticity r 0.47-0.50 here, 0.41 the skin's)."""
    photo, true_albedo, shading = _photo()
    skin_tint = np.array([1.0, 0.8, 0.65])
    iris = true_albedo < SKIN
    photo3 = photo * np.where(iris[..., None], np.array([0.5, 0.7, 1.0]), skin_tint)
    yy, xx = np.mgrid[0:H, 0:W].astype(float)
    left = ((xx - EYES[0, 0]) / (EYE_AXES[0] * 80)) ** 2 + ((yy - EYES[0, 1]) / (EYE_AXES[1] * 80)) ** 2 < 1.6**2
    filled = np.where(left[..., None], SKIN * skin_tint, photo3 / shading[..., None]).astype(np.float32)
    filled[(xx < 56) & (yy > 40)] = (0.30, 0.16, 0.07)  # hair
    out = EyeDetail(photo3, shading, EYES, 1.0).apply(filled, np.where(left, 0.0, 1.0))
    for x in (48, 54):  # the eye's skin, off the iris
        chroma = out[50, x] / out[50, x].sum()
        assert np.abs(chroma - skin_tint / skin_tint.sum()).max() < 0.01, (x, chroma)
        assert 0.3 * SKIN < out[50, x].mean() < SKIN, out[50, x]  # within the ring's own brightness
