"""Where each face of a photo sits on the model grid, and what its placement leaves in doubt.

``place_faces`` is the policy: eyes given (a sidecar's, or ``--eyes``) place one face by the
similarity that puts the model's eyes on them; otherwise every face the detector and face mesh
find (``photo.faces.find_faces``) is placed by its landmarks (``photo.faces.place_on_grid``);
with finding switched off the photo is taken as a frontal crop framed like the model grid.
A placement's ``doubts`` are what the landmarks themselves say is wrong with the face (cut by the
frame, turned too far for a frontal model, a mesh that does not fit a face); the fit's quality
check adds them to its flags.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from ..geometry.raster import polygon_mask
from ..model.shape_model import ShapeModel
from .align import Alignment, centred_alignment, eyes_alignment, inside_input, stretch_vertically, to_model_grid
from .faces import FoundFace, Pose, find_faces, head_pose, place_on_grid
from .mediapipe import OUTER_CORNERS

NOSE_TIP = 1  # the face mesh's vertex at the tip of the nose
MOUTH_CORNERS = (61, 291)

# the frontal model's reach in yaw: turned further, a face fitted with it (a model without turned views, a
# model file) is doubtful (docs/accuracy.md, "Pose")
MAX_FRONTAL_YAW = 15.0
# turned further than this, a face is refused: the far half of the face is hidden (docs/accuracy.md, "Turned heads")
MAX_YAW = 50.0
# the frontal model's reach in pitch (a model without pitched views), and the pitched views': tilted further, a face
# is doubtful (docs/accuracy.md, "Turned heads": renders read at 39-42 deg fitted within 12-14 deg, at 48 deg 19-20)
MAX_FRONTAL_PITCH = 20.0
MAX_PITCH = 45.0
# the landmarks' placement fit leaves at most this much (root-mean-square, in eye distances) on a face: real
# faces well under it, concentric rings (which both nets take for a face) over it (docs/tuning.md)
MAX_PLACEMENT_RMS = 0.12
# eyes closer than this share of the model grid's (36 px on the default 128^2 grid) leave the fit too few pixels:
# the photo is then enlarged more than twice onto the grid
MIN_FIT_IOD_SHARE = 0.45
# a face's eyes, brows and lips may run past the frame by this share of their outline points: a tight crop
# cuts the brows' ends
MAX_CUT = 0.1
CUT_BY_FRAME = "the face is cut by the frame"  # its doubt begins so: a face all the same (``method.quality``)
# a face-like thing the face mesh doubts is refused, left as the photo has it (docs/accuracy.md, "Turned heads"): real
# faces (79 of the people set's, 317 of 319 Yale B photos) and the turned renders are meshed with a presence of 0.987
# or more, their noses 0.35-0.54 of the eyes' width out of the face (``_nose_out``; renders turned 50 deg or tilted 50
# deg among them), and their skin's red share at most 0.019 under
# its green's or blue's (a bluish indoor frame; grey in a grey or faded photo; a painted face's 0.05-0.11). Two Yale B exposures striped by interference read 0.57 (the detector 0.72) and
# 0.90 (the detector missed it): a mesh this unsure of a face the detector is not sure of either is refused
DOUBTED_PRESENCE = 0.75
DOUBTED_DETECTION = 0.5
TURN_DOUBT = "the head is "  # how the doubts of a head's turn and tilt begin (``pose_doubts``)
FLAT_NOSE = 0.15
SKIN_REDDER = -0.035  # a face's red share of its inner skin's chromaticity less its green's or blue's, at least


@dataclass(frozen=True)
class FacePlacement:
    """One face of a photo. alignment: model pixel -> photo pixel; found: "detected" (by the detector
    and the face mesh), "mesh only" (the face mesh, in the photo taken as one face's crop), "given"
    (its eyes) or "centre asked"; eyes: (2, 2) photo pixels ``[[x, y], [x, y]]``,
    image-left first; box: (4,) ``x0, y0, x1, y1`` photo pixels; pose: the head's rotation (found
    faces); outlines: the parts' outlines in photo pixels (``FoundFace.outlines``; found faces; a turned
    face's ``oval`` is its mesh's whole outline, ``FoundFace.silhouette``, and ``fit`` the oval its fit
    trusts); doubts: one phrase per problem the placement sees; stretch: the face's length against the model's;
    presence: the face mesh's score; plausible: whether the landmarks have a face's proportions; face: the
    found face (its landmarks) it was placed by; view: the (yaw, pitch) of the model it is placed for (the
    model's heads turned so, ``model.default_model.turned_model``); refused: why it is not fitted at all
    (turned too far), else empty."""

    alignment: Alignment
    found: str
    eyes: np.ndarray
    box: np.ndarray
    pose: Pose | None = None
    outlines: dict[str, list[np.ndarray]] | None = None
    doubts: tuple[str, ...] = ()
    stretch: float = 1.0
    presence: float | None = None
    plausible: bool = True
    face: FoundFace | None = None
    view: tuple[float, float] = (0.0, 0.0)
    refused: str = ""

    def record(self) -> dict:
        """What ``summary.json`` says of the face: box, eyes and pose (rounded, photo pixels, degrees)."""
        rec = {"box": [round(float(v), 1) for v in self.box], "eyes": np.round(self.eyes, 1).tolist(),
               "found": self.found, "pose": None if self.pose is None else self.pose.record()}
        if self.presence is not None:
            rec["presence"] = round(self.presence, 3)
        if self.view != (0.0, 0.0):
            rec["model_view"] = {"yaw": self.view[0], "pitch": self.view[1]}
        return rec

    def grid_outline(self, name: str = "oval") -> list[np.ndarray]:
        """The outlines of ``name`` on the model grid ``(col, row)`` (empty without landmarks)."""
        if self.outlines is None:
            return []
        inv = cv2.invertAffineTransform(self.alignment.matrix)
        return [np.asarray(o, np.float64) @ inv[:, :2].T + inv[:, 2] for o in self.outlines.get(name, [])]


def small_face(iod: float, model: ShapeModel) -> list[str]:
    """The doubt of a face whose eyes are ``iod`` photo pixels apart, if that is under
    ``MIN_FIT_IOD_SHARE`` of the model grid's."""
    least = MIN_FIT_IOD_SHARE * float(np.linalg.norm(model.eyes[1] - model.eyes[0]))
    if iod >= least:
        return []
    # whole pixels that never read as enough: 15.6 against 16.0 said "16 px apart; the fit wants 16"
    return [f"the face is small (eyes {math.floor(iod)} px apart; the fit wants at least {math.ceil(least)})"]


def model_box(model: ShapeModel, al: Alignment, shape: tuple[int, int]) -> np.ndarray:
    """(4,) ``x0, y0, x1, y1``: the pixels of a photo (H, W) the model's face covers under ``al``."""
    rows, cols = np.nonzero(model.mask)
    corners = np.array([[cols.min(), rows.min()], [cols.max(), rows.min()], [cols.min(), rows.max()],
                        [cols.max(), rows.max()]], np.float64)
    p = al.points_to_input(corners)
    h, w = shape
    return np.clip(np.concatenate([p.min(axis=0), p.max(axis=0)]), 0.0, [w - 1, h - 1, w - 1, h - 1])


def place_given_eyes(model: ShapeModel, eyes: np.ndarray, how: str, face_length: str | float,
                     shape: tuple[int, int]) -> FacePlacement:
    """One face placed by its eyes (2, 2) photo pixels: the similarity that puts the model's eyes
    on them, stretched by ``face_length`` when it is a number. Eyes given right-eye first are taken
    in image order (the model's image-left eye goes on the image-left one)."""
    eyes = np.asarray(eyes, np.float64)
    if eyes[0, 0] > eyes[1, 0]:
        eyes = eyes[::-1]
    al = eyes_alignment(eyes, model.eyes, how)
    if isinstance(face_length, (int, float)) and not isinstance(face_length, bool):
        eye_row = float(np.mean(model.eyes[:, 1]))
        al = stretch_vertically(al, float(face_length), eye_row, f"{al.how}; face length x{float(face_length):.3f} (given)")
    iod = float(np.linalg.norm(eyes[1] - eyes[0]))
    return FacePlacement(al, "given", eyes, model_box(model, al, shape), doubts=tuple(small_face(iod, model)))


def pose_doubts(pose: Pose, frontal: bool) -> tuple[str, list[str]]:
    """Why a face at ``pose`` is refused ("" when it is not) and what leaves it in doubt, fitted with a ``frontal``
    model or with one turned to its view: turned past ``MAX_YAW``, refused; past ``MAX_FRONTAL_YAW`` with a frontal
    model, doubtful; tilted past ``MAX_PITCH`` (``MAX_FRONTAL_PITCH`` with a frontal model), doubtful."""
    yaw, pitch = pose.view
    refused, doubts = "", []
    if abs(yaw) > MAX_YAW:
        said = f"{yaw:+.0f}" if round(abs(yaw)) > MAX_YAW else f"{yaw:+.1f}"  # not "+50" past a reach of 50
        refused = f"the head is turned {said} deg (yaw); faces turned up to {MAX_YAW:.0f} deg are fitted"
    elif frontal and abs(yaw) > MAX_FRONTAL_YAW:
        doubts.append(f"the head is turned {yaw:+.0f} deg (yaw); the frontal model fits up to "
                      f"{MAX_FRONTAL_YAW:.0f} deg")
    if abs(pitch) > MAX_PITCH:
        doubts.append(f"the head is tilted {pitch:+.0f} deg (pitch); faces tilted up to {MAX_PITCH:.0f} deg are fitted")
    elif frontal and abs(pitch) > MAX_FRONTAL_PITCH:
        doubts.append(f"the head is tilted {pitch:+.0f} deg (pitch); the frontal model fits up to "
                      f"{MAX_FRONTAL_PITCH:.0f} deg")
    return refused, doubts


def not_a_face(face: FoundFace, rgb: np.ndarray | None = None) -> str:
    """Why the face mesh doubts ``face`` is a face ("" when it does not): its presence under ``DOUBTED_PRESENCE``
    where the detector scored it under ``DOUBTED_DETECTION`` (or did not find it), a flat mesh (its nose under
    ``FLAT_NOSE`` of the eyes' width out of the face, ``_nose_out``), or, in a colour photo
    ``rgb`` (H, W, 3) uint8, no skin's colour inside its outline (``SKIN_REDDER``): a painted or printed face."""
    if face.presence < DOUBTED_PRESENCE and face.score < DOUBTED_DETECTION:
        return f"not a face: the face mesh doubts it (presence {face.presence:.2f})"
    nose = _nose_out(face.mesh)
    if nose < FLAT_NOSE:
        return f"not a face: the face mesh finds it flat (its nose {nose:.2f} of the eyes' width out)"
    redder = _redder(face, rgb)
    if redder < SKIN_REDDER:
        return f"not a face: no skin's colour on it (red {100 * redder:+.0f} % of green or blue)"
    return ""


def _nose_out(mesh: np.ndarray) -> float:
    """How far the mesh's (468, 3) nose tip stands out of the plane through its outer eye corners and its mouth
    corners' midpoint, over the outer eye corners' distance (3-D: the same whichever way the head is turned)."""
    a, b = mesh[OUTER_CORNERS[0]], mesh[OUTER_CORNERS[1]]
    normal = np.cross(b - a, mesh[list(MOUTH_CORNERS)].mean(axis=0) - a)
    normal /= max(float(np.linalg.norm(normal)), 1e-12)
    return float(abs((mesh[NOSE_TIP] - a) @ normal) / max(float(np.linalg.norm(b - a)), 1e-12))


def _redder(face: FoundFace, rgb: np.ndarray | None) -> float:
    """The red share of the chromaticity of ``face``'s inner skin (its outline shrunk by 0.15 eye distances, its
    eyes, brows and lips left out) less the larger of green's and blue's (0 for a grey photo or too few pixels)."""
    if rgb is None or rgb.ndim != 3:
        return 0.0
    h, w = rgb.shape[:2]
    x0, y0, x1, y1 = np.clip(np.concatenate([face.oval.min(axis=0), face.oval.max(axis=0)]).astype(int),
                             0, [w - 1, h - 1, w - 1, h - 1])
    inner = np.zeros((y1 - y0 + 1, x1 - x0 + 1), np.uint8)
    cv2.fillPoly(inner, [np.round(face.oval - [x0, y0]).astype(np.int32)], 1)
    for part in face.outlines()["eyes"] + face.outlines()["brows"] + face.outlines()["lips"]:
        cv2.fillPoly(inner, [np.round(part - [x0, y0]).astype(np.int32)], 0)
    k = max(1, int(0.15 * face.iod))
    inner = cv2.erode(inner, np.ones((k, k), np.uint8)) > 0
    if inner.sum() < 50:
        return 0.0
    px = rgb[y0:y1 + 1, x0:x1 + 1][inner].astype(np.float64) + 1.0
    share = np.median(px / px.sum(axis=1, keepdims=True), axis=0)
    return float(share[0] - max(share[1], share[2]))


def place_found(model: ShapeModel, face: FoundFace, shape: tuple[int, int], face_length: str | float,
                doubted: str = "") -> FacePlacement:
    """A face found by the face mesh, placed by its landmarks (``faces.place_on_grid``) on ``model``'s
    grid, seen at the model's ``view``; with ``face_length`` "off" the stretch is 1, with a number it is
    that. Turned or tilted too far (``pose_doubts``), it is refused or doubtful; ``doubted``: why it is not a
    face (``not_a_face``), refused for that first."""
    mouth = model.mouth if face_length == "auto" else None
    matrix, stretch, rms = place_on_grid(face, model.grid, model.eyes, mouth, model.view)
    how = f"landmarks; face length x{stretch:.3f}"
    al = Alignment(matrix, how)
    if isinstance(face_length, (int, float)) and not isinstance(face_length, bool):
        eye_row = float(np.mean(model.eyes[:, 1]))
        al = stretch_vertically(al, float(face_length), eye_row, f"landmarks; face length x{float(face_length):.3f} (given)")
        stretch = float(face_length)
    pose = head_pose(face)
    doubts = []
    core = np.vstack([o for name in ("eyes", "brows", "lips") for o in face.outlines()[name]])
    h, w = shape
    cut = np.mean((core[:, 0] < 0) | (core[:, 0] > w - 1) | (core[:, 1] < 0) | (core[:, 1] > h - 1))
    if cut > MAX_CUT:
        doubts.append(f"{CUT_BY_FRAME} ({100 * cut:.0f} % of its eyes, brows and lips outside)")
    refused, turned = pose_doubts(pose, model.view == (0.0, 0.0))
    doubts += turned
    if rms > MAX_PLACEMENT_RMS:
        doubts.append(f"the landmarks do not fit a face's proportions (off by {rms:.2f} of the eye distance)")
    doubts += small_face(face.iod, model)

    found = "detected" if face.detected else "mesh only"
    outlines = face.outlines()
    if model.view != (0.0, 0.0):
        # turned: the oval's far-cheek vertices lie behind the cheek, inside the face's outline (its mesh's hull);
        # the fit trusts the oval (the steep strip beyond it is fitted worse and holds background), the face's
        # products cover the whole outline, the model's normals where the fit did not look
        outlines["fit"], outlines["oval"] = outlines["oval"], [face.silhouette]
    o = outlines["oval"][0]
    box = np.clip(np.concatenate([o.min(axis=0), o.max(axis=0)]), 0.0, [w - 1, h - 1, w - 1, h - 1])
    return FacePlacement(al, found, face.eyes, box, pose, outlines, tuple(doubts), stretch, face.presence,
                         rms <= MAX_PLACEMENT_RMS, face, model.view, doubted or refused)


def place_faces(model: ShapeModel, photo_rgb: np.ndarray, eyes: np.ndarray | None = None, eyes_how: str = "given eyes",
                find: bool = True, face_length: str | float = "auto",
                finder: Callable[[np.ndarray], list[FoundFace]] = find_faces) -> list[FacePlacement]:
    """Every face of a photo (``photo_rgb`` (H, W, 3) uint8 RGB), largest first (module docstring):
    one from ``eyes`` when given; else those ``finder`` finds (none: an empty list) when ``find``; else the
    centred crop."""
    shape = photo_rgb.shape[:2]
    if eyes is not None:
        return [place_given_eyes(model, eyes, eyes_how, face_length, shape)]
    if not find:
        al = centred_alignment(shape, model.grid)
        al = Alignment(al.matrix, "centred crop (asked)")
        return [FacePlacement(al, "centre asked", al.points_to_input(model.eyes), model_box(model, al, shape))]
    return [place_found(model, f, shape, face_length, not_a_face(f, photo_rgb)) for f in finder(photo_rgb)]


def outline_mask(placement: FacePlacement, grid: tuple[int, int], name: str = "oval") -> np.ndarray | None:
    """(Hm, Wm) bool: the model pixels inside the face's outline ``name`` (``oval``: the face's own; ``fit``: what
    its fit trusts, when that is narrower, else the oval); None when the face mesh drew none."""
    outline = placement.grid_outline(name) or placement.grid_outline("oval")
    return polygon_mask(outline[0], grid) if outline else None


def outline_on_grid(placement: FacePlacement, model: ShapeModel, shape: tuple[int, int], name: str = "oval") -> np.ndarray:
    """(Hm, Wm) bool: the model pixels inside a photo of ``shape`` (H, W) and inside the face's outline
    ``name`` (``outline_mask``) when the face mesh drew one."""
    seen = inside_input(placement.alignment, shape, model.grid)
    outline = outline_mask(placement, model.grid, name)
    return seen if outline is None else seen & outline


def features_on_grid(placement: FacePlacement, grid: tuple[int, int],
                     names: tuple[str, ...] = ("eyes", "brows", "lips")) -> np.ndarray | None:
    """(Hm, Wm) bool: the face's ``names`` (its eyes, brows and lips) on the model grid, from its landmarks (None
    without)."""
    parts = [o for name in names for o in placement.grid_outline(name)]
    if not parts:
        return None
    return np.logical_or.reduce([polygon_mask(o, grid) for o in parts])


def face_on_grid(image: np.ndarray, placement: FacePlacement, model: ShapeModel) -> tuple[np.ndarray, np.ndarray]:
    """A placed face as the fit sees it: (Hm, Wm) the photo ``image`` (H, W) resampled to the model grid,
    and (Hm, Wm) bool the model pixels the photo shows, inside the photo and inside the outline the fit
    trusts when the face mesh drew one (beyond it, hair, background or a collar are not the face)."""
    return to_model_grid(image, placement.alignment, model.grid), outline_on_grid(placement, model, image.shape, "fit")
