"""What the method records: every fit iteration, and each node's products once per frame.

Entity / topic paths are ``<node>/<name>``; arrays are on the model grid (``(Hm, Wm)`` or
``(Hm, Wm, 3)``, NaN off the face); see ``recordings/README.md``.
"""
from __future__ import annotations

import os

import numpy as np

from ...flow.frame import Frame
from ...flow.recording import Event, FrameRecording, Kind, OnMask, Recorder
from ..method.nodes import (
    AlbedoNode,
    CombineNode,
    IntegrateNode,
    LoadNode,
    PhotoRelightNode,
    QualityNode,
    RelightNode,
    RemapNode,
    RobustFitNode,
    SfsInitNode,
    ShadowNode,
)
from ..method.relight import surface_mesh
from ..method.robust_fit import FitIteration
from ..model.shape_model import ShapeModel

# The method's channel names, for the engine's replay (``flow/replay.py`` knows none of them).
CONVERGENCE = "robust_fit/convergence"  # per-iteration scalars of the fit (``FitIteration.scalars``)
CONVERGENCE_PLOTS = ("sigma", "change_deg", "residual_mean")  # the panels of ``replay --plot``
CONVERGENCE_LABELS = {"sigma": "robust scale σ (radians)", "change_deg": "mean change of the normals (degrees)",
                      "residual_mean": "mean residual (radians)"}
# the method's steps in the order they run: where two recordings split, for ``diff``
STAGES = tuple(node.name for node in (LoadNode, RemapNode, SfsInitNode, RobustFitNode, CombineNode, IntegrateNode,
                                     ShadowNode, AlbedoNode, QualityNode, RelightNode, PhotoRelightNode))


def stage_rank(channel: str) -> int:
    """The rank of the step that recorded ``channel`` (``<node>/<name>``); the frame record last."""
    node = channel.split("/", 1)[0]
    return STAGES.index(node) if node in STAGES else len(STAGES)


DISPLAY_KINDS = {"normals": Kind.NORMALS, "model_normals": Kind.NORMALS, "depth": Kind.DEPTH}  # re-logging


class FitRecorder:
    """The fit node's observer (``method.nodes.FitObserver``): sends each kept iteration to the
    recorder. With ``--record-every N`` it keeps iterations 1, 1 + N, ... and always the last one
    (held back until the fit ends, see ``finish``).
    """

    def __init__(self, model: ShapeModel, recorder: Recorder):
        self.model, self.recorder = model, recorder
        self._held: dict[int, FitIteration] = {}

    def iteration(self, frame: Frame, it: FitIteration) -> None:
        if it.iteration == 1:  # the frame's first events: say what it is called (its output name)
            self.recorder.name_frame(frame.id, frame.meta.get("stem"))
        if self.recorder.keep_iteration(it.iteration):
            self._emit(frame.id, it)
            self._held.pop(frame.id, None)
        else:
            self._held[frame.id] = it

    def finish(self, frame: Frame) -> None:
        """Emit the last iteration if thinning held it back."""
        it = self._held.pop(frame.id, None)
        if it is not None:
            self._emit(frame.id, it)

    def _emit(self, fid: int, it: FitIteration) -> None:
        """Face-pixel copies only: the recorder's thread puts them on the grid (``OnMask``)."""
        mask, r, k = self.model.mask, self.recorder, it.iteration

        def on_face(values: np.ndarray) -> OnMask:
            return OnMask(np.array(values, np.float32), mask)

        r.emit(Event(fid, "robust_fit/normals", Kind.NORMALS, on_face(it.normals), k))
        r.emit(Event(fid, "robust_fit/model_normals", Kind.NORMALS, on_face(it.model_normals), k))
        r.emit(Event(fid, "robust_fit/weights", Kind.IMAGE, on_face(it.weights), k))
        r.emit(Event(fid, "robust_fit/residuals", Kind.ARRAY, on_face(it.residuals), k))
        r.emit(Event(fid, "robust_fit/b", Kind.ARRAY, np.array(it.b, np.float32), k))
        r.emit(Event(fid, CONVERGENCE, Kind.SCALARS, it.scalars(), k))


class RecordNode:
    """Records a frame's products once (input, remap, init, final normals, depth, shadows,
    albedo, relit, novel view, mesh); the last node before writing."""

    name = "record"

    def __init__(self, model: ShapeModel, recorder: Recorder):
        self.model, self.recorder = model, recorder

    def __call__(self, frame: Frame) -> Frame:
        d, m, fid, emit = frame.data, self.model, frame.id, self.recorder.emit
        self.recorder.name_frame(fid, frame.meta.get("stem"))
        emit(Event(fid, "load/grid_image", Kind.IMAGE, d["grid_image"].astype(np.float32)))
        emit(Event(fid, "remap/remapped", Kind.IMAGE, d["remapped"]))
        emit(Event(fid, "sfs_init/normals", Kind.NORMALS, OnMask(np.array(d["initial"], np.float32), m.mask)))
        emit(Event(fid, "combine/normals", Kind.NORMALS, d["normals"]))
        emit(Event(fid, "integrate/depth", Kind.DEPTH, d["depth"]))
        emit(Event(fid, "shadow/cast", Kind.IMAGE, d["shadow"].cast.astype(np.float32)))
        emit(Event(fid, "shadow/attached", Kind.IMAGE, d["shadow"].attached.astype(np.float32)))
        emit(Event(fid, "albedo/albedo", Kind.IMAGE, d["albedo"]))
        if "relit" in d:
            emit(Event(fid, "relight/relit", Kind.IMAGE, d["relit"]))
            emit(Event(fid, "relight/novel_view", Kind.IMAGE, d["novel_view"]))
        emit(Event(fid, "integrate/mesh", Kind.MESH, surface_mesh(d["depth"], d["albedo"])))
        return frame


def frame_name(fr: FrameRecording) -> str:
    """What a recorded frame is called across runs: its input's file name once it finished (output
    names and frame ids depend on what else a run was given), else ``#<frame id>``. ``diff`` pairs
    the frames of two runs by it."""
    source = (fr.record or {}).get("source")
    return os.path.basename(source) if isinstance(source, str) and source else f"#{fr.frame}"
