"""``shadowflow run``: stream inputs through the method's nodes on the ``flow`` pipeline,
write outputs and recordings, keep ``summary.json`` current after every frame."""
from __future__ import annotations

import dataclasses
import functools
import json
import os
import socket
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

from ...flow.files import FolderLock, exclusive_folder
from ...flow.frame import Frame
from ...flow.jsonsafe import jsonable
from ...flow.manifest import JOURNAL_NAME, MANIFEST_NAME, RunManifest, config_hash
from ...flow.recording import RecordOptions
from ...flow.runstore import RunStore
from ..method.options import MethodOptions
from ..model.shape_model import ShapeModel
from .clips import ClipSink
from .counts import status_lines, tally
from .engine import engine
from .intake import Intake, run_file_clash, run_files
from .ledger import RunLedger
from .outputs import real_path, summary_record
from .process import HeapTrimmer, one_blas_thread, release_large_frees
from .report import LARGE_PHOTOS, REPORT_NAME, CardPictures, write_report
from .sinks import RunRecording
from .storage import check_out, refuse_link, storage_failure
from .terminal import Progress, say

# seconds one step may take on one frame unless told otherwise: a step takes a second or two on a 40-megapixel photo,
# so a frame past this is stuck (a file that costs unbounded work, a hung filesystem), and the run goes on without it
DEFAULT_FRAME_TIMEOUT = 120.0


@dataclass
class RunOptions:
    """record: subset of {"rerun", "mcap"}; fit_workers: threads for the fit node (local engine);
    resume: skip inputs whose outputs are complete; quiet: no progress or notes (errors still said);
    silent: nothing said at all (the API's ``quiet``: its ``RunResult`` and records say everything);
    frame_timeout: seconds any one node may spend on one frame before the frame fails; in_flight: the
    most frames in the local pipeline at once (None: ``frames_in_flight``)."""

    record: tuple[str, ...] = ("rerun", "mcap")
    record_options: RecordOptions = field(default_factory=RecordOptions)
    fit_workers: int = 1
    queue_size: int = 2
    in_flight: int | None = None
    resume: bool = False
    quiet: bool = False
    silent: bool = False
    frame_timeout: float | None = DEFAULT_FRAME_TIMEOUT
    dask: str | None = None  # ``--dask``: local, local:N, tcp://HOST:PORT or env (None: threads here)


@dataclass
class RunResult:
    """out: the output folder; frames: how many frames have a summary record; not_ok: how many of
    those are not "ok" (failed, or a face doubtful or refused: ``counts.photo_status``); stopped: a stop (signal)
    cut the run short;
    storage_error: why the output folder stopped taking data, if it did (the run stopped then);
    cluster_error: why a Dask cluster was lost mid-run, if it was (the run stopped then); report: the
    ``report.html`` written, or None (none was: the folder took no more); counts: the photos and faces ok, doubtful,
    failed and refused (``counts.tally``, as the report says them)."""

    out: Path
    frames: int
    not_ok: int
    stopped: bool
    storage_error: str | None = None
    cluster_error: str | None = None
    report: Path | None = None
    counts: dict[str, int] | None = None

    @functools.cached_property
    def records(self) -> list[dict]:
        """The summary records, in input order (``summary.json`` read back: the run kept them on
        disk, not in memory)."""
        return json.loads((self.out / "summary.json").read_bytes())


def tool_version() -> str:
    """The installed package's version ("unknown" when run from a tree that was never installed)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("shadowflow")
    except PackageNotFoundError:
        return "unknown"


def run_config(model: ShapeModel, options: MethodOptions) -> dict:
    """What decides a run's outputs (the manifest's ``config``): tool version, model fingerprint and
    the method's options. Threads, timeouts, verbosity and what is recorded do not (a resumed job's
    recording parts may differ in what they keep)."""
    return json.loads(json.dumps({
        "tool": "shadowflow", "version": tool_version(), "model": model.fingerprint, "model_source": model.source,
        "options": dataclasses.asdict(options)}, default=jsonable))


def _differences(a: dict, b: dict, prefix: str = "") -> list[str]:
    """The keys (dotted) whose values differ between two JSON objects."""
    out = []
    for k in sorted(set(a) | set(b)):
        va, vb = a.get(k), b.get(k)
        if isinstance(va, dict) and isinstance(vb, dict):
            out += _differences(va, vb, f"{prefix}{k}.")
        elif va != vb:
            out.append(f"{prefix}{k}")
    return out


def run_stream(paths: Iterable[str], out: Path, model: ShapeModel, options: MethodOptions,
               run: RunOptions, total: int | None = None) -> RunResult:
    """Process ``paths`` (any iterable, e.g. a folder watcher); see ``RunResult``.

    One run at a time per ``out`` (a second one gets ``FolderBusy``). A full, read-only or
    over-quota output folder stops the run (frames written so far stay complete, ``summary.json``
    lists them); ``--resume`` finishes the job once there is room.
    """
    if isinstance(paths, (list, tuple)):
        written = run_files(out)
        for path in paths:
            clash = run_file_clash(path, written)
            if clash:
                raise ValueError(clash)
    check_out(out)
    release_large_frees()
    holder = f"pid {os.getpid()} on {socket.gethostname()}, started {time.strftime('%Y-%m-%d %H:%M:%S')}"
    with exclusive_folder(out, holder) as lock:
        if not run.dask:
            return _run_locked(paths, out, model, options, run, total, lock=lock)
        from .cluster import dask_client

        with dask_client(run.dask) as client:
            return _run_locked(paths, out, model, options, run, total, client, lock)


def _run_locked(paths: Iterable[str], out: Path, model: ShapeModel, options: MethodOptions,
                run: RunOptions, total: int | None, client=None, lock: FolderLock | None = None) -> RunResult:
    """The run, once ``out`` is locked (``lock``): on this machine's threads, or on ``client``'s Dask cluster."""
    note = (lambda msg: None) if run.quiet or run.silent else say
    config = run_config(model, options)
    config_id = config_hash(config)
    previous = RunManifest.load(out) if run.resume else None
    if run.resume and previous is None and (out / "summary.json").exists():
        note(f"note: {out} has no readable {MANIFEST_NAME} from the earlier run: every input is redone")
    if previous is not None and previous.config_id != config_id and previous.entries:
        changed = ", ".join(_differences(previous.config, config)[:6])
        note(f"note: the model or options differ from the earlier run in {out} ({changed}): its frames are redone")
    for name in (MANIFEST_NAME, JOURNAL_NAME, "summary.json"):
        refuse_link(out / name)
    store = RunStore(out)  # the records and input entries, on disk (a long job stays flat in memory)
    try:
        store.entries.update(previous.entries if previous else {})
        manifest = RunManifest(config, list(previous.recordings) if previous else [], store.entries)
        return StoredRun(paths, out, model, options, run, total, client, manifest, previous is not None,
                         store, lock).execute()
    finally:
        store.close(remove=lock is None or lock.held())  # (in a folder made anew under the run: not ours)



class StoredRun:
    """One run into a locked ``out`` whose manifest's entries and records are in ``store``. ``execute()`` streams
    the inputs (named by its ``intake``) through the ``engine``; each finished frame comes to ``done``, which
    closes its recording (``recording``), keeps its record, journal entry and summary (``ledger``) and moves
    the progress line; at the end, the recordings, summary, manifest and report are written. A full disk
    (or any storage failure) stops the run (``ledger.out_of_storage``), as ``out`` removed or replaced under
    the run does (its ``lock`` no longer held: nothing more is written there). ``resumed``: it goes on from
    an earlier run's manifest."""

    def __init__(self, paths: Iterable[str], out: Path, model: ShapeModel, options: MethodOptions, run: RunOptions,
                 total: int | None, client, manifest: RunManifest, resumed: bool, store: RunStore,
                 lock: FolderLock | None = None):
        self.out, self.model, self.options, self.run, self.client, self.lock = out, model, options, run, client, lock
        self.note = (lambda msg: None) if run.quiet or run.silent else say
        self.shout = (lambda msg: None) if run.silent else say  # errors, and what --quiet still says
        # outputs must never land on an input: all of them when the list is known, else as they come
        self.protected: set[Path] = {real_path(p) for p in paths} if isinstance(paths, (list, tuple)) else set()
        written = run_files(out)  # what no input may be (``run_file_clash``)
        self.recording = RunRecording(out, run, manifest, client is not None, resumed)
        # the report's pictures of the first photos, made while the run held them (``WriteNode``): the
        # report then reads no photo back (a 4 MP photo and its relit file: 0.2 s)
        self.cards: dict[str, CardPictures] = {}
        manifest.save(out)  # the job's parts and inputs so far, before any frame
        self.ledger = RunLedger(out, store, manifest, lock, self.shout)
        self.intake = Intake(paths, run.resume, options, self.ledger, self.protected, written, self.note)
        self.progress = Progress(total, not run.quiet, run.silent)
        self.clips = ClipSink(out, options.extra_lights, self.ledger, self.recording, self.progress)
        self.trim_heap = HeapTrimmer()

    # -- each finished frame ----------------------------------------------------------------------

    def done(self, frame: Frame) -> None:
        """A frame the pipeline is done with, in input order: recorded, journaled, summarised."""
        ledger = self.ledger
        if ledger.storage is None:
            ledger.folder_lost()
        if frame.cancelled:  # stopped before it finished: no record, so --resume redoes it
            frame.drop_data()
        elif frame.meta.get("clip") and ledger.storage is None and not storage_failure(frame.error):
            self.clips.done(frame)  # a clip's frame, or its end: its relit clips and books
            self.trim_heap()
        elif frame.skipped:
            if ledger.stored(frame.meta["stem"], frame.meta["previous"]):
                ledger.save_summary()
                self.progress.update(True)
        elif storage_failure(frame.error):  # not the frame's fault: leave it for --resume
            ledger.out_of_storage(frame.status)
            frame.drop_data()
        elif ledger.storage is not None:  # finished after the run stopped taking data: not journaled, so
            frame.drop_data()  # --resume redoes it, and summary.json does not call it done
        else:
            self._finished(frame)

    def _finished(self, frame: Frame) -> None:
        ledger = self.ledger
        card = frame.meta.pop("card", None)
        if card is not None and len(self.cards) < LARGE_PHOTOS:
            self.cards[frame.meta["stem"]] = card
        rec = summary_record(frame)
        if not ledger.stored(frame.meta["stem"], rec):  # (taken again, as a watched file that changed: the newer record)
            frame.drop_data()
            return
        failed = self.recording.frame_recorded(frame, rec, ledger.save_manifest)
        if failed is not None:  # --resume redoes the frame: summary.json does not call it done
            ledger.out_of_storage(f"{self.out}: {failed}")
            ledger.drop_record(frame.meta["stem"])
            frame.drop_data()
            return
        if ledger.storage is None:
            ledger.journal_entry(frame, rec)
        ledger.save_summary()
        self.progress.update(frame.ok)
        for part in frame.parts:  # a view's model built on its first face: said once, with the run's notes
            for path in part.meta.get("models_built", ()):
                self.note(f"note: built the model of heads turned this way, once; cached in {path}")
        for line in status_lines(rec):
            self.progress.write(line)
        frame.drop_data()  # the frame's arrays are on disk now: free them
        self.trim_heap()

    # -- the run ----------------------------------------------------------------------------------

    def execute(self) -> RunResult:
        """Stream every input through the pipeline, then close the recordings and write the summary, the
        manifest and the report."""
        self.pipeline = self.ledger.pipeline = engine(self.run, self.model, self.options, self.out, self.protected,
                                                      self.recording, self.lock, self.client, self.done)
        report = None
        try:
            with one_blas_thread():
                for _ in self.pipeline.run(self.intake.frames(), handle_signals=True):
                    pass
        finally:
            report = self._close()
        lost = getattr(self.pipeline, "lost", None)
        if lost:
            self.shout(f"error: {lost}; finished frames are written; run again with --resume to complete the job")
        counts = tally(self.ledger.store.records)  # as the report counts them
        stopped = self.pipeline.stopped and self.ledger.storage is None
        return RunResult(self.out, counts["inputs"], counts["inputs"] - counts["inputs ok"], stopped, self.ledger.storage,
                         lost, report, counts)

    def _report(self) -> Path | None:
        """``report.html`` written, or None (with a note) when it could not be."""
        out, tap = self.out, self.recording.tap
        try:
            return write_report(out, self.ledger.store.records, out if "mcap" in self.run.record else None,
                                series=tap.series() if tap is not None else None, cards=self.cards)
        except OSError as exc:  # the outputs and the summary are written: the report is a view of them
            self.shout(f"note: {out / REPORT_NAME}: not written ({exc.strerror or exc})")
            return None

    def _close(self) -> Path | None:
        """The run's files closed and written, whatever ended it; the report's path, if it was written. Into a
        folder removed or replaced under the run, nothing (its summary and manifest would be another run's)."""
        ledger = self.ledger
        self.progress.close()
        self.clips.abort()  # a clip cut short by a stop: redone whole by --resume
        ledger.journal.close()
        self.recording.close(ledger.storage is not None, self.shout)
        if ledger.folder_lost():
            return None
        ledger.save_summary(force=True)
        self.recording.list_parts()
        ledger.compact_manifest()
        report = self._report() if ledger.storage is None else None
        if self.pipeline.stopped and ledger.storage is None:  # shown even under --quiet: the job is not complete
            self.shout("stopped: finished frames are written; run again with --resume to complete the job")
        return report
