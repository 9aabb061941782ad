"""How a run counts what it did, said the same way on the terminal, in ``report.html`` and by the exit code: each
photo ok, doubtful or failed, each of its faces ok, doubtful or refused, read from its ``summary.json`` record."""
from __future__ import annotations

from typing import Iterable

from ..method.quality import NO_FACE


def counted_faces(rec: dict) -> list[tuple[int, dict]]:
    """The faces of a finished input (its ``summary_record``) that count, numbered from 1: every face, less the
    candidates the fit found no face in beside a real face (listed in summary.json with their reason, not the
    photo's faces); none when the input failed as a whole."""
    faces = rec.get("faces") or []
    if rec.get("failed_in") or not faces:
        return []
    has_face = any(_kind(f["status"]) != "refused" for f in faces)
    return [(k, f) for k, f in enumerate(faces, start=1)
            if not (has_face and _kind(f["status"]) == "refused" and f": {NO_FACE}" in f["status"])]


def _kind(status: str) -> str:
    """A face's status as counted: "ok", "doubtful" (outputs written, to be looked at) or "refused"."""
    return "ok" if status == "ok" else "doubtful" if status.startswith("doubtful: ") else "refused"


def photo_status(rec: dict) -> str:
    """A finished input as counted: "failed" (no outputs: no face, or it failed as a whole), "ok" (every face that
    counts is ok) or "doubtful" (written, a face doubtful or refused)."""
    if rec.get("clip") is not None:  # a clip: its faces are its frames' (frames.jsonl)
        return "ok" if rec["status"] == "ok" else "failed"
    kinds = [_kind(f["status"]) for _, f in counted_faces(rec)]
    if "ok" not in kinds and "doubtful" not in kinds:
        return "failed"
    return "ok" if all(k == "ok" for k in kinds) else "doubtful"


def tally(records: Iterable[dict]) -> dict[str, int]:
    """How many photos are ok, doubtful and failed, and how many of their faces are ok, doubtful and refused
    (``photo_status``, ``counted_faces``); how many clips are ok and failed, and how many of their frames had a face
    ok, doubtful or none that came through (their records' ``frame_status``): what the terminal and the report both
    say of a run. "inputs" and "inputs ok" count photos and clips together (the exit code's)."""
    t = dict.fromkeys(("photos", "ok", "doubtful", "failed", "faces", "faces ok", "faces doubtful", "refused",
                       "clips", "clips ok", "clips failed", "frames", "frames ok", "frames doubtful",
                       "frames without"), 0)
    for rec in records:
        if rec.get("clip") is not None:
            _tally_clip(t, rec)
            continue
        t["photos"] += 1
        t[photo_status(rec)] += 1
        for _, face in counted_faces(rec):
            t["faces"] += 1
            kind = _kind(face["status"])
            t["refused" if kind == "refused" else f"faces {kind}"] += 1
    t["inputs"], t["inputs ok"] = t["photos"] + t["clips"], t["ok"] + t["clips ok"]
    return t


def _tally_clip(t: dict[str, int], rec: dict) -> None:
    """A clip's record counted into ``t``: the clip ok or failed, its frames by their status (``frame_status``:
    "ok", "doubtful: ...", or why no face came through)."""
    t["clips"] += 1
    t[f"clips {photo_status(rec)}"] += 1
    for why, n in (rec["clip"].get("frame_status") or {}).items():
        t["frames"] += n
        kind = "ok" if why == "ok" else "doubtful" if why.startswith("doubtful") else "without"
        t[f"frames {kind}"] += n


def _many(n: int, word: str) -> str:
    return f"{n} {word}" + ("" if n == 1 else "s")


def tally_text(t: dict[str, int]) -> str:
    """``tally`` in words: "3 photos (2 ok, 1 doubtful, 0 failed); 5 faces (3 ok, 1 doubtful, 1 refused)", and for
    clips "1 clip (1 ok, 0 failed) of 30 frames (28 with a face ok, 2 doubtful, 0 without)"; photos are not named
    in a run of clips only."""
    parts = []
    if t["photos"] or not t.get("clips"):
        parts.append(f"{_many(t['photos'], 'photo')} ({t['ok']} ok, {t['doubtful']} doubtful, {t['failed']} failed); "
                     f"{_many(t['faces'], 'face')} ({t['faces ok']} ok, {t['faces doubtful']} doubtful, "
                     f"{t['refused']} refused)")
    if t.get("clips"):
        parts.append(f"{_many(t['clips'], 'clip')} ({t['clips ok']} ok, {t['clips failed']} failed) of "
                     f"{_many(t['frames'], 'frame')} ({t['frames ok']} with a face ok, {t['frames doubtful']} "
                     f"doubtful, {t['frames without']} without)")
    return "; ".join(parts)


def status_lines(rec: dict) -> list[str]:
    """What the terminal says of a finished input (its ``summary_record``): nothing when every face is
    ok, else one line per face (or for the input) that failed, was refused or is doubtful, naming its file."""
    faces = counted_faces(rec)
    if not faces:  # the input failed as a whole
        return [] if rec["status"] == "ok" else [f"error: {rec['status']}"]
    lines = []
    for k, face in faces:
        status = face["status"]
        name = rec["source"] if k == 1 else f"{rec['source']} (face {k})"
        if _kind(status) == "doubtful":
            lines.append(f"doubtful: {name}: {status[len('doubtful: '):]}")
        elif _kind(status) == "refused":
            lines.append(f"error: {status}")
    return lines
