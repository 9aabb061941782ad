"""``shadowflow eval shadows``: shadows the face does not cast, laid over Yale B photos and relit frontally.

For each subject, each input light (``LIGHTS``) and each kind of shadow (``occluders.KINDS``: a brim's, leaves', a
hand's, each drawn at random from the eyes found in the photo, keeping ``AMBIENT`` of the light in its core, its
penumbra ``PENUMBRA`` eye distances wide), the photo is relit frontally with and without the shadow
(``--foreign-shadows`` on, the light known from Yale B's names), over the face where stereo has normals:

- ``removed``: the share of the shadow's RMS error taken away, ``1 - rms(relit shadowed - relit clean) /
  rms(photo shadowed - photo clean)``: 0 when the relit photo keeps the shadow as it was, 1 when it comes back as
  the photo without it does;
- ``psnr`` and ``psnr_clean``: each relit photo against the real frontal photo, dB after a least-squares gain, and
  ``gap`` their difference (none for a frontal input: its photo relit without a shadow is the frontal photo itself).

Seeds make every shadow the same from run to run; ``--seed`` draws others (the held-out check takes other subjects
and another seed). Nothing is stored.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ...flow.chain import Chain
from ...flow.frame import Frame
from ..method.options import MethodOptions
from ..method.products import input_grid_products
from ..model.shape_model import ShapeModel
from ..photo.loader import read_photo
from ..relight.nodes import photo_nodes
from ..relight.products import relit_photos
from .occluders import KINDS, lay_shadow, occluder
from .people import figure
from .yaleb import build_ground_truth, subject_folders
from .yaleb_benchmark import gained_psnr

LIGHTS = ((0, 0), (25, 0), (-25, 0))
AMBIENT = (0.25, 0.45)  # the share of the light a shadow's core keeps, drawn uniformly
PENUMBRA = (0.01, 0.06)  # its penumbra's Gaussian width, eye distances, drawn uniformly


def removed_share(relit: np.ndarray, relit_clean: np.ndarray, photo: np.ndarray, photo_clean: np.ndarray,
                  region: np.ndarray) -> float:
    """The share of a shadow's RMS error over ``region`` (H, W) bool that the relighting took away (module
    docstring): ``relit`` and ``relit_clean`` (H, W) the photo relit with and without it, ``photo`` and
    ``photo_clean`` the photo with and without it."""
    before = float(np.sqrt(np.mean((np.asarray(photo, np.float64) - photo_clean)[region] ** 2)))
    after = float(np.sqrt(np.mean((np.nan_to_num(np.asarray(relit, np.float64)) - relit_clean)[region] ** 2)))
    return 1.0 - after / before if before > 0 else float("nan")


def _relit(chain: Chain, path: Path, image: np.ndarray) -> tuple[Frame, dict]:
    frame = chain.process(Frame(0, str(path), data={"image": image}))
    if not frame.ok:
        raise RuntimeError(frame.status)
    return frame, input_grid_products(frame.parts[0], relit_photos(frame))


def evaluate_subject(folder: str | Path, model: ShapeModel, options: MethodOptions = MethodOptions(light="yaleb"),
                     seed: int = 0, lights=LIGHTS, kinds=KINDS, looked_for: bool = True) -> list[dict]:
    """One row per input light and kind of shadow for the subject in ``folder`` (module docstring); a photo whose
    face is not found, with or without its shadow, gives a row with ``skipped``: why. looked_for: False relights
    without ``foreign_shadows`` (what the rest of the relighting makes of such a shadow)."""
    subject = build_ground_truth(folder)
    chain = Chain(photo_nodes(model, dataclasses.replace(options, foreign_shadows=looked_for)))
    rows = []
    for az, el in lights:
        path = subject.image_path(az, el)
        clean = read_photo(path).grey
        name = f"{az:+d},{el:+d}"
        try:
            frame, out = _relit(chain, path, clean)
        except RuntimeError as e:
            rows.extend({"subject": subject.name, "light": name, "kind": k, "skipped": str(e)} for k in kinds)
            continue
        region = out["mask"] & subject.stereo.valid
        relit_clean = np.nan_to_num(out["relit"]).astype(np.float64)
        eyes = np.asarray(frame.parts[0].data["placement"].eyes, np.float64)
        iod = float(np.hypot(*(eyes[1] - eyes[0])))
        frontal = (az, el) == (0, 0)
        for k, kind in enumerate(kinds):
            rng = np.random.default_rng([seed, k, az + 180, el + 90])
            ambient = float(rng.uniform(*AMBIENT))
            blocked = occluder(kind, clean.shape, eyes, rng)
            shadowed = lay_shadow(clean, blocked, ambient, float(rng.uniform(*PENUMBRA)) * iod)
            row = {"subject": subject.name, "light": name, "kind": kind, "ambient": round(ambient, 3)}
            try:
                shadowed_frame, shadowed_out = _relit(chain, path, shadowed)
            except RuntimeError as e:
                rows.append({**row, "skipped": str(e)})
                continue
            relit = np.nan_to_num(shadowed_out["relit"]).astype(np.float64)
            found = shadowed_frame.parts[0].meta.get("foreign_shadows") or {}
            row.update(removed=removed_share(relit, relit_clean, shadowed, clean, region),
                       psnr=gained_psnr(relit, subject.frontal, region),
                       psnr_clean=None if frontal else gained_psnr(relit_clean, subject.frontal, region),
                       found_area=found.get("area", 0.0))
            row["gap"] = None if frontal else row["psnr_clean"] - row["psnr"]
            rows.append(row)
    return rows


def evaluate(data: str | Path, model: ShapeModel, subjects: list[str] | None = None, seed: int = 0,
             options: MethodOptions = MethodOptions(light="yaleb"), looked_for: bool = True, note=print) -> list[dict]:
    """Rows for every ``yaleB*`` subject folder in ``data`` (or those named in ``subjects``), as
    ``evaluate_subject``'s."""
    folders = subject_folders(data, subjects)
    rows = []
    for folder in folders:
        rows.extend(evaluate_subject(folder, model, options, seed, looked_for=looked_for))
        note(f"{folder.name}: {sum('skipped' not in r for r in rows if r['subject'] == folder.name)} shadowed photos")
    return rows


def summarise(rows: list[dict]) -> list[dict]:
    """Per kind of shadow and per frontal / side input: the photos scored, the mean share removed, the mean gap."""
    out = []
    for kind in sorted({r["kind"] for r in rows}):
        for side in (False, True):
            rs = [r for r in rows if r["kind"] == kind and "skipped" not in r and (r["light"] != "+0,+0") == side]
            if not rs:
                continue
            gaps = [r["gap"] for r in rs if r.get("gap") is not None]
            out.append({"kind": kind, "lights": "+-25,+0" if side else "+0,+0", "n": len(rs),
                        "removed": float(np.mean([r["removed"] for r in rs])),
                        "removed_min": float(np.min([r["removed"] for r in rs])),
                        "gap": float(np.mean(gaps)) if gaps else None})
    return out


def format_table(rows: list[dict], summary: list[dict]) -> str:
    """Each photo's line, then the means (``summarise``)."""
    f = figure
    lines = [f"{'subject':8} {'light':>7} {'kind':6} {'ambient':>7} {'removed':>8} {'relit dB':>8} "
             f"{'clean dB':>8} {'gap dB':>7} {'found':>6}"]
    for r in rows:
        if "skipped" in r:
            lines.append(f"{r['subject']:8} {r['light']:>7} {r['kind']:6} skipped: {r['skipped']}")
            continue
        lines.append(f"{r['subject']:8} {r['light']:>7} {r['kind']:6} {r['ambient']:7.2f} {100 * r['removed']:7.0f}% "
                     f"{r['psnr']:8.2f} {f(r['psnr_clean'], '8.2f'):>8} {f(r['gap'], '7.2f'):>7} "
                     f"{100 * r['found_area']:5.0f}%")
    lines.append("means:")
    for s in summary:
        lines.append(f"{s['kind']:6} {s['lights']:>8} n={s['n']:<3d} removed {100 * s['removed']:3.0f}% "
                     f"(least {100 * s['removed_min']:3.0f}%), gap {f(s['gap'], '.2f')} dB")
    return "\n".join(lines)
