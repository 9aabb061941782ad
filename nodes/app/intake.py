"""A run's inputs as frames: each one's output folder name and frame id (this run's choices kept in its store, an
earlier run's reused with ``--resume``, an input moved since known by its content), refused when it is one of
the run's own files, skipped when ``--resume`` finds its outputs complete."""
from __future__ import annotations

import re
from collections.abc import Iterable, Iterator
from pathlib import Path

from ...flow.frame import Frame
from ...flow.manifest import InputEntry, file_identity, input_key
from ..method.options import MethodOptions
from .clip_io import is_clip
from .clips import clip_complete, clip_frames
from .inputs import input_fingerprint
from .ledger import RunLedger
from .outputs import FACE_FILES, OUTPUT_FILES, RUN_FILES, real_path, relit_name, run_output_folder, safe_stem
from .storage import cannot_write


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


def complete(out: Path, name: str, record: dict, extra_lights: Iterable = ()) -> bool:
    """All output files of a frame named ``name`` whose summary record is ``record`` exist (each was written by an
    atomic rename): the photo's folder's, a relit photo for each of ``extra_lights`` (``--relight``) among them,
    and each other face's folder the record lists (``face-<k>/``)."""
    if record.get("clip") is not None:  # a clip's folder: its relit clips and frames.jsonl
        return clip_complete(out / name, extra_lights)
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


class Intake:
    """The inputs ``paths`` of a run (``resume``: ``--resume``; ``options``: the method's) as frames, their names
    and ids kept in the ``ledger``'s store and manifest; each input's real path added to ``protected`` (no
    output may land on it) once taken; none may be one of ``run_files``; ``note``: how a note is said."""

    def __init__(self, paths: Iterable[str], resume: bool, options: MethodOptions, ledger: RunLedger,
                 protected: set[Path], run_files: set[Path], note):
        self.paths, self.resume, self.options, self.ledger = paths, resume, options, ledger
        self.out, self.store, self.manifest, self.config_id = ledger.out, ledger.store, ledger.manifest, ledger.config_id
        self.protected, self.run_files, self.note = protected, run_files, note

    def frames(self) -> Iterator[Frame]:
        """The inputs as frames; a store that takes no more ends them."""
        try:
            yield from self.named_frames()
        except OSError as exc:
            self.ledger.out_of_storage(cannot_write(exc.filename, exc))

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
            if named is None:
                continue
            frame = self._frame(path, key, identity, fingerprint, *named)
            if frame.ok and not frame.skipped and is_clip(path):  # one frame per frame of the clip, then its end
                yield from clip_frames(frame, self._take_id, self.options.frames)
            else:
                yield frame

    def _take_id(self) -> int:
        """A new frame id (a clip's frames after its first)."""
        self._next_id += 1
        return self._next_id - 1

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
        if not (self.resume and identity is not None and self.manifest.entries):
            return None
        if self._gone is None:
            self._gone = self.manifest.gone()
        old = self._gone.pop(fingerprint, None) if self._gone else None
        if old is None:
            return None
        moved = self.manifest.move(old, key, identity)
        self.ledger.journal_append(moved)
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
        reusable = (self.resume and earlier is not None and earlier.record is not None
                    and earlier.record.get("status") == "ok" and earlier.config == self.config_id)
        if reusable:  # (a changed configuration was said once, before the run)
            if not earlier.same_file(identity, fingerprint):
                self.note(f"note: {path} changed since the earlier run: redone")
            elif complete(self.out, name, earlier.record, self.options.extra_lights):
                frame.skipped = True
                frame.meta["previous"] = {**earlier.record, "source": str(path)}
        return frame
