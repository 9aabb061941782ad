"""Writer: map a frame's model-grid products back to the input grid and write the layout of
``conventions.md`` (``OUT/<stem>/...`` and ``OUT/summary.json``), every file atomically."""
from __future__ import annotations

import io
import itertools
import json
import os
import re
import unicodedata
from collections.abc import MutableSet
from pathlib import Path
from typing import Iterable

import cv2
import numpy as np

from ...flow.files import atomic_write_bytes, atomic_write_chunks, json_array_chunks
from ...flow.frame import Frame
from ..method.products import input_grid_products, photo_mesh
from ..model.shape_model import ShapeModel

OUTPUT_FILES = ("normals.npy", "mask.png", "weights.npy", "depth.npy", "albedo.png", "shadow.png",
                "relit.png", "novel_view.png", "mesh.ply")


def real_path(path: str | Path) -> Path:
    """Absolute path with symlinks resolved as far as they go (a symlink loop stops there)."""
    try:
        return Path(path).resolve()
    except (OSError, RuntimeError):  # a symlink loop: its own name is the best we know
        return Path(os.path.abspath(path))


def safe_stem(path: str, taken: MutableSet[str]) -> str:
    """A file-system-safe, unique output folder name for an input path.

    Keeps letters, digits, ``.``, ``_`` and ``-`` (after Unicode NFKD folding), never starts
    with ``.`` or ``-``, and appends ``-2``, ``-3``... when the name is already in ``taken``
    (lower-case names, a set or one on disk; the name then joins it).
    """
    stem = Path(path).stem
    stem = unicodedata.normalize("NFKD", stem).encode("ascii", "ignore").decode("ascii")
    stem = re.sub(r"[^A-Za-z0-9._-]+", "_", stem).lstrip(".-_") or "input"
    stem = stem[:120]
    name, k = stem, 2
    while name.lower() in taken:
        name, k = f"{stem}-{k}", k + 1
    taken.add(name.lower())
    return name


def _npy_bytes(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, arr, allow_pickle=False)
    return buf.getvalue()


def _png_bytes(img8: np.ndarray) -> bytes:
    ok, enc = cv2.imencode(".png", img8)
    if not ok:
        raise OSError("PNG encoding failed")
    return enc.tobytes()


def mesh_ply_bytes(m: dict[str, np.ndarray]) -> bytes:
    """A mesh (``surface_mesh``'s dict) as a binary PLY with vertex colours."""
    import trimesh

    colours = np.column_stack([m["colours"], np.full(len(m["colours"]), 255, np.uint8)])
    mesh = trimesh.Trimesh(vertices=m["vertices"], faces=m["triangles"], vertex_colors=colours, process=False)
    return mesh.export(file_type="ply")


def to_8bit(values: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """[0, 1] floats (H, W) or RGB (H, W, 3) -> uint8 (RGB becomes OpenCV's BGR), 0 off the mask."""
    v = np.clip(np.nan_to_num(values) * 255.0 + 0.5, 0, 255)
    if v.ndim == 3:
        v = v[..., ::-1]
        if mask is not None:
            mask = mask[..., None]
    return (v if mask is None else np.where(mask, v, 0)).astype(np.uint8)


def light_name(light: np.ndarray) -> str:
    """A light's file-name tag, Yale B style: ``A+030E-10`` (azimuth, elevation in whole degrees;
    azimuth positive toward the image's left, as ``light_from_angles``)."""
    s = np.asarray(light, np.float64) / np.linalg.norm(light)
    el = np.degrees(np.arcsin(np.clip(s[1], -1, 1)))
    az = np.degrees(np.arctan2(-s[0], s[2]))
    return f"A{int(round(az)):+04d}E{int(round(el)):+03d}"


def write_outputs(frame: Frame, model: ShapeModel, folder: Path) -> dict[str, str]:
    """Write every output file of one frame into ``folder``; returns name -> path. Each file is
    encoded, written and let go before the next (a large photo's files are not all held at once)."""
    p = input_grid_products(frame, model)
    mask = p.pop("mask")
    encoders = {
        "normals.npy": lambda: _npy_bytes(p.pop("normals")),
        "mask.png": lambda: _png_bytes(np.where(mask, 255, 0).astype(np.uint8)),
        "weights.npy": lambda: _npy_bytes(p.pop("weights")),
        "depth.npy": lambda: _npy_bytes(p.pop("depth")),
        "albedo.png": lambda: _png_bytes(to_8bit(p.pop("albedo"), mask)),  # colour for a colour photo
        "shadow.png": lambda: _png_bytes(np.where(p.pop("lit"), 255, 0).astype(np.uint8)),
        "relit.png": lambda: _png_bytes(to_8bit(p.pop("relit"))),
        "novel_view.png": lambda: _png_bytes(to_8bit(frame.data["novel_view"], frame.data["novel_view"] > 0)),
    }
    for light, relit in p.pop("relit_extra"):
        encoders[f"relit_{light_name(light)}.png"] = lambda relit=relit: _png_bytes(to_8bit(relit))
    encoders["mesh.ply"] = lambda: mesh_ply_bytes(photo_mesh(frame, model))  # the fit's resolution, the photo's frame
    written = {}
    for name, encode in encoders.items():
        atomic_write_bytes(folder / name, encode())
        written[name] = str(folder / name)
    return written


class WriteNode:
    """Writes ``OUT/<frame.meta['stem']>/``; refuses to write over any input file."""

    name = "write"

    def __init__(self, model: ShapeModel, out_dir: Path, protected: set[Path]):
        self.model, self.out_dir, self.protected = model, out_dir, protected

    def __call__(self, frame: Frame) -> Frame:
        folder = self.out_dir / frame.meta["stem"]
        for path in (folder, *(folder / n for n in OUTPUT_FILES)):
            if path.is_symlink():  # would write outside --out, or over whatever the link names
                raise ValueError(f"{frame.source}: {path} is a symbolic link; refusing to write through it")
        clash = [n for n in OUTPUT_FILES if real_path(folder / n) in self.protected]
        if clash:
            raise ValueError(f"{frame.source}: writing {folder / clash[0]} would overwrite an input")
        write_outputs(frame, self.model, folder)
        frame.meta["outputs"] = str(folder)
        return frame


def summary_record(frame: Frame) -> dict:
    """One ``summary.json`` record (conventions.md) for a finished or failed frame."""
    m = frame.meta
    rec = {
        "source": frame.source,
        "stem": m.get("stem"),
        "status": frame.status,
        "quality": m.get("quality"),
        "light": m.get("light"),
        "light_source": m.get("light_source"),
        "alignment": m.get("alignment"),
        "iterations": m.get("iterations"),
        "converged": m.get("converged"),
        "final_sigma": m.get("final_sigma"),
        "seconds": round(float(sum(m.get("timings", {}).values())), 4),
    }
    if m.get("reduced"):
        rec["reduced"] = m["reduced"]
    if frame.failed_in:
        rec["failed_in"] = frame.failed_in
    flags = (m.get("quality") or {}).get("flags")
    if frame.ok and flags:  # outputs written, but the user should look before trusting them
        rec["status"] = "doubtful: " + "; ".join(flags)
    return rec


def write_summary(out_dir: Path, records: Iterable[dict]) -> None:
    """``out_dir/summary.json``: the records (input order) as a JSON list, written atomically and
    record by record (a run's records come from its store on disk, never all in memory)."""
    chunks = json_array_chunks(records, indent=2)
    atomic_write_chunks(out_dir / "summary.json", itertools.chain(chunks, [b"\n"]))
