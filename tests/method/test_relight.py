"""The surface turned for the novel view (``relight.novel_view``)."""
import numpy as np
from scipy import ndimage
from shadowflow.nodes.method.relight import novel_view


def _face_with_a_nose(n=96):
    """(H, W) heights in pixels of a dome with a sharp ridge down its middle (a nose), NaN off it."""
    rows, cols = np.mgrid[0:n, 0:n].astype(float)
    x, y = (cols - n / 2) / (0.42 * n), (rows - n / 2) / (0.45 * n)
    inside = x**2 + y**2 < 1
    dome = 0.3 * n * np.sqrt(np.clip(1 - x**2 - y**2, 0, None))
    nose = 0.12 * n * np.exp(-0.5 * (x / 0.07) ** 2) * np.exp(-0.5 * ((y + 0.05) / 0.3) ** 2)
    return np.where(inside, dome + nose, np.nan)


def test_the_turned_surface_has_no_crack_where_the_nose_hides_the_cheek():
    depth = _face_with_a_nose()
    albedo = np.where(np.isfinite(depth), 0.8, np.nan)
    view = novel_view(depth, albedo, 45.0)
    face = ndimage.binary_erosion(view > 0, iterations=3)
    assert face.sum() > 2000
    # frontal light on a smooth surface: no pixel far darker than the pixels around it (the nose's side,
    # turned edge-on, drew a line of near-black pixels down the face)
    local = ndimage.median_filter(view, size=5)
    cracks = face & (view < 0.5 * local)
    assert cracks.sum() == 0, np.argwhere(cracks)[:10]
    # and the turned dome is still shaded as a dome: its side turned away from the light is darker
    rows = slice(40, 56)
    cols = np.nonzero(face[rows].any(axis=0))[0]
    left, right = view[rows, cols[:8]].mean(), view[rows, cols[-8:]].mean()
    assert abs(left - right) > 0.05


def test_a_colour_albedo_turns_with_its_colours_and_a_grey_one_stays_grey():
    depth = _face_with_a_nose()
    face = np.isfinite(depth)
    grey = np.where(face, 0.8, np.nan)
    colour = np.where(face[..., None], np.array([0.8, 0.6, 0.4]), np.nan)
    plain, coloured = novel_view(depth, grey, 30.0), novel_view(depth, colour, 30.0)
    assert plain.shape == depth.shape and coloured.shape == depth.shape + (3,)
    seen = plain > 0.05
    assert seen.sum() > 2000
    # the same shading in every channel, scaled by each channel's albedo
    np.testing.assert_allclose(coloured[seen][:, 0], plain[seen], atol=1e-5)
    np.testing.assert_allclose(coloured[seen][:, 1] / coloured[seen][:, 0], 0.75, atol=1e-4)
    np.testing.assert_allclose(coloured[seen][:, 2] / coloured[seen][:, 0], 0.5, atol=1e-4)
