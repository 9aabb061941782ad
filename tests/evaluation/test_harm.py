"""The no-reference harm measure (``relight/harm.py``) and the people evaluation's table and sheet on synthetic faces with known damage."""
from __future__ import annotations

import numpy as np
import pytest
from shadowflow.nodes.evaluation.people import contact_sheet, format_table, summarise
from shadowflow.nodes.relight.harm import (
    added_edges,
    colour_blotches,
    colour_shift,
    face_ellipse,
    flattened,
    harm,
    light_move,
)

EYES = np.array([[150.0, 160.0], [250.0, 160.0]])  # 100 px apart


def _skin(seed: int = 0, shape=(400, 400)) -> np.ndarray:
    """(H, W, 3) linear 'skin': a warm tone with pores' fine texture."""
    rng = np.random.default_rng(seed)
    tone = np.array([0.45, 0.3, 0.22], np.float32)
    texture = 1.0 + 0.08 * rng.standard_normal(shape).astype(np.float32)
    return tone * texture[..., None]


def _disc(centre, radius, shape=(400, 400)) -> np.ndarray:
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]]
    return (xx - centre[0]) ** 2 + (yy - centre[1]) ** 2 <= radius**2


def test_the_ellipse_is_placed_by_the_eyes_and_follows_their_roll():
    e = face_ellipse(EYES, (400, 400))
    y0, _, x0, _ = e.box
    rows, cols = np.nonzero(e.mask)
    # 1 x 1.35 eye distances (semi-axes), centred 0.45 below the eyes' midpoint
    assert cols.min() + x0 == pytest.approx(100, abs=1.5) and cols.max() + x0 == pytest.approx(300, abs=1.5)
    assert rows.min() + y0 == pytest.approx(205 - 135, abs=1.5) and rows.max() + y0 == pytest.approx(205 + 135, abs=1.5)
    # the same eyes given the other way round: the same ellipse; rolled by 90 degrees: the ellipse turns with them
    assert np.array_equal(face_ellipse(EYES[::-1], (400, 400)).mask, e.mask)
    rolled = face_ellipse(np.array([[200.0, 150.0], [200.0, 250.0]]), (400, 400))
    r_rows, r_cols = np.nonzero(rolled.mask)
    assert np.ptp(r_cols) > np.ptp(r_rows)  # longer across the image now


def test_an_unchanged_face_or_a_smooth_change_of_light_is_no_harm():
    photo = _skin()
    assert harm(photo, photo, EYES).h == 0.0
    yy, xx = np.mgrid[0:400, 0:400].astype(np.float32)
    smooth = 0.6 + 0.9 * np.exp(-((xx - 120) ** 2 + (yy - 200) ** 2) / (2 * 150.0**2))  # a light from the left
    relit = photo * smooth[..., None]
    score = harm(photo, relit, EYES)
    assert score.h < 1.5 and score.p == 0.0  # a light 2.5x brighter on one side than the other


@pytest.mark.parametrize("damage", ["patch", "erased beard", "outline"])
def test_patches_erased_texture_and_outlines_are_harm(damage):
    photo = _skin(1)
    beard = _disc((200, 300), 45)
    photo[beard] *= 0.15  # a dark beard
    relit = photo.copy()
    if damage == "patch":  # a flat, brighter tone pasted over a cheek
        relit[_disc((150, 230), 20)] = 0.7
    elif damage == "erased beard":  # the beard taken for shadow and painted as skin
        relit[beard] = np.array([0.45, 0.3, 0.22], np.float32)
    else:  # the face relit 1.5x with a hard edge
        relit[_disc((200, 205), 90)] *= 1.5
    score = harm(photo, relit, EYES)
    # one such flaw on a face: above what a person called good (1.0-4.1 %), each pixel of it a blotch (P)
    assert score.h > 6.0, score
    assert score.p > 2.0


def test_within_the_face_only_its_outline_against_the_background_is_no_harm():
    """A head turned so far that the eyes' ellipse reaches past its outline onto the background: the face relit
    2x smoothly is a step at the outline over the ellipse (what the honesty check had taken for harm on turned
    renders), none over the face's own pixels; a patch inside the face is harm either way."""
    photo = _skin(3)
    face = np.zeros((400, 400), bool)
    face[:, :260] = True  # the outline crosses the ellipse (x 100-300) at x = 260
    relit = photo.copy()
    relit[face] *= 2.0
    assert harm(photo, relit, EYES).h > 8.0  # above the honesty check's bound (relight.nodes.EVEN_HARM)
    assert harm(photo, relit, EYES, within=face).h < 0.5
    relit[_disc((170, 230), 30)] = 1.6  # a flat, brighter tone pasted over a cheek
    assert harm(photo, relit, EYES, within=face).h > 6.0


def test_halves_say_whether_a_face_is_lit_evenly():
    photo = _skin(2)
    assert harm(photo, photo, EYES).even
    side = photo.copy()
    side[:, :200] *= 1.4  # the image-left half 40 % brighter
    score = harm(side, side, EYES)
    assert not score.even and score.halves == pytest.approx(1.4, rel=0.02)


def test_a_light_from_the_image_left_moves_the_light_left():
    photo = _skin(3)
    xx = np.mgrid[0:400, 0:400][1].astype(np.float32)
    relit = photo * np.exp(0.004 * (200 - xx))[..., None]  # brighter toward the image's left
    # each half's centroid lies 4 a / (3 pi) = 42 px from the axis: 2 x 0.004 x 42 apart in log (the blur, normalised
    # over the ellipse, flattens the ramp at its edge a little)
    assert light_move(photo, relit, EYES) == pytest.approx(2 * 0.004 * 400 / (3 * np.pi), rel=0.1)
    darker_left = photo * np.exp(0.004 * (xx - 200))[..., None]
    assert light_move(photo, darker_left, EYES) == pytest.approx(-2 * 0.004 * 400 / (3 * np.pi), rel=0.1)


def test_the_summary_counts_evenly_lit_faces_and_the_ones_called_ok_that_are_harmed():
    rows = [{"photo": "a.jpg", "face": 1, "status": "ok", "h": 2.0, "p": 0.0, "halves": 1.05, "even": True, "move": 0.6},
            {"photo": "a.jpg", "face": 2, "status": "ok", "h": 15.0, "p": 6.0, "halves": 1.1, "even": True, "move": 0.4},
            {"photo": "b.jpg", "face": 1, "status": "doubtful", "h": 30.0, "p": 9.0, "halves": 1.5, "even": False,
             "move": 0.2, "reason": "x"},
            {"photo": "c.jpg", "face": 1, "status": "refused", "reason": "turned"},
            {"photo": "d.jpg", "face": 0, "status": "refused", "reason": "no face found"}]
    s = summarise(rows)
    assert (s["faces"], s["relit"], s["refused"], s["doubtful"], s["inputs_refused"]) == (4, 3, 1, 1, 1)
    assert s["even"] == 2 and s["even_h_median"] == pytest.approx(8.5) and s["even_ok_over_bad"] == 1
    assert s["ok_over_bad"] == 1 and s["move_median"] == pytest.approx(0.4)
    assert "evenly lit (halves within 15 %): 2 faces" in format_table(rows)
    assert contact_sheet(rows) is None  # no thumbnails kept


def test_a_white_light_keeps_the_skins_colour_and_a_tint_is_a_colour_shift():
    """A change of level alone, however uneven, shifts no colour; the skin turned greyer (its red lowered against
    its green, as a per-channel change of light did to pink skin) is a colour shift of about the log ratio; H does
    not see it."""
    photo = _skin()
    yy, xx = np.mgrid[0:400, 0:400].astype(np.float32)
    level = (0.6 + 0.9 * np.exp(-((xx - 120) ** 2 + (yy - 200) ** 2) / (2 * 150.0**2)))[..., None]
    assert colour_shift(photo, photo * level, EYES) < 0.2  # (EPS, added to each channel, moves it a little)
    greyer = photo * level * np.array([0.93, 1.0, 1.0], np.float32)  # ln 0.93: 7 % of red against green
    assert colour_shift(photo, greyer, EYES) == pytest.approx(100 * -np.log(0.93), rel=0.05)
    assert harm(photo, greyer, EYES).h < 1.5  # (as the level change alone: the test above)
    outside = photo.copy()
    outside[:40] *= np.array([0.5, 1.0, 1.0], np.float32)  # above the face's ellipse: not the face
    assert colour_shift(photo, outside, EYES) == 0.0
    assert colour_shift(photo[..., :1], photo[..., :1] * 0.5, EYES) == 0.0  # a grey photo has no colour to shift


def _side_lit(seed: int):
    """(photo, lifted, ramp) a skin lit from the image's left with a hard-edged shadow (0.3 of the light) over its
    right cheek, the same skin with that shadow lifted exactly (the photo's texture kept) and relit frontally (the
    left-to-right fall of light taken away), and that fall (H, W)."""
    photo = _skin(seed)
    xx = np.mgrid[0:400, 0:400][1].astype(np.float32)
    ramp = np.exp(0.006 * (200 - xx))
    shadow = _disc((250, 240), 40)
    shaded = photo * ramp[..., None]
    shaded[shadow] *= 0.3
    return shaded, photo, shadow


def test_a_lifted_shadow_and_a_new_light_add_no_edge_and_no_colour():
    """What a relighting does rightly takes edges away (a shadow's rim) and keeps the colour; the new light's own
    shadow is an edge it adds rightly, when its shading is given."""
    photo, lifted, _ = _side_lit(4)
    assert added_edges(photo, lifted, EYES) < 0.5 and colour_blotches(photo, lifted, EYES) < 0.5
    new_shadow = np.where(_disc((150, 240), 35), 0.3, 1.0).astype(np.float32)  # the new light's, on the other cheek
    relit = lifted * new_shadow[..., None]
    assert added_edges(photo, relit, EYES) > 3.0  # its rim is an edge the photo has not ...
    assert added_edges(photo, relit, EYES, new_light=new_shadow) < 0.5  # ... which the new light makes


@pytest.mark.parametrize("damage", ["pasted patch", "painted slab"])
def test_a_pasted_patch_or_a_painted_slab_adds_edges(damage):
    """A patch pasted with a hard rim, or the shadowed cheek painted flat over a wider region: edges the photo has
    not, over more of the face than ``relight.nodes.ADDED_EDGES`` (7.2 %), alone enough to give the face back; the
    lifted face beside them adds none."""
    photo, lifted, _ = _side_lit(5)
    damaged = lifted.copy()
    if damage == "pasted patch":
        for centre in ((140, 200), (260, 300), (190, 280), (130, 290), (270, 200)):
            damaged[_disc(centre, 22)] *= 1.8
    else:  # a paler slab with a scalloped rim, as a mask painted over a beard and a shadowed side
        yy, xx = np.mgrid[0:400, 0:400]
        angle = np.arctan2(yy - 240, xx - 250)
        slab = np.hypot(xx - 250, yy - 240) < 60 + 18 * np.sin(9 * angle)
        damaged[slab] = np.array([0.8, 0.55, 0.42], np.float32)
    assert added_edges(photo, damaged, EYES) > 7.2
    assert added_edges(photo, lifted, EYES) < 0.5


def test_orange_and_green_blotches_are_a_change_of_colour_at_a_fine_scale():
    """A white change of light (a lifted shadow, a ramp) changes no colour; blotches a third of an eye distance
    wide, warmer or greener by 30-50 %, do (``relight.nodes.COLOUR_BLOTCHES`` 14 %); a grey photo has no colour to
    change."""
    photo, lifted, _ = _side_lit(6)
    assert colour_blotches(photo, lifted, EYES) < 0.5
    blotchy = lifted.copy()
    for k, centre in enumerate(((150, 200), (250, 210), (200, 290), (140, 280), (260, 290), (200, 220), (200, 330))):
        tint = np.array([1.5, 1.0, 0.7] if k % 2 else [0.75, 1.3, 0.85], np.float32)
        blotchy[_disc(centre, 22)] *= tint
    assert colour_blotches(photo, blotchy, EYES) > 14.0
    grey = photo.mean(axis=-1)
    assert colour_blotches(grey, blotchy.mean(axis=-1), EYES) == 0.0


def test_a_black_shadow_lifted_to_the_skins_colour_has_no_colour_of_its_own_to_lose():
    """A pixel at the noise floor has no colour to keep: a render's black nose shadow lifted to skin read 11 % of
    the face before such pixels were left out. (The log's floor lifted with the light, ``added_edges``, is held by
    ``tests/evaluation/test_colour.py``: Yale B's sRGB copies lit from 70 degrees came back as they were without
    it.)"""
    photo = _skin(7)
    black = photo.copy()
    black[_disc((230, 230), 40)] = 0.0
    assert colour_blotches(black, photo, EYES) < 1.0
    assert colour_blotches(black * 0.5, photo, EYES) < 1.0  # a change of level alone, the black still black


def test_what_the_file_clipped_relit_darker_is_flattened():
    """``flattened``: the share of the face at its file's top (a channel at 255) that the relit face darkens by a
    tenth or more. A clipped disc darkened by the exposure counts whole; darkened by 5 %, brightened, or darkened
    where the file is not at its top (a hair under it), it does not."""
    photo = _skin()
    face = _disc((200, 220), 150)
    disc = _disc((200, 150), 40)  # 5,000 px of the face's 70,000
    photo[disc] = [1.0, 0.97, 0.9]  # its red channel at the file's top
    share = 100.0 * disc.sum() / face.sum()
    assert flattened(photo, photo * 0.8, face) == pytest.approx(share, rel=1e-6)
    assert flattened(photo, photo * 0.95, face) == 0.0
    assert flattened(photo, photo * 1.2, face) == 0.0
    below = photo.copy()
    below[disc] = [0.99, 0.97, 0.9]
    assert flattened(below, below * 0.8, face) == 0.0
    assert flattened(photo, photo * 0.8, face & ~disc) == 0.0
