"""A run's records and input entries kept on disk, not in memory, so a job of any length keeps
the process flat.

``RunStore`` is an SQLite file (``.run.sqlite``) in the output folder for the length of one run:
the records (JSON objects keyed by a unique name, in the order first put), the manifest's input
entries (``EntryStore``, a mapping by input key), the output names handed out (``NameSet``) and
what this run gave each input (``Assigned``). It is a scratch, never the durable
copy: the journal holds every finished frame and ``summary.json`` / ``manifest.json`` are
written from the store (streamed, ``flow.files.json_array_chunks``), after which it is removed. A run
killed before that leaves it behind; the next run replaces it. Face-agnostic.
"""
from __future__ import annotations

import errno
import json
import os
import sqlite3
import threading
from collections.abc import Iterator, MutableMapping, MutableSet
from dataclasses import asdict
from pathlib import Path

from .manifest import InputEntry
from .jsonsafe import jsonable

STORE_NAME = ".run.sqlite"
_PAGE = 512  # rows read at a time when streaming
_SCHEMA = (
    # a scratch: no rollback journal, no fsync, 2 MiB of page cache
    "PRAGMA journal_mode=OFF", "PRAGMA synchronous=OFF", "PRAGMA cache_size=-2048", "PRAGMA temp_store=FILE",
    # keys and names are stored as bytes (``_blob``): a path need not be valid UTF-8
    "CREATE TABLE records (pos INTEGER PRIMARY KEY, name BLOB UNIQUE NOT NULL, body TEXT NOT NULL)",
    "CREATE TABLE entries (key BLOB PRIMARY KEY, frame INTEGER NOT NULL, body TEXT NOT NULL)",
    "CREATE INDEX entries_by_frame ON entries (frame, key)",
    "CREATE TABLE names (name BLOB PRIMARY KEY)",
    "CREATE TABLE assigned (key BLOB PRIMARY KEY, name BLOB NOT NULL, frame INTEGER NOT NULL, size INTEGER, "
    "mtime_ns INTEGER, fingerprint TEXT NOT NULL DEFAULT '')",
)


def _blob(text: str) -> bytes:
    """A key or name as bytes, undecodable file-name bytes (``surrogateescape``) kept as they were."""
    return text.encode("utf-8", "surrogateescape")


def _text(blob: bytes) -> str:
    return blob.decode("utf-8", "surrogateescape")


class RunStore:
    """The scratch store in ``folder`` (whatever is at its name, a stale store or a link, is
    removed first: a link is never followed). Safe to use from several threads (one connection,
    one lock). A failure of its file is an ``OSError`` naming it."""

    def __init__(self, folder: str | os.PathLike):
        self.path = Path(folder) / STORE_NAME
        self.path.unlink(missing_ok=True)
        self._lock = threading.Lock()
        try:
            self._db = sqlite3.connect(self.path, isolation_level=None, check_same_thread=False)
        except sqlite3.OperationalError as exc:
            raise OSError(errno.EIO, str(exc), str(self.path)) from exc
        for sql in _SCHEMA:
            self._execute(sql)
        self.entries = EntryStore(self)
        self.records = RecordView(self)
        self.names = NameSet(self)
        self.assigned = Assigned(self)

    def put_record(self, name: str, record: dict) -> None:
        """Add ``record`` under ``name``, or replace the one of that name in its place."""
        self._execute("INSERT INTO records (name, body) VALUES (?, ?) ON CONFLICT (name) DO UPDATE SET body = excluded.body",
                      (_blob(name), json.dumps(record, separators=(",", ":"))))

    def drop_record(self, name: str) -> None:
        """Remove the record under ``name``, if any."""
        self._execute("DELETE FROM records WHERE name = ?", (_blob(name),))

    def _execute(self, sql: str, args: tuple = ()) -> list:
        """The statement's rows; a failure of the file (full disk, I/O error) as ``OSError`` naming it."""
        with self._lock:
            try:
                return self._db.execute(sql, args).fetchall()
            except sqlite3.OperationalError as exc:
                code = errno.ENOSPC if getattr(exc, "sqlite_errorcode", None) == sqlite3.SQLITE_FULL else errno.EIO
                raise OSError(code, str(exc), str(self.path)) from exc

    def _pages(self, sql: str, start: tuple) -> Iterator[tuple]:
        """Rows of ``sql`` (keyset-paged: it takes the last row's sort key and a limit), a page at a
        time under the lock, so other threads may write between pages."""
        after = start
        while True:
            rows = self._execute(sql, (*after, _PAGE))
            yield from rows
            if len(rows) < _PAGE:
                return
            after = rows[-1][:len(start)]

    def close(self, remove: bool = True) -> None:
        """Close the store, and remove its file (``remove``) if the folder lets it: a folder that takes no more
        keeps it (the run has said why already), and the next run replaces it."""
        with self._lock:
            self._db.close()
        if remove:
            try:
                self.path.unlink(missing_ok=True)
            except OSError:
                pass


class RecordView:
    """The store's records in order: ``len`` and re-iterable (each pass reads the file again)."""

    def __init__(self, store: RunStore):
        self._store = store

    def __len__(self) -> int:
        return self._store._execute("SELECT count(*) FROM records")[0][0]

    def __iter__(self) -> Iterator[dict]:
        for _, body in self._store._pages("SELECT pos, body FROM records WHERE pos > ? ORDER BY pos LIMIT ?", (-1,)):
            yield json.loads(body)

    def counts(self) -> tuple[int, int]:
        """(records, records whose "status" is not "ok"), counted in the file."""
        n, not_ok = self._store._execute(
            "SELECT count(*), coalesce(sum(coalesce(json_extract(body, '$.status'), '') IS NOT 'ok'), 0) FROM records")[0]
        return n, not_ok


class EntryStore(MutableMapping):
    """The manifest's input entries by input key, in the store (``RunManifest.entries``)."""

    def __init__(self, store: RunStore):
        self._store = store

    def __getitem__(self, key: str) -> InputEntry:
        rows = self._store._execute("SELECT body FROM entries WHERE key = ?", (_blob(key),))
        if not rows:
            raise KeyError(key)
        return InputEntry(**json.loads(rows[0][0]))

    def __setitem__(self, key: str, entry: InputEntry) -> None:
        body = json.dumps(asdict(entry), separators=(",", ":"), default=jsonable)
        self._store._execute("INSERT OR REPLACE INTO entries (key, frame, body) VALUES (?, ?, ?)",
                             (_blob(key), entry.frame, body))

    def __delitem__(self, key: str) -> None:
        if key not in self:
            raise KeyError(key)
        self._store._execute("DELETE FROM entries WHERE key = ?", (_blob(key),))

    def __contains__(self, key: object) -> bool:
        return isinstance(key, str) and bool(self._store._execute("SELECT 1 FROM entries WHERE key = ?", (_blob(key),)))

    def __len__(self) -> int:
        return self._store._execute("SELECT count(*) FROM entries")[0][0]

    def __iter__(self) -> Iterator[str]:
        for (key,) in self._store._pages("SELECT key FROM entries WHERE key > ? ORDER BY key LIMIT ?", (b"",)):
            yield _text(key)

    def values(self) -> Iterator[InputEntry]:  # type: ignore[override]
        return self.by_frame()

    def by_frame(self) -> Iterator[InputEntry]:
        """Every entry, by frame id."""
        sql = "SELECT frame, key, body FROM entries WHERE (frame, key) > (?, ?) ORDER BY frame, key LIMIT ?"
        for _, _, body in self._store._pages(sql, (-1, b"")):
            yield InputEntry(**json.loads(body))


class NameSet(MutableSet):
    """A set of names (the output names taken), in the store."""

    def __init__(self, store: RunStore):
        self._store = store

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and bool(self._store._execute("SELECT 1 FROM names WHERE name = ?", (_blob(name),)))

    def add(self, name: str) -> None:
        self._store._execute("INSERT OR IGNORE INTO names (name) VALUES (?)", (_blob(name),))

    def discard(self, name: str) -> None:
        self._store._execute("DELETE FROM names WHERE name = ?", (_blob(name),))

    def __len__(self) -> int:
        return self._store._execute("SELECT count(*) FROM names")[0][0]

    def __iter__(self) -> Iterator[str]:
        for (name,) in self._store._pages("SELECT name FROM names WHERE name > ? ORDER BY name LIMIT ?", (b"",)):
            yield _text(name)


class Assigned:
    """What this run gave each input key: its output name, frame id and file identity
    (``(size, mtime_ns)`` or None), and the caller's fingerprint of what it was made of then."""

    def __init__(self, store: RunStore):
        self._store = store

    def get(self, key: str) -> tuple[str, int, tuple[int, int] | None] | None:
        rows = self._store._execute("SELECT name, frame, size, mtime_ns FROM assigned WHERE key = ?", (_blob(key),))
        if not rows:
            return None
        name, frame, size, mtime = rows[0]
        return _text(name), frame, None if size is None else (size, mtime)

    def fingerprint(self, key: str) -> str:
        rows = self._store._execute("SELECT fingerprint FROM assigned WHERE key = ?", (_blob(key),))
        return rows[0][0] if rows else ""

    def put(self, key: str, name: str, frame: int, identity: tuple[int, int] | None, fingerprint: str = "") -> None:
        size, mtime = identity if identity is not None else (None, None)
        self._store._execute("INSERT OR REPLACE INTO assigned (key, name, frame, size, mtime_ns, fingerprint) "
                             "VALUES (?, ?, ?, ?, ?, ?)", (_blob(key), _blob(name), frame, size, mtime, fingerprint))
