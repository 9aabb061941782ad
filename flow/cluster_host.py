"""A Dask ``LocalCluster`` (its scheduler and its worker processes) hosted in a child process.

Run inside the client, a ``LocalCluster``'s scheduler keeps a little state for every task the
client submits (about 1.9 kB a frame measured, see ``docs/streaming.md``), so the client's memory
grew with the length of the stream. ``local_cluster`` starts the cluster in a process of its own
and yields its scheduler's address; the client then holds nothing but its ``Client``.

The child lives exactly as long as the caller wants it, whatever happens to the caller:
- it reads its standard input until end-of-file, which comes when the caller closes it, exits,
  or is killed (even by ``kill -9``: the kernel closes the pipe), and then closes the cluster,
  whose worker processes end with it;
- it runs in a session of its own, so a terminal's Ctrl-C reaches the caller alone, which stops its
  stream cleanly first (its frames in flight are still being handed back) and closes the cluster
  after.
Knows nothing about faces.
"""
from __future__ import annotations

import logging
import os
import select
import signal
import subprocess
import sys
from contextlib import contextmanager
from typing import Iterator

START_TIMEOUT = 120.0  # seconds for the cluster to start (imports and worker processes on a busy machine)
STOP_TIMEOUT = 60.0  # seconds for it to close once told; then its process group is killed


def serve(n_workers: int, threads_per_worker: int = 1) -> None:
    """The child's side: start the cluster, print its scheduler's address on one line, and keep it
    until standard input ends."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=n_workers, threads_per_worker=threads_per_worker, processes=True,
                      host="127.0.0.1", scheduler_port=0, dashboard_address=None,
                      silence_logs=logging.ERROR) as cluster:
        sys.stdout.write(cluster.scheduler_address + "\n")
        sys.stdout.flush()
        while sys.stdin.buffer.read(4096):  # until the caller closes the pipe, or dies
            pass


@contextmanager
def local_cluster(n_workers: int, threads_per_worker: int = 1,
                  start_timeout: float = START_TIMEOUT) -> Iterator[str]:
    """A LocalCluster of ``n_workers`` processes in a child process; yields its scheduler's address
    (``tcp://127.0.0.1:PORT``) and closes it afterwards. ``RuntimeError`` if it does not start."""
    code = f"from shadowflow.flow.cluster_host import serve; serve({int(n_workers)}, {int(threads_per_worker)})"
    proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            start_new_session=True)
    try:
        ready, _, _ = select.select([proc.stdout], [], [], start_timeout)
        address = proc.stdout.readline().decode(errors="replace").strip() if ready else ""
        if not address.startswith("tcp://"):
            status = proc.poll()
            why = f"it exited with status {status}" if status is not None else f"no address in {start_timeout:.0f} s"
            raise RuntimeError(f"the local Dask cluster did not start ({why})")
        yield address
    finally:
        _stop(proc)


def _stop(proc: subprocess.Popen) -> None:
    """Tell the child to close its cluster (end of its input) and wait; kill its whole process group
    (the child and its workers) if it does not."""
    try:
        proc.stdin.close()
    except OSError:
        pass
    try:
        proc.wait(timeout=STOP_TIMEOUT)
    except subprocess.TimeoutExpired:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait()
    finally:
        proc.stdout.close()
