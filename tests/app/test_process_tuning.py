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


def test_a_fits_megabyte_arrays_reuse_the_heaps_pages_and_a_photos_large_ones_go_back():
    """After ``release_large_frees``: a 3 MB array (a 128² fit's (2N, K) product is 1.8-3.7 MB) made and freed 40
    times is given its pages once, not each time (the mmap threshold alone fixed the trim threshold at 128 kiB, and
    each came from freshly zeroed pages: the fit took 48 ms instead of 35); a 64 MB array (a photo's plane) goes
    back to the system when freed."""
    import resource

    import numpy as np
    from shadowflow.nodes.app.process import _libc_function, release_large_frees

    if _libc_function("mallopt") is None:
        pytest.skip("not glibc")
    try:
        _rss_kib()
    except OSError:
        pytest.skip("no /proc")
    release_large_frees()
    pages = (3 << 20) // resource.getpagesize()
    np.ones(3 << 18, np.float32)  # the heap grown once
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(40):
        np.ones(3 << 18, np.float32)
    faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before
    assert faults < 4 * pages, (faults, pages)  # measured: 0; 40 x 768 before
    held = _rss_kib()
    big = np.ones(16 << 20, np.float32)
    assert _rss_kib() > held + (48 << 10)
    del big
    assert _rss_kib() < held + (8 << 10)
