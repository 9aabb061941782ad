"""What a run keeps in its output folder as its frames finish: each frame's record in the run's store, its entry
in the manifest's journal, ``summary.json`` and the manifest. The first storage failure (the folder full,
read-only or over quota, or removed or replaced under the run) stops the run, said once."""
from __future__ import annotations

import math
import time
from pathlib import Path

from ...flow.files import FolderLock
from ...flow.frame import Frame
from ...flow.manifest import JOURNAL_NAME, MANIFEST_NAME, InputEntry, Journal, RunManifest
from ...flow.runstore import RunStore
from .outputs import write_summary
from .storage import cannot_write


class RunLedger:
    """The books of one run into a locked ``out`` (``lock``; None: not locked): ``store`` (the records and
    input entries, on disk), ``manifest`` and its journal (opened here, once the manifest is saved),
    ``summary.json``. ``storage``: the first storage failure, which stops ``pipeline`` (the engine, once
    made); ``shout``: how an error is said."""

    def __init__(self, out: Path, store: RunStore, manifest: RunManifest, lock: FolderLock | None, shout):
        self.out, self.store, self.manifest, self.lock, self.shout = out, store, manifest, lock, shout
        self.config_id = manifest.config_id
        self.storage: str | None = None  # the first storage failure, which stops the run
        self.summary_clock = {"last": -math.inf, "cost": 0.0}  # the first frame's record is written at once
        self.pipeline = None  # the engine, which a storage failure stops: set once it is made
        self.journal = Journal(out)

    def folder_lost(self) -> bool:
        """``out`` was removed or replaced under the run (its ``.lock`` is not the one this run holds): said once,
        and the run stops writing there (a run started into it since holds it now)."""
        if self.lock is None or self.lock.held():
            return False
        self.out_of_storage(f"{self.out}: removed or replaced during the run (its .lock is not this run's); "
                            "nothing more is written there")
        return True

    def out_of_storage(self, why: str) -> None:
        if self.storage is None:
            self.storage = why
            self.shout(f"error: {why}; stopping (free space or make it writable, then run again with --resume)")
        if self.pipeline is not None:
            self.pipeline.stop()

    def save_summary(self, force: bool = False) -> None:
        """summary.json, rewritten whole: at the end, and meanwhile no more often than keeps its cost
        under 5 % of the run (the journal already holds every finished frame)."""
        clock = self.summary_clock
        now = time.monotonic()
        if not force and now - clock["last"] < max(1.0, 20.0 * clock["cost"]):
            return
        t0 = time.perf_counter()
        try:
            write_summary(self.out, self.store.records)
        except OSError as exc:
            self.out_of_storage(cannot_write(self.out / "summary.json", exc))
        clock.update(last=time.monotonic(), cost=time.perf_counter() - t0)

    def save_manifest(self) -> None:
        """manifest.json rewritten mid-run (it folds the journal in and removes it: a new one follows)."""
        try:
            self.manifest.save(self.out)
            self.journal.reopen()
        except OSError as exc:
            self.out_of_storage(cannot_write(self.out / MANIFEST_NAME, exc))

    def compact_manifest(self) -> None:
        """manifest.json written at the end, the journal folded in; a note when it cannot be (the journal keeps
        what it could not fold in: --resume reads both)."""
        try:
            self.manifest.save(self.out)
        except OSError as exc:
            self.shout(f"note: {self.out / MANIFEST_NAME}: not compacted ({exc.strerror or exc})")

    def journal_append(self, entry: InputEntry) -> None:
        try:
            self.manifest.entries[entry.path] = entry
            self.journal.append(entry)
        except OSError as exc:
            self.out_of_storage(cannot_write(exc.filename or self.out / JOURNAL_NAME, exc))

    def journal_entry(self, frame: Frame, rec: dict) -> None:
        size, mtime = frame.meta.get("identity") or (-1, -1)
        self.journal_append(InputEntry(frame.meta["input_key"], size, mtime, frame.meta["stem"], frame.id,
                                       self.config_id, rec, frame.meta.get("sha256", "")))

    def stored(self, name: str, rec: dict) -> bool:
        """The frame's record put in the store; False (and the run stops) when the folder takes no more."""
        try:
            self.store.put_record(name, rec)
            return True
        except OSError as exc:
            self.out_of_storage(cannot_write(exc.filename, exc))
            return False

    def drop_record(self, name: str) -> None:
        try:
            self.store.drop_record(name)
        except OSError:
            pass  # the store takes no more either: the run is stopping, and says why already
