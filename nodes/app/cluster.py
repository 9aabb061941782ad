"""``--dask``: the method's nodes as tasks on a Dask cluster (``flow.distributed``).

Each worker builds the method's chain once (``WorkerChain``) and writes each frame's outputs
under ``--out`` itself (so ``--out`` must be storage every worker sees, as on a cluster's
shared file system); each frame's recording events travel back with it and the client records
them, so ``run.mcap`` / ``run.rrd`` are the same files a local run writes.
"""
from __future__ import annotations

import logging
import os
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

from ...flow.frame import Frame
from ...flow.recording import EventCollector, RecordOptions
from ..method.nodes import LoadNode, MethodOptions, method_nodes
from ..model.shape_model import ShapeModel
from .outputs import WriteNode
from .record import FitRecorder, RecordNode

DASK_METAVAR = "local[:N]|tcp://HOST:PORT|env"
DASK_HELP = ("run frames as tasks on Dask: local (a LocalCluster, one worker process per core), local:N "
             "(N processes), tcp://HOST:PORT (a running scheduler), or env (DASK_SCHEDULER_ADDRESS); "
             "needs shadowflow[dask]; --out must be storage every worker sees")


@dataclass(frozen=True)
class WorkerChain:
    """What a worker runs on each frame (picklable; called once per worker with the model):
    load, the method's nodes, the recorder's per-frame products and the writer; then the frame
    goes back holding only its recording events (``data["events"]``): its arrays are on disk."""

    options: MethodOptions
    out: Path
    protected: frozenset
    record: bool
    record_options: RecordOptions

    def __call__(self, model: ShapeModel):
        worker_setup()
        collector = EventCollector(self.record_options) if self.record else None
        observer = FitRecorder(model, collector) if collector is not None else None
        nodes = [LoadNode(model, self.options), *method_nodes(model, self.options, observer)]
        if collector is not None:
            nodes.append(RecordNode(model, collector))
        nodes.append(WriteNode(model, self.out, set(self.protected)))

        def hand_back(frame: Frame) -> None:
            frame.data = {"events": collector.take(frame.id) if collector is not None else []}

        return nodes, hand_back


def worker_setup() -> None:
    """What a local run does for itself, in a worker process: BLAS on one thread (the fit's matrices
    are small) and glibc's allocator tuned (``runner.release_large_frees``)."""
    from threadpoolctl import threadpool_limits

    from .process import release_large_frees

    threadpool_limits(limits=1, user_api="blas")
    release_large_frees()


def parse_dask(spec: str) -> tuple[str, int | str | None]:
    """``--dask`` -> ("local", workers or None) or ("address", "tcp://..."); ``ValueError`` otherwise."""
    if spec == "env":
        address = os.environ.get("DASK_SCHEDULER_ADDRESS")
        if not address:
            raise ValueError("--dask env: DASK_SCHEDULER_ADDRESS is not set")
        return "address", address
    if spec == "local":
        return "local", None
    if spec.startswith("local:"):
        try:
            n = int(spec.split(":", 1)[1])
        except ValueError:
            n = 0
        if n < 1:
            raise ValueError(f"--dask local:N needs N >= 1 worker processes, not {spec!r}")
        return "local", n
    if "://" in spec:
        return "address", spec
    raise ValueError(f"--dask takes local, local:N, tcp://HOST:PORT or env, not {spec!r}")


@contextmanager
def dask_client(spec: str) -> Iterator[object]:
    """A ``distributed.Client`` for ``--dask SPEC`` (a LocalCluster of worker processes, one thread
    each, or a running scheduler), closed afterwards."""
    kind, arg = parse_dask(spec)
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise ValueError("--dask needs Dask: pip install 'shadowflow[dask]'") from None
    if kind == "local":
        n = arg or os.cpu_count() or 1
        with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                          silence_logs=logging.ERROR) as cluster, \
                Client(cluster) as client:
            client.run(worker_setup)
            yield client
    else:
        with Client(arg, timeout="20s") as client:
            client.run(worker_setup)
            yield client
