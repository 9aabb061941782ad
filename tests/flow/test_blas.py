"""BLAS on one thread, set from the main thread only: a frame's thread entering and leaving the limit does not
change it under the main thread's work."""
from __future__ import annotations

import threading

import numpy  # noqa: F401  (loads the BLAS the limit applies to)
from shadowflow.flow.blas import single_threaded_blas
from threadpoolctl import threadpool_info, threadpool_limits


def _blas_threads() -> list[int]:
    return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]


def test_a_frame_thread_leaving_the_limit_does_not_lift_the_main_threads():
    with threadpool_limits(limits=2, user_api="blas"):  # two to start from on any machine
        assert _blas_threads() and all(n == 2 for n in _blas_threads())
        inside, leave = threading.Event(), threading.Event()

        def frame_thread() -> None:
            with single_threaded_blas():  # entered before the main thread's, left during it
                inside.set()
                leave.wait(5)

        t = threading.Thread(target=frame_thread)
        t.start()
        inside.wait(5)
        with single_threaded_blas():
            leave.set()
            t.join(5)
            during = _blas_threads()
        after = _blas_threads()
    assert all(n == 1 for n in during)
    assert all(n == 2 for n in after)


def test_only_the_main_thread_sets_the_limit(monkeypatch):
    """The limit is process-wide and each setter puts back what it found: a frame's thread that set it would
    put two threads back under the main thread's one-thread work when it left first."""
    import threadpoolctl

    calls = []

    class Recorder:
        def __init__(self, limits, user_api):
            calls.append((threading.current_thread().name, limits, user_api))

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

    monkeypatch.setattr(threadpoolctl, "threadpool_limits", Recorder)

    def frame_thread() -> None:
        with single_threaded_blas():
            pass

    t = threading.Thread(target=frame_thread, name="frame")
    t.start()
    t.join(5)
    assert calls == []
    with single_threaded_blas():
        pass
    assert calls == [(threading.main_thread().name, 1, "blas")]
