"""A streaming pipeline: nodes in worker threads joined by bounded queues.

Frames enter from any iterable; each stage runs one node in ``workers`` threads (or, ``ordered``, in one that takes
them in input order); stages are
joined by ``queue.Queue(maxsize=queue_size)``, so a slow stage blocks the ones before it
(backpressure) and at most ``sum(workers) + (stages + 1) * queue_size`` frames are in flight
however long the stream, or ``in_flight`` when that is fewer (frames that hold large arrays: a
long pipeline's queues would otherwise hold dozens of them). Results leave in input order. A node that raises fails only that
frame (see ``run_node``); ``stop()`` (or SIGINT / SIGTERM under ``handle_signals``) stops
taking new frames and lets the frames in flight leave at once, marked ``cancelled`` (a node already running on one
finishes first); frames finished before the stop are emitted as usual.
"""
from __future__ import annotations

import dataclasses
import queue
import threading
import time
from dataclasses import dataclass
from typing import Callable, Iterable, Iterator

from .frame import Frame
from .stream import END, InOrder, Source, Stoppable


def run_node(node, frame: Frame, timeout: float | None = None) -> Frame:
    """Run one node on one frame with fault isolation, a time limit and timing.

    A failed, skipped or cancelled frame passes through untouched. An exception fails the frame with a one-line
    reason that names the frame's source; the node's wall time (s) goes to
    ``frame.meta["timings"][node.name]``. With ``timeout`` (seconds) the node runs on a copy
    of the frame in its own thread; past the limit the frame fails ("timed out") and goes on.
    Python cannot kill a thread: the abandoned call's copy is marked ``cancelled`` (a node
    that checks it, like a fit loop, stops early) and its result is dropped.
    """
    if not frame.ok or frame.skipped or frame.cancelled:
        return frame
    t0 = time.perf_counter()
    try:
        frame = node(frame) if timeout is None else _call_with_timeout(node, frame, timeout)
    except KeyboardInterrupt:
        raise
    except Exception as exc:  # noqa: BLE001 - a node's failure is the frame's, not the stream's
        text = str(exc)
        if not text.startswith(frame.source):
            text = f"{frame.source}: {type(exc).__name__}: {text}"
        frame.fail(node.name, text)
        frame.error = exc
    frame.meta.setdefault("timings", {})[node.name] = time.perf_counter() - t0
    return frame


_abandoned: list[threading.Thread] = []  # node calls left running past their time limit


def wait_for_abandoned(timeout: float) -> int:
    """Give node calls abandoned by a time limit up to ``timeout`` seconds (in all) to end;
    returns how many still run. A process should not exit while one runs inside native code
    (the interpreter's shutdown can abort it): call this first, and leave with ``os._exit``
    if any remain."""
    deadline = time.monotonic() + timeout
    for t in list(_abandoned):
        t.join(max(0.0, deadline - time.monotonic()))
        if not t.is_alive():
            _abandoned.remove(t)
    return len(_abandoned)


def _call_with_timeout(node, frame: Frame, timeout: float) -> Frame:
    work = dataclasses.replace(frame, data=dict(frame.data), meta=dict(frame.meta))
    box: dict = {}

    def call() -> None:
        try:
            box["frame"] = node(work)
        except BaseException as exc:  # noqa: BLE001 - handed to the waiting thread
            box["error"] = exc

    name = getattr(node, "name", "node")
    thread = threading.Thread(target=call, name=f"flow-{name}-call", daemon=True)
    thread.start()
    thread.join(timeout)
    if thread.is_alive():
        work.cancel()
        _abandoned.append(thread)
        raise TimeoutError(f"{frame.source}: timed out after {timeout:g} s in {name}")
    if "error" in box:
        raise box["error"]
    return box["frame"]


@dataclass(frozen=True)
class Stage:
    """A node and how many worker threads run it (at least one: none would never finish a frame). ``ordered``: the
    node takes the frames in input order, whatever order the stages before finished them in (one worker: a node
    that carries state from one frame to the next)."""

    node: object
    workers: int = 1
    ordered: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.workers, int) or self.workers < 1:
            raise ValueError(f"a stage needs at least one worker, not {self.workers!r}")
        if self.ordered and self.workers != 1:
            raise ValueError(f"an ordered stage runs on one worker, not {self.workers}")


class Pipeline(Stoppable):
    """Run frames through stages of nodes concurrently; iterate over ``run`` for results.

    stages: nodes or ``Stage``s in order. queue_size: capacity of each queue between stages.
    in_flight: the most frames between the source and the caller at once (None: as the queues allow).
    on_done: called in input order with each finished (or failed) frame, on the caller's
    thread, before it is yielded. frame_timeout: seconds one node may take on one frame
    (None: no limit), see ``run_node``.
    """

    def __init__(self, stages: Iterable, queue_size: int = 2,
                 on_done: Callable[[Frame], None] | None = None, frame_timeout: float | None = None,
                 in_flight: int | None = None):
        self.stages = [s if isinstance(s, Stage) else Stage(s) for s in stages]
        if not self.stages:
            raise ValueError("a pipeline needs at least one node")
        self.queue_size = max(1, int(queue_size))
        self.on_done = on_done
        self.frame_timeout = frame_timeout
        if in_flight is not None and in_flight < 1:
            raise ValueError(f"in_flight must be at least 1, not {in_flight!r}")
        self.in_flight = in_flight
        super().__init__()
        self._lock = threading.Lock()
        self._in_flight = 0
        self.max_in_flight = 0  # observed, for tests and benchmarks

    def run(self, frames: Iterable[Frame], handle_signals: bool = False) -> Iterator[Frame]:
        queues = [queue.Queue(maxsize=self.queue_size) for _ in range(len(self.stages) + 1)]
        slots = None if self.in_flight is None else threading.Semaphore(self.in_flight)
        source = Source(frames, queues[0], self._stop, ends=self.stages[0].workers, on_take=self._took, slots=slots)
        threads = []
        for i, stage in enumerate(self.stages):
            remaining = [stage.workers]
            for k in range(stage.workers):
                name = f"flow-{getattr(stage.node, 'name', i)}-{k}"
                threads.append(threading.Thread(target=self._work, args=(queues, i, remaining), name=name,
                                                daemon=True))
        with self.signals(handle_signals):
            source.start()
            for t in threads:
                t.start()
            try:
                yield from self._emit(queues[-1], slots)
            finally:
                source.close()
        if source.errors:
            raise source.errors[0]

    def _took(self) -> None:
        with self._lock:
            self._in_flight += 1
            self.max_in_flight = max(self.max_in_flight, self._in_flight)

    def _work(self, queues: list[queue.Queue], i: int, remaining: list[int]) -> None:
        """A worker of stage ``i``: each frame through its node, until the stage before has ended; the
        stage's last worker to end tells every worker of the next one."""
        stage, q_in, q_out = self.stages[i], queues[i], queues[i + 1]
        # an ordered stage's one worker holds what comes early until the frames before it have come (every frame
        # reaches every stage, failed or cancelled ones too, so none is waited for in vain)
        order: InOrder[tuple[int, Frame]] | None = InOrder() if stage.ordered else None
        while True:
            item = q_in.get()
            if item is END:
                with self._lock:
                    remaining[0] -= 1
                    last = remaining[0] == 0
                if last:
                    for _ in range(self.stages[i + 1].workers if i + 1 < len(self.stages) else 1):
                        q_out.put(END)
                return
            if order is None:
                q_out.put(self._step(stage, *item))
                continue
            order.put(item[0], item)
            for seq, frame in order.ready():
                q_out.put(self._step(stage, seq, frame))

    def _step(self, stage: Stage, seq: int, frame: Frame) -> tuple[int, Frame]:
        """``(seq, frame)`` after the stage's node."""
        if self._stop.is_set():
            frame.cancel()  # stopped: unfinished frames leave without more work
        try:
            frame = run_node(stage.node, frame, self.frame_timeout)
        except BaseException as exc:  # noqa: BLE001 - KeyboardInterrupt inside a worker
            frame.fail(getattr(stage.node, "name", "node"), f"{frame.source}: interrupted ({exc!r})")
            self._stop.set()
        return seq, frame

    def _emit(self, out: queue.Queue, slots: threading.Semaphore | None) -> Iterator[Frame]:
        """The last stage's frames in input order (``on_done`` first; its slot given back after), until it
        has ended."""
        order: InOrder[Frame] = InOrder()
        while (item := out.get()) is not END:
            order.put(*item)
            for frame in order.ready():
                with self._lock:
                    self._in_flight -= 1
                if self.on_done is not None:
                    self.on_done(frame)
                if slots is not None:
                    slots.release()
                yield frame
