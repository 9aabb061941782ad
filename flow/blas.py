"""BLAS (OpenBLAS, MKL) on one thread, set from the main thread only.

``threadpoolctl.threadpool_limits`` sets a process-wide limit and, on leaving, puts back the limit it found.
Entered from a frame's thread it races the main thread's own: leaving first, it puts back two threads in
the middle of the main thread's one-thread work; and OpenBLAS 0.3.31 ignores a limit set from another
thread while the main thread holds one. So only the main thread sets it: a run, a fit or an evaluation holds
it there around the frames' threads, which then work under it. (Models are built in a process of their own,
``nodes.model.default_model``, so their bits do not depend on any of this.)
"""
from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def single_threaded_blas() -> Iterator[None]:
    """BLAS on one thread inside, when called from the main thread; elsewhere nothing changes (the main
    thread's limit, if it holds one, applies)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        yield
