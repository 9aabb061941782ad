"""The one chain a run gives each photo, built in one place for the local engine and the Dask workers."""
from __future__ import annotations

from pathlib import Path
from typing import Callable, MutableSet

from ...flow.recording import Recorder
from ..method.options import MethodOptions
from ..relight.nodes import photo_nodes
from ..model.shape_model import ShapeModel
from .clips import ClipNode
from .outputs import WriteNode
from .record import FitRecorder, RecordNode
from .report import CardNode
from .steady import SteadyLightNode, SteadyRelightNode, SteadyYawNode
from .view import PageNode


def run_nodes(model: ShapeModel, options: MethodOptions, out: Path, protected: MutableSet[Path],
              recorder: Recorder | None = None, still_ours: Callable[[], bool] | None = None) -> list:
    """A photo's nodes in a run: load, find its faces, the method on each face (``photo_nodes``), each
    fit's iterations and each face's products recorded when there is a ``recorder``, a clip's frames steadied and
    relit for its clips (``steady``, ``clips``), and the outputs
    written under ``out`` (never over a path in ``protected``, nor once ``still_ours`` says ``out`` is not
    the run's any more)."""
    observer = FitRecorder(recorder) if recorder is not None else None
    after = (RecordNode(recorder),) if recorder is not None else ()
    # a clip's faces steadied once found and once relit (one thread each: its frames in order), its frames relit for
    # its clips; then
    # writing the files, the photo's page and the report's pictures: three steps, each reading what the run made
    return [*photo_nodes(model, options, observer, after=after, after_faces=(SteadyLightNode(),)),
            SteadyYawNode(), SteadyRelightNode(), ClipNode(),
            WriteNode(out, protected, options.arrays, still_ours), PageNode(), CardNode()]
