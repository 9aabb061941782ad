"""``ScalarsTap``: a sink that keeps one channel's scalars in memory, so a run can plot its
convergence at the end without reading its recording back (which decompresses every array)."""
from __future__ import annotations

import os

from .events import Event, Kind, Sink


class ScalarsTap(Sink):
    """Keeps the ``SCALARS`` events of ``path`` for the first ``limit`` frames that have any.

    ``series()`` gives ``(name, {iteration: {name: value}})`` per frame in frame order, the form
    ``replay.convergence_figure`` draws; a frame is named by its closing record's ``source``
    (file name only), else ``#<frame id>``. Memory: the scalars of ``limit`` frames.
    """

    def __init__(self, path: str, limit: int):
        self.path, self.limit = path, limit
        self._rows: dict[int, dict[int | None, dict]] = {}
        self._names: dict[int, str] = {}

    def write(self, event: Event) -> None:
        if event.kind is Kind.FRAME:
            source = event.value.get("source") if isinstance(event.value, dict) else None
            if event.frame in self._rows and isinstance(source, str) and source:
                self._names[event.frame] = os.path.basename(source)
            return
        if event.kind is not Kind.SCALARS or event.path != self.path:
            return
        if event.frame not in self._rows and len(self._rows) >= self.limit:
            return
        self._rows.setdefault(event.frame, {})[event.iteration] = dict(event.value)

    def series(self) -> list[tuple[str, dict[int | None, dict]]]:
        return [(self._names.get(f, f"#{f}"), rows) for f, rows in sorted(self._rows.items())]
