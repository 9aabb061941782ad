"""What every stream engine shares (``Pipeline`` on threads, ``DaskPipeline`` on a cluster): the stop
flag and its signals, the source read on a thread of its own, and the re-order buffer that lets
frames leave in input order. Knows nothing about what the frames hold.
"""
from __future__ import annotations

import contextlib
import queue
import signal
import threading
from typing import Callable, Generic, Iterable, Iterator, TypeVar

from .frame import Frame

END = object()  # end-of-stream marker

T = TypeVar("T")


class Stoppable:
    """A stream engine's stop flag: ``stop()`` asks it to take no new frames; SIGINT / SIGTERM call it
    under ``handle_signals``."""

    def __init__(self) -> None:
        self._stop = threading.Event()

    def stop(self) -> None:
        """Take no new frames; unfinished frames in flight are emitted ``cancelled``."""
        self._stop.set()

    @property
    def stopped(self) -> bool:
        return self._stop.is_set()

    @contextlib.contextmanager
    def signals(self, handle: bool) -> Iterator[None]:
        """With ``handle`` (and on the main thread), SIGINT / SIGTERM call ``stop()`` while the block runs;
        a second one raises ``KeyboardInterrupt`` (stop now). The previous handlers come back after."""
        if not handle or threading.current_thread() is not threading.main_thread():
            yield
            return

        def handler(signum, _frame):
            if self.stopped:  # second signal: stop now
                raise KeyboardInterrupt
            self.stop()

        previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
        try:
            yield
        finally:
            for sig, h in previous.items():
                signal.signal(sig, h)


class Source:
    """The frames of a run read on a thread of their own (a watched folder may block) into ``queue`` as
    ``(seq, frame)``, then ``ends`` x ``END``. It stops taking frames once ``stop`` is set or ``close()``
    is called; ``on_take`` is called before each frame goes in (e.g. to count the frames in flight);
    with ``slots`` it takes one of them before each frame (the engine gives it back when the frame
    leaves), so at most that many frames are in flight; ``errors``: what broke the source, for the run
    to raise after its frames."""

    def __init__(self, frames: Iterable[Frame], into: queue.Queue, stop: threading.Event, ends: int = 1,
                 on_take: Callable[[], None] | None = None, name: str = "flow-source",
                 slots: threading.Semaphore | None = None):
        self.queue, self.errors, self.slots = into, [], slots
        self._stop, self._closing, self._ends, self._on_take = stop, threading.Event(), ends, on_take
        self._thread = threading.Thread(target=self._feed, args=(frames,), name=name, daemon=True)

    def start(self) -> None:
        self._thread.start()

    def close(self) -> None:
        """The run is over: the source stops at its next frame."""
        self._closing.set()

    def _ended(self) -> bool:
        return self._stop.is_set() or self._closing.is_set()

    def _feed(self, frames: Iterable[Frame]) -> None:
        try:
            for item in enumerate(frames):
                if self._ended() or not self._slot():
                    break
                if self._on_take is not None:
                    self._on_take()
                # a frame taken is handed on (a stopped engine emits it cancelled) unless the run is over
                while not self._closing.is_set():
                    try:
                        self.queue.put(item, timeout=0.2)
                        break
                    except queue.Full:
                        continue
        except BaseException as exc:  # noqa: BLE001 - a broken source ends the stream, reported by the run
            self.errors.append(exc)
        finally:
            for _ in range(self._ends):
                self.queue.put(END)

    def _slot(self) -> bool:
        """A slot taken (waiting while every one is in flight); False when the stream ended meanwhile."""
        if self.slots is None:
            return True
        while not self.slots.acquire(timeout=0.2):
            if self._ended():
                return False
        return True

    def get(self, timeout: float):
        """The next ``(seq, frame)``, ``END`` after the last, or None when none came within ``timeout`` s."""
        try:
            return self.queue.get(timeout=timeout)
        except queue.Empty:
            return None


class InOrder(Generic[T]):
    """The re-order buffer: items put by sequence number as they finish (``put``), taken in sequence order
    (``ready``) as soon as every earlier one has been. ``pending``: seq -> item, not yet taken."""

    def __init__(self) -> None:
        self.pending: dict[int, T] = {}
        self.next_seq = 0

    def put(self, seq: int, item: T) -> None:
        self.pending[seq] = item

    def finished(self, item: T) -> bool:
        """Whether ``item`` may leave (an engine may keep unfinished work in ``pending`` too)."""
        return True

    def ready(self) -> Iterator[T]:
        """The items whose turn has come, in sequence order."""
        while self.next_seq in self.pending and self.finished(self.pending[self.next_seq]):
            item = self.pending.pop(self.next_seq)
            self.next_seq += 1
            yield item
