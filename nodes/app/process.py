"""Process-wide tuning for the method's work: BLAS on one thread, glibc's allocator told to give
memory back. Used by runs, fits, evaluations and Dask workers alike."""
from __future__ import annotations

from contextlib import contextmanager
from functools import cache
from typing import Callable, Iterator

from ...flow.blas import single_threaded_blas

# glibc's allocator (``release_large_frees``): arrays from 4 MiB (a 1 MP photo's plane) are mapped and given back
# when freed; smaller ones (a fit's buffers, 1-4 MB at 128², a face's box at 4 MP) are reused from the heap, which
# keeps 4 MiB of freed memory at its top before it gives any back
MMAP_THRESHOLD = 4 << 20
TRIM_THRESHOLD = 4 << 20


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Run BLAS (OpenBLAS, MKL) on one thread inside: the fit's matrices are small (K <= 100) and the
    pipeline already runs frames on several threads, so BLAS's own threads only contend. Measured on
    this 2-core machine: 16 demo faces 1.7-1.9 s against 3.4-4.5 s, one fit 51-55 ms against
    166-210 ms (``benchmarks/bench_nodes.py`` without ``OPENBLAS_NUM_THREADS=1``)."""
    with single_threaded_blas():  # shared with the model builds: the last one out puts the limit back
        yield


def release_large_frees() -> None:
    """glibc only: serve arrays of ``MMAP_THRESHOLD`` and more by ``mmap`` (``M_MMAP_THRESHOLD``), so that their
    memory goes back to the system when freed, keep to two malloc arenas (``M_ARENA_MAX``), and let a heap keep
    up to ``TRIM_THRESHOLD`` of freed memory at its top (``M_TRIM_THRESHOLD``).
    By default glibc raises the mmap threshold up to 32 MiB as arrays are freed, and a large
    photo's arrays then stay in per-thread heaps: a 33 MP photo's run peaked at 860 MB RSS
    instead of 660 (``benchmarks/bench_photo.py --scale 25 --jpeg``); and each of the pipeline's
    dozen threads gets an arena of its own, whose freed pieces other threads cannot reuse: RSS
    grew by about 40 kB a frame (192 -> 207 MiB over 360 unrecorded frames; flat with two
    arenas, ``benchmarks/bench_soak.py``). Setting the mmap threshold fixes the trim threshold at its
    128 kiB default too: every array of a megabyte or more, a fit's (2N, K) modes product each step, came
    from fresh pages, zeroed by the kernel, and a 128² face's fit took 48 ms instead of 35 (docs/speed.md).
    Call it before the threads start. Elsewhere: nothing."""
    mallopt = _libc_function("mallopt")
    if mallopt is not None:
        mallopt(-3, MMAP_THRESHOLD)  # M_MMAP_THRESHOLD
        mallopt(-1, TRIM_THRESHOLD)  # M_TRIM_THRESHOLD
        mallopt(-8, 2)  # M_ARENA_MAX


def _libc_function(name: str) -> Callable | None:
    """The C library's function ``name`` (glibc's allocator tuning), or None where there is none."""
    return getattr(_libc(), name, None)


@cache
def _libc():
    """The C library, loaded once a process (``find_library`` runs ``ldconfig``), or None."""
    import ctypes
    import ctypes.util

    path = ctypes.util.find_library("c")
    try:
        return ctypes.CDLL(path) if path else None
    except OSError:
        return None


class HeapTrimmer:
    """glibc only: ``malloc_trim(0)`` (the heap's free pages given back to the system) when called,
    at most once every ``period`` seconds; elsewhere nothing. A burst (e.g. the pipeline's queues
    filling while the recording process is renewed) leaves the heap with tens of MiB freed but
    kept: glibc returns free memory by itself only from the heap's top, and only past a trim
    threshold it has raised to up to 64 MiB by then. Measured: a call takes 2-13 ms."""

    def __init__(self, period: float = 10.0):
        import time

        self.period, self._clock, self._last = period, time.monotonic, time.monotonic()
        self._trim = _libc_function("malloc_trim")

    def __call__(self) -> bool:
        """Trim if ``period`` has passed since the last; True if it did."""
        now = self._clock()
        if self._trim is None or now - self._last < self.period:
            return False
        self._trim(0)
        self._last = self._clock()
        return True
