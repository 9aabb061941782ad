"""The unit of work that travels between nodes."""
from __future__ import annotations

import threading
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, Iterator

# cancelling a frame waits for a step a node takes on one under ``Frame.while_running`` (and the reverse): once
# ``cancel`` returns, no such step is under way or starts, so a node abandoned by a time limit says nothing more
# of a frame the run has already closed (a late iteration of its fit reopened the frame in the recording)
_CANCELLING = threading.Lock()


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
        """Mark the frame and its parts ``cancelled`` (a node working on any of them may stop early); waits for
        a step under ``while_running`` on any of them to end."""
        with _CANCELLING:
            self._mark_cancelled()

    def _mark_cancelled(self) -> None:
        self.cancelled = True
        for part in self.parts:
            part._mark_cancelled()

    @contextmanager
    def while_running(self) -> Iterator[bool]:
        """``with frame.while_running() as going:`` a step (e.g. reporting progress) that ``cancel`` cannot
        interleave with: ``going`` is False if the frame was already cancelled. Keep the step short."""
        with _CANCELLING:
            yield not self.cancelled

    def drop_data(self) -> None:
        """Let go of the frame's arrays and its parts' (their files are written); meta and status stay."""
        self.data = {}
        for part in self.parts:
            part.drop_data()
