"""What covers a face inside its outline: hair over the forehead or a temple, a dark head or hat brim
the face mesh's oval reaches into. Such pixels are not skin in shadow: the fit must not read them as
shape, nor the albedo as the face's own.

They are found on the model grid as the dark regions that come in from beyond the face's outline: where
the model's mean face says the face is lit, a pixel far darker than the face's typical skin under that
shading (under a share ``DARK_SHARE`` of it) is not shaded skin; the connected dark regions that reach the
outline are what covers the face. Eyes, brows and lips, dark too, are the face's own and kept (their
landmark outlines, when the face mesh gave them). On the face's shadowed side darkness says nothing, and
hair there is left to the fit's robust weights.
"""
from __future__ import annotations

import cv2
import numpy as np

from ..model.shape_model import ShapeModel
from .placement import FacePlacement, features_on_grid, outline_mask

# a pixel under this share of the face's typical brightness-to-shading ratio is not lit skin: the astronaut's hair
# is a third of her face's; the head the composite photos draw around a Yale B crop 0.4-0.5 of its skin, missed at
# 0.4 (docs/accuracy.md, "What covers a face")
DARK_SHARE = 0.55
# the mean face's shading (n . s) from which the ratio is judged: below it the face may be in attached or cast
# shadow, and darkness says nothing (at 0.3 a shadowed temple under a light from 35 degrees was taken)
LIT_SHADING = 0.45
BORDER_PX = 3  # model pixels: a dark region this near the outline reaches it (the rim itself is seldom lit)
EDGE_SHARE = 0.8  # a dark region's neighbour under this share of the typical ratio is its blended edge
FEATURE_PX = 2  # model pixels: the landmarks' outlines of eyes and brows lie a pixel or two inside their dark


def covered_pixels(image: np.ndarray, seen: np.ndarray, shading: np.ndarray, beyond: np.ndarray,
                   features: np.ndarray | None = None, dark_share: float = DARK_SHARE,
                   lit_shading: float = LIT_SHADING) -> np.ndarray:
    """(Hm, Wm) bool: the ``seen`` pixels that something dark covers, coming in from ``beyond`` the face.

    image (Hm, Wm) brightness, linear; seen (Hm, Wm) bool, the face pixels the photo shows; shading (Hm, Wm)
    the ``n . s`` the photo's light gives each pixel by the mean face (anything off ``seen``); beyond
    (Hm, Wm) bool: what lies past the face's outline (not the photo's frame: a face it cuts goes on beyond it,
    brows and all); features (Hm, Wm) bool or None: eyes, brows and lips, never taken (grown by
    ``FEATURE_PX``). A dark region is taken when it reaches within ``BORDER_PX`` of ``beyond``, with the
    lit pixels beside it under ``EDGE_SHARE`` of the typical ratio (the blend at its edge).
    """
    seen = np.asarray(seen, bool)
    keep = np.zeros_like(seen) if features is None else cv2.dilate(
        np.asarray(features, np.uint8), np.ones((2 * FEATURE_PX + 1,) * 2, np.uint8)).astype(bool)
    s = np.nan_to_num(np.asarray(shading, np.float64), nan=0.0)
    lit = seen & (s >= lit_shading) & ~keep
    if lit.sum() < 20:
        return np.zeros_like(seen)
    ratio = np.asarray(image, np.float64) / np.maximum(s, 1e-6)
    ratio /= float(np.median(ratio[lit]))  # 1: the face's typical lit skin
    dark = lit & (ratio < dark_share)
    if not dark.any():
        return dark
    border = cv2.dilate(np.asarray(beyond, np.uint8), np.ones((2 * BORDER_PX + 1,) * 2, np.uint8)).astype(bool)
    _, labels = cv2.connectedComponents(dark.astype(np.uint8), connectivity=8)
    touching = np.unique(labels[border & dark])
    covered = np.isin(labels, touching[touching > 0])
    grown = cv2.dilate(covered.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    # the blended edge: a lit neighbour part dark, part skin (the skin beside it, and pixels too turned from the
    # light to judge, are left to the fit)
    edge = grown & lit & (ratio < EDGE_SHARE)
    return (covered | edge) & seen & ~keep


def covered_on_grid(grid_image: np.ndarray, seen: np.ndarray, placement: FacePlacement, model: ShapeModel,
                    grid_light: np.ndarray) -> np.ndarray:
    """(Hm, Wm) bool: the ``seen`` model pixels that hair or a dark head covers (``covered_pixels``), judged
    under ``grid_light`` (3,), model camera frame, by the model's mean normals, coming in past the outline the
    fit trusts (the model's own edge without landmarks); the landmarks' eyes, brows and lips are kept.
    grid_image (Hm, Wm) linear brightness on the model grid; seen (Hm, Wm) bool."""
    shading = model.to_image(model.mean_normals @ np.asarray(grid_light, np.float64))
    outline = outline_mask(placement, model.grid, "fit")
    inside = model.mask if outline is None else outline & model.mask
    return covered_pixels(grid_image, seen & model.mask, shading, ~inside, features_on_grid(placement, model.grid))
