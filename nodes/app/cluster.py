"""``--dask``: the method's nodes as tasks on a Dask cluster (``flow.distributed``).

Each worker builds the method's chain once (``WorkerChain``), writes each frame's outputs under
``--out`` itself, and records the frames it runs in recording parts of its own beside the
client's, ``run.worker-<name>.mcap`` / ``.rrd`` (so ``--out`` must be storage every worker sees,
as on a cluster's shared file system). Only the frame's record travels back; the client lists
the parts in the run manifest, and ``replay`` / ``diff`` read them as one run. Measured on this
2-core machine (``benchmarks/bench_dask.py``, 200 recorded frames): with the iterations sent back
for the client to record, two workers gave 1.25x one; recorded where they run, see the README.
"""
from __future__ import annotations

import logging
import os
import re
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

from ...flow.cluster_host import local_cluster
from ...flow.frame import Frame
from ...flow.recording import McapSink, Recorder, RecordOptions
from ..method.options import MethodOptions
from ..model.shape_model import ShapeModel
from .blueprint import rerun_sink
from .chain import run_nodes
from .outputs import summary_record

DASK_METAVAR = "local[:N]|tcp://HOST:PORT|env"
DASK_HELP = ("run frames as tasks on Dask: local (a LocalCluster, one worker process per core), local:N "
             "(N processes), tcp://HOST:PORT (a running scheduler), or env (DASK_SCHEDULER_ADDRESS); "
             "needs shadowflow[dask]; --out must be storage every worker sees")

SUFFIXES = {"mcap": "mcap", "rerun": "rrd"}  # --record's formats -> their files' suffixes


@dataclass(frozen=True)
class WorkerChain:
    """What a worker runs on each frame (picklable; called once per worker with the model):
    load, the method's nodes, the recorder's per-frame products and the writer; each frame is
    then recorded in this worker's recording parts (``record``: "mcap", "rerun"; ``recording_id``:
    the client's Rerun recording id, so the viewer shows all the parts as one recording) and goes
    back holding only its metadata (its arrays are on disk), with ``meta["recording_parts"]``."""

    options: MethodOptions
    out: Path
    protected: frozenset
    record: tuple[str, ...]
    record_options: RecordOptions
    recording_id: str

    def __call__(self, model: ShapeModel):
        worker_setup()
        recorder, sinks = self._recorder() if self.record else (None, [])
        nodes = run_nodes(model, self.options, self.out, set(self.protected), recorder)

        def finish(frame: Frame) -> None:
            if recorder is not None:  # recorded before the client's journal says the frame is done
                recorder.frame_done(frame.id, summary_record(frame), wait=True)
                if recorder.error is not None:
                    frame.meta["recording_error"] = f"recording failed: {recorder.error}"
            frame.meta["recording_parts"] = [p.name for sink in sinks for p in sink.paths]
            frame.drop_data()

        return nodes, finish, (recorder.close if recorder is not None else None)

    def _recorder(self) -> tuple[Recorder, list]:
        paths = reserve_parts(self.out, f"run.worker-{_worker_name()}", [SUFFIXES[f] for f in self.record])
        sinks = []
        if "mcap" in paths:
            sinks.append(McapSink(paths["mcap"]))
        if "rrd" in paths:
            sinks.append(rerun_sink(paths["rrd"], self.recording_id))
        return Recorder(sinks, self.record_options), sinks


def _worker_name() -> str:
    """This Dask worker's name, as a file name may hold it (``0``, ``tcp-10-0-0-5-40123``)."""
    try:
        from distributed import get_worker

        name = str(get_worker().name)
    except (ImportError, ValueError):  # not in a worker (a test calling the chain directly)
        name = f"pid{os.getpid()}"
    return re.sub(r"[^A-Za-z0-9_]+", "-", name).strip("-")[:64] or "w"


def reserve_parts(out: Path, stem: str, suffixes: list[str]) -> dict[str, Path]:
    """New empty files ``out/<stem>.<suffix>`` (``<stem>-2.<suffix>``... when any is taken: a
    restarted worker, a resumed run), created exclusively and never through a symbolic link,
    so two workers or two runs never write one file. Returns suffix -> path."""
    for k in range(1, 10_000):
        name = stem if k == 1 else f"{stem}-{k}"
        made: dict[str, Path] = {}
        try:
            for suffix in suffixes:
                path = out / f"{name}.{suffix}"
                os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o644))
                made[suffix] = path
            return made
        except FileExistsError:
            for path in made.values():
                path.unlink()
    raise OSError(f"{out}: no free name for this worker's recording ({stem}-N)")


def worker_setup() -> None:
    """What a local run does for itself, in a worker process: BLAS on one thread (the fit's matrices
    are small) and glibc's allocator tuned (``process.release_large_frees``)."""
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
    each, hosted in a child process that ends with this one; or a running scheduler), closed
    afterwards."""
    kind, arg = parse_dask(spec)
    try:
        from distributed import Client
    except ImportError:
        raise ValueError("--dask needs Dask: pip install 'shadowflow[dask]'") from None
    # the client logs its reconnection attempts with tracebacks when a scheduler goes away; the run says
    # so itself in one line (``DaskPipeline.lost``)
    with _quiet_logger("distributed"), _quiet_logger("distributed.client"), _client(kind, arg, Client) as client:
        yield client


@contextmanager
def _quiet_logger(name: str) -> Iterator[None]:
    """``name``'s log records under CRITICAL dropped for the duration."""
    logger = logging.getLogger(name)
    level = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        logger.setLevel(level)


@contextmanager
def _client(kind: str, arg, Client) -> Iterator[object]:
    if kind == "local":
        # the cluster's scheduler runs in a process of its own, not in this one: it keeps state per
        # task, which would grow the client's memory with the stream (``flow.cluster_host``)
        with local_cluster(arg or os.cpu_count() or 1) as address, Client(address, timeout="20s") as client:
            client.run(worker_setup)
            yield client
    else:
        with Client(arg, timeout="20s") as client:
            client.run(worker_setup)
            yield client
