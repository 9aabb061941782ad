"""A sequential chain of nodes with per-frame fault isolation."""
from __future__ import annotations

from typing import Callable, Iterable, Iterator, Protocol

from .frame import Frame
from .pipeline import run_node


class Node(Protocol):
    """A step: ``name`` and ``__call__(frame) -> frame``; raise to fail the frame."""

    name: str

    def __call__(self, frame: Frame) -> Frame: ...


class Chain:
    """Runs each frame through ``nodes`` in order.

    An exception inside a node fails that frame (status = the exception's one-line text,
    ``failed_in`` = the node) and skips its remaining nodes; the stream goes on. Per-node
    wall times (seconds) are kept in ``frame.meta["timings"]``; ``frame_timeout`` as in ``run_node``.
    """

    def __init__(self, nodes: Iterable[Node], on_done: Callable[[Frame], None] | None = None,
                 frame_timeout: float | None = None):
        self.nodes = list(nodes)
        self.on_done = on_done
        self.frame_timeout = frame_timeout

    def process(self, frame: Frame) -> Frame:
        for node in self.nodes:
            frame = run_node(node, frame, self.frame_timeout)
        if self.on_done is not None:
            self.on_done(frame)
        return frame

    def run(self, frames: Iterable[Frame]) -> Iterator[Frame]:
        for frame in frames:
            yield self.process(frame)
