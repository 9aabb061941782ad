"""``Recorder``: takes events from any thread and writes them to its sinks on one thread of its own."""
from __future__ import annotations

import queue
import threading
from dataclasses import dataclass, replace

import numpy as np

from .events import ARRAY_KINDS, Event, Kind, OnMask, Sink


@dataclass
class RecordOptions:
    """every: keep iterations 1, 1 + every, ... and the last; float16: store float arrays as
    float16 (half the bytes, about 3 significant digits); own_process: the file sinks write in a
    process of their own (``ProcessSinks``), else on the recorder's thread."""

    every: int = 1
    float16: bool = False
    own_process: bool = True

    def keep(self, iteration: int, last: bool = False) -> bool:
        """Is fit iteration ``iteration`` (1-based) recorded? 1, 1 + every, ... and the last."""
        return last or self.every <= 1 or (iteration - 1) % self.every == 0


class Recorder:
    """Collects events from any thread and writes them on its own thread.

    ``emit`` blocks when ``max_pending`` events are waiting (backpressure instead of
    unbounded memory). Errors in a sink are kept and raised by ``close``.
    """

    def __init__(self, sinks: list[Sink], options: RecordOptions | None = None, max_pending: int = 256):
        self.sinks = sinks
        self.options = options or RecordOptions()
        self._q: queue.Queue = queue.Queue(maxsize=max_pending)
        self._error: BaseException | None = None
        self._closed_frames = 0  # frames flushed by every sink (or dropped after an error)
        self._asked = 0  # frames handed to frame_done
        self._closed = False
        self._flushed = threading.Condition()
        self._thread = threading.Thread(target=self._loop, name="flow-recorder", daemon=True)
        self._thread.start()

    @property
    def error(self) -> BaseException | None:
        """The first error a sink raised (recording stopped there), or None."""
        return self._error

    def keep_iteration(self, iteration: int, last: bool = False) -> bool:
        return self.options.keep(iteration, last)

    def emit(self, event: Event) -> None:
        if self.options.float16 and event.kind in ARRAY_KINDS:
            v = event.value
            a = v.values if isinstance(v, OnMask) else np.asarray(v)
            if a.dtype.kind == "f":
                half = a.astype(np.float16)
                event = replace(event, value=OnMask(half, v.mask) if isinstance(v, OnMask) else half)
        self._put(("event", event))

    def name_frame(self, frame: int, name: str | None) -> None:
        """Tell the sinks what frame ``frame`` is called (its events, queued after this, use it)."""
        if name:
            self._put(("name", (frame, name)))

    def frame_done(self, frame: int, record: dict, wait: bool = False) -> None:
        """Close a frame: its status record, then every sink flushes it to disk. ``wait``:
        return only once that is done (so a caller can then mark the frame finished)."""
        if self._closed:
            return
        self._put(("event", Event(frame, "frames", Kind.FRAME, record)))
        self._put(("done", frame))
        self._asked += 1
        if wait:
            target = self._asked
            with self._flushed:
                self._flushed.wait_for(lambda: self._closed_frames >= target or not self._thread.is_alive())

    def _put(self, item: tuple) -> None:
        """Queue ``item``, waiting while the queue is full; after ``close`` it is dropped (a
        cancelled task still running must not block on a queue nobody empties)."""
        while not self._closed:
            try:
                self._q.put(item, timeout=0.5)
                return
            except queue.Full:
                continue

    def _loop(self) -> None:
        while True:
            kind, item = self._q.get()
            if kind == "stop":
                return
            if self._error is None:  # after an error nothing more is written; close() reports it
                try:
                    for s in self.sinks:
                        if kind == "event":
                            s.write(item)
                        elif kind == "name":
                            s.name_frame(*item)
                        else:
                            s.frame_done(item)
                except BaseException as exc:  # noqa: BLE001 - reported by close()
                    self._error = exc
            if kind == "done":
                with self._flushed:
                    self._closed_frames += 1
                    self._flushed.notify_all()

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._q.put(("stop", None))
        self._thread.join()
        for s in self.sinks:
            try:
                s.close()
            except BaseException as exc:  # noqa: BLE001
                self._error = self._error or exc
        if self._error is not None:
            raise RuntimeError(f"recording failed: {self._error}") from self._error

