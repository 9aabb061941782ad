"""Hostile use of the engine itself (``flow.pipeline``): a node that hangs or raises fails only its frame,
and a stage that could never finish a frame is refused. Moved here from the app's hostile suite."""
import time

import pytest
from shadowflow.flow.frame import Frame
from shadowflow.flow.pipeline import Pipeline


class _Sleepy:
    """A node that hangs on frames whose source contains 'hang' (and raises on 'boom')."""

    name = "sleepy"

    def __call__(self, frame: Frame) -> Frame:
        if "hang" in frame.source:
            time.sleep(30)
        if "boom" in frame.source:
            raise RuntimeError("exploded")
        frame.data["seen"] = True
        return frame


def test_a_hanging_or_raising_node_fails_only_its_frame():
    sources = ["a", "hang-1", "b", "boom", "c"]
    t0 = time.perf_counter()
    frames = list(Pipeline([_Sleepy()], frame_timeout=0.5).run(Frame(i, s) for i, s in enumerate(sources)))
    assert time.perf_counter() - t0 < 10  # not 30 s: the hung call was abandoned
    assert [f.source for f in frames] == sources
    assert [f.ok for f in frames] == [True, False, True, False, True]
    assert "timed out after 0.5 s in sleepy" in frames[1].status and frames[1].failed_in == "sleepy"
    assert "RuntimeError: exploded" in frames[3].status
    assert all(f.data.get("seen") for f in frames if f.ok)


def test_a_stage_without_workers_is_refused_by_the_engine():
    from shadowflow.flow.pipeline import Stage

    with pytest.raises(ValueError, match="at least one worker"):
        Stage(lambda f: f, 0)
