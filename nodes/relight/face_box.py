"""Where one face is in its photo: the box the relit face is made in, the larger one its layer is carried into the
photo over (the face and its feather), and the face's parts there (``Features``).

Two boxes: the face's own (``box``: the face and ``INNER_MARGIN``), where the relit face is made, and the layer's
(``layer_box``: the face and its feather), where only the face's change of light is carried into the photo around
it (``compose.outside_gain``; the part of it no light changes, ``surround``, is made once here).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..geometry.raster import polygon_mask
from ..photo.align import Alignment, face_box, mask_to_input, scalar_to_input
from .compose import Surround, surround
from .fields import distance_inside, grow

# everything but the feather is computed in the face's own box, grown by this many photo pixels
INNER_MARGIN = 4


@dataclass(frozen=True)
class Features:
    """A face's parts the face mesh drew, as photo-pixel outlines ((n, 2) each): ``eyes``, ``brows``, ``lips`` (the
    lips and the mouth's opening), ``nostrils``. Empty lists where no mesh drew them."""

    eyes: list
    brows: list
    lips: list
    nostrils: list = ()

    @property
    def all(self) -> list:
        return [*self.eyes, *self.brows, *self.lips, *self.nostrils]


class FaceBox:
    """One face's boxes in its photo. photo: (H, W, C) the whole photo; alignment: model pixel -> photo pixel; mask:
    (Hm, Wm) bool, the model's face; outline: (n, 2) the face's own outline in photo pixels, or None; segment: (h, w,
    C) linear photo -> (h, w) how sure a segmentation is that each pixel is the person, or None; feather: photo
    pixels the relit face's light fades over; features: the face's parts (``Features``), or None.

    The layer's box (the face and its feather: ``layer_box`` (y0, y1, x0, x1) photo pixels, ``layer_photo``,
    ``layer_face``, its own skin beyond the model ``layer_beyond``, the person around it ``layer_person``) and, in
    it, the face's own box (``inner`` slices; ``box`` in the photo), where the relit face is computed: its
    ``photo`` (h, w, C), ``face`` (h, w) bool, ``shape`` (h, w), ``al`` (model pixel -> box pixel).
    """

    def __init__(self, photo: np.ndarray, alignment: Alignment, mask: np.ndarray, outline: np.ndarray | None,
                 segment: Callable[[np.ndarray], np.ndarray] | None, feather: float, features: Features | None):
        self.mask, self.feather = mask, feather
        ly0, ly1, lx0, lx1 = face_box(mask, alignment, photo.shape[:2], margin=2.5 * feather + 4)
        self.layer_box = (ly0, ly1, lx0, lx1)
        self.layer_photo = np.atleast_3d(photo[ly0:ly1, lx0:lx1])
        layer_face = mask_to_input(mask, alignment.cropped(lx0, ly0), (ly1 - ly0, lx1 - lx0))
        self.layer_beyond = None  # the face's own skin the model does not reach (jaw, cheeks): relit as its rim
        if outline is not None:  # the face's own outline, at the photo's resolution
            own = polygon_mask(np.asarray(outline) - [lx0, ly0], layer_face.shape)
            self.layer_beyond = own & ~layer_face
            layer_face &= own
        self.layer_face = layer_face
        # where the person is around the face (hair, neck), not the background: the change of light reaches that far
        self.layer_person = None if segment is None else segment(self.layer_photo)
        rows, cols = np.nonzero(layer_face.any(axis=1))[0], np.nonzero(layer_face.any(axis=0))[0]
        if not rows.size:
            rows = cols = np.zeros(1, int)
        m = INNER_MARGIN
        iy0, iy1 = max(0, int(rows[0]) - m), min(ly1 - ly0, int(rows[-1]) + 1 + m)
        ix0, ix1 = max(0, int(cols[0]) - m), min(lx1 - lx0, int(cols[-1]) + 1 + m)
        self.inner = (slice(iy0, iy1), slice(ix0, ix1))  # the face's box within the layer's
        self.box = (ly0 + iy0, ly0 + iy1, lx0 + ix0, lx0 + ix1)
        y0, y1, x0, x1 = self.box
        self.al = alignment.cropped(x0, y0)
        self.photo = np.atleast_3d(photo[y0:y1, x0:x1])
        self.shape = self.photo.shape[:2]
        self.face = self.layer_face[self.inner]
        self.features = features or Features([], [], [], [])

    @cached_property
    def inside_distance(self) -> np.ndarray:
        """(h, w) float32 each face pixel's distance inside ``face`` to its border, pixels (0 off it): its rim is
        read by the fade, the room's light, the glints and the shadows from elsewhere alike."""
        return distance_inside(self.face)

    @cached_property
    def surround(self) -> Surround:
        """What carries the face's change of light into the photo around it whatever the light
        (``compose.surround``), made once for all of the face's lights."""
        return surround(self.layer_photo, self.layer_face, self.feather, self.layer_beyond, self.layer_person)

    def on_photo(self, grid: np.ndarray) -> np.ndarray:
        """(h, w) bool: a (Hm, Wm) bool map on the model grid (``mask``) brought to the box's pixels."""
        return np.nan_to_num(scalar_to_input(grid.astype(np.float32), self.mask, self.al, self.shape)) >= 0.5

    def outlined(self, outlines: list, margin_px: float) -> np.ndarray:
        """(h, w) bool: the box's pixels inside the ``outlines`` (photo pixels), grown by ``margin_px``."""
        if not outlines:
            return np.zeros(self.shape, bool)
        y0, _, x0, _ = self.box
        return grow(np.logical_or.reduce([polygon_mask(np.asarray(o) - [x0, y0], self.shape) for o in outlines]),
                    margin_px)

    def in_layer(self, values: np.ndarray) -> np.ndarray:
        """(h, w[, C]) values on the face's box -> the layer's box, 0 around."""
        out = np.zeros(self.layer_face.shape + values.shape[2:], np.float32)
        out[self.inner] = values
        return out
