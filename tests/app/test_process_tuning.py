"""Process-wide tuning (``nodes/app/process.py``): the heap's freed pages given back."""
import ctypes
import ctypes.util

import pytest
from shadowflow.nodes.app.process import HeapTrimmer


def _rss_kib() -> int:
    return next(int(line.split()[1]) for line in open("/proc/self/status") if line.startswith("VmRSS"))


def test_the_heap_trimmer_gives_back_freed_pages_held_below_a_live_block_and_no_more_often_than_its_period():
    """64 MiB freed in 64 kB blocks, every other one of 2,048 (each between two still in use, so
    no freed block joins another or the heap's top), stays resident: glibc returns free memory by
    itself only from the top. The trimmer gives it back, then waits out its period."""
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
        blocks = [libc.malloc(64 << 10) for _ in range(2048)]
        for b in blocks:
            libc.memset(b, 1, 64 << 10)
        for b in blocks[1::2]:
            libc.free(b)
        trim = HeapTrimmer(period=3600.0)
        trim._last -= 3600.0
        held = _rss_kib()
        assert trim() is True
        given_back = held - _rss_kib()
        assert trim() is False  # within its period
        for b in blocks[::2]:
            libc.free(b)
    finally:
        libc.mallopt(-1, 128 << 10)
    assert given_back > 48 << 10, given_back
