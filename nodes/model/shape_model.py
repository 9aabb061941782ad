"""Statistical model of facial surface normals (Smith & Hancock, section 2).

At each model pixel the training normals are mapped by the azimuthal equidistant projection
(AEP) about that pixel's mean normal into its tangent plane; PCA over the stacked 2-D points
gives the modes. A needle-map is then ``v = vbar + P b`` with ``P`` the (2N, K) modes.
"""
from __future__ import annotations

import hashlib
import io
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import ndimage

from ...flow.files import atomic_write_bytes
from ..geometry.integrate import fill_holes
from ..geometry.normals import (
    aep_forward,
    aep_inverse,
    normalize,
    normals_from_depth,
    tangent_basis,
)
from .canonical import canonical_eyes

MODEL_FORMAT_VERSION = 1


@dataclass
class ShapeModel:
    """A trained needle-map model on a canonical grid.

    grid: (H, W); eyes: (2, 2) canonical eye centres ``[[x, y], [x, y]]`` (pixels, x = column);
    mask: (H, W) bool model region; mean_normals: (N, 3) unit, camera frame, over the N mask
    pixels in row-major order; mean_proj: (N, 2) mean AEP coordinates (radians);
    modes: (2N, K) orthonormal columns, rows ordered (pixel, tangent axis);
    eigenvalues: (K,) variance of each mode (radians squared); source: provenance text;
    mouth: (2,) the mean face's mouth centre ``[x, y]`` (lips' parting line, pixels) if the training
    source knows it (a found face's length is then measured against it, ``photo.faces``), else None;
    view: (yaw, pitch) degrees the training heads were turned (``faces.placement.turn_to_view``; (0, 0)
    frontal); mirror: (N,) int, each mask pixel's mirror image across the face's midline (an index into
    the mask pixels, -1 where the camera does not see it), for a turned model; None: the column mirrored
    about the eyes' midpoint.
    """

    grid: tuple[int, int]
    eyes: np.ndarray
    mask: np.ndarray
    mean_normals: np.ndarray
    mean_proj: np.ndarray
    modes: np.ndarray
    eigenvalues: np.ndarray
    source: str
    mouth: np.ndarray | None = None
    view: tuple[float, float] = (0.0, 0.0)
    mirror: np.ndarray | None = None
    e1: np.ndarray = field(init=False, repr=False)
    e2: np.ndarray = field(init=False, repr=False)
    _derived: dict = field(init=False, repr=False, compare=False, default_factory=dict)

    def __post_init__(self) -> None:
        self.grid = (int(self.grid[0]), int(self.grid[1]))
        self.mask = np.asarray(self.mask, bool)
        self.mouth = None if self.mouth is None else np.asarray(self.mouth, np.float64).reshape(2)
        self.view = (float(self.view[0]), float(self.view[1]))
        self.mirror = None if self.mirror is None else np.asarray(self.mirror, np.int32).reshape(-1)
        self.e1, self.e2 = tangent_basis(self.mean_normals.astype(np.float64))

    def modes_as(self, dtype) -> np.ndarray:
        """The (2N, K) modes as C-contiguous ``dtype``, converted once per model."""
        key = ("modes", np.dtype(dtype).str)
        if key not in self._derived:
            self._derived[key] = np.ascontiguousarray(self.modes, dtype=dtype)
        return self._derived[key]

    @property
    def iod(self) -> float:
        """Model pixels between the canonical eye centres."""
        return float(np.linalg.norm(np.subtract(*np.asarray(self.eyes, np.float64))))

    @property
    def mirrors_by_column(self) -> bool:
        """Whether each pixel's mirror image is its column's flip about the eyes' midpoint: a frontal model, or one
        whose heads are turned in pitch alone (its ``mirror`` map then is that flip: checked on the -20 deg view)."""
        return self.mirror is None or self.view[0] == 0.0

    @property
    def normal_variance(self) -> np.ndarray:
        """(N,) variance of each pixel's normal over the modes (AEP radians squared, both axes)."""
        if "normal_variance" not in self._derived:
            p = self.modes.astype(np.float64).reshape(self.n_pixels, 2, -1)
            self._derived["normal_variance"] = np.einsum("nak,k->n", p**2, self.eigenvalues.astype(np.float64))
        return self._derived["normal_variance"]

    @property
    def fingerprint(self) -> str:
        """A hash of everything the fit reads from the model (16 hex digits): equal models, equal text."""
        if "fingerprint" not in self._derived:
            h = hashlib.sha256(repr(self.grid).encode())
            for a in (self.eyes, self.mask, self.mean_normals, self.mean_proj, self.modes, self.eigenvalues,
                      np.zeros(0) if self.mouth is None else self.mouth):
                a = np.ascontiguousarray(a)
                h.update(f"{a.dtype.str}{a.shape}".encode())
                h.update(a.tobytes())
            if self.view != (0.0, 0.0):  # a frontal model's text is what it was before models had views
                h.update(repr(self.view).encode())
                h.update(np.ascontiguousarray(self.mirror).tobytes() if self.mirror is not None else b"")
            self._derived["fingerprint"] = h.hexdigest()[:16]
        return self._derived["fingerprint"]

    @property
    def n_pixels(self) -> int:
        return int(self.mean_normals.shape[0])

    @property
    def n_modes(self) -> int:
        return int(self.modes.shape[1])

    def truncated(self, k: int) -> "ShapeModel":
        """The same model with only its first ``k`` modes."""
        k = max(1, min(int(k), self.n_modes))
        key = ("truncated", k)
        if key not in self._derived:  # kept: a stream asks for the same one every frame
            self._derived[key] = ShapeModel(self.grid, self.eyes, self.mask, self.mean_normals, self.mean_proj,
                                            self.modes[:, :k], self.eigenvalues[:k], self.source, self.mouth,
                                            self.view, self.mirror)
        return self._derived[key]

    def project(self, normals: np.ndarray) -> np.ndarray:
        """(N, 3) unit normals on the mask pixels -> (N, 2) AEP coordinates."""
        return aep_forward(normals, self.mean_normals, self.e1, self.e2)

    def unproject(self, coords: np.ndarray) -> np.ndarray:
        """(N, 2) AEP coordinates -> (N, 3) unit normals."""
        return aep_inverse(coords, self.mean_normals, self.e1, self.e2)

    def synthesize(self, b: np.ndarray) -> np.ndarray:
        """Normals (N, 3) of shape parameters ``b`` (K,)."""
        v = self.mean_proj + (self.modes[:, : len(b)] @ b).reshape(-1, 2)
        return self.unproject(v)

    def closest_coefficients(self, normals: np.ndarray, known: np.ndarray | None = None) -> np.ndarray:
        """Least-squares coefficients ``b`` (K,) of a needle-map in the model's AEP space.

        normals: (N, 3) unit, camera frame, over the model pixels; known: (N,) bool, the pixels
        that count (default all; the others may hold anything). ``synthesize(b)`` is then the
        closest needle-map the model can represent: what no fit of this model can beat.
        """
        known = np.ones(self.n_pixels, bool) if known is None else np.asarray(known, bool)
        if not known.any():
            return np.zeros(self.n_modes)
        if known.all():  # the modes are orthonormal over the whole face: a plain projection
            v = self.project(np.asarray(normals, np.float64)) - self.mean_proj
            return self.modes.astype(np.float64).T @ v.reshape(-1)
        n = np.asarray(normals, np.float64)[known]
        v = aep_forward(n, self.mean_normals[known], self.e1[known], self.e2[known]) - self.mean_proj[known]
        rows = np.repeat(known, 2)
        return np.linalg.lstsq(self.modes[rows].astype(np.float64), v.reshape(-1), rcond=None)[0]

    def closest_normals(self, normals: np.ndarray, known: np.ndarray | None = None) -> np.ndarray:
        """(N, 3) the closest needle-map the model can represent to ``normals`` (N, 3) at the
        ``known`` (N,) pixels (``closest_coefficients``): the model's floor for that face."""
        return self.synthesize(self.closest_coefficients(normals, known))

    def to_image(self, values: np.ndarray, fill: float = np.nan) -> np.ndarray:
        """Scatter per-mask-pixel values (N, ...) onto the grid: (H, W, ...)."""
        out = np.full(self.grid + values.shape[1:], fill, dtype=np.result_type(values.dtype, np.float32))
        out[self.mask] = values
        return out


def train_shape_model(
    depths: np.ndarray,
    n_modes: int = 60,
    eyes: np.ndarray | None = None,
    source: str = "",
    min_coverage: float = 1.0,
    mouth: np.ndarray | None = None,
    view: tuple[float, float] = (0.0, 0.0),
) -> ShapeModel:
    """Train a needle-map model from aligned height fields.

    depths: (M, H, W) heights in pixel units on the canonical grid, NaN off each face.
    The model region is the pixels covered by at least ``min_coverage`` of the faces, with
    interior holes filled, eroded by one pixel so every normal there has a full stencil.
    n_modes: K, at most M - 1. mouth: (2,) the faces' mean mouth centre, if known; view: the (yaw, pitch)
    the faces are seen at (their mirror map is set by the source, ``faces.ict.mirror_pixels``). Returns the model.
    """
    depths = np.asarray(depths, np.float64)
    m, h, w = depths.shape
    coverage = np.isfinite(depths).mean(axis=0)
    region = ndimage.binary_fill_holes(coverage >= min_coverage - 1e-9)
    region = ndimage.binary_erosion(region, iterations=1)
    region = _largest_component(region)
    normals = np.empty((m, int(region.sum()), 3))
    for i in range(m):
        d = fill_holes(depths[i], region)
        normals[i] = normals_from_depth(d)[region]
    if not np.all(np.isfinite(normals)):
        raise ValueError("training faces do not cover the model region")
    return train_from_normals(normals, region, n_modes, eyes, source, mouth, view)


def train_from_normals(
    normals: np.ndarray, mask: np.ndarray, n_modes: int, eyes: np.ndarray | None, source: str,
    mouth: np.ndarray | None = None, view: tuple[float, float] = (0.0, 0.0),
) -> ShapeModel:
    """Model from (M, N, 3) unit needle-maps over the N pixels of ``mask`` (H, W)."""
    m = normals.shape[0]
    mean_n = normalize(normals.mean(axis=0))
    e1, e2 = tangent_basis(mean_n)
    v = np.stack([aep_forward(normals[i], mean_n, e1, e2) for i in range(m)])  # (M, N, 2)
    vbar = v.mean(axis=0)
    x = (v - vbar).reshape(m, -1)
    _, sing, vt = np.linalg.svd(x, full_matrices=False)
    k = max(1, min(int(n_modes), m - 1))
    grid = tuple(mask.shape)
    return ShapeModel(
        grid=grid,
        eyes=canonical_eyes(grid) if eyes is None else np.asarray(eyes, float),
        mask=mask,
        mean_normals=mean_n.astype(np.float32),
        mean_proj=vbar.astype(np.float32),
        modes=vt[:k].T.astype(np.float32),
        eigenvalues=(sing[:k] ** 2 / max(m - 1, 1)).astype(np.float32),
        source=source,
        mouth=mouth,
        view=view,
    )


def _largest_component(mask: np.ndarray) -> np.ndarray:
    labels, n = ndimage.label(mask)
    if n <= 1:
        return mask
    sizes = ndimage.sum(mask, labels, index=np.arange(1, n + 1))
    return labels == (1 + int(np.argmax(sizes)))


def save_model(model: ShapeModel, path: str | os.PathLike) -> Path:
    """Write ``model`` as an ``.npz`` readable with ``allow_pickle=False`` (atomically)."""
    buf = io.BytesIO()
    np.savez_compressed(
        buf,
        version=np.int64(MODEL_FORMAT_VERSION),
        grid=np.array(model.grid, np.int64),
        eyes=np.asarray(model.eyes, np.float64),
        mask=model.mask,
        mean_normals=model.mean_normals,
        mean_proj=model.mean_proj,
        modes=model.modes,
        eigenvalues=model.eigenvalues,
        source=np.array(model.source),
        **({} if model.mouth is None else {"mouth": np.asarray(model.mouth, np.float64)}),
        **({} if model.view == (0.0, 0.0) else {"view": np.asarray(model.view, np.float64)}),
        **({} if model.mirror is None else {"mirror": model.mirror.astype(np.int32)}),
    )
    return atomic_write_bytes(path, buf.getvalue())


MAX_MODEL_BYTES = 1 << 30  # a model's members may unpack to at most 1 GiB (a 256^2, K = 99 one is ~40 MB)
# a model grid's side: the fit works at 128^2; every step allocates grid-sized arrays, so a 5000^2 grid of a few
# face pixels (a 1 MB file) would take gigabytes
MIN_GRID_SIDE, MAX_GRID_SIDE = 16, 512


def check_grid(grid, what: str = "grid") -> tuple[int, int]:
    """``(H, W)`` of a model grid, each side an integer from ``MIN_GRID_SIDE`` to ``MAX_GRID_SIDE``, or
    ``ValueError`` naming ``what``."""
    h, w = (int(x) for x in grid)
    if not (MIN_GRID_SIDE <= h <= MAX_GRID_SIDE and MIN_GRID_SIDE <= w <= MAX_GRID_SIDE):
        raise ValueError(f"{what} {h} x {w} is over the {MAX_GRID_SIDE}-pixel limit of a side" if max(h, w) > MAX_GRID_SIDE
                         else f"{what} {h} x {w}: each side is at least {MIN_GRID_SIDE} pixels")
    return h, w


def _model_arrays(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """The arrays of a model file: a regular file, an intact zip whose members declare no more than
    ``MAX_MODEL_BYTES`` in all, read without pickles."""
    import zipfile
    import zlib

    p = Path(path)
    if not p.is_file():
        raise ValueError(f"{path}: not a regular file")
    try:
        with zipfile.ZipFile(p) as zf:  # sizes from the directory; checksums are checked as np.load reads
            declared = sum(i.file_size for i in zf.infolist())
            if declared > MAX_MODEL_BYTES:
                raise ValueError(f"its members unpack to {declared} bytes, over the {MAX_MODEL_BYTES}-byte limit")
        with np.load(p, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as exc:
        raise ValueError(f"{path}: not a readable model file ({exc})") from None


def _check_members(path, data: dict[str, np.ndarray]) -> None:
    """Every member a model needs is there, numeric, and its format is not newer than this code's."""
    required = ("grid", "eyes", "mask", "mean_normals", "mean_proj", "modes", "eigenvalues")
    missing = [k for k in required if k not in data]
    if missing:
        raise ValueError(f"{path}: model file lacks {', '.join(missing)}")
    for k, v in data.items():
        if v.dtype.kind not in "biuf" and k != "source":
            raise ValueError(f"{path}: '{k}' holds {v.dtype}, not numbers")
    version = data.get("version", np.array(0))
    if version.shape != () or version.dtype.kind not in "iu":
        raise ValueError(f"{path}: 'version' must be one integer")
    if int(version) > MODEL_FORMAT_VERSION:
        raise ValueError(f"{path}: model format {int(version)} is newer than this shadowflow ({MODEL_FORMAT_VERSION})")


def _check_shapes(path, data: dict[str, np.ndarray], mask: np.ndarray) -> None:
    """The grid within its limits and matching the mask; every array of the shape the mask and the modes
    imply, all finite."""
    n = int(mask.sum())
    grid = data["grid"]
    if grid.shape != (2,) or tuple(int(x) for x in grid) != mask.shape:
        raise ValueError(f"{path}: 'grid' {grid.tolist()} does not match the mask's shape {list(mask.shape)}")
    check_grid(grid, f"{path}: 'grid'")
    modes = data["modes"]
    if modes.ndim != 2 or modes.shape[1] < 1:
        raise ValueError(f"{path}: 'modes' must be a (2N, K) array")
    k = modes.shape[1]
    expected = {"mean_normals": (n, 3), "mean_proj": (n, 2), "modes": (2 * n, k), "eigenvalues": (k,), "eyes": (2, 2)}
    for name, shape in expected.items():
        if data[name].shape != shape:
            raise ValueError(f"{path}: '{name}' is {list(data[name].shape)}, its mask and modes say {list(shape)}")
    for name in expected:
        if not np.all(np.isfinite(data[name])):
            raise ValueError(f"{path}: '{name}' holds NaN or infinite values")


# a model's eyes on one row of its grid, as an upright face's: within this slope (14 degrees); every built-in model's,
# the turned views' too, are level
MAX_EYE_SLOPE = 0.25


def _check_eyes(path, eyes: np.ndarray, mouth: np.ndarray | None, shape: tuple[int, int]) -> None:
    """``ValueError`` unless the model's eyes are an upright face's on its grid: image-left first, on one row, apart,
    inside the grid, above its mouth. A model whose eyes were swapped placed every face mirrored about the vertical
    and upside down, and its fits came back ``ok``."""
    (x1, y1), (x2, y2) = eyes
    if x2 - x1 < 2.0:
        raise ValueError(f"{path}: 'eyes' {eyes.tolist()} must be the two eye centres image-left first "
                         "[[x1, y1], [x2, y2]], x1 < x2 (these are swapped or on one point)")
    if abs(y2 - y1) > MAX_EYE_SLOPE * (x2 - x1):
        raise ValueError(f"{path}: 'eyes' {eyes.tolist()} are not on one row of the grid, as an upright face's")
    if not (np.all(eyes >= 0) and np.all(eyes[:, 0] < shape[1]) and np.all(eyes[:, 1] < shape[0])):
        raise ValueError(f"{path}: 'eyes' {eyes.tolist()} lie outside the {shape[1]} x {shape[0]} grid")
    if mouth is not None and not mouth[1] > max(y1, y2):
        raise ValueError(f"{path}: 'mouth' {mouth.tolist()} is not below the eyes {eyes.tolist()}")


def load_model(path: str | os.PathLike) -> ShapeModel:
    """Read a model written by ``save_model`` without trusting it: a regular file, an intact zip
    whose members declare no more than ``MAX_MODEL_BYTES`` in all, numeric arrays (no pickles) of
    the shapes the grid and mask imply, all finite. Raises ``ValueError`` naming what is wrong."""
    data = _model_arrays(path)
    _check_members(path, data)
    mask = data["mask"].astype(bool)
    _check_shapes(path, data, mask)
    mouth = data.get("mouth")
    if mouth is not None and (mouth.shape != (2,) or not np.all(np.isfinite(mouth))):
        raise ValueError(f"{path}: 'mouth' must be two finite numbers [x, y]")
    _check_eyes(path, data["eyes"].astype(np.float64), mouth, mask.shape)
    view = data.get("view", np.zeros(2))
    if view.shape != (2,) or not np.all(np.abs(view) <= 90.0):
        raise ValueError(f"{path}: 'view' must be two angles [yaw, pitch] within 90 degrees")
    mirror = data.get("mirror")
    n = int(mask.sum())
    if mirror is not None and (mirror.shape != (n,) or mirror.dtype.kind not in "iu" or mirror.min() < -1 or mirror.max() >= n):
        raise ValueError(f"{path}: 'mirror' must be one index per mask pixel, -1 to {n - 1}")
    return ShapeModel(
        grid=tuple(int(x) for x in data["grid"]),
        eyes=data["eyes"].astype(float),
        mask=mask,
        mean_normals=data["mean_normals"].astype(np.float32),
        mean_proj=data["mean_proj"].astype(np.float32),
        modes=data["modes"].astype(np.float32),
        eigenvalues=data["eigenvalues"].astype(np.float32),
        source=str(data.get("source", "")),
        mouth=None if mouth is None else mouth.astype(np.float64),
        view=(float(view[0]), float(view[1])),
        mirror=None if mirror is None else mirror.astype(np.int32),
    )
