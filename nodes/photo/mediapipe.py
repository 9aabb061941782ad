"""MediaPipe's face detector (BlazeFace, short range), 468-point face mesh and selfie segmentation, run by
LiteRT (Google's TensorFlow Lite runtime) where it is installed, else by OpenCV's dnn (``runtime``).

The three ``.tflite`` files in ``data/`` are MediaPipe's (Apache-2.0, ``data/NOTICE``); the code that
feeds them and reads their outputs is ours:

- ``detect_faces``: the detector sees a 128 x 128 RGB image in [-1, 1]; it finds faces whose box is
  about 0.15-0.6 of its side. A photo is therefore shown to it whole (as it is, and on a canvas twice
  its size for a face that fills the frame) and in overlapping tiles at halving sizes, down to the
  tile that shows a face with ``min_iod`` pixels between its eyes. Its 896 anchors are decoded here
  (SSD anchors, strides 8, 16, 16, 16), and the boxes of all views merged by weighted non-maximum
  suppression.
- ``face_mesh``: the mesh model sees a 192 x 192 RGB crop in [0, 1], square, 1.5 x the face, turned
  so the eyes are level; it gives 468 points (x, y in crop pixels, z a relative depth on the same
  scale, smaller = nearer the camera) and a face-presence logit. A face's settled crop is looked at
  twice, as it is and as its mirror image (``mesh_on_crop``), and the points averaged.
- ``person_share``: the segmentation model sees a 256 x 256 RGB image in [0, 1] and gives, for each
  pixel, how sure it is that a person (face, hair, neck, clothes) is there, not the background.

Everything here is in photo pixels: x = column, y = row (down).
"""
from __future__ import annotations

import json
import os
import threading
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from .align import Alignment, grid_reach
from .native_messages import decoder_messages_dropped

DATA = Path(__file__).resolve().parent / "data"
DETECTOR_FILE = DATA / "face_detection_short_range.tflite"
MESH_FILE = DATA / "face_landmark.tflite"
MIRROR_FILE = DATA / "face_mesh_mirror.json"
SEGMENTER_FILE = DATA / "selfie_segmentation.tflite"
SEGMENTER_SIDE = 256  # the segmentation model's input, square

DETECTOR_SIZE = 128
MESH_SIZE = 192
# the detector's threshold: MediaPipe's graph uses 0.5; lower, as every candidate must then satisfy the face
# mesh (whose presence score is 0.000-0.001 on non-faces), so faces at the small end of the detector's reach
# (a face without hair or neck around it, 0.2 of the view: 0.25-0.55) are kept
MIN_SCORE = 0.35
NMS_IOU = 0.3  # boxes overlapping more than this are one face (MediaPipe's weighted NMS)
ROI_SCALE = 1.5  # the mesh's crop is this many times the face (a tighter crop mis-scales the mesh)
# a face's box is about 2.1 x its eyes' distance; the detector finds boxes down to a fifth of its view
# (docs/tuning.md, "Finding faces")
BOX_PER_IOD = 2.1
MIN_BOX_SHARE = 0.2
TILE_STRIDE = 0.72  # of a tile's side: a face up to 0.28 of a tile (larger ones: the next level) is whole in one
WHOLE_REACH = 0.75  # tiles stop once they are this share of the photo's long side: the whole views see the rest

# mesh vertices (MediaPipe's canonical face mesh numbering)
OUTER_CORNERS = (33, 263)  # the image-left eye's outer corner, the image-right eye's


def _litert():
    """LiteRT's interpreter class (``ai-edge-litert``, Google's TensorFlow Lite runtime), or None where it is
    not installed: it runs both nets about twice as fast as OpenCV's dnn (XNNPACK kernels)."""
    try:
        from ai_edge_litert.interpreter import Interpreter
    except ImportError:
        return None
    return Interpreter


class _LiteRtNet:
    """One model in LiteRT, called as ``(N=1, H, W, C) float32 -> named outputs``."""

    def __init__(self, path: Path, interpreter):
        with decoder_messages_dropped():  # its note on loading, on standard error
            self._net = interpreter(model_path=str(path), num_threads=1)  # one core: the run's threads share them
            self._net.allocate_tensors()
        self._input = self._net.get_input_details()[0]["index"]
        self._outputs = {o["name"]: o["index"] for o in self._net.get_output_details()}

    def __call__(self, x: np.ndarray, outputs: list[str]) -> tuple[np.ndarray, ...]:
        self._net.set_tensor(self._input, x)
        self._net.invoke()
        return tuple(self._net.get_tensor(self._outputs[name]) for name in outputs)


class _OpenCvNet:
    """One model in OpenCV's dnn (its classic engine), called as LiteRT's is: NHWC in, named outputs."""

    def __init__(self, path: Path):
        kwargs = {"engine": cv2.dnn.ENGINE_CLASSIC} if hasattr(cv2.dnn, "ENGINE_CLASSIC") else {}
        self._net = cv2.dnn.readNetFromTFLite(str(path), **kwargs)

    def __call__(self, x: np.ndarray, outputs: list[str]) -> tuple[np.ndarray, ...]:
        self._net.setInput(np.ascontiguousarray(x.transpose(0, 3, 1, 2)))
        return tuple(self._net.forward(outputs))


RUNTIMES = ("litert", "opencv")


def runtime() -> str:
    """Which runtime runs the nets: ``SHADOWFLOW_NETS`` (litert | opencv) when set, else LiteRT where it is
    installed, else OpenCV's dnn. The two find the same faces, landmarks within a pixel (tests/photo/test_faces.py)."""
    asked = os.environ.get("SHADOWFLOW_NETS", "").strip().lower()
    if asked and asked not in RUNTIMES:
        raise RuntimeError(f"SHADOWFLOW_NETS={asked!r}: choose from {', '.join(RUNTIMES)}")
    if asked == "opencv" or (not asked and _litert() is None):
        return "opencv"
    if _litert() is None:
        raise RuntimeError("SHADOWFLOW_NETS=litert, but ai-edge-litert is not installed")
    return "litert"


def _load(path: Path, litert_only: bool = False):
    if not path.is_file():
        raise RuntimeError(f"{path}: MediaPipe model missing from the package (reinstall shadowflow)")
    return _LiteRtNet(path, _litert()) if litert_only or runtime() == "litert" else _OpenCvNet(path)


class NetPool:
    """The loaded nets of one model, lent to one caller at a time: a net is not safe to share between
    threads, and loading one takes milliseconds, so the nets outlive the threads that use them (a
    time-limited step runs each frame in a new thread)."""

    def __init__(self, path: Path, litert_only: bool = False):
        self.path, self.litert_only = path, litert_only  # litert_only: a model OpenCV's dnn gets wrong
        self._free: list = []
        self._lock = threading.Lock()

    def forward(self, x: np.ndarray, outputs: list[str]) -> tuple[np.ndarray, ...]:
        """The named outputs of the net for the input ``x`` (1, H, W, C) float32."""
        with self._lock:
            net = self._free.pop() if self._free else None
        if net is None:
            net = _load(self.path, self.litert_only)
        try:
            return net(x, outputs)
        finally:
            with self._lock:
                self._free.append(net)


DETECTOR = NetPool(DETECTOR_FILE)
MESH = NetPool(MESH_FILE)
SEGMENTER = NetPool(SEGMENTER_FILE)


def person_share(rgb: np.ndarray, to_display: Callable[[np.ndarray], np.ndarray] | None = None) -> np.ndarray:
    """(H, W) float32 in [0, 1]: how sure MediaPipe's selfie segmentation is that each pixel of ``rgb``
    ((H, W, 3) or (H, W, 1) float in [0, 1]) is a person, not the background; the image seen at 256 x 256 (a
    few milliseconds), the answer brought back to its size. ``to_display``: applied to the 256 x 256 image
    first, to show the net the photo as a camera saved it (``linear_to_srgb`` for a linear colour photo)."""
    h, w = rgb.shape[:2]
    small = cv2.resize(np.asarray(rgb, np.float32), (SEGMENTER_SIDE, SEGMENTER_SIDE), interpolation=cv2.INTER_AREA)
    small = small.reshape(SEGMENTER_SIDE, SEGMENTER_SIDE, -1)
    if small.shape[-1] != 3:
        small = np.repeat(small[..., :1], 3, axis=-1)
    if to_display is not None:
        small = to_display(small)
    (share,) = SEGMENTER.forward(np.clip(small, 0.0, 1.0).astype(np.float32)[None], ["activation_10"])
    share = np.clip(np.asarray(share, np.float32).reshape(SEGMENTER_SIDE, SEGMENTER_SIDE), 0.0, 1.0)
    return cv2.resize(share, (w, h), interpolation=cv2.INTER_LINEAR)  # (bilinear: stays within [0, 1])


def _anchors() -> np.ndarray:
    """(896, 2) anchor centres in [0, 1] of the detector's input: 16 x 16 cells with 2 anchors,
    then 8 x 8 cells with 6 (strides 8 and 16, 16, 16), row by row."""
    out = []
    for stride, per_cell in ((8, 2), (16, 6)):
        cells = DETECTOR_SIZE // stride
        ys, xs = np.mgrid[0:cells, 0:cells]
        centres = np.stack([(xs + 0.5) / cells, (ys + 0.5) / cells], axis=-1).reshape(-1, 1, 2)
        out.append(np.repeat(centres, per_cell, axis=1).reshape(-1, 2))
    return np.concatenate(out)


ANCHORS = _anchors()


@dataclass(frozen=True)
class Detection:
    """One face the detector saw. box: (4,) ``x0, y0, x1, y1``; keypoints: (6, 2) the image-left eye,
    the image-right eye, nose tip, mouth, image-left ear, image-right ear; photo pixels; score in [0, 1]."""

    box: np.ndarray
    keypoints: np.ndarray
    score: float


def _decode(scores: np.ndarray, regressors: np.ndarray, to_photo: np.ndarray) -> list[Detection]:
    """Detections of one detector view. scores (896,) logits; regressors (896, 16); to_photo: (2, 3)
    the view's input pixels -> photo pixels (a scale and a shift)."""
    s = 1.0 / (1.0 + np.exp(-np.clip(scores.astype(np.float64), -80.0, 80.0)))
    keep = np.flatnonzero(s >= MIN_SCORE)
    out = []
    for k in keep:
        r = regressors[k].astype(np.float64)
        centre = r[:2] / DETECTOR_SIZE + ANCHORS[k]
        half = r[2:4] / DETECTOR_SIZE / 2.0
        pts = np.vstack([centre - half, centre + half, r[4:].reshape(6, 2) / DETECTOR_SIZE + ANCHORS[k]])
        pts = pts * DETECTOR_SIZE @ to_photo[:, :2].T + to_photo[:, 2]
        out.append(Detection(pts[:2].reshape(4), pts[2:], float(s[k])))
    return out


def _views(shape: tuple[int, int], min_iod: float) -> list[tuple[float, float, float]]:
    """The detector's views of a photo (H, W): ``(scale, x0, y0)``, each the 128^2 window whose
    pixel (u, v) is the photo's ``(x0 + u / scale, y0 + v / scale)``: the photo whole (centred on
    a canvas twice its size, for a face that fills it, and as it is), then tiles of the finest size
    (``min_iod``) and twice, four times... that, each level's overlapping by ``1 - TILE_STRIDE``."""
    h, w = shape
    side = float(max(h, w))
    views = []
    for canvas in (2.0 * side, side):
        scale = DETECTOR_SIZE / canvas
        views.append((scale, (w - canvas) / 2.0, (h - canvas) / 2.0))
    tile = max(float(DETECTOR_SIZE), min_iod * BOX_PER_IOD / MIN_BOX_SHARE)
    while tile < WHOLE_REACH * side:  # larger faces: the whole photo's view finds them
        stride = TILE_STRIDE * tile
        xs = np.linspace(0.0, max(w - tile, 0.0), int(np.ceil(max(w - tile, 0.0) / stride)) + 1)
        ys = np.linspace(0.0, max(h - tile, 0.0), int(np.ceil(max(h - tile, 0.0) / stride)) + 1)
        views += [(DETECTOR_SIZE / tile, float(x), float(y)) for y in ys for x in xs]
        tile *= 2.0
    return views


def _shrunk(rgb: np.ndarray, factor: float) -> tuple[np.ndarray, np.ndarray]:
    """``rgb`` area-averaged by ``factor`` (< 1) and the (3, 3) map from its pixels to the photo's."""
    h, w = rgb.shape[:2]
    small = cv2.resize(rgb, (max(1, round(w * factor)), max(1, round(h * factor))), interpolation=cv2.INTER_AREA)
    return small, np.diag([w / small.shape[1], h / small.shape[0], 1.0])


def _around(rgb: np.ndarray, to_photo: np.ndarray, size: int, margin: float) -> tuple[np.ndarray, np.ndarray]:
    """The part of the photo a ``size``^2 window (``to_photo``, (2, 3)) shows, ``margin`` pixels wider (a view,
    not a copy), and the (3, 3) map from its pixels to the photo's: a large photo is then shrunk only there."""
    y0, y1, x0, x1 = grid_reach(Alignment(to_photo, "crop"), (size, size), rgb.shape[:2], int(np.ceil(margin)))
    return rgb[y0:y1, x0:x1], np.array([[1.0, 0.0, x0], [0.0, 1.0, y0], [0.0, 0.0, 1.0]])


def _pyramid(rgb: np.ndarray, scales: list[float]) -> dict[float, tuple[np.ndarray, np.ndarray]]:
    """The photo area-averaged to each of ``scales`` (largest first): ``scale -> (image, its pixels ->
    the photo's (3, 3))``; each from the last one made, so the full photo is averaged down only once."""
    out: dict[float, tuple[np.ndarray, np.ndarray]] = {}
    src, from_src, at = rgb, np.eye(3), 1.0
    for scale in scales:
        small, to_src = _shrunk(src, scale / at)
        src, from_src, at = small, from_src @ to_src, scale
        out[scale] = (src, from_src)
    return out


def _window(src: np.ndarray, to_photo: np.ndarray, size: int, from_src: np.ndarray | None = None) -> np.ndarray:
    """(size, size, 3) uint8: the window whose pixel (u, v) is photo pixel ``to_photo @ (u, v, 1)``
    (2, 3), sampled from ``src`` whose pixels map to the photo's by ``from_src`` (3, 3; None: src is
    the photo); black beyond the photo."""
    full = np.vstack([to_photo, [0.0, 0.0, 1.0]])
    if from_src is not None:
        full = np.linalg.inv(from_src) @ full
    return cv2.warpAffine(src, full[:2], (size, size), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0))


def detect_faces(rgb: np.ndarray, min_iod: float = 30.0) -> list[Detection]:
    """Every face the detector finds in ``rgb`` (H, W, 3) uint8 RGB, largest first.

    min_iod: the smallest distance between the eyes, in pixels, the tiles are made fine enough for
    (smaller faces may be found too)."""
    h, w = rgb.shape[:2]
    found: list[Detection] = []
    views = _views((h, w), min_iod)
    pyramid = _pyramid(rgb, sorted({scale for scale, _, _ in views if scale < 0.5}, reverse=True))
    for scale, x0, y0 in views:
        to_photo = np.array([[1.0 / scale, 0.0, x0], [0.0, 1.0 / scale, y0]])
        if scale < 0.5:  # area-averaged first, so the window is not aliased
            small, from_small = pyramid[scale]
            win = _window(small, to_photo, DETECTOR_SIZE, from_small)
        else:
            win = _window(rgb, to_photo, DETECTOR_SIZE)
        x = win.astype(np.float32) / np.float32(127.5) - np.float32(1.0)
        scores, regressors = DETECTOR.forward(x[None], ["classificators", "regressors"])
        found += _decode(scores.reshape(-1), regressors.reshape(-1, 16), to_photo)
    return weighted_nms(found)


def _iou(a: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    ix = np.clip(np.minimum(a[2], boxes[:, 2]) - np.maximum(a[0], boxes[:, 0]), 0, None)
    iy = np.clip(np.minimum(a[3], boxes[:, 3]) - np.maximum(a[1], boxes[:, 1]), 0, None)
    inter = ix * iy
    area = lambda b: (b[..., 2] - b[..., 0]) * (b[..., 3] - b[..., 1])  # noqa: E731
    return inter / np.maximum(area(a) + area(boxes) - inter, 1e-9)


def weighted_nms(found: list[Detection], iou: float = NMS_IOU) -> list[Detection]:
    """Merge detections of one face (boxes overlapping by more than ``iou``) into their
    score-weighted mean, best first; returned largest first."""
    if not found:
        return []
    order = sorted(found, key=lambda d: -d.score)
    boxes = np.array([d.box for d in order])
    left = np.ones(len(order), bool)
    out = []
    for i in range(len(order)):
        if not left[i]:
            continue
        group = left & (_iou(boxes[i], boxes) > iou)
        group[i] = True
        left &= ~group
        members = [order[j] for j in np.flatnonzero(group)]
        wts = np.array([d.score for d in members])
        box = np.average([d.box for d in members], axis=0, weights=wts)
        kps = np.average([d.keypoints for d in members], axis=0, weights=wts)
        out.append(Detection(box, kps, float(order[i].score)))
    return sorted(out, key=lambda d: -(d.box[2] - d.box[0]))


@dataclass(frozen=True)
class Roi:
    """A square crop of the photo: centre (2,) photo pixels, side in pixels, angle: radians the crop
    is turned by (the face's eye line, image-left to image-right eye, measured from the x axis with y
    down, i.e. clockwise as seen)."""

    centre: np.ndarray
    side: float
    angle: float

    def to_photo(self, size: int) -> np.ndarray:
        """(2, 3) affine: crop pixel (u, v) of a ``size``^2 crop -> photo pixel."""
        c, s = np.cos(self.angle), np.sin(self.angle)
        k = self.side / size
        lin = k * np.array([[c, -s], [s, c]])
        return np.column_stack([lin, np.asarray(self.centre, np.float64) - lin @ np.array([size / 2.0, size / 2.0])])


def roi_from_detection(d: Detection) -> Roi:
    """The mesh's crop for a detection: its box's centre and long side x ``ROI_SCALE``, turned by its eye line."""
    v = d.keypoints[1] - d.keypoints[0]
    angle = float(np.arctan2(v[1], v[0]))
    side = float(max(d.box[2] - d.box[0], d.box[3] - d.box[1])) * ROI_SCALE
    return Roi((d.box[:2] + d.box[2:]) / 2.0, side, angle)


def roi_from_mesh(points: np.ndarray) -> Roi:
    """The mesh's crop from a mesh (468, 2+) in photo pixels: its extent in the frame turned by the
    outer eye corners' line, x ``ROI_SCALE`` (MediaPipe's tracking crop)."""
    p = np.asarray(points, np.float64)[:, :2]
    v = p[OUTER_CORNERS[1]] - p[OUTER_CORNERS[0]]
    angle = float(np.arctan2(v[1], v[0]))
    c, s = np.cos(angle), np.sin(angle)
    turned = p @ np.array([[c, -s], [s, c]])  # into the eye-level frame (rotation by -angle)
    lo, hi = turned.min(axis=0), turned.max(axis=0)
    centre = np.array([[c, -s], [s, c]]) @ ((lo + hi) / 2.0)
    return Roi(centre, float(max(hi - lo)) * ROI_SCALE, angle)


def face_mesh(rgb: np.ndarray, roi: Roi, mirrored: bool = False) -> tuple[np.ndarray, float]:
    """The 468-point mesh in ``roi`` of ``rgb`` (H, W, 3) uint8: ``(points (468, 3) float64, presence)``;
    points are x, y in photo pixels and z in the same pixels, toward the camera positive; presence
    in [0, 1] (under 0.5: no face). ``mirrored``: the mesh's look at the crop's mirror image, its points
    mirrored back onto the face (``mesh_on_crop``)."""
    to_photo = roi.to_photo(MESH_SIZE)
    shrink = roi.side / MESH_SIZE  # photo pixels per crop pixel
    if shrink > 2.0:  # a large face: area-average the photo first, so the crop is not aliased
        region, offset = _around(rgb, to_photo, MESH_SIZE, margin=2.0 * shrink)  # only what the crop shows
        small, from_small = _shrunk(region, 1.5 / shrink)
        crop = _window(small, to_photo, MESH_SIZE, offset @ from_small)
    else:
        crop = _window(rgb, to_photo, MESH_SIZE)
    pts, logit = mesh_on_crop(crop.astype(np.float32) / np.float32(255.0), mirrored)
    xy = pts[:, :2] @ to_photo[:, :2].T + to_photo[:, 2]
    z = -pts[:, 2] * (roi.side / MESH_SIZE)
    p = 1.0 / (1.0 + np.exp(-np.clip(logit, -80.0, 80.0)))
    return np.column_stack([xy, z]), float(p)


def mesh_on_crop(crop: np.ndarray, mirrored: bool = False) -> tuple[np.ndarray, float]:
    """The face mesh of a (192, 192, 3) float32 crop in [0, 1]: ``(points (468, 3) float64, presence
    logit)``, points x, y in crop pixels (column, row) and z as the model gives it. ``mirrored``: the
    mesh of the crop's mirror image, each point mirrored back onto the crop and given its partner's
    place in the list (``mesh_mirror``). The model is not symmetric: its two looks at a face disagree by
    1-2 % of the eye distance, a left-right bias and noise that their mean halves (``faces.confirmed_face``;
    ``docs/accuracy.md``, "Both ways"); the mean of a crop's two looks is exactly the mirror of its
    mirror image's."""
    seen = np.ascontiguousarray(crop[:, ::-1]) if mirrored else crop
    mesh, presence = MESH.forward(seen[None], ["conv2d_21", "conv2d_31"])
    pts = mesh.reshape(468, 3).astype(np.float64)
    if mirrored:
        pts = pts[mesh_mirror()]
        pts[:, 0] = (crop.shape[1] - 1) - pts[:, 0]  # column u of the mirror image is column W-1-u
    return pts, float(presence.reshape(-1)[0])


@lru_cache(maxsize=1)
def mesh_mirror() -> np.ndarray:
    """(468,) int: for each face-mesh point, the point that is its mirror image across the face's
    midline (the image-left eye's outer corner 33 and the image-right's 263; the midline's points are
    their own). From MediaPipe's canonical face model (``data/face_mesh_mirror.json``, ``data/NOTICE``)."""
    order = np.asarray(json.loads(MIRROR_FILE.read_text()), np.intp)
    if order.shape != (468,) or not np.array_equal(order[order], np.arange(468)):
        raise ValueError(f"{MIRROR_FILE}: not a mirror pairing of the mesh's 468 points")
    order.flags.writeable = False  # shared by every call
    return order
