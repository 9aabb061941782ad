"""The engine a run streams its frames through: this machine's threads (``flow.Pipeline``, one stage a node),
or a Dask cluster (``flow.distributed.DaskPipeline``, the chain on its workers)."""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from ...flow.files import FolderLock
from ...flow.frame import Frame
from ...flow.pipeline import Pipeline, Stage
from ..method.options import MethodOptions
from ..model.shape_model import ShapeModel
from .chain import run_nodes
from .sinks import RunRecording

if TYPE_CHECKING:
    from .runner import RunOptions


def frames_in_flight(fit_workers: int) -> int:
    """How many photos a local run holds at once: one beside each fit worker's, so that the photo steps of
    one frame run while another is fitted. More wins nothing and a long pipeline's queues would fill with
    large photos (its 17 stages let 53 in; figures in docs/speed.md, "A photo's whole run")."""
    return 1 + fit_workers


def local_stages(nodes: list, workers: int) -> list[Stage]:
    """The local engine's stages of ``nodes``: a node that carries state from frame to frame (``in_order``: a clip's
    steadying) takes them in input order on one thread; a thread-safe one (``thread_safe``: the fit, the relighting)
    runs in ``workers`` (``--workers``); any other in one."""
    return [Stage(n, ordered=True) if getattr(n, "in_order", False)
            else Stage(n, workers if getattr(n, "thread_safe", False) else 1) for n in nodes]


def engine(run: RunOptions, model: ShapeModel, options: MethodOptions, out: Path, protected: set[Path],
           recording: RunRecording, lock: FolderLock | None, client, on_done: Callable[[Frame], None]):
    """The engine of a run into ``out`` (locked by ``lock``; no output may land on a path in ``protected``):
    this machine's threads, or the Dask cluster of ``client``; each frame it is done with, in input order,
    goes to ``on_done``."""
    if client is None:
        still_ours = lock.held if lock is not None else None
        nodes = run_nodes(model, options, out, protected, recording.recorder, still_ours)
        stages = local_stages(nodes, run.fit_workers)
        return Pipeline(stages, queue_size=run.queue_size, on_done=on_done, frame_timeout=run.frame_timeout,
                        in_flight=run.in_flight or frames_in_flight(run.fit_workers))
    from ...flow.distributed import DaskPipeline
    from .cluster import WorkerChain

    chain = WorkerChain(options, out.resolve(), frozenset(protected), tuple(run.record),
                        run.record_options, recording.recording_id if "rerun" in run.record else "")
    return DaskPipeline(client, chain, shared=model, on_done=on_done, frame_timeout=run.frame_timeout)
