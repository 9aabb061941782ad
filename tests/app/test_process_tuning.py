"""Process-wide tuning (``nodes/app/process.py``): the heap's freed pages given back."""
import ctypes
import ctypes.util

import pytest
from shadowflow.nodes.app.process import HeapTrimmer


def _rss_kib() -> int:
    return next(int(line.split()[1]) for line in open("/proc/self/status") if line.startswith("VmRSS"))


def test_the_heap_trimmer_gives_back_freed_pages_held_below_a_live_block_and_no_more_often_than_its_period():
    """64 MiB freed in 64 kB blocks, each below a small block still in use, stays resident (glibc
    returns free memory by itself only from the heap's top); the trimmer gives it back, then waits
    out its period."""
    name = ctypes.util.find_library("c")
    libc = ctypes.CDLL(name) if name else None
    if libc is None or not hasattr(libc, "malloc_trim") or not hasattr(libc, "mallopt"):
        pytest.skip("not glibc")
    try:
        _rss_kib()
    except OSError:
        pytest.skip("no /proc")
    libc.malloc.restype = ctypes.c_void_p
    libc.free.argtypes = [ctypes.c_void_p]
    libc.memset.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_size_t]
    libc.mallopt(-1, 1 << 30)  # M_TRIM_THRESHOLD: nothing given back by free() itself
    libc.mallopt(-3, 1 << 20)  # M_MMAP_THRESHOLD: the blocks from the heap
    try:
        blocks, pins = [], []
        for _ in range(1024):
            blocks.append(libc.malloc(64 << 10))
            libc.memset(blocks[-1], 1, 64 << 10)
            pins.append(libc.malloc(64))  # after each: the freed blocks cannot merge into one
        for b in blocks:
            libc.free(b)
        trim = HeapTrimmer(period=3600.0)
        trim._last -= 3600.0
        held = _rss_kib()
        assert trim() is True
        given_back = held - _rss_kib()
        assert trim() is False  # within its period
        for p in pins:
            libc.free(p)
    finally:
        libc.mallopt(-1, 128 << 10)
    assert given_back > 48 << 10, given_back
