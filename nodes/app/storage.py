"""The output folder (``--out``) checked before a run, and what stops a run once it takes no more data: the
storage failures and their one line."""
from __future__ import annotations

import errno
import os
from pathlib import Path

from ...flow.files import atomic_write_bytes
from .outputs import foreign_run_files

# errors that fail every later write too: the run stops instead of failing frame after frame (EPERM, EACCES: the
# folder made immutable or read-only under the run; ESTALE: removed or replaced under it, ``FolderLock``)
STORAGE_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS, errno.EPERM, errno.EACCES, errno.ESTALE}


class StorageError(OSError):
    """The output folder cannot take more data (full, read-only, over quota)."""


def refuse_link(path: Path) -> None:
    """``ValueError`` when ``path`` is a symbolic link: nothing under ``--out`` is written through one."""
    if path.is_symlink():
        raise ValueError(f"{path}: is a symbolic link; shadowflow writes nothing through links in --out "
                         "(remove it, or choose another --out)")


def cannot_write(path, exc: OSError) -> str:
    """The one line said when ``path`` could not be written."""
    return f"{path}: cannot be written ({exc.strerror or exc})"


def out_folder(text: str | os.PathLike) -> Path:
    """``--out`` (or the API's ``out``) as a folder; ``ValueError`` for an empty name, which would be the working
    folder (and a run writes over its ``report.html``, ``summary.json`` and ``manifest.json``)."""
    if not os.fspath(text).strip():
        raise ValueError(f"--out {os.fspath(text)!r}: an empty name; name a folder (--out . for this one)")
    return Path(text)


def check_out(out: Path) -> None:
    """``check_writable``, once ``out`` is known to hold no file of a run's names that a run did not write
    (``outputs.foreign_run_files``); else ``ValueError`` naming the first."""
    foreign = foreign_run_files(out)
    if foreign:
        more = f" (and {len(foreign) - 1} more)" if len(foreign) > 1 else ""
        if (out / foreign[0]).is_symlink():
            refuse_link(out / foreign[0])
        raise ValueError(f"--out {out}: holds {foreign[0]}, which no shadowflow run wrote, and a run writes over "
                         f"it{more}; choose another --out")
    check_writable(out)


def check_writable(out: Path) -> None:
    """Create ``out`` if needed and prove a file can be written there; else ``StorageError``."""
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = atomic_write_bytes(out / ".shadowflow-write-test", b"ok")
        probe.unlink()
    except OSError as exc:
        raise StorageError(f"--out {out}: cannot write there ({exc.strerror or exc})") from None


def storage_failure(exc: BaseException | None) -> bool:
    """``exc`` is a storage failure (``STORAGE_ERRNOS``): not the frame's fault, and every later write would fail too."""
    return isinstance(exc, OSError) and exc.errno in STORAGE_ERRNOS
