"""A sequential chain of nodes with per-frame fault isolation."""
from __future__ import annotations

import time
from typing import Callable, Iterable, Iterator, Protocol

from flow.frame import Frame


class Node(Protocol):
    """A step: ``name`` and ``__call__(frame) -> frame``; raise to fail the frame."""

    name: str

    def __call__(self, frame: Frame) -> Frame: ...


class Chain:
    """Runs each frame through ``nodes`` in order.

    An exception inside a node fails that frame (status = the exception's one-line text,
    ``failed_in`` = the node) and skips its remaining nodes; the stream goes on. Per-node
    wall times (seconds) are kept in ``frame.meta["timings"]``.
    """

    def __init__(self, nodes: Iterable[Node], on_done: Callable[[Frame], None] | None = None):
        self.nodes = list(nodes)
        self.on_done = on_done

    def process(self, frame: Frame) -> Frame:
        timings = frame.meta.setdefault("timings", {})
        for node in self.nodes:
            if not frame.ok:
                break
            t0 = time.perf_counter()
            try:
                frame = node(frame)
            except KeyboardInterrupt:
                raise
            except Exception as exc:  # noqa: BLE001 - a node's failure is the frame's, not the stream's
                text = str(exc)
                if not text.startswith(frame.source):
                    text = f"{frame.source}: {type(exc).__name__}: {text}"
                frame.fail(node.name, text)
            timings[node.name] = time.perf_counter() - t0
        if self.on_done is not None:
            self.on_done(frame)
        return frame

    def run(self, frames: Iterable[Frame]) -> Iterator[Frame]:
        for frame in frames:
            yield self.process(frame)
