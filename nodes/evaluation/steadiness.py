"""How steady a relit clip is, against the clip it came from: the relit face should add no flicker of its own.

Fed one frame at a time (``Steadiness.add``: the input frame, the relit frame, the face's eyes), nothing of the
clip is held but the frame before. Over the face's ellipse from its eyes (``evenness.face_ellipse``, the one the
harm measure uses), on 8-bit luma (levels of 255, Rec. 601 weights of the encoded values, as a viewer sees them):

- **flicker**: per pair of consecutive frames with a face, the change of the relit face's mean level minus the
  change of the input's (each frame's mean over its own ellipse: the region follows the face); its RMS over the
  clip, in levels;
- **excess change**: the mean absolute frame-to-frame change of the relit face's pixels (the same pixels in both
  frames: the later frame's ellipse), less the input's, in levels (a relit face that shimmers while its mean stays
  put);
- **H**: ``relight.harm``'s H of each relit frame against its input (%), its median over the frames measured.
  A relit clip is a lossy encoding of the relit frames: H counts the codec's own change as well. Given the input
  as the same encoder gives it back (``floor``), its H is the codec's share; ``h_beyond_codec`` is each frame's H
  with that share taken out (in quadrature: H is an RMS), its median over the frames.

A frame without a face breaks the chain of pairs (a cut, a face lost): the next pair starts after it.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..photo.encoding import srgb_to_linear
from ..photo.evenness import face_ellipse
from ..relight.harm import harm

LUMA = np.array([0.299, 0.587, 0.114], np.float32)


def _linear(rgb8: np.ndarray) -> np.ndarray:
    return srgb_to_linear(np.asarray(rgb8, np.float32) / np.float32(255.0))


def luma8(rgb: np.ndarray) -> np.ndarray:
    """(H, W) float32 luma in levels of 255 of an (H, W, 3) uint8 RGB frame (or (H, W) grey)."""
    a = np.asarray(rgb, np.float32)
    return a if a.ndim == 2 else a @ LUMA


@dataclass
class Steadiness:
    """The figures of one clip's face, gathered frame by frame (``add``) and summed up by ``figures``.
    ``harm_every``: H is measured on every that-many-th frame with a face (it costs a blur of the face)."""

    harm_every: int = 1
    level_steps: list = field(default_factory=list)  # relit change of mean level minus the input's, levels
    pixel_excess: list = field(default_factory=list)  # mean |relit change| minus mean |input change|, levels
    harms: list = field(default_factory=list)
    floors: list = field(default_factory=list)  # H of the input through the codec alone, where given
    frames: int = 0
    with_face: int = 0
    _before: tuple | None = None  # (input luma, relit luma) of the frame before, when it had a face

    def add(self, before: np.ndarray, after: np.ndarray, eyes: np.ndarray | None,
            floor: np.ndarray | None = None) -> None:
        """One frame: ``before`` the input and ``after`` the relit frame, (H, W, 3) uint8 RGB of one size; ``eyes``
        (2, 2) photo pixels of the face measured, or None when the frame has none; ``floor``: the input through the
        relit clip's encoder alone, or None."""
        if np.shape(before) != np.shape(after):
            raise ValueError(f"the relit frame is {np.shape(after)}, its input {np.shape(before)}")
        self.frames += 1
        if eyes is None:
            self._before = None
            return
        ellipse = face_ellipse(np.asarray(eyes, np.float64), np.shape(before)[:2], 0.0)
        y0, y1, x0, x1 = ellipse.box
        m = ellipse.mask
        if not m.any():
            self._before = None
            return
        lb, la = luma8(before[y0:y1, x0:x1]), luma8(after[y0:y1, x0:x1])
        levels = (float(lb[m].mean()), float(la[m].mean()))  # the face's mean level, over its own ellipse
        full = (luma8(before), luma8(after))
        if self._before is not None:
            (pb, pa), (lpb, lpa) = self._before
            self.level_steps.append((levels[1] - lpa) - (levels[0] - lpb))
            # a pixel's change, over this frame's ellipse in both
            db, da = (lb - pb[y0:y1, x0:x1])[m], (la - pa[y0:y1, x0:x1])[m]
            self.pixel_excess.append(float(np.abs(da).mean() - np.abs(db).mean()))
        self._before = (full, levels)
        if self.with_face % max(self.harm_every, 1) == 0:
            lin_b = _linear(before)
            self.harms.append(harm(lin_b, _linear(after), eyes).h)
            if floor is not None:
                self.floors.append(harm(lin_b, _linear(floor), eyes).h)
        self.with_face += 1

    def figures(self) -> dict:
        """``frames``, ``with_face``, ``pairs``; ``flicker`` (RMS levels), ``excess_change`` (mean levels),
        ``h_median``, ``h_codec`` and ``h_beyond_codec`` (%); a figure is None when there was nothing to measure it
        on."""
        steps = np.asarray(self.level_steps, np.float64)
        beyond = None
        if self.floors and len(self.floors) == len(self.harms):
            h, f = np.asarray(self.harms), np.asarray(self.floors)
            beyond = float(np.median(np.sqrt(np.maximum(h * h - f * f, 0.0))))
        return {"frames": self.frames, "with_face": self.with_face, "pairs": int(steps.size),
                "flicker": float(np.sqrt(np.mean(steps ** 2))) if steps.size else None,
                "excess_change": float(np.mean(self.pixel_excess)) if self.pixel_excess else None,
                "h_median": float(np.median(self.harms)) if self.harms else None,
                "h_codec": float(np.median(self.floors)) if self.floors else None, "h_beyond_codec": beyond}
