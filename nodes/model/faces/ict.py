"""ICT-FaceKit's morphable face model as a source of real-scan faces.

ICT-FaceKit (USC Institute for Creative Technologies; Li et al., "Learning Formation of
Physically-Based Face Attributes", CVPR 2020; MIT licence, notice in ``nodes/data/``) is a
linear identity model learnt from light-stage scans of real people: a face is
``neutral + sum_k w_k identity_k`` with ``w_k ~ N(0, 1)``. Its frame: centimetres, +x toward the
subject's left (the image's right in a frontal photo), +y up, +z toward the camera.

Readers take the upstream ``FaceXModel/`` folder (``generic_neutral_mesh.obj`` and
``identityNNN.obj``, optionally the expression OBJs), the one-file ``.npz`` of it
(``neutral``, ``identity_deltas``, ``faces``, optionally ``expression_deltas``), or the compact
face-area basis this package ships (``nodes/data/ict_face_basis.npz``, written by
``write_compact``). All of them become an ``IctBasis`` over the face area only, with the two iris
centres (the eye points) carried as linear functions of the same weights.
"""
from __future__ import annotations

import io
import os
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ....flow.files import atomic_write_bytes
from .placement import align_to_eyes, render_mesh, turn_to_view

FACE_VERTICES = 9409  # upstream vertex ranges: 0-9408 is the full face area
IRIS_RIGHT = (23791, 24591)  # the subject's right iris: the image's left eye
IRIS_LEFT = (22221, 23021)  # the subject's left iris: the image's right eye
UPSTREAM_VERTICES = 26719
# the lips' parting line at the midline: Multi-PIE landmarks 62 and 66 (inner lips, upper and lower),
# upstream vertex_indices.json "idx_to_landmark_verts"; both inside the face area
STOMION = (5533, 5517)
# the Multi-PIE 68 facial landmarks (0-based order: jaw 0-16, brows 17-26, nose 27-35, eyes 36-47, mouth 48-67),
# upstream vertex_indices.json "idx_to_landmark_verts"; all inside the face area
LANDMARKS = (1225, 1888, 1052, 367, 1719, 1722, 2199, 1447, 966, 3661, 4390, 3927, 3924, 2608, 3272, 4088, 3443,
             268, 493, 1914, 2044, 1401, 3615, 4240, 4114, 2734, 2509, 978, 4527, 4942, 4857, 1140, 2075, 1147,
             4269, 3360, 1507, 1542, 1537, 1528, 1518, 1511, 3742, 3751, 3756, 3721, 3725, 3732, 5708, 5695, 2081,
             0, 4275, 6200, 6213, 6346, 6461, 5518, 5957, 5841, 5702, 5711, 5533, 6216, 6207, 6470, 5517, 5966)
COMPACT_FORMAT = "shadowflow-ict-face-basis-1"
SHIPPED = Path(__file__).resolve().parents[1] / "data" / "ict_face_basis.npz"


@dataclass(frozen=True)
class IctBasis:
    """The face area of the ICT model. neutral: (V, 3) cm; identity: (K, V, 3) cm per unit
    weight; triangles: (T, 3) int over the V face vertices, counter-clockwise seen from +z;
    eyes: (2, 3) iris centres of the neutral face, image-left (subject's right) first;
    eye_identity: (K, 2, 3) their change per unit identity weight; expressions: (E, V, 3),
    blendshape deltas for weights in [0, 1] (E may be 0); expression_names: (E,) str."""

    neutral: np.ndarray
    identity: np.ndarray
    triangles: np.ndarray
    eyes: np.ndarray
    eye_identity: np.ndarray
    expressions: np.ndarray
    expression_names: tuple[str, ...]

    @property
    def n_identity(self) -> int:
        return int(self.identity.shape[0])

    def face(self, w_identity: np.ndarray, w_expression: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Vertices (V, 3) and eye points (2, 3) of one face, cm, the model's frame.
        w_identity: (k,) with k <= K (the first k modes); w_expression: (E,) in [0, 1]."""
        w = np.asarray(w_identity, np.float64)
        k = len(w)
        v = self.neutral + np.tensordot(w, self.identity[:k], axes=1)
        eyes = self.eyes + np.tensordot(w, self.eye_identity[:k], axes=1)
        if w_expression is not None and len(self.expressions):
            v = v + np.tensordot(np.asarray(w_expression, np.float64), self.expressions, axes=1)
        return v, eyes


def read_ict(path: str | os.PathLike) -> IctBasis:
    """An ``IctBasis`` from an upstream ``FaceXModel/`` folder, its one-file ``.npz`` or the compact
    basis. Raises ``ValueError`` naming the file and what is wrong (missing, truncated, wrong
    shapes, object arrays: nothing is unpickled)."""
    p = Path(path)
    if not p.exists():
        raise ValueError(f"{p}: no such file or folder (give the ICT-FaceKit FaceXModel/ folder or its .npz)")
    if p.is_dir():
        return _read_folder(p)
    data = _read_npz(p)
    if str(data.get("format", "")) == COMPACT_FORMAT:
        return _from_compact(p, data)
    return _from_full(p, data)


def shipped_basis() -> IctBasis:
    """The compact face-area basis inside the package (identity modes only)."""
    return read_ict(SHIPPED)


def write_compact(basis: IctBasis, path: str | os.PathLike, dtype=np.float16) -> Path:
    """Write the face-area basis (identity only) as a compact ``.npz``: deltas as ``dtype``
    (float16 moves a vertex by under 1e-3 cm, far below a model pixel), the rest exact."""
    buf = io.BytesIO()
    np.savez_compressed(
        buf, format=np.array(COMPACT_FORMAT), neutral=basis.neutral.astype(np.float32),
        identity_deltas=basis.identity.astype(dtype), triangles=basis.triangles.astype(np.int32),
        eyes=basis.eyes.astype(np.float32), eye_deltas=basis.eye_identity.astype(np.float32),
        licence=np.array("ICT-FaceKit, Copyright (c) 2020 USC Institute for Creative Technologies, MIT License"))
    return atomic_write_bytes(path, buf.getvalue())


def ict_faces(basis: IctBasis, n: int, seed: int = 0, grid: tuple[int, int] = (128, 128),
              expressions: float = 0.0, view: tuple[float, float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """``n`` random identities rendered on ``grid`` with their iris centres on the canonical eye
    pixels: ``(depths (n, H, W) float32 px, NaN off the face; albedos, 1 on the face)``; with a
    ``view`` (yaw, pitch) degrees, each head turned so (``placed``).

    Identity weights are N(0, 1) per mode, as the model defines them (deterministic in ``seed``).
    ``expressions`` > 0: each face also gets each blendshape with that probability, at a weight
    drawn from U(0, 1) (needs a basis read with its expressions).
    """
    if expressions > 0 and not len(basis.expressions):
        raise ValueError("this ICT basis holds no expression blendshapes (the shipped one holds identities only): "
                         "give the full model, ict:PATH")
    rng = np.random.default_rng(seed)
    depths = []
    for _ in range(n):
        w = rng.standard_normal(basis.n_identity)
        we = None
        if expressions > 0:
            e = len(basis.expressions)
            we = rng.random(e) * (rng.random(e) < expressions)
        depths.append(render_identity(basis, w, grid, we, view))
    d = np.stack(depths).astype(np.float32)
    return d, np.where(np.isfinite(d), 1.0, np.nan).astype(np.float32)


def canonical_mouth(basis: IctBasis, grid: tuple[int, int] = (128, 128),
                    view: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """(2,) ``[x, y]`` pixels: the mean face's mouth centre (stomion) with its irises on the
    canonical eye pixels of ``grid`` (the head turned by ``view``, ``placed``)."""
    verts, eyes = basis.face(np.zeros(basis.n_identity))
    return placed(verts[list(STOMION)].mean(axis=0, keepdims=True), eyes, grid, view)[0, :2]


def placed(points: np.ndarray, eyes: np.ndarray, grid: tuple[int, int], view: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """(P, 3) points of a face (cm, the model's frame) on ``grid`` (column, row, height px): its iris
    centres ``eyes`` (2, 3) on the canonical eye pixels (``align_to_eyes``), then the head turned by
    ``view`` = (yaw, pitch) degrees as the camera sees it (``placement.turn_to_view``)."""
    p = align_to_eyes(np.asarray(points, np.float64), eyes[0], eyes[1], grid)
    if tuple(view) == (0.0, 0.0):
        return p
    return turn_to_view(p, align_to_eyes(np.asarray(eyes, np.float64), eyes[0], eyes[1], grid), view)


def mirror_pixels(basis: IctBasis, mask: np.ndarray, view: tuple[float, float]) -> np.ndarray:
    """(N,) int32: for each of the N pixels of a model's ``mask`` (H, W) whose heads are turned by
    ``view`` (yaw, pitch) degrees, the mask pixel (an index into them, row-major) that shows its mirror
    image across the face's midline, -1 where the camera does not see that (the far cheek's mirror of
    the near one) or it is off the mask. Found on the mean face: each vertex's mirror is the vertex
    nearest its reflection in x (the model's frame is symmetric about x = 0)."""
    from scipy.spatial import cKDTree

    from ...geometry.raster import rasterize

    grid = mask.shape
    verts, eyes = basis.face(np.zeros(basis.n_identity))
    px = placed(verts, eyes, grid, view)
    twin = cKDTree(verts).query(verts * [-1.0, 1.0, 1.0])[1]
    depth, at = rasterize(px, basis.triangles, grid, attributes=px[twin])  # each pixel's mirror point, placed
    index = np.full(grid, -1, np.int64)
    index[mask] = np.arange(int(mask.sum()))
    rows, cols = np.nonzero(mask)
    m = at[rows, cols]
    r, c = np.rint(m[:, 1]), np.rint(m[:, 0])
    ok = np.isfinite(m).all(axis=1)
    ok[ok] &= (r[ok] >= 0) & (r[ok] < grid[0]) & (c[ok] >= 0) & (c[ok] < grid[1])
    out = np.full(len(rows), -1, np.int64)
    ri, ci = r[ok].astype(np.int64), c[ok].astype(np.int64)
    # seen: the mirror point is the surface the camera sees there (within a pixel of its height), not hidden behind it
    seen = np.abs(depth[ri, ci] - m[ok, 2]) <= 1.0
    out[np.flatnonzero(ok)[seen]] = index[ri[seen], ci[seen]]
    return out.astype(np.int32)


def render_identity(basis: IctBasis, w_identity: np.ndarray, grid: tuple[int, int] = (128, 128),
                    w_expression: np.ndarray | None = None, view: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """Height field (H, W) float32 px, NaN off the face, of one face with its iris centres on the
    canonical eye pixels of ``grid`` (interior holes, the eyes and mouth, filled smoothly), the head
    turned by ``view`` (yaw, pitch) degrees (``placed``)."""
    verts, eyes = basis.face(w_identity, w_expression)
    return render_mesh(placed(verts, eyes, grid, view), basis.triangles, grid)


# --- readers -------------------------------------------------------------------------------

def _read_npz(p: Path) -> dict[str, np.ndarray]:
    try:
        with np.load(p, allow_pickle=False) as z:
            if not isinstance(z, np.lib.npyio.NpzFile):
                raise ValueError("a single array, not an .npz of named arrays")
            return {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if "allow_pickle" in msg:
            msg = "holds object arrays, which are never unpickled"
        raise ValueError(f"{p}: not a readable ICT model file ({msg})") from None


def _array(p: Path, data: dict, key: str, shape: tuple, kind: str = "f") -> np.ndarray:
    """``data[key]`` checked against ``shape`` (None: any size) and dtype kind."""
    if key not in data:
        raise ValueError(f"{p}: ICT model file lacks '{key}'")
    a = data[key]
    if a.dtype.kind not in kind or a.ndim != len(shape) or any(s is not None and s != t for s, t in zip(shape, a.shape)):
        want = "x".join("N" if s is None else str(s) for s in shape)
        raise ValueError(f"{p}: '{key}' is {a.dtype} of shape {'x'.join(map(str, a.shape)) or 'scalar'}, expected {want}")
    if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
        raise ValueError(f"{p}: '{key}' holds NaN or infinite values")
    return a


def _from_full(p: Path, data: dict) -> IctBasis:
    neutral = _array(p, data, "neutral", (UPSTREAM_VERTICES, 3)).astype(np.float64)
    ids = _array(p, data, "identity_deltas", (None, UPSTREAM_VERTICES, 3))
    faces = _array(p, data, "faces", (None, None), "iu")
    expr = data.get("expression_deltas")
    if expr is not None:
        expr = _array(p, data, "expression_deltas", (None, UPSTREAM_VERTICES, 3))
    names = tuple(str(x) for x in data.get("expression_names", np.array([], str)))
    return _face_area(p, neutral, ids, faces, expr, names)


def _from_compact(p: Path, data: dict) -> IctBasis:
    neutral = _array(p, data, "neutral", (None, 3)).astype(np.float64)
    v = len(neutral)
    ids = _array(p, data, "identity_deltas", (None, v, 3)).astype(np.float64)
    k = len(ids)
    tri = _array(p, data, "triangles", (None, 3), "iu").astype(np.int64)
    if tri.size and (tri.min() < 0 or tri.max() >= v):
        raise ValueError(f"{p}: 'triangles' index vertices outside 0..{v - 1}")
    return IctBasis(neutral, ids, tri, _array(p, data, "eyes", (2, 3)).astype(np.float64),
                    _array(p, data, "eye_deltas", (k, 2, 3)).astype(np.float64), np.zeros((0, v, 3)), ())


def _face_area(p: Path, neutral: np.ndarray, ids: np.ndarray, faces: np.ndarray, expr: np.ndarray | None,
               names: tuple[str, ...]) -> IctBasis:
    """Cut an upstream-topology model (26,719 vertices) down to the face area and its eyes."""
    if len(ids) == 0:
        raise ValueError(f"{p}: the ICT model has no identity modes")
    if faces.shape[1] not in (3, 4) or faces.max() >= UPSTREAM_VERTICES:
        raise ValueError(f"{p}: 'faces' is not a polygon list over {UPSTREAM_VERTICES} vertices")
    tri = _triangulate(faces)
    tri = tri[np.all(tri < FACE_VERTICES, axis=1)]
    eye_idx = [np.arange(*IRIS_RIGHT), np.arange(*IRIS_LEFT)]
    eyes = np.stack([neutral[i].mean(axis=0) for i in eye_idx])
    ids64 = ids.astype(np.float64)
    eye_ids = np.stack([ids64[:, i].mean(axis=1) for i in eye_idx], axis=1)  # (K, 2, 3)
    face = slice(0, FACE_VERTICES)
    ex = np.zeros((0, FACE_VERTICES, 3)) if expr is None else expr[:, face].astype(np.float64)
    return IctBasis(neutral[face], ids64[:, face], tri, eyes, eye_ids, ex, names[:len(ex)])


def _triangulate(faces: np.ndarray) -> np.ndarray:
    """(F, 3|4) polygons, -1 padding a triangle's 4th index -> (T, 3) triangles."""
    faces = np.asarray(faces, np.int64)
    if faces.shape[1] == 3:
        return faces
    quad = faces[:, 3] >= 0
    return np.concatenate([faces[:, :3], faces[quad][:, [0, 2, 3]]])


_IDENTITY_OBJ = re.compile(r"identity(\d{3})\.obj")


def _read_folder(folder: Path) -> IctBasis:
    neutral_path = folder / "generic_neutral_mesh.obj"
    if not neutral_path.is_file():
        raise ValueError(f"{folder}: no generic_neutral_mesh.obj (is this ICT-FaceKit's FaceXModel folder?)")
    neutral, faces = read_obj(neutral_path)
    if len(neutral) != UPSTREAM_VERTICES:
        raise ValueError(f"{neutral_path}: {len(neutral)} vertices, ICT-FaceKit's topology has {UPSTREAM_VERTICES}")
    id_paths = sorted((f for f in folder.iterdir() if _IDENTITY_OBJ.fullmatch(f.name)), key=lambda f: f.name)
    if not id_paths:
        raise ValueError(f"{folder}: no identityNNN.obj files")
    ids = np.stack([_same_topology(f, neutral) for f in id_paths]) - neutral
    names, exprs = [], []
    for f in sorted(folder.glob("*.obj")):
        if f == neutral_path or _IDENTITY_OBJ.fullmatch(f.name) or not re.fullmatch(r"[a-z]+[A-Za-z]*(_[LR])?\.obj", f.name):
            continue
        names.append(f.stem)
        exprs.append(_same_topology(f, neutral) - neutral)
    expr = np.stack(exprs) if exprs else None
    return _face_area(folder, neutral, ids, faces, expr, tuple(names))


def _same_topology(path: Path, neutral: np.ndarray) -> np.ndarray:
    v, _ = read_obj(path, faces=False)
    if v.shape != neutral.shape:
        raise ValueError(f"{path}: {len(v)} vertices, the neutral mesh has {len(neutral)}")
    return v


def read_obj(path: Path, faces: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """Vertices (V, 3) float64 in file order and polygons (F, 4) int (0-based, -1 padding a
    triangle) of a Wavefront OBJ. File order matters here (the model's modes are per vertex),
    and general mesh loaders may reorder or split vertices at texture seams."""
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise ValueError(f"{path}: cannot read ({exc.strerror or exc})") from None
    verts = re.findall(r"^v\s+(\S+)\s+(\S+)\s+(\S+)", text, flags=re.M)
    try:
        v = np.array(verts, np.float64).reshape(-1, 3)
    except ValueError:
        raise ValueError(f"{path}: a vertex line is not three numbers") from None
    if len(v) == 0 or not np.all(np.isfinite(v)):
        raise ValueError(f"{path}: no vertices, or vertices that are not finite numbers")
    if not faces:
        return v, None
    polys = []
    for line in re.findall(r"^f\s+(.+)$", text, flags=re.M):
        idx = [int(t.split("/")[0]) for t in line.split()]
        if len(idx) not in (3, 4):
            raise ValueError(f"{path}: a face with {len(idx)} corners (triangles and quads are read)")
        polys.append([i - 1 if i > 0 else len(v) + i for i in idx] + [-1] * (4 - len(idx)))
    f = np.array(polys, np.int64).reshape(-1, 4)
    if len(f) == 0 or f.max() >= len(v) or f[f >= 0].min() < 0:
        raise ValueError(f"{path}: faces missing or indexing vertices that do not exist")
    return v, f
