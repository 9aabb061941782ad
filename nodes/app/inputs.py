"""What a run reads: files, folders and glob patterns expanded to input paths, and a folder
watched for new images (``shadowflow run --watch``)."""
from __future__ import annotations

import glob
import os
import stat
import time
from pathlib import Path
from typing import Iterator

from ...flow.manifest import content_hash
from ..photo.loader import IMAGE_SUFFIXES as STILL_SUFFIXES
from ..photo.sidecar import sidecar_path
from .clip_io import CLIP_SUFFIXES

IMAGE_SUFFIXES = STILL_SUFFIXES | CLIP_SUFFIXES  # what a run takes from a folder or glob: stills and clips


def _output_folder(path: Path) -> bool:
    """A folder of a run's outputs (``OUT/<stem>/``), e.g. ``photo.png/`` made from ``photo.png.png``; a clip's
    (``clip.mp4/`` holding ``relit.mp4``) too."""
    return path.is_dir() and (((path / "normals.npy").is_file() and (path / "mask.png").is_file())
                              or (path / "frames.jsonl").is_file())


def expand_inputs(items: list[str], note=print) -> list[str]:
    """Files, folders (sorted, not recursed; names without an image suffix skipped with a
    note, hidden files and output folders without one) and glob patterns -> paths. Anything named like an image is kept, even a folder,
    a broken link or a pipe: its frame then fails with the loader's exact reason."""
    out: list[str] = []
    for item in items:
        p = Path(item)
        if p.is_dir():
            for f in sorted(p.iterdir()):
                if f.name.startswith(".") or _output_folder(f):
                    continue  # hidden files, and a run's own outputs when --out is this folder
                if f.suffix.lower() in IMAGE_SUFFIXES:
                    out.append(str(f))
                elif f.suffix.lower() != ".json":
                    note(f"{f}: skipped (not an image)")
        elif not p.exists() and any(ch in item for ch in "*?["):
            matches = sorted(glob.glob(item))
            if not matches:
                note(f"{item}: no file matches")
            out.extend(m for m in matches if Path(m).suffix.lower() in IMAGE_SUFFIXES)
        else:
            out.append(item)  # missing or unreadable files fail as frames, with their reason
    return out


class FolderWatch:
    """Image files in ``folder`` (sorted), then each new one as it appears; iterate it for paths.

    A file is taken once its size and mtime, and its sidecar's (``<stem>.json``), have stayed the same for
    ``settle`` seconds (or their mtimes are already that old), so a file still being copied in is not read
    half-written. A file taken before is taken again when it or its sidecar changes (replaced, completed
    after a stalled copy was read and failed, or its sidecar arriving after it). Ends after ``idle_exit`` seconds with nothing new handed on and
    nothing waiting to settle (None: never, until Ctrl-C), or when the folder goes away: ``error``
    then says why (one line)."""

    def __init__(self, folder: Path, suffixes: set[str], idle_exit: float | None, poll: float = 0.5,
                 settle: float = 1.0):
        self.folder, self.suffixes, self.idle_exit, self.poll, self.settle = folder, suffixes, idle_exit, poll, settle
        self.error: str | None = None

    def _listing(self) -> dict[Path, tuple[tuple, int, float]] | None:
        """path -> (identity: its and its sidecar's size and mtime_ns, size, the later mtime in s) of the image
        files now in the folder; None when it is gone."""
        try:
            names = sorted(self.folder.iterdir())
        except OSError as exc:
            self.error = f"--watch {self.folder}: {exc.strerror or exc}; stopped watching"
            return None
        found = {}
        for f in names:
            if f.suffix.lower() not in self.suffixes or f.name.startswith("."):
                continue  # hidden files (a Mac's ._ companions) are skipped, as in folder mode
            try:
                st = f.stat()
            except OSError:
                continue  # gone again, or a dangling link: nothing to take yet
            if stat.S_ISREG(st.st_mode):
                side = _sidecar_stat(f)
                ident = (st.st_size, st.st_mtime_ns, *(side[:2] if side else ()))
                found[f] = (ident, st.st_size, max(st.st_mtime, side[2] if side else 0.0))
        return found

    def __iter__(self) -> Iterator[str]:
        taken: dict[Path, tuple] = {}  # identity when last taken
        since: dict[Path, tuple[tuple, float]] = {}  # identity first seen unchanged, and when
        last_new = time.monotonic()
        while True:
            listing = self._listing()
            if listing is None:
                return
            now, wall = time.monotonic(), time.time()
            waiting = False  # a file seen but not yet taken (being copied in): not idle
            for f, (ident, size, mtime) in listing.items():
                if taken.get(f) == ident:
                    continue
                if since.get(f, (None,))[0] != ident:
                    since[f] = (ident, now)
                settled = now - since[f][1] >= self.settle or wall - mtime >= self.settle
                if size > 0 and settled:
                    taken[f] = ident
                    yield str(f)
                    # the idle clock starts when a file is handed on: the run may take its time over a burst
                    last_new = time.monotonic()
                elif not settled:  # (an empty file that stays empty is nothing to wait for)
                    waiting = True
            if self.idle_exit is not None and not waiting and time.monotonic() - last_new > self.idle_exit:
                return
            time.sleep(self.poll)


def _sidecar_stat(image: Path) -> tuple[int, int, float] | None:
    """(size, mtime_ns, mtime in s) of the image's sidecar when it has one (a regular file), else None."""
    try:
        st = sidecar_path(image).stat()
    except (OSError, ValueError):
        return None
    return (st.st_size, st.st_mtime_ns, st.st_mtime) if stat.S_ISREG(st.st_mode) else None


def input_fingerprint(path: str | os.PathLike) -> str:
    """What an input is made of, for ``--resume`` to recognise: the SHA-256 of the image's bytes, and
    of its sidecar's when it has one (its eyes and light change the fit). Empty when the image cannot
    be read."""
    image = content_hash(path)
    if not image:
        return ""
    try:
        side = sidecar_path(path)
        has_side = side.is_file()
    except (OSError, ValueError):
        has_side = False
    return f"{image}+{content_hash(side) or 'unreadable'}" if has_side else image
