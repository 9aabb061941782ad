"""A run's recording: its sinks (``run.mcap``, ``run.rrd``; on a recording process of their own when the run is
on this machine), their files listed in the run's manifest, the report's tap of the convergence scalars, and
the recorder that feeds them; each frame's recording closed with its record."""
from __future__ import annotations

import uuid
from pathlib import Path
from typing import TYPE_CHECKING

from ...flow.frame import Frame
from ...flow.manifest import RunManifest
from ...flow.recording import McapSink, ProcessSinks, Recorder, ScalarsTap
from ...flow.recording.process import renewed_sink
from .blueprint import rerun_sink
from .channels import CONVERGENCE
from .report import PLOT_FRAMES
from .storage import refuse_link

if TYPE_CHECKING:
    from .runner import RunOptions

# the Rerun sink's process is made anew every this many frames (five of its 100-frame segments): the SDK
# keeps a few hundred bytes for every entity path a process has logged, for the life of the process
# (docs/tuning.md, "Streaming")
RERUN_RENEW_FRAMES = 500


def _recording_path(out: Path, suffix: str, resume: bool) -> Path:
    """``run.<suffix>``; a resumed run adds ``run.partN.<suffix>`` and keeps the earlier ones."""
    path = out / f"run.{suffix}"
    if resume:
        k = 2
        while path.exists():
            path = out / f"run.part{k}.{suffix}"
            k += 1
    return path


class RunRecording:
    """The recording of a run into ``out`` as ``run`` asks (``run.record``), its files listed in ``manifest``:
    ``sinks``, ``tap`` (or None), ``recorder`` (None: nothing is recorded here) and ``recording_id``.
    ``distributed``: the frames are recorded on Dask workers; ``resumed``: the job goes on from an earlier run."""

    def __init__(self, out: Path, run: RunOptions, manifest: RunManifest, distributed: bool, resumed: bool):
        self.out, self.run, self.manifest = out, run, manifest
        own_process = run.record_options.own_process and not distributed
        self.recording_id = str(uuid.uuid4())  # the Rerun recording's id: a distributed run's parts share it
        specs = self._sink_specs(own_process)
        if specs and own_process:
            self.sinks: list = [ProcessSinks(specs)]  # encoding and compression on the other core
        else:
            self.sinks = [factory(*args, **kwargs) for factory, args, kwargs in specs]
        # the report's convergence plot from what this run records, instead of reading the recording
        # back at the end (it decompresses every array, docs/tuning.md); a resumed or distributed
        # job's frames are recorded elsewhere too, so its report reads the recording
        self.tap = (ScalarsTap(CONVERGENCE, PLOT_FRAMES) if self.sinks and not resumed and not distributed
                    else None)
        if self.tap is not None:
            self.sinks.append(self.tap)
        self.recorder = Recorder(self.sinks, run.record_options) if self.sinks else None

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

    def frame_recorded(self, frame: Frame, rec: dict, save_manifest) -> str | None:
        """The frame's recording closed with its record (before the journal says it is done), or why it
        could not be; a Dask worker's recording parts listed in the manifest at once (``save_manifest``)."""
        worker_parts = frame.meta.pop("recording_parts", None)  # recorded on a Dask worker, in these
        if worker_parts:
            new_parts = [p for p in worker_parts if p not in self.manifest.recordings]
            if new_parts:  # listed at once, so a killed run's parts are still read as the job's
                self.manifest.recordings.extend(new_parts)
                save_manifest()
        failed = frame.meta.pop("recording_error", None)
        if failed is None and self.recorder is not None and worker_parts is None:
            self.recorder.frame_done(frame.id, rec, wait=True)
            if self.recorder.error is not None:
                failed = f"recording failed ({self.recorder.error})"
        return failed

    def close(self, storage_failed: bool, shout) -> None:
        """The recorder closed, whatever ended the run; its error is a note (``shout``) when the run stopped
        for want of storage (``storage_failed``), else raised."""
        if self.recorder is not None:
            try:
                self.recorder.close()
            except RuntimeError as exc:
                if not storage_failed:
                    raise
                shout(f"note: {exc}")

    def list_parts(self) -> None:
        """Every file the sinks wrote listed in the manifest (a long run's .rrd goes on in segment files: the
        job's parts too)."""
        for sink in self.sinks:
            for path in sink.paths:
                if path.name not in self.manifest.recordings:
                    self.manifest.recordings.append(path.name)
