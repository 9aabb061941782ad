"""Sources of aligned face height fields on a canonical grid, for training and evaluation.

Every source returns ``(depths (M, H, W) float32 in pixel units with NaN off each face,
albedos (M, H, W) float32)`` with the two eye centres of every face on the grid's canonical
eye pixels, seen by an orthographic camera looking down -z.
"""
from __future__ import annotations

import json
import os
import re
import tomllib
from pathlib import Path

import numpy as np

from .faces.facegen import render_face, sample_face
from .faces.ict import canonical_mouth, ict_faces, mirror_pixels, placed, read_ict, shipped_basis
from .faces.placement import align_to_eyes, render_mesh


def procedural(n: int, seed: int = 0, grid: tuple[int, int] = (128, 128)) -> tuple[np.ndarray, np.ndarray]:
    """``n`` faces from the procedural anthropometric generator (deterministic in ``seed``)."""
    rng = np.random.default_rng(seed)
    depths, albedos = [], []
    for _ in range(n):
        d, _, a = render_face(sample_face(rng), grid)
        depths.append(d)
        albedos.append(a)
    return np.stack(depths), np.stack(albedos)


# iBUG-68 eye corner landmarks (1-based): image-left eye 37/40, image-right eye 43/46.
_EYE_CORNERS = ((37, 40), (43, 46))


def eos_model(path: str | os.PathLike, n: int, seed: int = 0, grid: tuple[int, int] = (128, 128),
              landmarks: str | os.PathLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``n`` faces drawn from an eos-format morphable model (e.g. the Surrey Face Model).

    Shape coefficients are drawn from N(0, 1) per mode of the rescaled basis. Eye centres
    are the mid-points of the eye-corner vertices given by the iBUG-to-model landmark file
    (default: ``ibug_to_sfm.txt`` next to the model). Albedo is constant 1 (shape-only model).
    Needs the ``eos-py`` package (``pip install shadowflow[eos]``).
    """
    depths = []
    for verts, tris, eyes, _ in eos_samples(path, n, seed, landmarks):
        depths.append(render_mesh(align_to_eyes(verts, eyes[0], eyes[1], grid), tris, grid))
    depths_a = np.stack(depths)
    return depths_a, np.where(np.isfinite(depths_a), 1.0, np.nan).astype(np.float32)


def eos_samples(path: str | os.PathLike, n: int, seed: int = 0, landmarks: str | os.PathLike | None = None
                ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """``n`` faces drawn from an eos-format morphable model (coefficients N(0, 1) per mode of the rescaled
    basis, deterministic in ``seed``): each ``(verts (V, 3), triangles (T, 3), eyes (2, 3): the eye-corner
    vertices' mid-points, image-left first, landmarks (68, 3): the iBUG points the landmark file maps, NaN
    for the others)``. ``landmarks``: the iBUG-to-model file (default ``ibug_to_sfm.txt`` next to the model).
    Needs the ``eos-py`` package (``pip install shadowflow[eos]``)."""
    try:
        import eos
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise RuntimeError("reading eos models needs the eos-py package: pip install 'shadowflow[eos]'") from exc
    path = Path(path)
    shape = eos.morphablemodel.load_model(str(path)).get_shape_model()
    tris = np.asarray(shape.get_triangle_list(), np.int64)
    mapping = read_landmark_mapping(Path(landmarks) if landmarks else path.with_name("ibug_to_sfm.txt"))
    k = shape.get_num_principal_components()
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        verts = np.asarray(shape.draw_sample(rng.standard_normal(k).astype(np.float32)), np.float64).reshape(-1, 3)
        lm = np.full((68, 3), np.nan)
        for number, vertex in mapping.items():
            lm[number - 1] = verts[vertex]
        eyes = np.stack([0.5 * (verts[mapping[a]] + verts[mapping[b]]) for a, b in _EYE_CORNERS])
        out.append((verts, tris, eyes, lm))
    return out


def read_landmark_mapping(path: str | os.PathLike) -> dict[int, int]:
    """iBUG landmark number -> vertex index, from an eos ``[landmark_mappings]`` TOML file."""
    with open(path, "rb") as f:
        data = tomllib.load(f)
    return {int(k): int(v) for k, v in data["landmark_mappings"].items()}


def mesh_folder(folder: str | os.PathLike, grid: tuple[int, int] = (128, 128)) -> tuple[np.ndarray, np.ndarray]:
    """Faces from a folder of meshes (``.obj`` / ``.ply``) and/or depth maps (``.npy``).

    Meshes are in millimetres, x right, y up, z toward the viewer, frontal; each needs a
    sidecar ``<stem>.json`` with ``{"eyes3d": [[x, y, z], [x, y, z]]}`` (image-left eye first).
    Depth maps (H, W) float are taken as already aligned to ``grid`` (NaN off the face).
    """

    import trimesh

    depths = []
    for f in sorted(Path(folder).iterdir()):
        suffix = f.suffix.lower()
        if suffix == ".npy":
            d = np.load(f, allow_pickle=False).astype(np.float32)
            if d.shape != tuple(grid):
                raise ValueError(f"{f}: depth map is {d.shape}, model grid is {tuple(grid)}")
            depths.append(d)
        elif suffix in (".obj", ".ply"):
            side = f.with_suffix(".json")
            if not side.exists():
                raise ValueError(f"{f}: mesh needs a sidecar {side.name} with eyes3d")
            eyes = np.asarray(json.loads(side.read_text())["eyes3d"], float)
            mesh = trimesh.load(f, force="mesh", process=False)
            v = align_to_eyes(np.asarray(mesh.vertices, float), eyes[0], eyes[1], grid)
            depths.append(render_mesh(v, np.asarray(mesh.faces), grid))
    if not depths:
        raise ValueError(f"{folder}: no .obj, .ply or .npy faces found")
    d = np.stack(depths)
    return d, np.where(np.isfinite(d), 1.0, np.nan).astype(np.float32)


SOURCES_HELP = "ict (the shipped real-scan model) | ict:PATH | procedural | eos:PATH | meshes:DIR"


def parse_source(spec: str) -> tuple[str, str | None]:
    """``ict`` | ``ict:PATH`` | ``procedural`` | ``eos:PATH`` | ``meshes:DIR`` -> (kind, argument)."""
    m = re.fullmatch(r"(procedural|ict)|(eos|meshes|ict):(.+)", spec)
    if not m:
        raise ValueError(f"unknown source {spec!r}: use {SOURCES_HELP}")
    return (m.group(1), None) if m.group(1) else (m.group(2), m.group(3))


def training_faces(spec: str, n: int, seed: int, grid: tuple[int, int], expressions: float = 0.0,
                   view: tuple[float, float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Faces to train a model on (``load_source``), their mean face's mouth centre (2,) and eye centres
    (2, 2) on ``grid`` where the source knows them (ICT; else None: the canonical eyes), the ICT model
    read once for all. ``view`` (yaw, pitch) degrees: the heads turned so (ICT only, ``faces.ict.placed``)."""
    kind, arg = parse_source(spec)
    if kind != "ict":
        if tuple(view) != (0.0, 0.0):
            raise ValueError(f"turned heads are a view of the ICT source, not of {spec!r}")
        return load_source(spec, n, seed, grid, expressions)[0], None, None

    basis = _ict_basis(arg)
    eyes = placed(basis.eyes, basis.eyes, grid, view)[:, :2] if tuple(view) != (0.0, 0.0) else None
    return ict_faces(basis, n, seed, grid, expressions, view)[0], canonical_mouth(basis, grid, view), eyes


def mirror_map(spec: str, mask: np.ndarray, view: tuple[float, float]) -> np.ndarray:
    """(N,) the mirror pixels of a model of the ICT source ``spec`` whose heads are turned by ``view``
    (``faces.ict.mirror_pixels``)."""
    kind, arg = parse_source(spec)
    if kind != "ict":
        raise ValueError(f"turned heads are a view of the ICT source, not of {spec!r}")
    return mirror_pixels(_ict_basis(arg), mask, view)


def _ict_basis(path: str | None):
    """The shipped ICT basis (``path`` None) or the one at ``path``."""

    return shipped_basis() if path is None else read_ict(path)


def load_source(spec: str, n: int, seed: int, grid: tuple[int, int],
                expressions: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Faces from a source spec (see ``parse_source``); ``expressions``: ICT only, the chance of
    each expression blendshape per face (``faces.ict.ict_faces``)."""
    kind, arg = parse_source(spec)
    if expressions and kind != "ict":
        raise ValueError(f"expressions are a variation of the ICT source, not of {spec!r}")
    if kind == "ict":

        return ict_faces(_ict_basis(arg), n, seed, grid, expressions)
    if kind == "procedural":
        return procedural(n, seed, grid)
    if kind == "eos":
        return eos_model(arg, n, seed, grid)
    d, a = mesh_folder(arg, grid)
    return d[:n], a[:n]
