"""What the method records: every fit iteration, and each node's products once per frame.

Entity / topic paths are ``<node>/<name>``; arrays are on the model grid (``(Hm, Wm)`` or
``(Hm, Wm, 3)``, NaN off the face); see ``recordings/README.md``.
"""
from __future__ import annotations

import os

import numpy as np

from ...flow.frame import Frame
from ...flow.recording import Event, FrameRecording, Kind, OnMask, Recorder
from ...flow.replay import Column
from . import channels as ch
from .channels import CONVERGENCE
from ..method.nodes import (
    AlbedoNode,
    CombineNode,
    FacesNode,
    IntegrateNode,
    LoadNode,
    QualityNode,
    RelightNode,
    RemapNode,
    RobustFitNode,
    SfsInitNode,
    ShadowNode,
)
from ..method.relight import surface_mesh
from ..method.robust_fit import FitIteration
from ..relight.nodes import PhotoRelightNode
from ..relight.products import foreign_on_grid

# The method's channel names (``channels.py``), for the engine's replay (``flow/replay`` knows none of them).
# the columns of ``replay``'s table: the final robust scale, the mean residual from the first iteration to the last
CONVERGENCE_TABLE = (Column("sigma", "sigma"), Column("residual first -> last", "residual_mean", ("first", "last")))
# the method's steps in the order they run: where two recordings split, for ``diff``
STAGES = tuple(node.name for node in (LoadNode, FacesNode, RemapNode, SfsInitNode, RobustFitNode, CombineNode,
                                     IntegrateNode, ShadowNode, AlbedoNode, QualityNode, RelightNode, PhotoRelightNode))


def stage_rank(channel: str) -> int:
    """The rank of the step that recorded ``channel`` (``[face<k>/]<node>/<name>``); the frame record last."""
    parts = channel.split("/")
    node = parts[1] if len(parts) > 2 and parts[0].startswith("face") else parts[0]
    return STAGES.index(node) if node in STAGES else len(STAGES)


def channel(frame: Frame, path: str) -> str:
    """Where a face's ``<node>/<name>`` is recorded: as it is for a photo's first (largest) face, under
    ``face<k>/`` for its k-th (``meta["face"]``), so a photo of one face records what it always did."""
    k = int(frame.meta.get("face", 1))
    return path if k <= 1 else f"face{k}/{path}"


DISPLAY_KINDS = {"normals": Kind.NORMALS, "model_normals": Kind.NORMALS, "depth": Kind.DEPTH,  # re-logging
                 "novel_view": Kind.IMAGE}  # (colour for a colour photo)
# the mesh is recorded as its parts (vertices, triangles, colours: ``Kind.MESH``); re-logged one by one they
# would show as meaningless images
RELOG_LEFT_OUT = ("mesh",)


class FitRecorder:
    """The fit node's observer (``method.nodes.FitObserver``): sends each kept iteration to the
    recorder. With ``--record-every N`` it keeps iterations 1, 1 + N, ... and always the last one
    (held back until the fit ends, see ``finish``).
    """

    def __init__(self, recorder: Recorder):
        self.recorder = recorder
        self._held: dict[int, FitIteration] = {}

    def iteration(self, frame: Frame, it: FitIteration) -> None:
        if it.iteration == 1:  # the frame's first events: say what it is called (its output name)
            self.recorder.name_frame(frame.id, frame.meta.get("stem"))
        key = (frame.id, frame.meta.get("face", 1))
        if self.recorder.keep_iteration(it.iteration):
            self._emit(frame, it)
            self._held.pop(key, None)
        else:
            self._held[key] = it

    def finish(self, frame: Frame) -> None:
        """Emit the last iteration if thinning held it back."""
        it = self._held.pop((frame.id, frame.meta.get("face", 1)), None)
        if it is not None:
            self._emit(frame, it)

    def _emit(self, frame: Frame, it: FitIteration) -> None:
        """Face-pixel copies only: the recorder's thread puts them on the grid (``OnMask``)."""
        mask, r, k, fid = frame.data["model"].mask, self.recorder, it.iteration, frame.id

        def on_face(values: np.ndarray) -> OnMask:
            return OnMask(np.array(values, np.float32), mask)

        r.emit(Event(fid, channel(frame, ch.FIT_NORMALS), Kind.NORMALS, on_face(it.normals), k))
        r.emit(Event(fid, channel(frame, ch.FIT_MODEL_NORMALS), Kind.NORMALS, on_face(it.model_normals), k))
        r.emit(Event(fid, channel(frame, ch.FIT_WEIGHTS), Kind.IMAGE, on_face(it.weights), k))
        r.emit(Event(fid, channel(frame, ch.FIT_RESIDUALS), Kind.ARRAY, on_face(it.residuals), k))
        r.emit(Event(fid, channel(frame, ch.FIT_COEFFICIENTS), Kind.ARRAY, np.array(it.b, np.float32), k))
        r.emit(Event(fid, channel(frame, CONVERGENCE), Kind.SCALARS, it.scalars(), k))


class RecordNode:
    """Records a frame's products once (input, remap, init, final normals, depth, shadows (with the shadows the
    face does not cast, when looked for), albedo, relit, novel view, mesh); the last node before writing."""

    name = "record"

    def __init__(self, recorder: Recorder):
        self.recorder = recorder

    def __call__(self, frame: Frame) -> Frame:
        d, fid = frame.data, frame.id
        m = d["model"]
        self.recorder.name_frame(fid, frame.meta.get("stem"))

        def emit(path: str, kind: Kind, value) -> None:
            self.recorder.emit(Event(fid, channel(frame, path), kind, value))

        emit(ch.GRID_IMAGE, Kind.IMAGE, d["grid_image"].astype(np.float32))
        emit(ch.REMAPPED, Kind.IMAGE, d["remapped"])
        emit(ch.INITIAL_NORMALS, Kind.NORMALS, OnMask(np.array(d["initial"], np.float32), m.mask))
        emit(ch.FINAL_NORMALS, Kind.NORMALS, d["normals"])
        emit(ch.DEPTH, Kind.DEPTH, d["depth"])
        emit(ch.CAST_SHADOW, Kind.IMAGE, d["shadow"].cast.astype(np.float32))
        emit(ch.ATTACHED_SHADOW, Kind.IMAGE, d["shadow"].attached.astype(np.float32))
        foreign = foreign_on_grid(frame)
        if foreign is not None:
            emit(ch.FOREIGN_SHADOW, Kind.IMAGE, foreign)
        emit(ch.ALBEDO, Kind.IMAGE, d["albedo"])
        if "relit" in d:
            emit(ch.RELIT, Kind.IMAGE, d["relit"])
            emit(ch.NOVEL_VIEW, Kind.IMAGE, d["novel_view"])
        emit(ch.MESH, Kind.MESH, surface_mesh(d["depth"], d["albedo"]))
        return frame


def frame_source(fr: FrameRecording) -> str:
    """A recorded frame's input as the run was given it (its path), else ``#<frame id>``: ``diff``
    pairs frames by it first, then by ``frame_name``."""
    source = (fr.record or {}).get("source")
    return source if isinstance(source, str) and source else f"#{fr.frame}"


def frame_name(fr: FrameRecording) -> str:
    """What a recorded frame is called across runs: its input's file name once it finished (output
    names and frame ids depend on what else a run was given), else ``#<frame id>``. ``diff`` pairs
    the frames of two runs by it."""
    source = (fr.record or {}).get("source")
    return os.path.basename(source) if isinstance(source, str) and source else f"#{fr.frame}"
