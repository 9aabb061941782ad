"""Faces in a photo: found by MediaPipe's detector and face mesh (``photo.mediapipe``), each with its
eyes, box, pose and the outlines of its parts, and placed on the model grid by its landmarks.

Vertex numbers are MediaPipe's canonical face mesh (468 vertices; the lists are public in MediaPipe's
``face_mesh_connections``). "Left" and "right" below are the IMAGE's, as everywhere in shadowflow.

Placement (``place_on_grid``): the model grid's landmarks are ICT-FaceKit's neutral face at its
Multi-PIE 68-point landmarks (``LANDMARK_PAIRS``: eye corners, nose, mouth corners, inner lips),
placed on the grid as every training face is (iris centres on the canonical eye pixels); the
photo's are the mesh's same points. The map from grid to photo is a similarity times a stretch
along the face's vertical axis (the face's length against the model's), fitted by weighted least
squares: the eyes, nose and mouth count alike whatever their number of points.

Pose (``head_pose``): the rotation of the best rigid fit (with scale) of the same ICT points in 3-D
to the mesh's 3-D points, as yaw, pitch and roll in degrees (``Pose``).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from .encoding import decode_samples
from .mediapipe import Roi, detect_faces, face_mesh, mesh_mirror, roi_from_detection, roi_from_mesh

# outlines, in order around each part
EYES = ((33, 7, 163, 144, 145, 153, 154, 155, 133, 173, 157, 158, 159, 160, 161, 246),
        (263, 249, 390, 373, 374, 380, 381, 382, 362, 398, 384, 385, 386, 387, 388, 466))
BROWS = ((70, 63, 105, 66, 107, 55, 65, 52, 53, 46), (300, 293, 334, 296, 336, 285, 295, 282, 283, 276))
LIPS = (61, 146, 91, 181, 84, 17, 314, 405, 321, 375, 291, 409, 270, 269, 267, 0, 37, 39, 40, 185)
MOUTH = (78, 95, 88, 178, 87, 14, 317, 402, 318, 324, 308, 415, 310, 311, 312, 13, 82, 81, 80, 191)  # inner lips
# the image-left nostril's opening (the other's is its mirror: ``mediapipe.mesh_mirror``)
NOSTRIL = (166, 79, 239, 238, 20, 60, 99, 240, 75)
OVAL = (10, 338, 297, 332, 284, 251, 389, 356, 454, 323, 361, 288, 397, 365, 379, 378, 400, 377, 152, 148, 176,
        149, 150, 136, 172, 58, 132, 93, 234, 127, 162, 21, 54, 103, 67, 109)

# mesh vertex -> Multi-PIE 68-point landmark (0-based), grouped by feature: the points placement fits
LANDMARK_PAIRS = {
    "eyes": ((33, 36), (133, 39), (362, 42), (263, 45)),  # outer and inner corners
    # the nasion and the point below the tip: the tip itself stands out of the face and moves in the
    # photo with the head's pitch (8 px on a 42 px eye distance, astronaut)
    "nose": ((168, 27), (2, 33)),
    "mouth": ((0, 51), (13, 62), (14, 66), (61, 48), (291, 54)),  # upper lip's top, inner lips, corners
}
# the stretch along the face's axis is kept within about 2.5 standard deviations of real faces
# (ICT-FaceKit identities' eye-to-mouth distances vary by 6 %)
STRETCH_LIMITS = (0.85, 1.15)

MIN_PRESENCE = 0.5  # the face mesh's own threshold (MediaPipe's graph uses 0.5)
# the photo as it stands, upside down, then on either side (``np.rot90``'s quarter turns); a face is found in the
# turn that shows it within MAX_ROLL of upright (a face on its side, meshed as it stands, comes out skewed)
QUARTER_TURNS = (0, 2, 1, 3)
MAX_ROLL = 45.0
# a photo whose faces the detector found upright, none with at least this score, is looked at upside down too: a
# Yale B face upside down was found upright at 0.53, its nostrils for eyes, and at 0.73 turned; every upright face
# of the held-out photos and Yale B found under it (65 photos) scored lower turned, or was not found (docs/accuracy.md)
SURE_DETECTION = 0.75
# a photo that shows no upright face is looked at turned at most this many pixels on its long side: whole
# views (the detector's 128 px) and the photo as one face's crop (the mesh's 192 px) need no more
TURNED_SIDE = 640
MIN_IOD = 30.0  # pixels between the eyes: the smallest face the detector is made to look for
SMALLEST_IOD = 12.0  # found faces smaller than this are left alone: too few pixels to fit
# the tracking crop is followed at most this many times, until it moves less than SETTLED of its side
TRACKING_PASSES = 3
SETTLED = 0.05
# the photo as one face's crop when the detector finds none: the face mesh's crop this many times the photo's
# long side (a tight crop under a side light: one size or the other finds the face, docs/tuning.md)
TIGHT_CROPS = (1.15, 1.5)
# a face the detector is not sure of (under SURE_DETECTION, or found by the mesh alone) must show a feature: one of its
# eyes or its mouth darker than the skin around it (``feature_darkness``) by at least this share of the light there.
# A featureless shaded ball meshed as a face (presence up to 0.81, in 7 of 108 framings) shows none: its shading is
# concave, every point brighter than its surround, -0.08 to -0.02; faces the detector was unsure of (98 of Yale B's,
# the held-out photos' and the project's renders, in deep shadow too) 0.18 and more (docs/tuning.md)
MIN_FEATURE_DARKNESS = 0.05


@dataclass(frozen=True)
class Pose:
    """Head rotation in degrees, camera frame (x right, y up, z toward the viewer), as the head's own:
    yaw > 0 the face turned toward the image's right, pitch > 0 the face tilted up, then roll > 0 the
    whole head turned counter-clockwise as seen in the photo (``R = Rz(roll) Ry(yaw) Rx(-pitch)``). So a
    photo's turn in its own plane (a photo on its side, upside down) moves the roll alone: a head looking
    down is ``pitch < 0`` whichever way up the photo is (camera-axis angles, ``Ry Rx Rz``, read a head
    looking down in a photo upside down as looking up). ``view``, (yaw, pitch), is how the model grid sees
    the head once its placement has taken the roll off."""

    yaw: float
    pitch: float
    roll: float

    @property
    def view(self) -> tuple[float, float]:
        """(yaw, pitch) degrees of the head with the photo's own roll taken off."""
        return (self.yaw, self.pitch)

    def record(self) -> dict[str, float]:
        return {"yaw": round(self.yaw, 1), "pitch": round(self.pitch, 1), "roll": round(self.roll, 1)}


@dataclass(frozen=True)
class FoundFace:
    """One face of a photo. mesh: (468, 3) x, y photo pixels (y down), z the same pixels toward the
    camera; presence: the mesh's face-presence score in [0, 1]; score: the detector's (0: the face
    mesh found it in the photo taken as one face's crop)."""

    mesh: np.ndarray
    presence: float
    score: float

    @property
    def detected(self) -> bool:
        """Whether the detector saw it (else only the face mesh did, in the photo taken as its crop)."""
        return self.score > 0.0

    @property
    def eyes(self) -> np.ndarray:
        """(2, 2) eye centres ``[[x, y], [x, y]]``, image-left first: the mean of each eye's outline."""
        return np.array([self.mesh[list(e), :2].mean(axis=0) for e in EYES])

    @property
    def roll(self) -> float:
        """Degrees the face is turned in the photo, counter-clockwise as seen: its eyes' line from the
        image-left eye to the image-right one (as the face stands upright) against the x axis."""
        e = self.eyes
        return float(np.degrees(np.arctan2(-(e[1, 1] - e[0, 1]), e[1, 0] - e[0, 0])))

    @property
    def iod(self) -> float:
        """Pixels between the eye centres."""
        e = self.eyes
        return float(np.linalg.norm(e[1] - e[0]))

    @property
    def oval(self) -> np.ndarray:
        """(36, 2) the face's outline, photo pixels, in order."""
        return self.mesh[list(OVAL), :2]

    @property
    def silhouette(self) -> np.ndarray:
        """(n, 2) the outline of the whole mesh as the photo shows it (its convex hull), photo pixels, in
        order: a turned face's outline, whose far cheek reaches past the oval's vertices (they lie behind
        it); the oval itself on a frontal face."""
        return cv2.convexHull(self.mesh[:, :2].astype(np.float32))[:, 0].astype(np.float64)

    @property
    def box(self) -> np.ndarray:
        """(4,) ``x0, y0, x1, y1``: the outline's extent."""
        o = self.oval
        return np.concatenate([o.min(axis=0), o.max(axis=0)])

    def outlines(self) -> dict[str, list[np.ndarray]]:
        """The parts' outlines, each (n, 2) photo pixels in order: ``eyes`` (two), ``brows`` (two),
        ``lips`` (the outer edge), ``mouth`` (the inner edge: teeth and the mouth's inside), ``nostrils`` (two),
        ``oval``."""
        p = self.mesh[:, :2]
        nostril = list(NOSTRIL)
        return {"eyes": [p[list(e)] for e in EYES], "brows": [p[list(b)] for b in BROWS], "lips": [p[list(LIPS)]],
                "mouth": [p[list(MOUTH)]], "nostrils": [p[nostril], p[mesh_mirror()[nostril]]],
                "oval": [p[list(OVAL)]]}


def find_faces(rgb: np.ndarray, min_iod: float = MIN_IOD) -> list[FoundFace]:
    """Every face in ``rgb`` (H, W, 3) uint8 RGB that the face mesh confirms, largest first.

    The faces of the photo as it stands (``upright_faces``, within ``MAX_ROLL`` of upright); when it
    shows none, of the photo turned a half, a quarter and three quarters (a photo saved upside down or
    on its side), the first turn whose faces the detector is sure of (``SURE_DETECTION``), else the turn
    it is surest of, mapped back: such a face is placed turned, its eyes listed as they are when the face
    is upright (image-left first then). When the detector is sure of none of the upright faces, the
    photo turned a half is looked at too, and its faces kept instead when the detector is surer of one
    of them (a face upside down meshes as one the right way up, its nostrils for eyes). Faces are
    upright in nearly every photo, and trying every turn of every candidate finds faces in a sleeve or
    a badge (a jacket's folds turned over)."""
    faces = upright_faces(rgb, min_iod)
    best = max((f.score for f in faces), default=-1.0)
    if best >= SURE_DETECTION:
        return faces
    # turned, the photo is seen whole only (a photo saved the wrong way up is mostly a portrait), so a smaller
    # copy shows the nets what the whole photo would, and is turned and looked at for a fraction of the cost;
    # faces found upright but none surely are looked at upside down too, and turned if the detector is surer so
    small, k = _for_turns(rgb)
    for quarter in QUARTER_TURNS[1:] if not faces else QUARTER_TURNS[1:2]:
        turned = upright_faces(np.ascontiguousarray(np.rot90(small, quarter)), float("inf"))
        score = max((f.score for f in turned), default=-1.0)
        if score > best:
            faces, best = [_scaled(_turned_back(f, quarter, small.shape[:2]), k) for f in turned], score
            if best >= SURE_DETECTION:
                break
    return faces


def _for_turns(rgb: np.ndarray) -> tuple[np.ndarray, float]:
    """``rgb`` area-averaged to at most ``TURNED_SIDE`` pixels on its long side, and the photo's pixels per
    pixel of it (1: small enough as it is)."""
    k = max(rgb.shape[:2]) / TURNED_SIDE
    if k <= 1.0:
        return rgb, 1.0
    h, w = rgb.shape[:2]
    size = (max(1, round(w / k)), max(1, round(h / k)))
    return cv2.resize(rgb, size, interpolation=cv2.INTER_AREA), w / size[0]


def _scaled(face: FoundFace, k: float) -> FoundFace:
    """A face found in a copy of the photo ``k`` times smaller, in the photo's pixels (pixel centres kept)."""
    if k == 1.0:
        return face
    x, y, z = face.mesh.T
    return FoundFace(np.column_stack([(x + 0.5) * k - 0.5, (y + 0.5) * k - 0.5, z * k]), face.presence, face.score)


def _turned_back(face: FoundFace, quarter: int, shape: tuple[int, int]) -> FoundFace:
    """A face found in the photo turned by ``np.rot90(photo, quarter)``, in the photo (H, W) as it is."""
    h, w = shape
    x, y, z = face.mesh.T
    if quarter == 1:  # rot90 once: (x, y) went to (y, w - 1 - x)
        x, y = w - 1 - y, x
    elif quarter == 2:
        x, y = w - 1 - x, h - 1 - y
    elif quarter == 3:  # (x, y) went to (h - 1 - y, x)
        x, y = y, h - 1 - x
    return FoundFace(np.column_stack([x, y, z]), face.presence, face.score)


def upright_faces(rgb: np.ndarray, min_iod: float = MIN_IOD) -> list[FoundFace]:
    """The faces of ``rgb`` as it stands. Each detection's crop is given to the face mesh, and again the
    crop its mesh implies (MediaPipe's tracking crop, which is better centred and turned); a face is
    kept when both reach ``MIN_PRESENCE`` and its eyes are at least ``SMALLEST_IOD`` apart. When the
    detector finds nothing, the photo is tried as a tight crop of one face (Yale B's crops, a face
    filling the frame in deep shadow). A mesh of a part of a found face (its eyes inside the face's
    outline) is not a face."""
    faces: list[FoundFace] = []
    featured = _Features(rgb)
    for d in detect_faces(rgb, min_iod):  # largest first: a part of a found face is not looked at again
        centre = (float(d.box[0] + d.box[2]) / 2.0, float(d.box[1] + d.box[3]) / 2.0)
        if any(cv2.pointPolygonTest(f.oval.astype(np.float32), centre, False) >= 0 for f in faces):
            continue
        _add(faces, featured(confirmed_face(rgb, roi_from_detection(d), d.score)))
    if not faces:  # a tight crop, or a face the detector missed in the dark: the photo as its crop (score 0)
        h, w = rgb.shape[:2]
        for side in TIGHT_CROPS:
            middle = Roi(np.array([(w - 1) / 2.0, (h - 1) / 2.0]), side * max(h, w), 0.0)
            _add(faces, featured(confirmed_face(rgb, middle, 0.0)))
            if faces:
                break
    faces = [f for f in faces if abs(f.roll) <= MAX_ROLL]  # others: the turn of the photo that shows them upright
    faces.sort(key=lambda f: -f.iod)
    return [f for k, f in enumerate(faces) if not any(part_of(f, g) for g in faces[:k])]


def feature_darkness(linear: np.ndarray, face: FoundFace) -> float:
    """How much darker than the skin around it a face's darkest feature is: the most, over its two eyes and its mouth,
    of the photo blurred at 0.2 of the eye distance less the photo blurred at 0.05 (a dark blob's centre is darker
    than its surround; pixel noise and slow shading left out), within a tenth of the eye distance of the landmark, as
    a share of the light there; ``linear``: the photo's grey in linear light. An eye or a mouth, lit or in shadow,
    is darker than its surround; a convex, evenly coloured surface under one light nowhere is."""
    iod = face.iod
    centres = np.vstack([face.eyes, np.vstack(face.outlines()["lips"]).mean(axis=0)])
    lo = np.floor(np.maximum(centres.min(axis=0) - iod, 0)).astype(int)
    hi = np.ceil(np.minimum(centres.max(axis=0) + iod + 1, linear.shape[::-1])).astype(int)
    if np.any(hi - lo < 3):
        return 0.0
    crop = linear[lo[1]:hi[1], lo[0]:hi[0]]
    darker = cv2.GaussianBlur(crop, (0, 0), max(0.2 * iod, 2.0)) - cv2.GaussianBlur(crop, (0, 0), max(0.05 * iod, 0.8))
    light = cv2.GaussianBlur(crop, (0, 0), 0.5 * iod)
    rows, cols = np.mgrid[lo[1]:hi[1], lo[0]:hi[0]]
    best = -np.inf
    for x, y in centres:
        near = (cols - x) ** 2 + (rows - y) ** 2 <= max(0.1 * iod, 1.0) ** 2
        if near.any():
            best = max(best, float(darker[near].max() / (light[near].mean() + 0.02)))
    return best if np.isfinite(best) else 0.0


class _Features:
    """``featured(face)``: ``face`` (or None), unless the detector is unsure of it (under ``SURE_DETECTION``) and it
    shows no feature (``feature_darkness`` under ``MIN_FEATURE_DARKNESS``): a featureless shaded ball, meshed as a
    face in some framings, is not one. The photo's grey in linear light is made once, when first asked."""

    def __init__(self, rgb: np.ndarray):
        self.rgb, self.linear = rgb, None

    def __call__(self, face: FoundFace | None) -> FoundFace | None:
        if face is None or face.score >= SURE_DETECTION:
            return face
        if self.linear is None:  # the nets' photo is as a camera encodes it (sRGB)
            self.linear = decode_samples(cv2.cvtColor(self.rgb, cv2.COLOR_RGB2GRAY), 255.0)
        return face if feature_darkness(self.linear, face) >= MIN_FEATURE_DARKNESS else None


def part_of(face: FoundFace, larger: FoundFace) -> bool:
    """Whether ``face`` is a part of ``larger`` that the mesh took for a face of its own: both its eyes within
    ``larger``'s outline (an eye and a brow, a nostril), or, when the detector was unsure of it (under
    ``SURE_DETECTION``), its mouth there: a face meshed over a found face's forehead, its brows taken for a mouth and
    the hair for eyes (a webcam clip's forehead, detected at 0.38, came back relit as a patch over the real face)."""
    oval = larger.oval.astype(np.float32)

    def within(x, y) -> bool:
        return cv2.pointPolygonTest(oval, (float(x), float(y)), False) >= 0

    if all(within(x, y) for x, y in face.eyes):
        return True
    return face.score < SURE_DETECTION and within(*np.vstack(face.outlines()["lips"]).mean(axis=0))


def confirmed_face(rgb: np.ndarray, roi: Roi, score: float) -> FoundFace | None:
    """The face mesh in ``roi``, then in the crop its mesh implies, until that crop stays put, its points
    the mean of the mesh's looks at that crop and at its mirror image (``face_mesh``'s ``mirrored``);
    None when the first look or the first crop its mesh implies does not reach ``MIN_PRESENCE`` (parts
    of a face, a pattern, pass the first but not the second), when the mesh is surer of the crop turned
    upside down, or the eyes are under ``SMALLEST_IOD`` apart."""
    mesh, presence = face_mesh(rgb, roi)
    if presence < MIN_PRESENCE:
        return None
    # the crop the mesh implies is better centred, sized and turned than the detector's (whose box a face
    # cut by the frame or in deep shadow can shrink to half of it): follow it until it stays put
    meshed, crop = roi, roi_from_mesh(mesh)
    for k in range(TRACKING_PASSES):
        tracked, again = face_mesh(rgb, crop)
        if again < MIN_PRESENCE:
            if k == 0:  # the crop its own mesh implies does not show a face: a face too small in the detector's
                return None  # box, meshed with its features in the background (a face without hair or neck)
            break
        mesh, presence, meshed = tracked, again, crop
        crop = roi_from_mesh(mesh)
        moved = np.linalg.norm(crop.centre - meshed.centre) + abs(crop.side - meshed.side)
        if moved < SETTLED * meshed.side:
            break
    mesh = 0.5 * (mesh + face_mesh(rgb, meshed, mirrored=True)[0])  # the settled crop looked at both ways
    # a face upside down meshes as one the right way up, its nostrils for eyes: the mesh is surer of it turned
    if face_mesh(rgb, Roi(crop.centre, crop.side, crop.angle + np.pi))[1] > presence:
        return None  # (the photo's half turn finds it)
    face = FoundFace(mesh, presence, score)
    return face if face.iod >= SMALLEST_IOD else None


def _add(faces: list[FoundFace], face: FoundFace | None) -> None:
    """Append ``face`` unless it is None or one of ``faces`` already (eyes within half their distance)."""
    if face is not None and not any(np.linalg.norm(f.eyes - face.eyes, axis=1).max() < 0.5 * f.iod for f in faces):
        faces.append(face)


def head_pose(face: FoundFace) -> Pose:
    """The head's rotation (``Pose``) from the rigid fit of the model's 3-D landmarks to the mesh's."""
    mesh_idx, template = _pairs()
    src = _template_3d()[template]  # camera frame, the model's units
    dst = face.mesh[mesh_idx] * np.array([1.0, -1.0, 1.0])  # y up
    from scipy.spatial.transform import Rotation

    # R = Rz(roll) Ry(yaw) Rx(-pitch): turned about the head's vertical, tilted, then rolled in the photo's plane
    roll, yaw, minus_pitch = Rotation.from_matrix(_rotation(src, dst)).as_euler("ZYX", degrees=True)
    return Pose(float(yaw), float(-minus_pitch), float(roll))


def _rotation(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """(3, 3) the rotation of the least-squares similarity taking points ``src`` (n, 3) onto ``dst``
    (Umeyama / Kabsch, reflections excluded)."""
    a, b = src - src.mean(axis=0), dst - dst.mean(axis=0)
    u, _, vt = np.linalg.svd(b.T @ a)
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


@lru_cache(maxsize=1)
def _pairs() -> tuple[np.ndarray, np.ndarray]:
    """(mesh vertex numbers, Multi-PIE landmark numbers) of every pair, in ``LANDMARK_PAIRS`` order."""
    pairs = [p for group in LANDMARK_PAIRS.values() for p in group]
    return np.array([m for m, _ in pairs]), np.array([t for _, t in pairs])


@lru_cache(maxsize=1)
def _template_3d() -> np.ndarray:
    """(68, 3) ICT-FaceKit's neutral face at its 68 landmarks, centimetres, camera frame (x right,
    y up, z toward the viewer), in the frame where its iris centres are level."""
    from ..model.faces.ict import LANDMARKS, shipped_basis

    basis = shipped_basis()
    return basis.neutral[list(LANDMARKS)].astype(np.float64)


@lru_cache(maxsize=32)
def grid_landmarks(grid: tuple[int, int], mouth: tuple[float, float] | None,
                   view: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """(68, 2) the model grid's landmarks ``(col, row)``: ICT-FaceKit's neutral face placed as every
    training face is (``model.faces.ict.placed``: its heads turned by ``view``, (yaw, pitch) degrees), then
    stretched about the eye row so its lips' parting line falls on the model's ``mouth`` (when the model
    knows it)."""
    from ..model.faces.ict import STOMION, placed, shipped_basis

    basis = shipped_basis()
    verts = np.vstack([_template_3d(), basis.neutral[list(STOMION)].mean(axis=0, keepdims=True)])
    px = placed(verts, basis.eyes, grid, view)[:, :2]
    if mouth is not None:
        eye_row = float(np.mean(placed(basis.eyes, basis.eyes, grid, view)[:, 1]))
        k = (mouth[1] - eye_row) / (px[-1, 1] - eye_row)
        px[:, 1] = eye_row + k * (px[:, 1] - eye_row)
    return px[:-1]


def fit_placement(grid_points: np.ndarray, photo_points: np.ndarray, weights: np.ndarray, about_row: float,
                  limits: tuple[float, float] = STRETCH_LIMITS) -> tuple[np.ndarray, float, float]:
    """The map from model grid to photo that best takes ``grid_points`` (n, 2) ``(col, row)`` onto
    ``photo_points`` (n, 2) ``(x, y)``, each pair counted by ``weights`` (n,): a similarity after a
    stretch by ``k`` along the grid's rows about ``about_row``. Returns ``(matrix (2, 3), k, rms)``,
    rms the weighted root-mean-square distance left, photo pixels. ``k`` is searched within ``limits``."""
    from scipy.optimize import minimize_scalar

    g = np.asarray(grid_points, np.float64)
    p = np.asarray(photo_points, np.float64)
    w = np.asarray(weights, np.float64) / np.sum(weights)

    def solve(k: float) -> tuple[np.ndarray, float]:
        q = g.copy()
        q[:, 1] = about_row + k * (q[:, 1] - about_row)
        qc, pc = w @ q, w @ p  # weighted centroids; then the similarity's a, b in closed form
        dq, dp = q - qc, p - pc
        norm = float(w @ np.sum(dq**2, axis=1))
        a = float(w @ np.sum(dq * dp, axis=1)) / norm
        b = float(w @ (dq[:, 0] * dp[:, 1] - dq[:, 1] * dp[:, 0])) / norm
        lin = np.array([[a, -b], [b, a]])
        t = pc - lin @ qc
        stretch = np.array([[1.0, 0.0, 0.0], [0.0, k, about_row * (1.0 - k)], [0.0, 0.0, 1.0]])
        matrix = (np.vstack([np.column_stack([lin, t]), [0.0, 0.0, 1.0]]) @ stretch)[:2]
        residual = q @ lin.T + t - p
        return matrix, float(np.sqrt(w @ np.sum(residual**2, axis=1)))

    k = float(minimize_scalar(lambda k: solve(k)[1], bounds=limits, method="bounded",
                              options={"xatol": 1e-4}).x)
    matrix, rms = solve(k)
    return matrix, k, rms


def place_on_grid(face: FoundFace, grid: tuple[int, int], eyes: np.ndarray,
                  mouth: np.ndarray | None, view: tuple[float, float] = (0.0, 0.0)) -> tuple[np.ndarray, float, float]:
    """``fit_placement`` of the model grid's landmarks (``grid_landmarks``; grid (Hm, Wm), the model's
    ``eyes`` (2, 2), ``mouth`` (2,) or None and ``view``) to the face's mesh: ``(matrix (2, 3) model
    pixel -> photo pixel, stretch, rms / the face's eye distance)``. Each feature (eyes, nose, mouth)
    weighs the same; without a model mouth the stretch is 1."""
    mesh_idx, template = _pairs()
    grid_pts = grid_landmarks(tuple(grid), None if mouth is None else (float(mouth[0]), float(mouth[1])),
                              (float(view[0]), float(view[1])))[template]
    weights = np.concatenate([np.full(len(g), 1.0 / len(g)) for g in LANDMARK_PAIRS.values()])
    limits = STRETCH_LIMITS if mouth is not None else (1.0, 1.0 + 1e-9)
    matrix, k, rms = fit_placement(grid_pts, face.mesh[mesh_idx, :2], weights, float(np.mean(eyes[:, 1])), limits)
    return matrix, k, rms / max(face.iod, 1e-9)
