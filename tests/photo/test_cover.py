"""What covers a face (``nodes/photo/cover.py``): dark regions coming in from beyond the face's outline
are left out; the face's own dark features, shadow, stubble and a photo's frame are not. Synthetic grids
with known regions, and the astronaut's fringe."""
import numpy as np
import pytest
from shadowflow.nodes.photo.cover import DARK_SHARE, covered_pixels

N, CY, CX, R = 80, 40, 40, 30
SKIN = 0.5  # albedo of the skin; the shading of a lit pixel is 0.9


def disc() -> np.ndarray:
    yy, xx = np.mgrid[0:N, 0:N]
    return (yy - CY) ** 2 + (xx - CX) ** 2 <= R**2


def face(dark: np.ndarray, albedo: float = 0.08, shading: float = 0.9) -> tuple[np.ndarray, np.ndarray]:
    """(image, shading) of a lit disc of skin with ``dark`` (bool) pixels of ``albedo``."""
    s = np.full((N, N), shading, np.float64)
    return np.where(dark, albedo, SKIN) * s, s


def rows(r0: int, r1: int, cols: tuple[int, int] = (0, N)) -> np.ndarray:
    out = np.zeros((N, N), bool)
    out[r0:r1, cols[0]:cols[1]] = True
    return out & disc()


def test_a_dark_fringe_coming_in_from_beyond_the_outline_is_covered():
    fringe = rows(0, CY - 18)  # hair over the forehead, down to 12 px inside the outline
    image, shading = face(fringe)
    assert np.array_equal(covered_pixels(image, disc(), shading, ~disc()), fringe)  # the skin beside it is kept
    blend = rows(CY - 18, CY - 17)  # the row where hair and skin blend, half and half
    image = np.where(blend, 0.5 * (image[CY - 19, CX] + image[CY - 16, CX]), image)
    assert np.array_equal(covered_pixels(image, disc(), shading, ~disc()), fringe | blend)


def test_dark_regions_inside_the_face_shadow_stubble_and_features_are_not_covered():
    inside = rows(CY - 4, CY + 4, (CX - 10, CX + 10))  # a dark patch that does not reach the outline
    image, shading = face(inside)
    assert not covered_pixels(image, disc(), shading, ~disc()).any()

    fringe = rows(0, CY - 18)
    image, shading = face(fringe)
    shading = np.where(fringe, 0.2, shading)  # the light does not reach it: darkness says nothing there
    assert not covered_pixels(image * np.where(fringe, 0.2 / 0.9, 1.0), disc(), shading, ~disc()).any()

    image, shading = face(fringe, albedo=(DARK_SHARE + 0.1) * SKIN)  # stubble: darker skin, not hair
    assert not covered_pixels(image, disc(), shading, ~disc()).any()

    image, shading = face(fringe)  # brows drawn there by the landmarks are the face's own
    assert not covered_pixels(image, disc(), shading, ~disc(), features=fringe).any()


def test_a_dark_region_cut_by_the_photos_frame_is_not_covered_unless_it_reaches_the_outline():
    seen = disc() & (np.arange(N)[:, None] >= CY - 15)  # the photo's frame cuts the face 15 px above its centre
    brows = rows(CY - 15, CY - 11, (CX - 8, CX + 8))  # dark along the frame's edge, 15 px from the outline
    image, shading = face(brows)
    assert not covered_pixels(image, seen, shading, ~disc()).any()
    band = rows(CY - 15, CY - 11)  # the same band across the whole face reaches the outline
    image, shading = face(band)
    assert covered_pixels(image, seen, shading, ~disc())[band].all()


def test_the_astronauts_fringe_is_left_out_of_her_fit_and_nothing_below_her_brows():
    skimage = pytest.importorskip("skimage")
    import shadowflow
    from shadowflow.nodes.photo.placement import outline_on_grid

    p = shadowflow.fit(skimage.data.astronaut())
    face = p.frame
    m, placement = p.model, face.data["placement"]
    outline = outline_on_grid(placement, m, face.data["image"].shape, "fit") & m.mask
    covered = face.data["grid_covered"]
    assert not (covered & ~(outline & face.data["grid_valid"])).any()
    brow_top = float(placement.grid_outline("brows")[0][:, 1].min())
    eye_row = float(m.eyes[:, 1].mean())
    rows = np.arange(m.grid[0])[:, None]
    # measured: 698 of her 5,841 face pixels: the fringe across her forehead (560 of them above her brows),
    # hair down her temple to her eyes, the shadow under her chin
    assert covered.sum() > 400
    assert (covered & (rows < brow_top)).sum() > 0.6 * covered.sum()
    cols = np.arange(m.grid[1])[None, :]
    lips_bottom = float(placement.grid_outline("lips")[0][:, 1].max())
    middle = (cols > m.eyes[0, 0]) & (cols < m.eyes[1, 0]) & (rows > eye_row - 0.2 * np.ptp(m.eyes[:, 0])) \
        & (rows < lips_bottom)
    assert not (covered & middle).any()  # her face between her eyes and down to her lips is all fitted
    assert abs(p.quality["covered"] - covered.sum() / (outline & face.data["grid_valid"]).sum()) < 1e-3
    # and hair it is: darker than the rest of her face by more than half
    assert np.median(face.data["grid_image"][covered]) < 0.5 * np.median(face.data["grid_image"][outline & ~covered])


def test_a_black_and_white_portraits_fringe_comes_back_as_its_own_hair(tmp_path):
    """The astronaut in black and white (a grey JPEG) relit frontally: her fringe, which the fit left out as
    covering her face, is kept as the photo has it (relit by the change of shading), not taken for shadow and
    filled with skin. Measured: 12 grey levels from the photo over it, its fine detail 1.2x the photo's; before,
    a flat patch of skin with a hard edge across the hair, 77 levels off and 0.6x the detail. (In colour the
    hair's colour already told it from skin.)"""
    import cv2
    import shadowflow
    from shadowflow.nodes.photo.align import mask_to_input

    data = pytest.importorskip("skimage.data")
    grey = cv2.cvtColor(np.ascontiguousarray(data.astronaut()), cv2.COLOR_RGB2GRAY)
    path = tmp_path / "black-and-white.jpg"
    cv2.imwrite(str(path), grey, [cv2.IMWRITE_JPEG_QUALITY, 92])
    out = shadowflow.fit(str(path))
    assert out.faces[0]["status"] == "ok"
    d = out.frame.data
    hair = mask_to_input(d["grid_covered"], d["alignment"], grey.shape) & out.mask
    assert hair.sum() > 300  # measured 788
    photo = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE).astype(np.float32)
    relit = np.nan_to_num(out.relit).astype(np.float32) * 255.0
    assert relit.ndim == 2 and np.abs(relit[hair] - photo[hair]).mean() < 30.0

    def detail(img: np.ndarray) -> float:
        return float((img - cv2.GaussianBlur(img, (0, 0), 2.0))[hair].std())

    assert detail(relit) > 0.8 * detail(photo)
