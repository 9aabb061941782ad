"""Is there a face, and did the fit work? Per-frame signals, a score and flags.

Signals (all measured on what the method already computed):
- ``eyes``: how the face was placed: detected (by the face mesh's landmarks), given (its eyes, or
  the placement itself), centre asked (taken as a frontal crop), or none;
- ``explained``: the share of the face's brightness variation the fitted shape explains, ``1 -
  var(I - rho S) / var(I)`` over the lit face (``S`` the fitted model's shading, ``rho`` the
  median albedo), each pixel weighted by the fit's robust weight: faces give 0.5-0.99 under any
  light from frontal to 70 degrees; noise, patterns, text, landscapes and faces turned away from
  the model's orientation give less. The eyes, where a face mesh drew them, and what lies around
  them within ``EYEWEAR_MARGIN`` (lashes, sockets, a pair of sunglasses) are left out: their darkness
  is albedo, which no shape explains (sunglasses made a well-placed face "explain 40 %");
- ``downweighted``: the share of the face the robust fit did not trust (weight under 0.5);
- ``clipped``: the share of the face clipped by over-exposure;
- ``inside``: the share of the face's core (brows to
  mouth between the outer eye corners, ``core_face``) inside the frame: tight crops such as Yale B's
  keep all of it though the model's forehead and chin run past them.

The score is ``explained`` scaled down by each problem, and halved by each flag; ``flags`` name
the problems, the placement's doubts (``photo.placement``) among them. A frame with no eyes whose
fit explains little has no face: it fails with that reason; so does a found face whose fit explains very
little, unless the face detector and the face mesh are both sure of it and its landmarks have a face's
proportions (a portrait in soft light, whose brightness is mostly albedo). A frame with a flag is
doubtful: its outputs are written and its status says why.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from ..photo.placement import CUT_BY_FRAME
from .robust_fit.robust import huber_weights

NO_FACE = "no face found"  # a frame's (or a face candidate's) reason when it holds no face
# a clip's face tracked this many frames (``meta["track_age"]``) is not refused as no face by its fit (a webcam face
# fitted badly on one frame of 158, "explains 12 %", came back unrelit between relit frames)
TRACKED_FACE = 3

# thresholds set between real and rendered faces (good) and the hostile corpus of tests/method/test_quality.py
# (bad); what each side measured: docs/tuning.md, "Quality"
MIN_EXPLAINED = 0.4  # a face's shading explains at least this much of its brightness
# ... which an evenly lit face (its eyes found) is not asked to: its score takes at least this for it
EVEN_EXPLAINED = 0.7
UNEXPLAINED = "the fitted face explains "  # how the flag of a fit that explains too little begins
NO_FACE_EXPLAINED = 0.75  # without eyes found, the fit must explain this much to count as a face
# a found face whose fit explains less than this is none (concentric rings, which the face finder takes for a
# face); under MIN_EXPLAINED, doubtful
LEAST_EXPLAINED = 0.25
# ... unless the face detector and the face mesh are this sure of it and its landmarks have a face's proportions:
# then it is a face the fit does not explain (a portrait in soft light, whose brightness is mostly its albedo),
# doubtful, not none (the rings: detector 0.50-0.60, a graffiti 0.51; real faces in soft light 0.83-0.97, under a
# leaves' dappled shadow 0.69: between them; docs/tuning.md)
CONFIDENT_DETECTION = 0.65
CONFIDENT_PRESENCE = 0.9
MAX_DOWNWEIGHTED = 0.7  # of the seen face's pixels the fit may give a weight under 0.5
MAX_CLIPPED = 0.4  # over-exposure the ratio scale handles
MIN_INSIDE = 0.75  # of the face's core inside the frame
# the eyes grown by this many interocular distances: albedo, not shading, for ``explained`` (sunglasses reach
# about this far past the eyes' outlines)
EYEWEAR_MARGIN = 0.2


@dataclass
class Quality:
    """score in [0, 1]; flags: the problems, one phrase each; signals: the measurements; no_face:
    the frame holds no face the method can use."""

    score: float
    flags: list[str] = field(default_factory=list)
    signals: dict[str, float | str] = field(default_factory=dict)
    no_face: bool = False

    def record(self) -> dict:
        return {"score": round(self.score, 3), "flags": list(self.flags),
                **{k: (round(v, 4) if isinstance(v, float) else v) for k, v in self.signals.items()}}


def core_face(model) -> np.ndarray:
    """(Hm, Wm) bool: the model's face from the brows to below the mouth, between the outer eye
    corners: what a usable photo shows whole."""
    eyes = np.asarray(model.eyes, np.float64)
    iod = model.iod
    rows, cols = np.mgrid[0:model.grid[0], 0:model.grid[1]]
    eye_row = float(eyes[:, 1].mean())
    box = ((cols >= eyes[0, 0] - 0.4 * iod) & (cols <= eyes[1, 0] + 0.4 * iod)
           & (rows >= eye_row - 0.5 * iod) & (rows <= eye_row + 1.4 * iod))
    return box & model.mask


def grown_region(parts: np.ndarray, margin_px: float) -> np.ndarray:
    """(Hm, Wm) bool: a face's parts (Hm, Wm) bool (``placement.features_on_grid``: its eyes, its lips) grown by
    ``margin_px`` model pixels."""
    return cv2.distanceTransform((~np.asarray(parts, bool)).astype(np.uint8), cv2.DIST_L2, 3) <= margin_px


def explained_variance(intensity: np.ndarray, shading: np.ndarray, use: np.ndarray,
                       weights: np.ndarray | None = None) -> float:
    """``1 - sum w (I - rho S)^2 / sum w (I - mean_w I)^2`` over the ``use`` pixels, ``rho`` the
    median of ``I / S`` where ``S >= 0.3``. intensity, shading, use, weights: (N,); weights: the
    fit's robust weights (default all 1, the plain share of variance). Under a light near the view
    axis a face's shading hardly varies and most of its brightness variation is albedo (brows,
    eyes, lips, nostrils), which no shape explains and the robust fit has already discounted:
    the plain share gave frontally lit Yale B photos 0.18-0.3, the weighted one 0.5-0.6.
    Returns a number <= 1 (0 when nothing fits)."""
    use = np.asarray(use, bool)
    I, S = np.asarray(intensity, np.float64)[use], np.asarray(shading, np.float64)[use]
    w = np.ones_like(I) if weights is None else np.asarray(weights, np.float64)[use]
    if I.size < 50 or np.var(I) < 1e-8 or w.sum() <= 0:
        return 0.0
    bright = S >= 0.3
    rho = float(np.median(I[bright] / S[bright])) if bright.sum() >= 20 else float(np.mean(I) / max(np.mean(S), 1e-6))
    spread = float(np.sum(w * (I - np.average(I, weights=w)) ** 2))
    if spread < 1e-12:
        return 0.0
    return float(1.0 - np.sum(w * (I - rho * S) ** 2) / spread)


def unread_weights(intensity: np.ndarray, model_normals: np.ndarray, light: np.ndarray, threshold: float) -> np.ndarray:
    """(N,) the robust weight each pixel would have had in the fit had it read it: Huber's, at ``threshold``
    (radians), of the angle between its fitted normal's cone and the cone its brightness puts it on. For the
    pixels the fit left out (hair, ``photo.cover``), which its quality must still count: with weight 0 a face
    placed upside down, brows and hair over its chin left out, read as a face its fit explains.
    intensity (N,) remapped brightness; model_normals (N, 3); light (3,) unit, both model frame."""
    on_cone = np.arccos(np.clip(np.asarray(intensity, np.float64), 0.0, 1.0))
    fitted = np.arccos(np.clip(np.asarray(model_normals, np.float64) @ np.asarray(light, np.float64), -1.0, 1.0))
    return huber_weights(on_cone - fitted, threshold)


def assess(eyes: str, explained: float, downweighted: float, clipped: float, inside: float,
           doubts: tuple[str, ...] = (), plausible: bool = True, presence: float | None = None,
           detection: float | None = None, even: bool = False) -> Quality:
    """The score and flags of one frame from its signals (module docstring); ``doubts``: what the
    face's placement found wrong (``photo.placement``), each a flag; ``plausible``: whether its
    landmarks have a face's proportions; ``presence``, ``detection``: the face mesh's and the face
    detector's scores for a found face (None: not found by them); ``even``: the face is lit evenly from side to
    side (``photo.evenness``): a soft or frontal light leaves little shading, and how little of it the fit explains
    says nothing of the fit (such faces were called doubtful for it, and the score took it as a bad fit)."""
    signals = {"eyes": eyes, "explained": explained, "downweighted": downweighted, "clipped": clipped,
               "inside": inside, "even": even}
    flags = list(doubts)
    if eyes == "none":
        flags.append("no eyes found")
    if even and eyes != "none":  # (its signals keep what the fit explained)
        explained = max(explained, EVEN_EXPLAINED)
    elif explained < MIN_EXPLAINED:
        flags.append(f"{UNEXPLAINED}{100 * max(explained, 0):.0f} % of the image's shading")
    if downweighted > MAX_DOWNWEIGHTED:
        flags.append(f"{100 * downweighted:.0f} % of the face down-weighted")
    if clipped > MAX_CLIPPED:
        flags.append(f"{100 * clipped:.0f} % of the face clipped")
    if inside < MIN_INSIDE:
        flags.append(f"{100 * (1 - inside):.0f} % of the face outside the frame")
    score = float(np.clip(explained, 0.0, 1.0))
    score *= 0.5 if eyes == "none" else 1.0
    score *= 1.0 - 0.5 * max(0.0, downweighted - 0.3)
    score *= 1.0 - max(0.0, clipped - 0.05)
    score *= min(1.0, inside / MIN_INSIDE) ** 4
    score *= 0.5 ** len(flags)  # a doubtful frame never outscores a clean one of the same fit
    no_face = _no_face(eyes, signals["explained"], doubts, plausible, presence, detection)
    # a frame that holds no face has no result to trust, however even its light
    return Quality(0.0 if no_face else score, flags, signals, no_face)


def _no_face(eyes: str, explained: float, doubts: tuple[str, ...], plausible: bool, presence: float | None,
             detection: float | None) -> bool:
    """Whether a frame holds no face (``assess``'s arguments)."""
    # a face cut by the frame is a face, doubtful for it: the frame takes its shading and the detector's sureness
    cut, doubts = _cut(doubts)
    # the face mesh sees faces in some patterns (concentric rings): a face its fit does not explain, that only the
    # mesh saw or whose placement is in doubt too, is none
    unexplained = explained < (MIN_EXPLAINED if eyes == "mesh only" or doubts else LEAST_EXPLAINED)
    # ... but one both nets are sure of, in a face's proportions, with nothing else in doubt, is a face: doubtful
    sure = (detection or 0.0) >= CONFIDENT_DETECTION or cut
    confirmed = eyes == "detected" and plausible and not doubts and (presence or 0.0) >= CONFIDENT_PRESENCE and sure
    # a mesh whose landmarks do not have a face's proportions must be a face the fit explains well
    implausible = not plausible and explained < NO_FACE_EXPLAINED
    return (eyes == "none" and explained < NO_FACE_EXPLAINED) or (unexplained and not confirmed) or implausible


def _cut(doubts: tuple[str, ...]) -> tuple[bool, tuple[str, ...]]:
    """Whether a face is cut by the frame (``placement.CUT_BY_FRAME``), and its other doubts."""
    others = tuple(d for d in doubts if not d.startswith(CUT_BY_FRAME))
    return len(others) < len(doubts), others
