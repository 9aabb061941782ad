"""``shadowflow run``: stream inputs through the method's nodes on the ``flow`` pipeline,
write outputs and recordings, keep ``summary.json`` current after every frame."""
from __future__ import annotations

import dataclasses
import functools
import json
import math
import os
import re
import socket
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Iterator

from ...flow.files import FolderLock, exclusive_folder
from ...flow.frame import Frame
from ...flow.manifest import (
    JOURNAL_NAME,
    MANIFEST_NAME,
    InputEntry,
    Journal,
    RunManifest,
    config_hash,
    file_identity,
    input_key,
)
from ...flow.pipeline import Pipeline, Stage
from ...flow.runstore import RunStore
from ...flow.recording import McapSink, ProcessSinks, Recorder, RecordOptions, ScalarsTap
from ...flow.jsonsafe import jsonable
from ...flow.recording.process import renewed_sink
from ..method.nodes import MethodOptions
from ..model.shape_model import ShapeModel
from .outputs import (
    FACE_FILES,
    OUTPUT_FILES,
    RUN_FILES,
    real_path,
    run_output_folder,
    relit_name,
    safe_stem,
    summary_record,
    write_summary,
)
from .counts import status_lines, tally
from .process import HeapTrimmer, one_blas_thread, release_large_frees
from .blueprint import rerun_sink
from .chain import run_nodes
from .inputs import input_fingerprint
from .channels import CONVERGENCE
from .storage import cannot_write, check_out, refuse_link, storage_failure
from .terminal import Progress, say
from .report import LARGE_PHOTOS, PLOT_FRAMES, REPORT_NAME, CardPictures, write_report


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


def frames_in_flight(fit_workers: int) -> int:
    """How many photos a local run holds at once: one beside each fit worker's, so that the photo steps of
    one frame run while another is fitted. More wins nothing and a long pipeline's queues would fill with
    large photos (its 17 stages let 53 in; figures in docs/speed.md, "A photo's whole run")."""
    return 1 + fit_workers


def _recording_path(out: Path, suffix: str, resume: bool) -> Path:
    """``run.<suffix>``; a resumed run adds ``run.partN.<suffix>`` and keeps the earlier ones."""
    path = out / f"run.{suffix}"
    if resume:
        k = 2
        while path.exists():
            path = out / f"run.part{k}.{suffix}"
            k += 1
    return path


# the Rerun sink's process is made anew every this many frames (five of its 100-frame segments): the SDK
# keeps a few hundred bytes for every entity path a process has logged, for the life of the process
# (docs/tuning.md, "Streaming")
RERUN_RENEW_FRAMES = 500


def complete(out: Path, name: str, record: dict, extra_lights: Iterable = ()) -> bool:
    """All output files of a frame named ``name`` whose summary record is ``record`` exist (each was written by an
    atomic rename): the photo's folder's, a relit photo for each of ``extra_lights`` (``--relight``) among them,
    and each other face's folder the record lists (``face-<k>/``)."""
    names = (*OUTPUT_FILES, *(relit_name(light) for light in extra_lights))
    if not all((out / name / n).is_file() for n in names):
        return False
    for face in record.get("faces") or ():
        sub = face.get("dir") if isinstance(face, dict) else None
        if sub is None or sub == name:
            continue
        if not (isinstance(sub, str) and re.fullmatch(re.escape(name) + r"/face-[0-9]+", sub)):
            return False  # not a folder this run writes: the frame is redone
        if not all((out / sub / n).is_file() for n in FACE_FILES):
            return False
    return True


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


def run_files(out: Path) -> set[Path]:
    """The real paths of the files a run writes beside its output folders in ``out``."""
    return {real_path(out / name) for name in RUN_FILES}


def run_file_clash(path: str, run_files: set[Path]) -> str | None:
    """Why an input cannot be run into the folder whose ``run_files`` these are: it, or its sidecar, is one
    of them (``summary.json`` would overwrite the sidecar of ``summary.png``, and ``manifest.png`` would
    read the run's manifest as its own); None when nothing clashes."""
    p = Path(path)
    if real_path(p) in run_files:
        return f"{p}: is a file the run writes in --out; choose another --out"
    side = p.with_suffix(".json")
    if real_path(side) in run_files:
        return (f"{p}: its sidecar {side.name} is the run's own {side.name} in --out; rename the photo or choose "
                "another --out")
    return None


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
    """One run into a locked ``out`` whose manifest's entries and records are in ``store``: its state and
    its steps as methods. ``execute()`` streams the inputs through the pipeline; each finished frame comes
    to ``done``, which keeps its record, journal entry, summary and progress; a full disk (or any storage
    failure) stops the run through ``out_of_storage``, as ``out`` removed or replaced under the run does (its
    ``lock`` no longer held: nothing more is written there). ``resumed``: it goes on from an earlier run's
    manifest."""

    def __init__(self, paths: Iterable[str], out: Path, model: ShapeModel, options: MethodOptions, run: RunOptions,
                 total: int | None, client, manifest: RunManifest, resumed: bool, store: RunStore,
                 lock: FolderLock | None = None):
        self.paths, self.out, self.model, self.options, self.run = paths, out, model, options, run
        self.total, self.client, self.manifest, self.resumed, self.store = total, client, manifest, resumed, store
        self.lock = lock
        self.note = (lambda msg: None) if run.quiet or run.silent else say
        self.shout = (lambda msg: None) if run.silent else say  # errors, and what --quiet still says
        self.config_id = manifest.config_id
        self.storage: str | None = None  # the first storage failure, which stops the run
        self.summary_clock = {"last": -math.inf, "cost": 0.0}  # the first frame's record is written at once
        # outputs must never land on an input: all of them when the list is known, else as they come
        self.protected: set[Path] = {real_path(p) for p in paths} if isinstance(paths, (list, tuple)) else set()
        self.pipeline = None  # made by ``execute``, after the recordings and the journal are open
        self.run_files = run_files(out)  # what no input may be (``run_file_clash``)
        self._open_recordings()
        manifest.save(out)  # the job's parts and inputs so far, before any frame
        self.journal = Journal(out)
        self.progress = Progress(total, not run.quiet, run.silent)
        self.trim_heap = HeapTrimmer()

    def _open_recordings(self) -> None:
        """The recording's sinks (MCAP, Rerun; on the recording process of their own when it runs here),
        their parts listed in the manifest, the report's tap and the recorder."""
        own_process = self.run.record_options.own_process and self.client is None
        self.recording_id = str(uuid.uuid4())  # the Rerun recording's id: a distributed run's parts share it
        specs = self._sink_specs(own_process)
        if specs and own_process:
            self.sinks: list = [ProcessSinks(specs)]  # encoding and compression on the other core
        else:
            self.sinks = [factory(*args, **kwargs) for factory, args, kwargs in specs]
        # the report's convergence plot from what this run records, instead of reading the recording
        # back at the end (it decompresses every array, docs/tuning.md); a resumed or distributed
        # job's frames are recorded elsewhere too, so its report reads the recording
        self.tap = (ScalarsTap(CONVERGENCE, PLOT_FRAMES) if self.sinks and not self.resumed and self.client is None
                    else None)
        if self.tap is not None:
            self.sinks.append(self.tap)
        # the report's pictures of the first photos, made while the run held them (``WriteNode``): the
        # report then reads no photo back (a 4 MP photo and its relit file: 0.2 s)
        self.cards: dict[str, CardPictures] = {}
        self.recorder = Recorder(self.sinks, self.run.record_options) if self.sinks else None

    def _sink_specs(self, own_process: bool) -> list[tuple]:
        """The recording's file sinks as ``(factory, args, kwargs)``, their files listed in the manifest."""
        run, manifest = self.run, self.manifest
        specs: list = []
        parts = {suffix: _recording_path(self.out, suffix, run.resume) for suffix in ("mcap", "rrd")}
        for path in parts.values():  # a link planted in --out would send the recording elsewhere
            refuse_link(path)
        if "mcap" in run.record:
            specs.append((McapSink, (str(parts["mcap"]),), {}))
            manifest.recordings.append(parts["mcap"].name)
        if "rerun" in run.record:
            rrd_args = (str(parts["rrd"]), self.recording_id)
            if own_process:  # the Rerun SDK keeps something of every entity path a process logs: renewed
                specs.append((renewed_sink, (f"{rerun_sink.__module__}:rerun_sink", list(rrd_args), {},
                                             RERUN_RENEW_FRAMES), {}))
            else:
                specs.append((rerun_sink, rrd_args, {}))
            manifest.recordings.append(parts["rrd"].name)
        return specs

    def _pipeline(self):
        """The engine: this machine's threads, or the Dask cluster of ``client``."""
        run = self.run
        if self.client is None:
            still_ours = self.lock.held if self.lock is not None else None
            nodes = run_nodes(self.model, self.options, self.out, self.protected, self.recorder, still_ours)
            stages = [Stage(n, run.fit_workers if getattr(n, "thread_safe", False) else 1) for n in nodes]
            return Pipeline(stages, queue_size=run.queue_size, on_done=self.done, frame_timeout=run.frame_timeout,
                            in_flight=run.in_flight or frames_in_flight(run.fit_workers))
        from ...flow.distributed import DaskPipeline
        from .cluster import WorkerChain

        chain = WorkerChain(self.options, self.out.resolve(), frozenset(self.protected), tuple(run.record),
                            run.record_options, self.recording_id if "rerun" in run.record else "")
        return DaskPipeline(self.client, chain, shared=self.model, on_done=self.done, frame_timeout=run.frame_timeout)

    # -- storage: the first failure stops the run -------------------------------------------------

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

    # -- the inputs as frames ---------------------------------------------------------------------

    def frames(self) -> Iterator[Frame]:
        """The inputs as frames; a store that takes no more ends them."""
        try:
            yield from self.named_frames()
        except OSError as exc:
            self.out_of_storage(cannot_write(exc.filename, exc))

    def named_frames(self) -> Iterator[Frame]:
        """Each input with its output name and frame id (the names taken and this run's choices
        are kept in the store)."""
        taken = self.store.names
        taken |= self.manifest.names()
        self._next_id = self.manifest.next_frame()
        self._gone: dict[str, str] | None = None  # the earlier inputs no longer at their paths, by fingerprint
        for path in self.paths:
            # what the input is made of, read once: to know it again if it moved here, and for a later --resume
            key, identity, fingerprint = input_key(path), file_identity(path), input_fingerprint(path)
            named = self._name(path, key, identity, fingerprint)
            if named is not None:
                yield self._frame(path, key, identity, fingerprint, *named)

    def _name(self, path: str, key: str, identity, fingerprint: str) -> tuple[str, int, InputEntry | None] | None:
        """``(output name, frame id, the earlier run's entry to reuse or None)`` of the input ``path`` (its
        input key, identity and fingerprint); None when this run has taken it already as it is."""
        manifest, assigned = self.manifest, self.store.assigned
        earlier = manifest.entries.get(key)
        given = assigned.get(key)  # this run's: name, id, identity
        if given is None and earlier is None:
            earlier = self._moved_here(key, identity, fingerprint)
        if given is not None:
            if given[2] == identity and assigned.fingerprint(key) == fingerprint:  # (a sidecar come since: redone)
                self.note(f"{path}: given more than once; processed once")
                return None
            name, fid = given[:2]  # changed since this run took it (a watched folder): redone
            earlier = None
        elif earlier is not None and run_output_folder(self.out / earlier.name):
            name, fid = earlier.name, earlier.frame
            self.store.names.add(name.lower())
        elif earlier is not None:  # its folder is someone else's now (replaced since): redone under another name
            name, fid, earlier = safe_stem(path, self.store.names, lambda n: run_output_folder(self.out / n)), \
                earlier.frame, None
        else:
            name, fid = safe_stem(path, self.store.names, lambda n: run_output_folder(self.out / n)), self._next_id
            self._next_id += 1
        assigned.put(key, name, fid, identity, fingerprint)
        self.protected.add(real_path(path))
        return name, fid, earlier

    def _moved_here(self, key: str, identity, fingerprint: str) -> InputEntry | None:
        """With ``--resume``, the earlier entry of an input moved to ``key`` (a renamed folder: its old
        path gone, its content the same), re-keyed here with its name, frame id and outputs; else None."""
        if not (self.run.resume and identity is not None and self.manifest.entries):
            return None
        if self._gone is None:
            self._gone = self.manifest.gone()
        old = self._gone.pop(fingerprint, None) if self._gone else None
        if old is None:
            return None
        moved = self.manifest.move(old, key, identity)
        self.journal_append(moved)
        return moved

    def _frame(self, path: str, key: str, identity, fingerprint: str, name: str, fid: int,
               earlier: InputEntry | None) -> Frame:
        """The frame of ``path``: skipped (its earlier record reused) when ``--resume`` finds its outputs
        complete and made from the same input under the same configuration."""
        frame = Frame(fid, path)
        frame.meta.update(stem=name, input_key=key, identity=identity)
        clash = run_file_clash(path, self.run_files)
        if clash:  # (a watched folder's newcomer: a listed one refused the run before it began)
            frame.fail("load", clash)
            return frame
        frame.meta["sha256"] = fingerprint
        reusable = (self.run.resume and earlier is not None and earlier.record is not None
                    and earlier.record.get("status") == "ok" and earlier.config == self.config_id)
        if reusable:  # (a changed configuration was said once, before the run)
            if not earlier.same_file(identity, fingerprint):
                self.note(f"note: {path} changed since the earlier run: redone")
            elif complete(self.out, name, earlier.record, self.options.extra_lights):
                frame.skipped = True
                frame.meta["previous"] = {**earlier.record, "source": str(path)}
        return frame

    # -- each finished frame ----------------------------------------------------------------------

    def done(self, frame: Frame) -> None:
        """A frame the pipeline is done with, in input order: recorded, journaled, summarised."""
        if self.storage is None:
            self.folder_lost()
        if frame.cancelled:  # stopped before it finished: no record, so --resume redoes it
            frame.drop_data()
        elif frame.skipped:
            if self.stored(frame.meta["stem"], frame.meta["previous"]):
                self.save_summary()
                self.progress.update(True)
        elif storage_failure(frame.error):  # not the frame's fault: leave it for --resume
            self.out_of_storage(frame.status)
            frame.drop_data()
        elif self.storage is not None:  # finished after the run stopped taking data: not journaled, so
            frame.drop_data()  # --resume redoes it, and summary.json does not call it done
        else:
            self._finished(frame)

    def _finished(self, frame: Frame) -> None:
        card = frame.meta.pop("card", None)
        if card is not None and len(self.cards) < LARGE_PHOTOS:
            self.cards[frame.meta["stem"]] = card
        rec = summary_record(frame)
        if not self.stored(frame.meta["stem"], rec):  # (taken again, as a watched file that changed: the newer record)
            frame.drop_data()
            return
        failed = self._recorded(frame, rec)
        if failed is not None:  # --resume redoes the frame: summary.json does not call it done
            self.out_of_storage(f"{self.out}: {failed}")
            self.drop_record(frame.meta["stem"])
            frame.drop_data()
            return
        if self.storage is None:
            self.journal_entry(frame, rec)
        self.save_summary()
        self.progress.update(frame.ok)
        for part in frame.parts:  # a view's model built on its first face: said once, with the run's notes
            for path in part.meta.get("models_built", ()):
                self.note(f"note: built the model of heads turned this way, once; cached in {path}")
        for line in status_lines(rec):
            self.progress.write(line)
        frame.drop_data()  # the frame's arrays are on disk now: free them
        self.trim_heap()

    def _recorded(self, frame: Frame, rec: dict) -> str | None:
        """The frame's recording closed with its record (before the journal says it is done), or why it
        could not be; a Dask worker's recording parts listed in the manifest at once."""
        worker_parts = frame.meta.pop("recording_parts", None)  # recorded on a Dask worker, in these
        if worker_parts:
            new_parts = [p for p in worker_parts if p not in self.manifest.recordings]
            if new_parts:  # listed at once, so a killed run's parts are still read as the job's
                self.manifest.recordings.extend(new_parts)
                self.save_manifest()
        failed = frame.meta.pop("recording_error", None)
        if failed is None and self.recorder is not None and worker_parts is None:
            self.recorder.frame_done(frame.id, rec, wait=True)
            if self.recorder.error is not None:
                failed = f"recording failed ({self.recorder.error})"
        return failed

    # -- the run ----------------------------------------------------------------------------------

    def execute(self) -> RunResult:
        """Stream every input through the pipeline, then close the recordings and write the summary, the
        manifest and the report."""
        self.pipeline = self._pipeline()
        report = None
        try:
            with one_blas_thread():
                for _ in self.pipeline.run(self.frames(), handle_signals=True):
                    pass
        finally:
            report = self._close()
        lost = getattr(self.pipeline, "lost", None)
        if lost:
            self.shout(f"error: {lost}; finished frames are written; run again with --resume to complete the job")
        counts = tally(self.store.records)  # as the report counts them
        stopped = self.pipeline.stopped and self.storage is None
        return RunResult(self.out, counts["photos"], counts["photos"] - counts["ok"], stopped, self.storage, lost,
                         report, counts)

    def _report(self) -> Path | None:
        """``report.html`` written, or None (with a note) when it could not be."""
        out = self.out
        try:
            return write_report(out, self.store.records, out if "mcap" in self.run.record else None,
                                series=self.tap.series() if self.tap is not None else None, cards=self.cards)
        except OSError as exc:  # the outputs and the summary are written: the report is a view of them
            self.shout(f"note: {out / REPORT_NAME}: not written ({exc.strerror or exc})")
            return None

    def _close(self) -> Path | None:
        """The run's files closed and written, whatever ended it; the report's path, if it was written. Into a
        folder removed or replaced under the run, nothing (its summary and manifest would be another run's)."""
        out, manifest = self.out, self.manifest
        self.progress.close()
        self.journal.close()
        if self.recorder is not None:
            try:
                self.recorder.close()
            except RuntimeError as exc:
                if self.storage is None:
                    raise
                self.shout(f"note: {exc}")
        if self.folder_lost():
            return None
        self.save_summary(force=True)
        for sink in self.sinks:  # a long run's .rrd goes on in segment files: the job's parts too
            for path in sink.paths:
                if path.name not in manifest.recordings:
                    manifest.recordings.append(path.name)
        try:
            manifest.save(out)
        except OSError as exc:  # the journal keeps what it could not fold in: --resume reads both
            self.shout(f"note: {out / MANIFEST_NAME}: not compacted ({exc.strerror or exc})")
        report = self._report() if self.storage is None else None
        if self.pipeline.stopped and self.storage is None:  # shown even under --quiet: the job is not complete
            self.shout("stopped: finished frames are written; run again with --resume to complete the job")
        return report
