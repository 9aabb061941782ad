"""A run's manifest: what made the outputs in a folder, from which inputs, under which names.

``manifest.json`` (atomic, written when a run starts and when it ends) holds the run's
configuration, the recording files that make up the job, and one entry per input ever
processed into the folder: its identity (path, size, mtime) and the output name and frame id
it was given. While a run goes, ``.journal.jsonl`` gets one line per finished frame (one
appended write each, so the cost does not grow with the run); ``RunManifest.load`` applies
it, so a killed run loses nothing it finished. Face-agnostic: the configuration is the
caller's JSON object, compared by its hash.
"""
from __future__ import annotations

import hashlib
import json
import os
import stat
from collections.abc import Iterator, MutableMapping
from dataclasses import asdict, dataclass, field
from itertools import chain
from pathlib import Path

from .files import atomic_write_chunks, json_array_chunks
from .jsonsafe import jsonable

MANIFEST_NAME = "manifest.json"
JOURNAL_NAME = ".journal.jsonl"
FORMAT = 1
MAX_MANIFEST_BYTES = 256 << 20  # a larger manifest or journal is not ours: it is not read


@dataclass
class InputEntry:
    """One input of the job. path: as given, made absolute (links not resolved); size, mtime_ns:
    its identity when it was processed; name: its output name; frame: its frame id in the
    recordings; config: hash of the configuration its record was made under; record: the
    summary record of its last finish."""

    path: str
    size: int
    mtime_ns: int
    name: str
    frame: int
    config: str
    record: dict | None = None
    sha256: str = ""  # the caller's fingerprint of the input (e.g. ``content_hash`` of its files)

    def same_file(self, identity: tuple[int, int] | None, fingerprint: str) -> bool:
        """Is the input (now of ``identity`` and ``fingerprint``, the caller's hash of what the input is
        made of) still what this entry was made from? Equal size and fingerprint; an entry written
        without one (an older manifest) falls back to equal size and mtime. The mtime alone proves
        nothing: a file can be replaced and its time put back."""
        if identity is None or identity[0] != self.size:
            return False
        if self.sha256:
            return fingerprint == self.sha256
        return identity[1] == self.mtime_ns


def _open_regular(path: str | os.PathLike, limit: int, follow: bool = True) -> int | None:
    """A read descriptor on ``path`` if it is a regular file of at most ``limit`` bytes (never
    blocks on a pipe; with ``follow=False`` a link is refused), else None."""
    flags = os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC | (0 if follow else os.O_NOFOLLOW)
    try:
        fd = os.open(path, flags)
    except (OSError, ValueError):
        return None
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode) or st.st_size > limit:
        os.close(fd)
        return None
    return fd


def content_hash(path: str | os.PathLike, limit: int = 1 << 30) -> str:
    """SHA-256 of a regular file's bytes (hex), or "" when it cannot be read or is over ``limit``."""
    h = hashlib.sha256()
    fd = _open_regular(path, limit)
    if fd is None:
        return ""
    with os.fdopen(fd, "rb") as f:
        try:
            while chunk := f.read(1 << 20):
                h.update(chunk)
        except OSError:
            return ""
    return h.hexdigest()


def input_key(path: str | os.PathLike) -> str:
    """The key an input is known by: its absolute path, links not resolved (two links to one
    file are two inputs)."""
    return os.path.abspath(os.fspath(path))


def file_identity(path: str | os.PathLike) -> tuple[int, int] | None:
    """``(size, mtime_ns)`` of the file ``path`` names, or None when it cannot be looked at."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return None
    return st.st_size, st.st_mtime_ns


def config_hash(config: dict) -> str:
    """A stable hash of a JSON-able configuration (key order does not matter)."""
    text = json.dumps(config, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _entry(obj) -> InputEntry | None:
    """An entry from untrusted JSON, or None when any field has the wrong type."""
    if not isinstance(obj, dict):
        return None
    want = {"path": str, "size": int, "mtime_ns": int, "name": str, "frame": int, "config": str}
    for key, kind in want.items():
        v = obj.get(key)
        if not isinstance(v, kind) or isinstance(v, bool):
            return None
    if not 0 <= obj["frame"] < 1 << 53 or not _is_name(obj["name"]) or "\x00" in obj["name"]:
        return None
    record, sha = obj.get("record"), obj.get("sha256")
    return InputEntry(obj["path"], obj["size"], obj["mtime_ns"], obj["name"], obj["frame"], obj["config"],
                      record if isinstance(record, dict) else None, sha if isinstance(sha, str) else "")


def _read_json_file(path: Path) -> bytes | None:
    """A regular file's bytes (links not followed, size capped), or None."""
    fd = _open_regular(path, MAX_MANIFEST_BYTES, follow=False)
    if fd is None:
        return None
    with os.fdopen(fd, "rb") as f:
        return f.read(MAX_MANIFEST_BYTES + 1)


@dataclass
class RunManifest:
    """config: the caller's configuration of the run that last started in the folder;
    recordings: file names (in the folder) of the job's recording parts, in order; entries:
    every input processed into the folder, by ``input_key`` (a dict, or a mapping whose values come
    by frame id, e.g. ``flow.runstore.EntryStore`` on disk)."""

    config: dict
    recordings: list[str] = field(default_factory=list)
    entries: MutableMapping[str, InputEntry] = field(default_factory=dict)

    @property
    def config_id(self) -> str:
        return config_hash(self.config)

    def by_frame(self) -> Iterator[InputEntry]:
        """The entries by frame id."""
        if isinstance(self.entries, dict):
            return iter(sorted(self.entries.values(), key=lambda e: e.frame))
        return iter(self.entries.values())

    def next_frame(self) -> int:
        return 1 + max((e.frame for e in self.entries.values()), default=-1)

    def names(self) -> set[str]:
        return {e.name.lower() for e in self.entries.values()}

    def gone(self) -> dict[str, str]:
        """fingerprint -> input key of the entries whose input is no longer at its path (a folder
        renamed or moved), to be recognised at the new one by what it is made of; an input seen twice
        under one fingerprint is left out (which of the two moved cannot be told)."""
        out: dict[str, str] = {}
        twice: set[str] = set()
        for e in self.entries.values():
            if e.sha256 and file_identity(e.path) is None:
                if e.sha256 in out:
                    twice.add(e.sha256)
                out[e.sha256] = e.path
        return {f: k for f, k in out.items() if f not in twice}

    def move(self, old: str, new: str, identity: tuple[int, int]) -> InputEntry:
        """The entry of input key ``old`` re-keyed as ``new`` (of ``identity``): its name, frame id and
        record kept. Returns the new entry (not yet journaled)."""
        entry = self.entries.pop(old)
        moved = InputEntry(new, identity[0], identity[1], entry.name, entry.frame, entry.config, entry.record,
                           entry.sha256)
        self.entries[new] = moved
        return moved

    @classmethod
    def load(cls, folder: str | os.PathLike) -> RunManifest | None:
        """The folder's manifest with its journal applied; None when there is none or it is not
        a manifest this code wrote (malformed entries are dropped: those inputs are redone)."""
        folder = Path(folder)
        data = _read_json_file(folder / MANIFEST_NAME)
        try:
            obj = json.loads(data) if data is not None else None
        except (ValueError, RecursionError):
            obj = None
        if not isinstance(obj, dict) or obj.get("format") != FORMAT or not isinstance(obj.get("config"), dict):
            return None
        try:
            config_hash(obj["config"])
        except (TypeError, ValueError):
            return None
        recordings = obj.get("recordings")
        recordings = [r for r in recordings if _is_name(r)] if isinstance(recordings, list) else []
        entries = {}
        for raw in obj.get("inputs") if isinstance(obj.get("inputs"), list) else []:
            e = _entry(raw)
            if e is not None:
                entries[e.path] = e
        _apply_journal(entries, read_journal(folder))
        return cls(obj["config"], recordings, _distinct(entries))

    def save(self, folder: str | os.PathLike) -> None:
        """Write ``manifest.json`` atomically, then empty the journal it now includes."""
        folder = Path(folder)
        head = {"format": FORMAT, "config": self.config, "config_id": self.config_id, "recordings": self.recordings,
                "inputs": []}
        text = json.dumps(head, indent=1, default=jsonable)  # ends '"inputs": []\n}': the entries go there, streamed
        inputs = json_array_chunks((asdict(e) for e in self.by_frame()), indent=1, level=1, default=jsonable)
        atomic_write_chunks(folder / MANIFEST_NAME, chain([text[:-len("[]\n}")].encode()], inputs, [b"\n}\n"]))
        journal = folder / JOURNAL_NAME
        if journal.is_symlink() or journal.exists():
            journal.unlink()


def _apply_journal(entries: dict[str, InputEntry], journal: list[InputEntry]) -> None:
    """The journal's entries over the manifest's, in order: newer, and an input moved since (a renamed
    folder) takes its frame over from its old path."""
    frames = {e.frame: e.path for e in entries.values()}
    for e in journal:
        if frames.get(e.frame, e.path) != e.path:
            entries.pop(frames[e.frame], None)
        entries[e.path] = e
        frames[e.frame] = e.path


def _distinct(entries: dict[str, InputEntry]) -> dict[str, InputEntry]:
    """Entries with no output name or frame id shared by two inputs (a hand-edited or damaged
    manifest): of those sharing one, the first by frame id is kept, the others' inputs are redone."""
    names: set[str] = set()
    frames: set[int] = set()
    out = {}
    for e in sorted(entries.values(), key=lambda e: (e.frame, e.path)):
        if e.name.lower() in names or e.frame in frames:
            continue
        names.add(e.name.lower())
        frames.add(e.frame)
        out[e.path] = e
    return out


def _is_name(x) -> bool:
    return isinstance(x, str) and bool(x) and "/" not in x and "\\" not in x and not x.startswith(".")


def read_journal(folder: str | os.PathLike) -> list[InputEntry]:
    """The entries of ``.journal.jsonl`` in order; a line cut by a kill, or anything malformed,
    is skipped."""
    data = _read_json_file(Path(folder) / JOURNAL_NAME)
    out = []
    for line in (data or b"").splitlines():
        try:
            e = _entry(json.loads(line))
        except (ValueError, RecursionError):
            continue
        if e is not None:
            out.append(e)
    return out


class Journal:
    """Appends one line per finished input to ``folder/.journal.jsonl`` (a link there is refused)."""

    def __init__(self, folder: str | os.PathLike):
        self.path = Path(folder) / JOURNAL_NAME
        self.fd = -1
        self.reopen()

    def reopen(self) -> None:
        """Go on in a new journal file: after ``RunManifest.save`` folded the old one in and removed it."""
        self.close()
        self.fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_APPEND | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)

    def append(self, entry: InputEntry) -> None:
        line = json.dumps(asdict(entry), separators=(",", ":"), default=jsonable) + "\n"
        data = line.encode()
        written = os.write(self.fd, data)  # one write: a kill leaves a whole line or a cut last one
        while written < len(data):
            written += os.write(self.fd, data[written:])

    def close(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1


def recording_parts(folder: str | os.PathLike, suffix: str) -> list[Path] | None:
    """The recording files of the job in ``folder`` whose name ends in ``.suffix``, as its
    manifest lists them (existing ones only); None when the folder has no readable manifest."""
    man = RunManifest.load(folder)
    if man is None:
        return None
    return [Path(folder) / r for r in man.recordings if r.endswith(f".{suffix}") and (Path(folder) / r).is_file()]

