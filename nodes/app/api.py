"""The Python API: ``fit`` one image in memory, ``run`` a stream of files into an output folder.

    import shadowflow
    result = shadowflow.fit("face.png")            # or an (H, W) / (H, W, 3) array
    result.normals, result.depth, result.albedo    # on the photo's pixel grid
    result.save("out/face")                        # the files ``shadowflow run`` writes

Both run the same nodes as the command line (``method.nodes``) with the same defaults.
"""
from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable

import numpy as np

from ...flow.chain import Chain
from ...flow.frame import Frame
from ...flow.recording import RecordOptions
from ..method.nodes import MethodOptions, photo_nodes
from ..method.products import input_grid_products, photo_mesh, relit_photos
from ..model.default_model import resolve_model
from ..model.shape_model import ShapeModel
from ..photo.encoding import decode_samples, linear_luminance, resolve, srgb_to_linear
from ..photo.loader import InputError, check_size, checked_light, luminance, parse_light, sample_range, shrunk
from .inputs import expand_inputs
from .outputs import OUTPUT_FILES, face_record, faces_of, real_path, write_outputs
from .process import one_blas_thread, release_large_frees
from .runner import RunOptions, RunResult, run_stream

ARRAY_SOURCE = "<array>"  # the frame's source when the image was given as an array


@dataclass
class Products:
    """What ``fit`` recovers from one photo. Images are on the photo's pixel grid (H, W), NaN (or
    False) off the face, camera frame (x right, y down, z toward the camera; conventions.md).

    normals (H, W, 3) float32 unit; depth (H, W) float32 heights in input pixels; albedo (H, W), or
    (H, W, 3) RGB for a colour photo, at the photo's resolution; weights (H, W) the fit's robust
    weights in [0, 1]; lit (H, W) bool, not in cast or attached shadow under the input light; relit
    (H, W[, 3]) the whole photo with the face lit from ``MethodOptions.relight_light`` and put back
    (auto-exposed on the face); relit_extra: ``(light, photo)`` for each of
    ``MethodOptions.extra_lights``; quality: score, flags and signals (``method/quality.py``);
    mask (H, W) bool face; novel_view (Hm, Wm) model grid, the surface turned about the vertical
    axis; light (3,) the light used (input camera frame); history: one dict of scalars per fit
    iteration (sigma, residual_mean, residual_median, downweighted_fraction, change_deg);
    iterations, converged: how the fit ended; frame: the face's frame, everything on the model grid
    (``method/keys.py``); model: the shape model used; faces: every face found, largest first, as
    ``summary.json`` gives them (box, eyes, pose, status, quality, light); photo: the photo's frame
    (its ``parts`` are the faces' frames).

    Every array above is the largest face's (the first of ``faces`` that came through), but ``relit``
    and ``relit_extra``, which are the whole photo with every face relit.
    """

    normals: np.ndarray
    depth: np.ndarray
    albedo: np.ndarray
    weights: np.ndarray
    lit: np.ndarray
    relit: np.ndarray
    relit_extra: list
    quality: dict
    mask: np.ndarray
    novel_view: np.ndarray
    light: np.ndarray
    history: list[dict[str, float]]
    iterations: int
    converged: bool
    frame: Frame
    model: ShapeModel
    faces: list[dict]
    photo: Frame

    @property
    def shadow(self) -> np.ndarray:
        """(H, W) bool: the face's cast or attached shadow under the input light."""
        return self.mask & ~self.lit

    @property
    def mesh(self) -> dict[str, np.ndarray]:
        """The face as a mesh at the fit's resolution in the photo's pixel frame: vertices (V, 3)
        float32 (column, -row, height), triangles (T, 3), colours (V, 3) uint8 grey albedo;
        ``mesh.ply`` holds the same (``method.products.photo_mesh``)."""
        return photo_mesh(self.frame, self.model)

    def save(self, folder: str | os.PathLike) -> dict[str, str]:
        """Write the files of one ``shadowflow run`` output folder (conventions.md) into ``folder``,
        each atomically; refuses to write over the input image. Returns name -> path."""
        folder = Path(folder)
        if self.frame.source != ARRAY_SOURCE:
            clash = [n for n in OUTPUT_FILES if real_path(folder / n) == real_path(self.frame.source)]
            if clash:
                raise ValueError(f"{folder / clash[0]}: is the input image; save somewhere else")
        folder.mkdir(parents=True, exist_ok=True)
        return write_outputs(self.photo, self.model, folder)


def _as_image(image: np.ndarray, encoding: str = "auto", max_pixels: int | None = None) -> tuple[dict, float]:
    """An array as the loader gives a file: ``(frame data, scale)``: the frame's ``image`` (H, W)
    float32 in [0, 1], and ``colour`` (H, W, 3) float32 RGB and ``rgb8`` for a colour one, in linear
    light (``encoding``: "auto" takes colour as sRGB and grey, or grey in three equal channels, as
    linear, as for files); scale: its pixels per pixel of the array (under 1 when it was reduced to
    ``max_pixels``, as a file is). Accepts (H, W) or (H, W, 3) RGB (or (H, W, 4) RGBA), uint8,
    uint16 or floats (on [0, 1], or larger ones on their own range, as a file's). Its size is checked
    as a file's header is (``InputError``)."""
    a = _checked_array(image)
    small = shrunk(a, max_pixels)
    scale = small.shape[0] / a.shape[0]
    a = small
    if a.dtype == np.uint8:
        f = a.astype(np.float32) / 255.0
    elif a.dtype == np.uint16:
        f = a.astype(np.float32) / 65535.0
    else:  # floats on [0, 1], or anything else on its own range (a 0-255 float array), as a file's samples
        f = a.astype(np.float32) / np.float32(sample_range(a))
    f = np.clip(f, 0.0, 1.0)
    if float(f.max() - f.min()) < 1.0 / 255.0:
        raise InputError(f"{ARRAY_SOURCE}: has no contrast: nothing to fit")
    grey_in_colour = f.ndim == 3 and np.array_equal(f[..., 0], f[..., 1]) and np.array_equal(f[..., 1], f[..., 2])
    if resolve(encoding, 3 if f.ndim == 3 and not grey_in_colour else 1) == "srgb":
        return _srgb_data(a, f), scale
    grey = np.clip(luminance(f), 0.0, 1.0)
    return ({"image": grey} if f.ndim == 2 else {"image": grey, "colour": f}), scale


def _checked_array(image) -> np.ndarray:
    """The array as (H, W) or (H, W, 3) samples (alpha dropped, booleans as 0 and 255), its size, type and
    values checked as a file's are (``InputError``)."""
    a = np.asarray(image)
    if a.ndim == 3 and a.shape[2] in (3, 4):
        a = a[..., :3]
    elif a.ndim != 2:
        raise InputError(f"{ARRAY_SOURCE}: shape {a.shape} is not (H, W) or (H, W, 3)")
    check_size(Path(ARRAY_SOURCE), a.shape[1], a.shape[0])
    if a.dtype.kind not in "uif" and a.dtype != bool:
        raise InputError(f"{ARRAY_SOURCE}: unsupported pixel type {a.dtype}")
    if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
        raise InputError(f"{ARRAY_SOURCE}: holds NaN or infinite values")
    return a.astype(np.uint8) * 255 if a.dtype == bool else a


def _srgb_data(a: np.ndarray, f: np.ndarray) -> dict:
    """The frame data of sRGB samples ``a`` (``f``: them on [0, 1]), decoded as a file of the same samples
    is (by a table for 8 and 16 bits), so that fit(array) is fit(path)."""
    rgb8 = a if a.dtype == np.uint8 else (f * 255.0 + 0.5).astype(np.uint8)
    full = {np.dtype(np.uint8): 255.0, np.dtype(np.uint16): 65535.0}.get(a.dtype)
    linear = decode_samples(a, full) if full else srgb_to_linear(f)
    rgb8 = rgb8 if rgb8.ndim == 3 else np.repeat(rgb8[..., None], 3, axis=-1)
    if linear.ndim == 2:
        return {"image": linear, "rgb8": rgb8}
    return {"image": linear_luminance(linear), "colour": linear, "rgb8": rgb8}


def _model(model: ShapeModel | str | os.PathLike | None) -> ShapeModel:
    return model if isinstance(model, ShapeModel) else resolve_model(None if model is None else str(model))


def _options(options: MethodOptions | None, light, eyes) -> MethodOptions:
    opts = options or MethodOptions()
    changes = {}
    if isinstance(light, str) and light.strip().lower() in ("auto", "yaleb"):
        changes["light"] = light.strip().lower()
    elif isinstance(light, str):  # "0,0,1", "30,10": as the command line reads it
        changes["light"] = parse_light(light)
    elif light is not None:
        changes["light"] = checked_light(light, "light")
    if eyes is not None:
        try:
            given = np.asarray(eyes, np.float64)
        except (TypeError, ValueError):
            given = np.empty(0)
        if given.size != 4:
            raise ValueError(f"eyes {eyes!r}: give the two eye centres [[x1, y1], [x2, y2]] in pixels")
        changes["eyes"] = given.reshape(2, 2)
    return dataclasses.replace(opts, **changes) if changes else opts


def fit(image: str | os.PathLike | np.ndarray, light: str | np.ndarray | None = None,
        eyes: np.ndarray | None = None, model: ShapeModel | str | os.PathLike | None = None,
        options: MethodOptions | None = None) -> Products:
    """Recover one face's shape, albedo and shadows, and relight it.

    image: a file (any format ``shadowflow run`` reads; a sidecar ``<stem>.json`` beside it is
    used) or an array (``_as_image``). light: None (a sidecar's, else estimated), "auto", "yaleb"
    (from an Extended Yale B file name), (3,) toward the light, camera frame, or (2,) its azimuth and
    elevation in degrees (azimuth > 0 toward the image's left, as Yale B's). eyes: None
    (detected, else a centred crop) or (2, 2) eye centres ``[[x, y], [x, y]]`` in input pixels,
    image-left first. model: None (the built-in ICT model), "ict", "procedural", a model ``.npz``
    or a ``ShapeModel``. options: every other choice (``MethodOptions``; ``light`` and ``eyes``
    above override its own). Raises ``ValueError`` (``InputError``) naming the problem.
    """
    shape_model = _model(model)
    opts = _options(options, light, eyes)
    if isinstance(image, (str, os.PathLike)):
        frame = Frame(0, str(image))
    else:
        data, scale = _as_image(image, opts.encoding, opts.max_pixels)
        meta = {"encoding": "srgb" if "rgb8" in data else "linear"}
        if scale != 1.0:  # reduced as a file would be: its given eyes with it
            h, w = np.asarray(image).shape[:2]
            meta["reduced"] = {"from": [w, h], "to": [data["image"].shape[1], data["image"].shape[0]]}
            if opts.eyes is not None:
                opts = dataclasses.replace(opts, eyes=np.asarray(opts.eyes) * scale)
        frame = Frame(0, ARRAY_SOURCE, data=data, meta=meta)
    release_large_frees()
    with one_blas_thread():
        photo = Chain(photo_nodes(shape_model, opts)).process(frame)
    if not photo.ok:
        raise InputError(photo.status)
    face = faces_of(photo)[0]
    p = input_grid_products(face, shape_model, relit_photos(photo))
    r = face.data["fit"]
    return Products(normals=p["normals"], depth=p["depth"], albedo=p["albedo"], weights=p["weights"], lit=p["lit"],
                    relit=p["relit"], relit_extra=p["relit_extra"], quality=face.meta["quality"], mask=p["mask"],
                    novel_view=face.data["novel_view"], light=np.asarray(face.data["light"], np.float64),
                    history=list(r.history), iterations=r.iterations, converged=r.converged, frame=face,
                    model=shape_model, faces=[face_record(f, None) for f in photo.parts], photo=photo)


def run(inputs: Iterable[str | os.PathLike], out: str | os.PathLike, model: ShapeModel | str | None = None,
        options: MethodOptions | None = None, record: tuple[str, ...] = ("rerun", "mcap"),
        record_every: int = 1, workers: int = 1, resume: bool = False, quiet: bool = True,
        dask: str | None = None) -> RunResult:
    """Stream image files (folders are listed, not recursed) through the method into ``out``, as
    ``shadowflow run`` does: ``out/<stem>/`` per image, ``out/summary.json``, and the recordings
    named in ``record`` (``run.rrd``, ``run.mcap``). A bad input fails its own frame only (its
    record in the result says why). ``dask``: run the frames on a Dask cluster (``--dask``: local,
    local:N, tcp://HOST:PORT). Returns the ``RunResult`` (summary records in input order)."""
    paths = expand_inputs([str(i) for i in inputs], note=lambda msg: None if quiet else print(msg))
    run_options = RunOptions(record=tuple(record), record_options=RecordOptions(every=record_every),
                             fit_workers=workers, resume=resume, quiet=quiet, dask=dask)
    return run_stream(paths, Path(out), _model(model), options or MethodOptions(), run_options, total=len(paths))
