"""What a run says on the terminal: a line on stderr (``say``), and the status line of a run's progress
(``Progress``)."""
from __future__ import annotations

import sys

from ...flow.replay.text import one_line


def say(line: str) -> None:
    """``line`` on stderr in one write (``print`` writes the text and its newline apart, and a writer on another
    thread between the two runs two lines into one), on one line: its control characters (a file name's escape
    sequences, BEL, C1 codes, newlines) written as Python escapes, so a name can neither drive the terminal nor
    forge a line of its own."""
    sys.stderr.write(one_line(line) + "\n")
    sys.stderr.flush()


class Progress:
    """One status line on a terminal (tqdm): done / total, frames per second, ETA, failures."""

    def __init__(self, total: int | None, enabled: bool, silent: bool = False):
        from tqdm import tqdm

        self.failed, self.silent = 0, silent
        self.bar = tqdm(total=total, unit="frame", disable=not (enabled and sys.stderr.isatty()),
                        dynamic_ncols=True, leave=True, file=sys.stderr)

    def update(self, ok: bool) -> None:
        if not ok:
            self.failed += 1
            self.bar.set_postfix_str(f"{self.failed} failed", refresh=False)
        self.bar.update(1)

    def grow(self, more: int) -> None:
        """``more`` frames to go than the total said (a clip counted as one input, then as its frames)."""
        if self.bar.total is not None and more > 0:
            self.bar.total += more
            self.bar.refresh()

    def write(self, line: str) -> None:
        """A line on stderr above the status line (which is redrawn below it), in one write (``say``); none when
        ``silent``."""
        if self.silent:
            return
        if self.bar.disable:
            say(line)
        else:
            self.bar.write(one_line(line), file=sys.stderr)

    def close(self) -> None:
        self.bar.close()
