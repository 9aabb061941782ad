"""Extended Yale Face Database B: photometric-stereo ground truth per subject.

A subject folder holds ``yaleBxx_P00A{+|-}aaaE{+|-}ee.pgm`` (one point light each, see
``conventions.md``) and ``yaleBxx_P00_Ambient.pgm``. Ground truth is built from all of them:
ambient removed, exposures with the lamp off or with interference stripes detected and left
out, each exposure registered to the first fit's rendering of it (subjects moved a few pixels
between exposures), then robust photometric stereo. Nothing here is ever written to disk.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..geometry.reflectance import light_from_angles
from ..photo.lights import yaleb_angles
from ..photo.loader import load_image
from .photometric_stereo import (
    StereoResult,
    photometric_stereo,
    register_translation,
    render,
)

FRONTAL = "P00A+000E+00"


def light_name(path: str | Path) -> str:
    """``P00A+050E+00`` from a Yale B file name."""
    return Path(path).stem.split("_", 1)[1]


def stripe_score(image: np.ndarray) -> float:
    """Interference stripes are horizontal: mean |second difference| of the row means."""
    return float(np.mean(np.abs(np.diff(np.asarray(image, np.float64).mean(axis=1), 2))))


@dataclass
class YaleSubject:
    """A subject's ground truth. stereo: photometric stereo on the subject's own grid;
    frontal: the real frontal photo (H, W) in [0, 1]; excluded: light name -> why it was left
    out; shifts: light name -> (dx, dy) pixels it was moved by to register it."""

    name: str
    folder: Path
    stereo: StereoResult
    frontal: np.ndarray
    exposures: int
    excluded: dict[str, str] = field(default_factory=dict)
    shifts: dict[str, tuple[float, float]] = field(default_factory=dict)

    def image_path(self, azimuth: int, elevation: int) -> Path:
        return self.folder / f"{self.name}_P00A{azimuth:+04d}E{elevation:+03d}.pgm"


def _unusable(images: np.ndarray, lights: np.ndarray, names: list[str]) -> dict[str, str]:
    """Exposures left out of the stereo, with why: interference stripes, a light behind the face plane."""
    excluded: dict[str, str] = {}
    stripes = np.array([stripe_score(im) for im in images])
    for i in np.flatnonzero(stripes > 4.0 * np.median(stripes)):
        excluded[names[i]] = f"interference stripes ({stripes[i] / np.median(stripes):.0f}x the usual row ripple)"
    for i in np.flatnonzero(lights[:, 2] <= 0.0):
        excluded.setdefault(names[i], "light behind the face plane")
    return excluded


def _dark(images: np.ndarray, lights: np.ndarray, names: list[str], stereo: StereoResult,
          excluded: dict[str, str]) -> dict[str, str]:
    """Exposures far darker than the stereo predicts for their light (the lamp off), with why."""
    out = {}
    for i, n in enumerate(names):
        if n in excluded:
            continue
        pred = render(stereo, lights[i])
        ratio = images[i][stereo.valid].sum() / max(pred[stereo.valid].sum(), 1e-9)
        if ratio < 0.3:
            out[n] = f"too dark for its light (lamp off?): {ratio:.2f} of the expected brightness"
    return out


def _registered(images: np.ndarray, lights: np.ndarray, names: list[str], stereo: StereoResult,
                excluded: dict[str, str], max_shift: float, shifts: dict) -> np.ndarray:
    """Each used exposure moved onto the stereo's rendering of it (by at most ``max_shift`` pixels; the
    shifts kept in ``shifts``)."""
    registered = images.copy()
    for i, n in enumerate(names):
        if n in excluded:
            continue
        moved, shift = register_translation(images[i], render(stereo, lights[i]))
        if np.hypot(*shift) <= max_shift:  # larger: a poor rendering to match, not a move
            registered[i], shifts[n] = moved, shift
    return registered


def subject_folders(data: str | Path, subjects: list[str] | None = None) -> list[Path]:
    """The ``yaleB*`` subject folders in ``data``, sorted (only those named in ``subjects``, if given);
    ``ValueError`` naming what is missing when a named one is, or when there are none."""
    folders = sorted(p for p in Path(data).iterdir() if p.is_dir() and p.name.startswith("yaleB"))
    if subjects:
        missing = sorted(set(subjects) - {p.name for p in folders})
        if missing:
            raise ValueError(f"{data}: no subject folder {', '.join(missing)}")
        folders = [p for p in folders if p.name in subjects]
    if not folders:
        raise ValueError(f"{data}: no yaleB* subject folders")
    return folders


def build_ground_truth(folder: str | Path, register_rounds: int = 2, max_shift: float = 5.0) -> YaleSubject:
    """Photometric-stereo normals and albedo for one subject folder (see module docstring);
    exposures are moved by at most ``max_shift`` pixels to register them."""
    folder = Path(folder)
    paths = sorted(p for p in folder.glob("*_P00A*.pgm"))
    if len(paths) < 10:
        raise ValueError(f"{folder}: expected Yale B exposures *_P00A*.pgm, found {len(paths)}")
    name = paths[0].stem.split("_", 1)[0]
    ambient_path = folder / f"{name}_P00_Ambient.pgm"
    ambient = load_image(ambient_path) if ambient_path.exists() else 0.0
    names = [light_name(p) for p in paths]
    raw = np.stack([load_image(p) for p in paths])
    images = np.clip(raw - ambient, 0.0, 1.0)
    lights = np.stack([light_from_angles(*yaleb_angles(p)) for p in paths])
    excluded = _unusable(images, lights, names)

    def fit(imgs: np.ndarray) -> StereoResult:
        use = np.array([n not in excluded for n in names])
        return photometric_stereo(imgs[use], lights[use])

    stereo = fit(images)
    dark = _dark(images, lights, names, stereo, excluded)
    if dark:
        excluded.update(dark)
        stereo = fit(images)
    shifts: dict[str, tuple[float, float]] = {}
    for _ in range(register_rounds):
        images = _registered(images, lights, names, stereo, excluded, max_shift, shifts)
        stereo = fit(images)
    frontal = raw[names.index(FRONTAL)] if FRONTAL in names else None
    return YaleSubject(name, folder, stereo, frontal, len(paths), excluded, shifts)
