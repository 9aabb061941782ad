"""The unit of work that travels between nodes."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


class FrameFailed(Exception):
    """Raised by a node to fail the current frame with a one-line reason."""


@dataclass
class Frame:
    """One input travelling through the pipeline.

    id: position in the stream (results are emitted in this order); source: where it came
    from (a path, or a name for generated input); data: named arrays and objects produced
    by nodes; meta: JSON-serialisable facts for the summary; status: "ok" or the one-line
    reason it failed; failed_in: the node that failed it; parts: frames of its own that one input
    became (e.g. each object found in it), each run through the nodes wrapped by ``EachPart`` and
    failing alone.
    """

    id: int
    source: str
    data: dict[str, Any] = field(default_factory=dict)
    meta: dict[str, Any] = field(default_factory=dict)
    status: str = "ok"
    failed_in: str | None = None
    skipped: bool = False  # passes through every node untouched (e.g. already done: resume)
    cancelled: bool = False  # the stream was stopped before this frame finished: not a result
    error: BaseException | None = field(default=None, repr=False)  # what failed it, if an exception
    parts: list[Frame] = field(default_factory=list, repr=False)

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def fail(self, node: str, reason: str) -> None:
        """Mark the frame failed; ``reason`` is folded to one line."""
        self.status = " ".join(str(reason).split()) or "failed"
        self.failed_in = node

    def cancel(self) -> None:
        """Mark the frame and its parts ``cancelled`` (a node working on any of them may stop early)."""
        self.cancelled = True
        for part in self.parts:
            part.cancel()

    def drop_data(self) -> None:
        """Let go of the frame's arrays and its parts' (their files are written); meta and status stay."""
        self.data = {}
        for part in self.parts:
            part.drop_data()
