"""A face's change of light carried from one frame of a clip to the next, so the relit face adds no flicker.

A frame's relit face is its photo times a change of light (``compose.FaceLayer``). Its coarse part (the log change
of luminance blurred over ``COARSE`` eye distances: the level, the light's fall across the face, a shadow lifted)
should move only as the person and the light move; fitted frame by frame it jitters (the fit, the exposure, the
shadow evidence each differ a little). So the coarse part is kept on a grid fixed to the face (``FaceGrid``: the
eyes' midpoint, their line and their distance; ``GRID`` samples a side over ``SPAN``), averaged over the frames
(``carry``: an exponential moving average, the frame's own share ``ALPHA``), and each frame's layer is multiplied by
the running coarse change over its own (``steadied``). A change of light the photo itself shows is not averaged:
when the photo's own coarse luminance on the grid moved since the frame before over most of the face, beyond the
frame's change of level (a light moved or switched: ``light_shown_changed``), the running change starts again from
the frame's own; averaged, the change made for the light before was laid over the photo under the new one. The
fine part (texture, the photo's own shadow edges) stays the frame's. Arrays are on the photo's pixel grid; eyes are
(2, 2) photo pixels, image-left eye first.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import cv2
import numpy as np

from ..photo.evenness import ELLIPSE_AXES, ELLIPSE_DROP, eye_axes
from .compose import FaceLayer, compose
from .fields import blur, smoothstep
from .harm import EPS

COARSE = 0.12  # the coarse part's Gaussian, eye distances (a change finer than this is the frame's own)
ALPHA = 0.3  # a frame's own share of the running coarse change (as the clip's light's, ``app.steady.ALPHA``)
GRID = 96  # samples a side of the face's grid
SPAN = ((-1.9, 1.9), (-1.5, 2.3))  # the face's grid: x (along the eyes) and y (down), eye distances from their midpoint
LIMIT = 0.7  # the correction of a pixel's log change, at most (a factor of 2): a carried field far off is no help
# A change of light the photo itself shows: three quarters of the face (the ellipse from its eyes) moved, in coarse
# log luminance on its grid since the frame before, by more than LIGHT_SHOWN past the median move (an exposure's
# change is the photo's level, which the change of light follows as it is). Measured, the lower quartile of that move
# over the face: a light swept across a Yale B face, 0.12-0.34 at its steps of 20-25 degrees, 0.05-0.14 at those of
# 10-15 degrees near the front (mostly not told); a webcam face in hard light with hands passing across it and its
# mouth opening wide (mohsin_face), 0.1 at most; talking faces in a studio, on a phone, 0.03 at most. On such a frame
# the running change starts again from the frame's own, and the face's light takes the frame's estimate
# (``app.steady.LightSmoother``). Taken wherever the photo moved on any frame (not only when most of the face did),
# the hands and the mouth let the webcam's relit face follow each frame's own relighting: its flicker 0.50 -> 1.17
# levels; taken only where the photo moved on such a frame, the change carried from the light before stayed where it
# did not (a nose's ridge lit under both lights), a bright stripe down it
LIGHT_SHOWN = 0.125


@dataclass(frozen=True)
class FaceGrid:
    """Where a face's grid lies in the photo: ``to_photo`` (2, 3) the affine map grid sample -> photo pixel."""

    to_photo: np.ndarray

    @classmethod
    def from_eyes(cls, eyes: np.ndarray) -> FaceGrid:
        mid, iod, u, down = eye_axes(eyes)
        (x0, x1), (y0, y1) = SPAN
        step_x, step_y = (x1 - x0) * iod / (GRID - 1), (y1 - y0) * iod / (GRID - 1)
        origin = mid + x0 * iod * u + y0 * iod * down
        return cls(np.array([[u[0] * step_x, down[0] * step_y, origin[0]],
                             [u[1] * step_x, down[1] * step_y, origin[1]]], np.float64))

    def in_box(self, box: tuple[int, int, int, int]) -> np.ndarray:
        """(2, 3) grid sample -> pixel of the photo's ``box`` (y0, y1, x0, x1)."""
        m = self.to_photo.copy()
        m[:, 2] -= [box[2], box[0]]
        return m


def coarse_change(layer: FaceLayer, photo: np.ndarray, iod_px: float) -> np.ndarray:
    """(h, w) float32 the coarse log change of luminance ``layer`` makes to ``photo`` (h, w, C) linear, its box of
    the photo: ``ln(Y_relit + EPS) - ln(Y_photo + EPS)``, blurred over ``COARSE`` eye distances (``iod_px``)."""
    h, w = photo.shape[:2]
    relit = compose(photo, [dataclasses.replace(layer, box=(0, h, 0, w))])
    r = np.log(_luminance(relit) + np.float32(EPS)) - np.log(_luminance(photo) + np.float32(EPS))
    return blur(r.astype(np.float32), COARSE * iod_px)


def _luminance(image: np.ndarray) -> np.ndarray:
    a = np.atleast_3d(np.asarray(image, np.float32))
    return a[..., 0] if a.shape[-1] == 1 else a @ np.array([0.2126, 0.7152, 0.0722], np.float32)


def to_grid(field: np.ndarray, grid: FaceGrid, box: tuple[int, int, int, int]) -> tuple[np.ndarray, np.ndarray]:
    """``field`` (h, w) on the photo's ``box`` sampled on the face's grid: (GRID, GRID) values and where they came
    from inside the box (bool)."""
    m = grid.in_box(box)
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    values = cv2.warpAffine(field.astype(np.float32), m, (GRID, GRID), flags=flags, borderMode=cv2.BORDER_CONSTANT)
    inside = cv2.warpAffine(np.ones(field.shape[:2], np.float32), m, (GRID, GRID), flags=flags,
                            borderMode=cv2.BORDER_CONSTANT)
    return values, inside > 0.999


def from_grid(values: np.ndarray, known: np.ndarray, grid: FaceGrid, box: tuple[int, int, int, int]
              ) -> tuple[np.ndarray, np.ndarray]:
    """The face's grid ``values`` (GRID, GRID), where ``known``, brought onto the photo's ``box``: (h, w) values
    and (h, w) float32 in [0, 1] how much of each is known."""
    h, w = box[1] - box[0], box[3] - box[2]
    m = grid.in_box(box)
    k = known.astype(np.float32)
    values = cv2.warpAffine((values * k).astype(np.float32), m, (w, h), flags=cv2.INTER_LINEAR,
                            borderMode=cv2.BORDER_CONSTANT)
    weight = cv2.warpAffine(k, m, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
    return values / np.maximum(weight, np.float32(1e-6)), weight


@dataclass
class Carried:
    """A face's running coarse change on its grid: ``values`` (GRID, GRID) float32 and where it is ``known``."""

    values: np.ndarray
    known: np.ndarray


def photo_on_grid(grey: np.ndarray, eyes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A photo's coarse log luminance (``ln(Y + EPS)`` blurred over ``COARSE`` eye distances) on its face's grid:
    ``grey`` (H, W) linear, ``eyes`` (2, 2) photo pixels -> ((GRID, GRID) float32, where it is known: bool)."""
    _, iod, _, _ = eye_axes(eyes)
    grid = FaceGrid.from_eyes(eyes)
    # only the grid's part of the photo, and the blur's reach around it
    corners = grid.to_photo @ np.array([[0, GRID - 1, 0, GRID - 1], [0, 0, GRID - 1, GRID - 1], [1, 1, 1, 1]])
    reach = 3.0 * COARSE * iod
    h, w = grey.shape
    x0, x1 = int(np.clip(corners[0].min() - reach, 0, w)), int(np.clip(np.ceil(corners[0].max() + reach) + 1, 0, w))
    y0, y1 = int(np.clip(corners[1].min() - reach, 0, h)), int(np.clip(np.ceil(corners[1].max() + reach) + 1, 0, h))
    if x1 <= x0 or y1 <= y0:  # the face's grid lies off the photo
        return np.zeros((GRID, GRID), np.float32), np.zeros((GRID, GRID), bool)
    crop = np.asarray(grey[y0:y1, x0:x1], np.float32)
    lum = blur(np.log(crop + np.float32(EPS)), COARSE * iod)
    return to_grid(lum, grid, (y0, y1, x0, x1))


def light_shown_changed(before: tuple[np.ndarray, np.ndarray], now: tuple[np.ndarray, np.ndarray]) -> bool:
    """Whether the photo itself shows that the light on a face changed between two frames: their coarse log
    luminance on its grid (``photo_on_grid``, (values, known) each) moved by more than ``LIGHT_SHOWN`` over three
    quarters of the face (the move past the median move: an exposure is not a change of light)."""
    both = before[1] & now[1] & _FACE
    if both.sum() < 0.25 * _FACE.sum():  # (a face mostly off the photo: not told)
        return False
    moved = (now[0] - before[0])[both]
    return bool(np.percentile(np.abs(moved - np.median(moved)), 25) > LIGHT_SHOWN)


def _face_on_grid() -> np.ndarray:
    """(GRID, GRID) bool the face on its grid: the ellipse from its eyes (``evenness.face_ellipse``'s)."""
    xs, ys = np.linspace(*SPAN[0], GRID), np.linspace(*SPAN[1], GRID)
    (a, b), drop = ELLIPSE_AXES, ELLIPSE_DROP
    return (xs[None, :] / a) ** 2 + ((ys[:, None] - drop) / b) ** 2 < 1.0


_FACE = _face_on_grid()


def carry(before: Carried | None, own: np.ndarray, own_known: np.ndarray, alpha: float = ALPHA) -> Carried:
    """The running coarse change after a frame whose own is ``own`` (GRID, GRID), known where ``own_known``: the
    average of ``before``'s and the frame's, the frame's share ``alpha``, where both know it; the frame's own where
    only it does."""
    if before is None:
        return Carried(own.astype(np.float32), own_known.copy())
    both = before.known & own_known
    values = np.where(both, (1.0 - alpha) * before.values + alpha * own, own).astype(np.float32)
    return Carried(values, own_known.copy())


def steadied(layer: FaceLayer, correction: np.ndarray) -> FaceLayer:
    """``layer`` with its change of light multiplied by ``exp(correction)`` (h, w) on its box: its relit face and its
    gain around it alike, so the face meets the photo around it without a seam (a face eased back to the photo as it
    was has a gain of 1 around it, and the change carried from the frames before reaches past its border). Where the
    correction is 0 (no frame's change reaches: its coarse part is exactly 0 there) the photo stays the photo, bit for
    bit."""
    c = np.exp(np.clip(correction, -LIMIT, LIMIT)).astype(np.float32)[..., None]
    return dataclasses.replace(layer, relit=(layer.relit * c).astype(np.float32),
                               gain=(layer.gain * c).astype(np.float32))


def steady_layer(layer: FaceLayer, photo: np.ndarray, eyes: np.ndarray, before: Carried | None,
                 alpha: float = ALPHA, light_changed: bool = False, alone: bool = False) -> tuple[FaceLayer, Carried]:
    """One frame's ``layer`` of a face steadied by the face's running coarse change ``before`` (None: the first
    frame, kept as it is): ``(layer, carried)``, the carried change for the next frame. ``photo`` (h, w, C) linear,
    the layer's box of the photo; ``eyes`` (2, 2) photo pixels; ``light_changed``: the photo shows the light changed
    since the frame before (``light_shown_changed``): the frame is kept as it is, and the running change starts again
    from its own; ``alone``: the frame was relit under a light of its own (``app.steady.LightSmoother``'s "alone"):
    kept as it is, the running change carried past it."""
    if alone and before is not None:
        return layer, before
    _, iod, _, _ = eye_axes(eyes)
    grid = FaceGrid.from_eyes(eyes)
    own = coarse_change(layer, photo, iod)
    own_grid, own_known = to_grid(own, grid, layer.box)
    if light_changed:
        before = None
    running = carry(before, own_grid, own_known, alpha)
    if before is None:
        return layer, running
    target, weight = from_grid(running.values, running.known, grid, layer.box)
    # where the grid knows nothing (past its span), the frame's own change stands; toward the box's edge too, so
    # no step can show where the layer ends
    correction = weight * (target - own) * _edge_taper(own.shape, 2.0 * COARSE * iod)
    return steadied(layer, correction), running


def _edge_taper(shape: tuple[int, int], width: float) -> np.ndarray:
    """(h, w) float32: 0 on a box's edge, rising smoothly to 1 ``width`` pixels in."""
    h, w = shape
    ys = np.minimum(np.arange(h), np.arange(h)[::-1]).astype(np.float32)
    xs = np.minimum(np.arange(w), np.arange(w)[::-1]).astype(np.float32)
    return np.minimum(smoothstep(ys, 0.0, width)[:, None], smoothstep(xs, 0.0, width)[None, :])
