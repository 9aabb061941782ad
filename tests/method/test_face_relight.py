"""One face relit in its box from arrays alone (``face_relight.FaceRelight``): a textured sphere on a
small model grid, placed 4x larger in a colour photo, with its true shape and light."""
from types import SimpleNamespace

import numpy as np
import pytest
from shadowflow.nodes.method.face_relight import FaceRelight
from shadowflow.nodes.method.photo_relight import compose
from shadowflow.nodes.photo.align import Alignment, mask_to_input, normals_to_input

GRID, R, SCALE, OFFSET = 48, 20.0, 4.0, (30.0, 20.0)
PHOTO_LIGHT = np.array([-0.6, 0.0, 0.8])  # from the image's left


def _sphere():
    """The model grid's sphere: (Hm, Wm) mask, (Hm, Wm, 3) normals (camera frame, y up, NaN off it), depth."""
    rows, cols = np.mgrid[0:GRID, 0:GRID].astype(float)
    x, y = (cols - GRID / 2 + 0.5) / R, -(rows - GRID / 2 + 0.5) / R
    mask = x**2 + y**2 < 0.95
    z = np.sqrt(np.clip(1 - x**2 - y**2, 0, None))
    normals = np.where(mask[..., None], np.dstack([x, y, z]), np.nan).astype(np.float32)
    return mask, normals, np.where(mask, z * R, np.nan).astype(np.float32)


@pytest.fixture(scope="module")
def scene():
    mask, normals, depth = _sphere()
    al = Alignment(np.array([[SCALE, 0.0, OFFSET[0]], [0.0, SCALE, OFFSET[1]]]), "test")
    shape = (260, 260)
    rng = np.random.default_rng(3)
    face = mask_to_input(mask, al, shape)
    n_photo = np.nan_to_num(normals_to_input(normals, mask, al, shape))
    shading = np.clip(n_photo @ PHOTO_LIGHT, 0.0, None)
    skin = np.array([0.62, 0.48, 0.38]) * (1 + 0.06 * rng.standard_normal(shape))[..., None]  # pores
    background = np.full(shape + (3,), 0.3) + 0.05 * rng.standard_normal(shape + (3,))
    photo = np.where(face[..., None], skin * shading[..., None], background).clip(0, 1).astype(np.float32)
    lit = mask & (np.nan_to_num(normals) @ PHOTO_LIGHT > 0.05)
    relight = FaceRelight(photo=photo, grey=photo.mean(-1), alignment=al, mask=mask, normals=normals, lit=lit,
                          albedo=np.where(mask, 0.5, np.nan).astype(np.float32), depth=depth, light=PHOTO_LIGHT,
                          iod_px=0.9 * R * SCALE)
    return relight, photo, face, shading


def test_the_box_holds_the_face_and_its_feather_and_stays_in_the_photo(scene):
    """The layer's box holds the face and its feather; the face's own box, where the relit face is made,
    holds the face and no more than its margin."""
    from shadowflow.nodes.method.face_relight import INNER_MARGIN

    relight, photo, face, _ = scene
    y0, y1, x0, x1 = relight.layer_box
    rows, cols = np.nonzero(face)
    assert 0 <= y0 and y1 <= photo.shape[0] and 0 <= x0 and x1 <= photo.shape[1]
    assert y0 <= rows.min() - relight.feather and rows.max() + relight.feather < y1
    assert x0 <= cols.min() - relight.feather and cols.max() + relight.feather < x1
    assert np.array_equal(relight.layer_face, face[y0:y1, x0:x1])
    fy0, fy1, fx0, fx1 = relight.box
    assert (fy0, fy1, fx0, fx1) == (rows.min() - INNER_MARGIN, rows.max() + 1 + INNER_MARGIN,
                                    cols.min() - INNER_MARGIN, cols.max() + 1 + INNER_MARGIN)
    assert np.array_equal(relight.face, face[fy0:fy1, fx0:fx1]) and relight.albedo.shape[:2] == relight.face.shape


def test_the_photos_own_light_gives_the_lit_face_back(scene):
    relight, photo, face, shading = scene
    y0, y1, x0, x1 = relight.layer_box
    layer = relight.layer(PHOTO_LIGHT)
    lit_skin = (face & (shading > 0.3))[y0:y1, x0:x1]
    error = np.abs(layer.relit[lit_skin] - photo[y0:y1, x0:x1][lit_skin]) / photo[y0:y1, x0:x1][lit_skin]
    assert np.median(error) < 0.02, np.median(error)


def test_a_frontal_light_brightens_the_dark_side_and_leaves_the_photo_beyond_the_box(scene):
    relight, photo, face, shading = scene
    y0, y1, x0, x1 = relight.layer_box
    layer = relight.layer(np.array([0.0, 0.0, 1.0]))
    # the sphere's right side, in the photo's attached shadow, is lit by a frontal light: at the same
    # normals a frontal light gives z, so it comes out several times brighter than it was
    dark = (face & (shading < 0.05))[y0:y1, x0:x1]
    lit = (face & (shading > 0.5))[y0:y1, x0:x1]
    assert dark.sum() > 500 and lit.sum() > 500
    assert np.median(layer.relit[dark]) > 4 * np.median(photo[y0:y1, x0:x1][dark])
    out = compose(photo, [layer])
    beyond = np.ones(photo.shape[:2], bool)
    beyond[y0:y1, x0:x1] = False
    assert np.array_equal(out[beyond], photo[beyond])
    assert not np.allclose(out[y0:y1, x0:x1], photo[y0:y1, x0:x1], atol=0.05)


def test_a_highlight_does_not_glow_where_a_new_light_puts_the_skin_in_shadow():
    """The sphere with a specular highlight on its lit (left) cheek, relit from the far right: the cheek falls
    into shadow, and the highlight, read as albedo, stayed a blotch there (1.46x the same sphere relit without
    it); now it dims with the cheek (within 25 % of that), while relit by the photo's own light it is kept."""
    mask, normals, depth = _sphere()
    al = Alignment(np.array([[SCALE, 0.0, OFFSET[0]], [0.0, SCALE, OFFSET[1]]]), "test")
    shape = (260, 260)
    face = mask_to_input(mask, al, shape)
    n_photo = np.nan_to_num(normals_to_input(normals, mask, al, shape))
    shading = np.clip(n_photo @ PHOTO_LIGHT, 0.0, None)
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]].astype(np.float32)
    cx, cy = OFFSET[0] + SCALE * 15, OFFSET[1] + SCALE * 24  # on the lit side, at the sphere's middle height
    blob = np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * 6.0**2))
    lit = mask & (np.nan_to_num(normals) @ PHOTO_LIGHT > 0.05)

    def relit(shine: float, light: np.ndarray) -> tuple[np.ndarray, tuple]:
        photo = np.where(face[..., None], np.array([0.62, 0.48, 0.38]) * shading[..., None] + shine * blob[..., None],
                         0.3).clip(0, 1).astype(np.float32)
        relight = FaceRelight(photo=photo, grey=photo.mean(-1), alignment=al, mask=mask, normals=normals, lit=lit,
                              albedo=np.where(mask, 0.5, np.nan).astype(np.float32), depth=depth, light=PHOTO_LIGHT,
                              iod_px=0.9 * R * SCALE)
        return relight.layer(light).relit.mean(-1), relight.layer_box

    away = np.array([0.9, 0.0, 0.44])  # the cheek turned from it: the room's light only
    (plain, box), (shiny, _) = relit(0.0, away), relit(0.25, away)
    y0, y1, x0, x1 = box
    peak = (blob > 0.8)[y0:y1, x0:x1]
    assert peak.sum() > 20
    glow = np.median(shiny[peak]) / np.median(plain[peak])
    assert glow < 1.25, glow  # measured 1.19: what is left is the 10 % margin (1.46 with the shine kept as albedo)
    (own_plain, _), (own_shiny, _) = relit(0.0, PHOTO_LIGHT), relit(0.25, PHOTO_LIGHT)
    kept = np.median(own_shiny[peak]) / np.median(own_plain[peak])
    assert kept > 1.3, kept  # the photo's own light keeps its highlight


def test_a_clipped_highlight_leaves_with_its_light_as_its_unclipped_rim_does():
    """The sphere with a highlight strong enough to clip its core (87 photo pixels at 1 in every channel), relit
    frontally, where the highlight moves away (``shine_lobe``): over the same sphere without it, the clipped core
    glows no more than 1.3x what its unclipped rim glows (measured 1.57x against 1.32x). The clipping's floor had
    kept the whole clipped top as if diffuse: 2.07x against 1.41x, the bright blotches beside Yale B's eyes at +-70.
    Relit by the photo's own light the core comes back clipped."""
    mask, normals, depth = _sphere()
    al = Alignment(np.array([[SCALE, 0.0, OFFSET[0]], [0.0, SCALE, OFFSET[1]]]), "test")
    shape = (260, 260)
    face = mask_to_input(mask, al, shape)
    shading = np.clip(np.nan_to_num(normals_to_input(normals, mask, al, shape)) @ PHOTO_LIGHT, 0.0, None)
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]].astype(np.float32)
    blob = np.exp(-((xx - OFFSET[0] - SCALE * 15) ** 2 + (yy - OFFSET[1] - SCALE * 24) ** 2) / (2 * 6.0**2))
    lit = mask & (np.nan_to_num(normals) @ PHOTO_LIGHT > 0.05)

    def relit(shine: float, light: np.ndarray):
        photo = np.where(face[..., None], np.array([0.62, 0.48, 0.38]) * shading[..., None] + shine * blob[..., None],
                         0.3).clip(0, 1).astype(np.float32)
        relight = FaceRelight(photo=photo, grey=photo.mean(-1), alignment=al, mask=mask, normals=normals, lit=lit,
                              albedo=np.where(mask, 0.5, np.nan).astype(np.float32), depth=depth, light=PHOTO_LIGHT,
                              iod_px=0.9 * R * SCALE)
        y0, y1, x0, x1 = relight.layer_box
        return relight.layer(light).relit.mean(-1), photo[y0:y1, x0:x1], blob[y0:y1, x0:x1]

    frontal = np.array([0.0, 0.0, 1.0])
    (plain, _, _), (shiny, photo, spot) = relit(0.0, frontal), relit(0.9, frontal)
    clipped = (photo >= 0.995).all(axis=-1)
    rim = (spot > 0.3) & (spot < 0.6) & ~clipped
    assert clipped.sum() > 50 and rim.sum() > 100
    core = np.median(shiny[clipped]) / np.median(plain[clipped])
    assert core < 1.3 * np.median(shiny[rim]) / np.median(plain[rim]), core
    own, _, _ = relit(0.9, PHOTO_LIGHT)
    assert np.median(own[clipped]) > 0.99


def test_a_brow_dark_into_the_shadow_is_kept_not_filled_as_shadow():
    """A brow (a band of a quarter of the skin's albedo, in the skin's colour, as a colour-graded film still's)
    runs from the lit side into the sphere's attached shadow: dark and joined to the shape's shadow, it was taken
    for shadow and filled with skin. Given the mesh's brow outline, its lit part keeps its own pixels, relit
    frontally as dark against the skin around it as the photo shows it, also where the light begins to graze it
    (shading 0.34-0.50), where skin's own pixels are not trusted under a frontal light. (Where the fit shades it
    0.5 or more, the brow's edges are rough as hair's strands are, and it keeps its pixels without the outline too:
    ``STRAND_SHADING``.)"""
    mask, normals, depth = _sphere()
    al = Alignment(np.array([[SCALE, 0.0, OFFSET[0]], [0.0, SCALE, OFFSET[1]]]), "test")
    shape = (260, 260)
    face = mask_to_input(mask, al, shape)
    shading = np.clip(np.nan_to_num(normals_to_input(normals, mask, al, shape)) @ PHOTO_LIGHT, 0.0, None)
    rows, cols = np.mgrid[0:shape[0], 0:shape[1]]
    brow = face & (np.abs(rows - 80) < 4) & (cols > 60) & (cols < 200)  # photo pixels
    albedo = np.where(brow, 0.25, 1.0)[..., None] * np.array([0.62, 0.48, 0.38])
    photo = np.where(face[..., None], albedo * (0.05 + 0.95 * shading)[..., None], 0.3).astype(np.float32)
    lit = mask & (np.nan_to_num(normals) @ PHOTO_LIGHT > 0.05)
    outline = np.array([[60.0, 76.0], [200.0, 76.0], [200.0, 84.0], [60.0, 84.0]])

    def relit_level(brows, x0, x1):  # the brow over the skin above it, relit frontally, photo columns x0:x1
        r = FaceRelight(photo=photo, grey=photo.mean(-1), alignment=al, mask=mask, normals=normals, lit=lit,
                        albedo=np.where(mask, 0.5, np.nan).astype(np.float32), depth=depth, light=PHOTO_LIGHT,
                        iod_px=0.9 * R * SCALE, brows=brows)
        out = compose(photo, [r.layer(np.array([0.0, 0.0, 1.0]))]).mean(-1)
        return np.median(out[78:83, x0:x1]) / np.median(out[66:72, x0:x1])

    assert relit_level(None, 148, 162) > 0.7  # filled with skin (1.08)
    assert 0.15 < relit_level([outline], 80, 110) < 0.4, relit_level([outline], 80, 110)
    assert relit_level([outline], 148, 162) < 0.6, relit_level([outline], 148, 162)  # 0.38; skin's trust: 0.8-1.1


def _frontal_disc() -> SimpleNamespace:
    """The sphere lit from the front (``light``), with a disc around model pixel (x, y) = (18, 20) for a shadow
    deeper than the model's. Its fields: the grid's ``mask``, ``normals``, ``depth``; the alignment ``al``; on the
    photo's 260 x 260 pixels the ``face``, its ``shading``, ``rows`` / ``cols`` and ``r_px``, the distance to the
    disc's ``centre`` (photo x, y); ``grid_r``, the same on the grid; ``lit``, the grid's lit mask, its shadow the
    disc's core only."""
    mask, normals, depth = _sphere()
    al = Alignment(np.array([[SCALE, 0.0, OFFSET[0]], [0.0, SCALE, OFFSET[1]]]), "test")
    shape, light = (260, 260), np.array([0.0, 0.0, 1.0])
    face = mask_to_input(mask, al, shape)
    shading = np.clip(np.nan_to_num(normals_to_input(normals, mask, al, shape)) @ light, 0.0, None)
    rows, cols = np.mgrid[0:shape[0], 0:shape[1]]
    centre = al.points_to_input(np.array([[18.0, 20.0]]))[0]  # model pixel (x, y) -> photo
    grid_r = np.hypot(*(np.mgrid[0:GRID, 0:GRID] - np.array([20.0, 18.0])[:, None, None]))
    return SimpleNamespace(mask=mask, normals=normals, depth=depth, al=al, light=light, face=face, shading=shading,
                           rows=rows, cols=cols, centre=centre, r_px=np.hypot(cols - centre[0], rows - centre[1]),
                           grid_r=grid_r, lit=mask & (grid_r >= 2.5))


def _disc_relight(d: SimpleNamespace, photo: np.ndarray, albedo: np.ndarray, iod_px: float = 0.9 * R * SCALE):
    """``FaceRelight`` of ``photo`` (260, 260, 3) on ``_frontal_disc``'s sphere, its grid albedo ``albedo``."""
    return FaceRelight(photo=photo, grey=photo.mean(-1), alignment=d.al, mask=d.mask, normals=d.normals, lit=d.lit,
                       albedo=albedo, depth=d.depth, light=d.light, iod_px=iod_px)


def test_the_fits_map_is_filled_again_where_the_photo_finds_a_shadow_the_grid_measured_as_lit():
    """A shadow deeper than the model's (an eye socket under a light from above): the photo is dark over a disc,
    the grid took only its core for shadow and measured the rest as lit, so the fit's albedo map holds the shadow
    there (0.1 against the skin's 0.5). Relit frontally, the disc is filled at the skin's level, not the map's
    (0.71 of it; 0.42 before)."""
    d = _frontal_disc()
    skin_rgb = np.array([0.62, 0.48, 0.38])
    dark = np.where(d.r_px < 24, 0.15, 1.0)[..., None]
    photo = np.where(d.face[..., None], skin_rgb * dark * d.shading[..., None], 0.3).astype(np.float32)
    # measured where the grid took it for lit: 0.1 over the disc's rim; its core the fit filled, as the skin's
    albedo = np.where(d.mask, np.where((d.grid_r < 6.5) & d.lit, 0.1, 0.5), np.nan).astype(np.float32)
    r = _disc_relight(d, photo, albedo)
    out = compose(photo, [r.layer(d.light)]).mean(-1)
    ring, skin_near = (d.r_px > 12) & (d.r_px < 20), (d.r_px > 32) & (d.r_px < 44) & d.face
    level = np.median(out[ring]) / np.median(out[skin_near])
    assert level > 0.6, level


def test_a_shadow_redder_than_the_skin_is_found_and_filled_and_hair_across_it_is_not():
    """An ordinary photo's skin reddens as it darkens (here each channel goes as the light to the power 0.8 / 1 /
    1.3): a shadow deeper than the model's, at a fifth of the light, is 0.17 from the lit skin's chromaticity, so it
    was not taken for skin, nor for shadow: kept as it was, it came back from a frontal light as a dark brown patch
    (0.24 of the skin's level). Now skin in its shade is found as shadow and filled at the skin's level. A band of
    hair strands across it, as dark and as red, is not smooth as skin is: it keeps its own pixels, dark in the fill.
    On a face under 60 px between the eyes the shadow is kept as before."""
    d = _frontal_disc()
    strands = (d.r_px < 22) & (np.abs(d.rows - (d.centre[1] + 10)) < 4)
    reach = d.shading * np.where(d.r_px < 24, 0.2, 1.0) * np.where(strands, np.where(d.cols % 2, 0.3, 0.9), 1.0)
    colour = np.array([0.62, 0.48, 0.38]) * reach[..., None] ** np.array([0.8, 1.0, 1.3])
    photo = np.where(d.face[..., None], colour, 0.3).astype(np.float32)
    r = _disc_relight(d, photo, np.where(d.mask, 0.5, np.nan).astype(np.float32))
    out = compose(photo, [r.layer(d.light)]).mean(-1)
    disc, skin_near = (d.r_px > 4) & (d.r_px < 20) & ~strands, (d.r_px > 32) & (d.r_px < 44) & d.face
    level = np.median(out[disc]) / np.median(out[skin_near])
    assert 0.7 < level < 1.3, level
    hair = np.median(out[strands & (d.r_px < 18)]) / np.median(out[disc])
    assert hair < 0.5, hair
    # a face under SHADE_MIN_IOD between the eyes: its colour too coarse to follow, the shadow is kept as it was
    small = _disc_relight(d, photo, np.where(d.mask, 0.5, np.nan).astype(np.float32), iod_px=50.0)
    out = compose(photo, [small.layer(d.light)]).mean(-1)
    assert np.median(out[disc]) / np.median(out[skin_near]) < 0.5


def test_strands_of_hair_with_the_skins_colour_over_lit_skin_are_not_taken_for_shadow():
    """Dark brown hair over a lit cheek in a warm shade has the skin's colour: a band of strands (every other column
    at 0.3 of the skin's brightness) over the lit sphere, where the grid's map has a small shadow, was dark skin next
    to a shadow, so a shadow (0.58 of its dark strands), filled with a flat patch of skin (its dark strands relit
    at 0.98 of the light ones). Rough as hair is, it keeps its own pixels (0.30, as the photo). A smooth dark band
    there, of the same colour, is still a shadow, and filled (1.14 of the skin around)."""
    d = _frontal_disc()
    pores = 1 + 0.06 * np.random.default_rng(5).standard_normal(d.face.shape)
    skin_rgb = np.array([0.62, 0.48, 0.38])

    def relit(pattern):
        photo = np.where(d.face[..., None], skin_rgb * (d.shading * pores * pattern)[..., None], 0.3)
        r = _disc_relight(d, photo.astype(np.float32), np.where(d.mask, 0.5, np.nan).astype(np.float32))
        y0, y1, x0, x1 = r.box
        shadow = np.zeros(d.face.shape, bool)
        shadow[y0:y1, x0:x1] = r.shadow
        return shadow, compose(photo.astype(np.float32), [r.layer(d.light)]).mean(-1)

    band = (d.r_px < 22) & (np.abs(d.rows - d.centre[1]) < 10)
    shadow, out = relit(np.where(band & (d.cols % 2 == 1), 0.3, 1.0))
    dark, light = band & (d.cols % 2 == 1) & (d.r_px < 18), band & (d.cols % 2 == 0) & (d.r_px < 18)
    assert not shadow[dark].any(), shadow[dark].mean()
    assert np.median(out[dark]) / np.median(out[light]) < 0.5, np.median(out[dark]) / np.median(out[light])
    shadow, out = relit(np.where(band, 0.3, 1.0))
    core = (d.r_px < 16) & (np.abs(d.rows - d.centre[1]) < 6)
    assert shadow[core].mean() > 0.9, shadow[core].mean()
    skin_near = (d.r_px > 32) & (d.r_px < 44) & d.face
    assert np.median(out[core]) / np.median(out[skin_near]) > 0.7, np.median(out[core]) / np.median(out[skin_near])
