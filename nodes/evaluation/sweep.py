"""``shadowflow eval sweep``: a Yale B subject's light swept across the face as a clip, relit frontally.

The subject's photos at elevation 0 from azimuth -70 to +70 degrees and back (``SWEEP``, each held ``HOLD`` frames:
a light moving in steps) are made a clip (lossless FFV1, grey, ``RATE`` frames a second). The run relights the clip
(its frames carried from one to the next: the light, the turn, the change of light) and the same photos one by one as
stills; each relit frame is scored against the subject's real frontal photo over the face where stereo has normals
(dB after a least-squares gain, the relit photo moved by the camera's shift, as ``eval yaleb`` scores them):

- ``clip_db``, ``still_db``, ``input_db``: per frame, the clip's relit frame, the same photo relit as a still, and the
  photo itself;
- ``level``: the relit face's mean level (of 255) per frame, and ``level_step``: the RMS of its change from frame to
  frame, which a relighting to one light keeps small whatever the photo's light (the photo's own is the input's);
- ``light_err``: the angle (degrees) between the light each frame's face was read under and the true light.

A frame's relit file is its ``--frames`` PNG (``OUT/<clip>/frames/<index>/relit.png``), not the H.264 clip, so the
clip and the stills are scored alike. Nothing is stored but in the run's folder.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..geometry.normals import angle_deg
from ..geometry.reflectance import light_from_angles
from ..photo.loader import load_image
from .people import figure
from .yaleb import YaleSubject
from .yaleb_benchmark import camera_shift, gained_psnr, stereo_shift, translate

SWEEP = (-70, -50, -25, -10, 0, 10, 25, 50, 70)  # azimuths at elevation 0 every subject has, degrees
HOLD = 2
RATE = 10


def sweep_order(azimuths: tuple[int, ...] = SWEEP, hold: int = HOLD) -> list[int]:
    """The azimuth of each frame: ``azimuths`` there and back (the last one once), each held ``hold`` frames."""
    there = list(azimuths)
    return [a for a in there + there[-2::-1] for _ in range(hold)]


def photo_path(subject: YaleSubject, azimuth: int) -> Path:
    """The subject's photo lit from ``azimuth`` degrees at elevation 0."""
    return subject.image_path(azimuth, 0)


def sweep_photos(subject: YaleSubject, order: list[int]) -> dict[int, np.ndarray]:
    """Each azimuth of ``order``'s photo of the subject: (H, W) float32 in [0, 1], linear (its file's values)."""
    return {a: load_image(photo_path(subject, a)) for a in sorted(set(order))}


def write_sweep_clip(photos: dict[int, np.ndarray], order: list[int], path: Path, rate: int = RATE) -> Path:
    """The ``photos`` (``sweep_photos``) in ``order`` (azimuths) written to ``path`` (.mkv) as a lossless grey clip."""
    import av

    frames = {a: np.round(np.clip(image, 0.0, 1.0) * 255.0).astype(np.uint8) for a, image in photos.items()}
    h, w = next(iter(frames.values())).shape
    with av.open(str(path), mode="w") as out:
        stream = out.add_stream("ffv1", rate=rate)
        stream.width, stream.height, stream.pix_fmt = w, h, "gray"
        for a in order:
            out.mux(stream.encode(av.VideoFrame.from_ndarray(frames[a], format="gray")))
        out.mux(stream.encode(None))
    return path


def _light_err(light, azimuth: int) -> float:
    if light is None:
        return float("nan")
    return float(angle_deg(np.asarray(light, np.float64)[None], light_from_angles(azimuth, 0)[None])[0])


def _face_light(record: dict | None) -> list | None:
    faces = [] if record is None else [f for f in record.get("faces", []) if f.get("light")]
    return faces[0]["light"] if faces else None


def score_sweep(subject: YaleSubject, photos: dict[int, np.ndarray], order: list[int], clip_folder: Path,
                still_folders: dict[int, Path], summary: dict[str, dict]) -> dict:
    """The figures of one subject's sweep (module docstring): ``photos`` its photos (``sweep_photos``),
    ``clip_folder`` the run's folder of the clip (its ``frames.jsonl`` and ``frames/``), ``still_folders`` each
    azimuth's still's folder, ``summary`` the run's records by stem (the stills' lights)."""
    region = subject.stereo.valid
    front = stereo_shift(subject, subject.frontal, light_from_angles(0, 0))
    shifts = {a: camera_shift(subject, photos[a], light_from_angles(a, 0), front) for a in photos}

    def db(image: np.ndarray, a: int) -> float:
        return gained_psnr(translate(image, shifts[a]), subject.frontal, region)

    def level(image: np.ndarray) -> float:
        return float(np.mean(np.nan_to_num(image)[region]) * 255.0)

    lines = {}
    with open(clip_folder / "frames.jsonl", encoding="utf-8") as f:
        for row in f:
            line = json.loads(row)
            lines[int(line["index"])] = line
    stills = {a: load_image(still_folders[a] / "relit.png") for a in photos}
    frames = []
    for i, a in enumerate(order):
        relit = load_image(clip_folder / "frames" / f"{i:06d}" / "relit.png")
        frames.append({"azimuth": a, "clip_db": db(relit, a), "still_db": db(stills[a], a),
                       "input_db": db(photos[a], a), "clip_level": level(relit), "still_level": level(stills[a]),
                       "input_level": level(photos[a]),
                       "clip_light_err": _light_err(_face_light(lines.get(i)), a),
                       "still_light_err": _light_err(_face_light(summary.get(still_folders[a].name)), a)})
    return {"subject": subject.name, "frames": frames, **_figures(frames)}


def _figures(frames: list[dict]) -> dict:
    """A sweep's figures over its frames: medians and means of each dB, the level's step RMS, the light's error."""
    out = {}
    for who in ("clip", "still", "input"):
        dbs = np.array([f[f"{who}_db"] for f in frames])
        levels = np.array([f[f"{who}_level"] for f in frames])
        out[f"{who}_db_median"] = float(np.median(dbs))
        out[f"{who}_db_mean"] = float(np.mean(np.minimum(dbs, 60.0)))  # (a photo scored against itself: 60 dB)
        out[f"{who}_level_step"] = float(np.sqrt(np.mean(np.diff(levels) ** 2)))
    for who in ("clip", "still"):
        out[f"{who}_light_err_median"] = float(np.nanmedian([f[f"{who}_light_err"] for f in frames]))
    # the frames the clip relit worse than its still by more than half a decibel
    out["clip_worse"] = int(sum(f["clip_db"] < f["still_db"] - 0.5 for f in frames))
    return out


def format_table(rows: list[dict]) -> str:
    """One line per subject: dB median (clip / stills / input), their means, the level's step RMS, the light's error,
    and the frames the clip relit worse than its still."""
    f = figure
    lines = [f"{'subject':10s} {'dB median clip/still/input':>27s} {'dB mean clip/still':>19s} "
             f"{'level step clip/still/input':>28s} {'light err clip/still':>21s} {'worse':>6s}"]
    for r in rows:
        lines.append(f"{r['subject']:10s} {f(r['clip_db_median'], '.2f'):>9s}/{f(r['still_db_median'], '.2f'):>6s}/"
                     f"{f(r['input_db_median'], '.2f'):>6s}      {f(r['clip_db_mean'], '.2f'):>6s}/"
                     f"{f(r['still_db_mean'], '.2f'):>6s}        {f(r['clip_level_step'], '.1f'):>6s}/"
                     f"{f(r['still_level_step'], '.1f'):>6s}/{f(r['input_level_step'], '.1f'):>6s}"
                     f"       {f(r['clip_light_err_median'], '.1f'):>5s}/{f(r['still_light_err_median'], '.1f'):>5s}"
                     f"   {r['clip_worse']:>3d}/{len(r['frames'])}")
    return "\n".join(lines)
