"""Writing files so that a reader never sees a partial one."""
from __future__ import annotations

import errno
import fcntl
import json
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterable, Iterator

_UMASK = os.umask(0)
os.umask(_UMASK)


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder and a rename.

    The file gets ordinary permissions (0666 less the umask), not mkstemp's 0600. An
    ``OSError`` (e.g. disk full) leaves no temporary file behind and names ``path``.
    """
    return atomic_write_chunks(path, (data,))


def atomic_write_chunks(path: str | os.PathLike, chunks: Iterable[bytes]) -> Path:
    """``atomic_write_bytes`` of the concatenated ``chunks``, written as they come: a large file
    made piece by piece (a report of thousands of rows) is never whole in memory."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            for data in chunks:
                f.write(data)
        os.chmod(tmp, 0o666 & ~_UMASK)
        os.replace(tmp, path)
    except BaseException as exc:
        if os.path.exists(tmp):
            os.unlink(tmp)
        if isinstance(exc, OSError) and exc.filename is None:  # say which file could not be written
            raise OSError(exc.errno, exc.strerror, str(path)) from exc
        raise
    return path


def json_array_chunks(items: Iterable, indent: int, level: int = 0, default=None) -> Iterator[bytes]:
    """``json.dumps(list(items), indent=indent)`` as it would appear nested ``level`` deep in an
    indented document, produced item by item (never the whole list in memory). Byte-equal to
    ``json.dumps`` of the list (tested)."""
    pad = " " * (indent * (level + 1))
    first = True
    for item in items:
        text = json.dumps(item, indent=indent, default=default).replace("\n", "\n" + pad)
        yield (("[\n" if first else ",\n") + pad + text).encode()
        first = False
    yield b"[]" if first else ("\n" + " " * (indent * level) + "]").encode()


class FolderBusy(RuntimeError):
    """Another process holds the folder's lock."""


class FolderLock:
    """The lock ``exclusive_folder`` holds: ``held()`` says whether it still guards the folder, i.e. the file at
    ``folder/.lock`` is still the one it locked (removing the folder, or the lock file, under a run lets a second
    run lock a new one)."""

    def __init__(self, fd: int, path: Path):
        self.fd, self.path = fd, path

    def held(self) -> bool:
        try:
            here, own = os.lstat(self.path), os.fstat(self.fd)
        except OSError:
            return False
        return (here.st_dev, here.st_ino) == (own.st_dev, own.st_ino)


@contextmanager
def exclusive_folder(folder: str | os.PathLike, holder: str) -> Iterator[FolderLock]:
    """Hold an exclusive lock on ``folder`` (``folder/.lock``, ``flock``) for the ``with`` body, which gets
    the ``FolderLock``.

    ``holder`` (e.g. a process id and command line) is written into the lock file so that a
    second process is told who holds it: ``FolderBusy`` with that text, at once (never waits).
    The kernel drops the lock when the holder exits, however it ends (kill -9 included), so a
    stale lock file is never an obstacle. The lock file is opened without following links.
    """
    path = Path(folder) / ".lock"
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o666 & ~_UMASK)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise OSError(exc.errno, "is a symbolic link; refusing to follow it", str(path)) from None
        raise
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            who = os.pread(fd, 4096, 0).decode("utf-8", "replace").strip() or "unknown process"
            raise FolderBusy(f"{folder}: in use by another run ({who}); wait for it to finish "
                             "or choose another --out") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, holder.encode("utf-8", "replace")[:4000], 0)
        yield FolderLock(fd, path)
    finally:
        os.close(fd)  # closing the descriptor releases the lock
