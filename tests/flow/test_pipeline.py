"""The engine on toy nodes: order, backpressure, fault isolation, stopping, skipping."""
import threading
import time

import pytest
from shadowflow.flow import Chain, Frame, Pipeline, Stage


class Sleepy:
    """Sleeps a frame-dependent time so frames finish out of order; fails on request."""

    def __init__(self, name, fail_ids=(), delay=0.002):
        self.name, self.fail_ids, self.delay = name, set(fail_ids), delay
        self.seen = []
        self.lock = threading.Lock()

    def __call__(self, frame):
        time.sleep(self.delay * ((frame.id * 7) % 5))
        if frame.id in self.fail_ids:
            raise ValueError("boom\non two lines")
        with self.lock:
            self.seen.append(frame.id)
        frame.data.setdefault("trail", []).append(self.name)
        return frame


def frames(n):
    return (Frame(i, f"item-{i}") for i in range(n))


@pytest.mark.parametrize("workers", [1, 3])
def test_results_in_input_order_with_failures_isolated(workers):
    a, b, c = Sleepy("a"), Sleepy("b", fail_ids={5, 17}), Sleepy("c")
    out = list(Pipeline([a, Stage(b, workers), c], queue_size=2).run(frames(40)))
    assert [f.id for f in out] == list(range(40))
    failed = [f for f in out if not f.ok]
    assert [f.id for f in failed] == [5, 17]
    assert failed[0].status == "item-5: ValueError: boom on two lines" and failed[0].failed_in == "b"
    assert 5 not in c.seen and len(c.seen) == 38  # later nodes skip a failed frame
    assert all(f.data["trail"] == ["a", "b", "c"] for f in out if f.ok)


@pytest.mark.parametrize("in_flight", [None, 3])
def test_an_ordered_stage_takes_frames_in_input_order_after_a_stage_of_many_workers(in_flight):
    """A node that carries state from frame to frame (a clip's steadying) is given them in order, however the stages
    before it finished them, failed ones included (they pass it by)."""
    first, carried, after = Sleepy("first", fail_ids={7}), Sleepy("carried"), Sleepy("after")
    stages = [Stage(first, 3), Stage(carried, ordered=True), Stage(after, 2)]
    out = list(Pipeline(stages, queue_size=2, in_flight=in_flight).run(frames(40)))
    assert carried.seen == [i for i in range(40) if i != 7]
    assert [f.id for f in out] == list(range(40))
    with pytest.raises(ValueError, match="one worker"):
        Stage(carried, 2, ordered=True)


def test_backpressure_bounds_frames_in_flight():
    slow = Sleepy("slow", delay=0.003)
    p = Pipeline([Sleepy("fast", delay=0.0), slow, Sleepy("fast2", delay=0.0)], queue_size=2)
    for _ in p.run(frames(60)):
        pass
    # queues of 2 between 3 one-worker stages, plus the source's queue: never the whole stream
    assert p.max_in_flight <= 3 + 4 * 2


def test_stop_takes_no_more_frames_and_cancels_unfinished_ones():
    a, b = Sleepy("a", delay=0.001), Sleepy("b", delay=0.001)
    p = Pipeline([a, b], queue_size=1)
    got = []
    for f in p.run(frames(1000)):
        got.append(f)
        if f.id == 10:
            p.stop()
    assert [f.id for f in got] == list(range(len(got))) and 11 <= len(got) < 20
    assert all(not f.cancelled for f in got[:11]) and all(f.cancelled for f in got[12:])
    assert all("b" not in f.data.get("trail", []) for f in got[12:])


def test_skipped_frames_pass_through_in_order():
    a = Sleepy("a")
    src = list(frames(6))
    src[2].skipped = True
    out = list(Pipeline([a]).run(src))
    assert [f.id for f in out] == list(range(6)) and 2 not in a.seen and out[2].ok


def test_chain_is_the_same_engine_sequentially():
    out = list(Chain([Sleepy("a", delay=0), Sleepy("b", fail_ids={1}, delay=0)]).run(frames(3)))
    assert [f.ok for f in out] == [True, False, True]
    assert set(out[0].meta["timings"]) == {"a", "b"}


def test_in_flight_bounds_the_frames_between_source_and_caller():
    """A long pipeline's queues would hold a dozen frames; ``in_flight`` holds it to a few, in order,
    and a stop while the source waits for a slot still ends the stream."""
    stages = [Sleepy(f"s{k}", delay=0.0) for k in range(6)] + [Sleepy("slow", delay=0.002)]
    p = Pipeline(stages, queue_size=2, in_flight=2)
    out = [f.id for f in p.run(frames(50))]
    assert out == list(range(50)) and p.max_in_flight == 2
    free = Pipeline(stages, queue_size=2)
    assert [f.id for f in free.run(frames(50))] == list(range(50)) and free.max_in_flight > 4
    stopping = Pipeline([Sleepy("a", delay=0.001)], in_flight=1)
    got = []
    for f in stopping.run(frames(1000)):
        got.append(f)
        if f.id == 3:
            stopping.stop()
    assert 4 <= len(got) < 10
    with pytest.raises(ValueError):
        Pipeline(stages, in_flight=0)


def test_a_cancel_waits_for_a_running_step_and_no_step_starts_after_it():
    """A node abandoned by a time limit keeps running on its own copy of the frame: a step it takes under
    ``while_running`` (its fit reporting an iteration to the recording) cannot straddle the cancel, so nothing
    it says arrives after the run has closed the frame (a late iteration reopened it in the recording)."""
    frame = Frame(0, "photo", parts=[Frame(0, "face")])
    part = frame.parts[0]
    inside, release, seen = threading.Event(), threading.Event(), []

    def step() -> None:
        with part.while_running() as going:
            seen.append(going)
            inside.set()
            release.wait(5)
            seen.append("step done")

    worker = threading.Thread(target=step)
    worker.start()
    assert inside.wait(5)
    canceller = threading.Thread(target=lambda: (frame.cancel(), seen.append("cancelled")))
    canceller.start()
    canceller.join(0.2)
    assert canceller.is_alive() and seen == [True]  # the cancel waits for the step under way
    release.set()
    worker.join(5)
    canceller.join(5)
    assert seen == [True, "step done", "cancelled"] and part.cancelled
    with part.while_running() as going:
        assert not going  # and a step after it is told the frame is gone
