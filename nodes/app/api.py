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
from ..method.options import MethodOptions
from ..method.products import input_grid_products, photo_mesh
from ..model.default_model import resolve_model
from ..model.shape_model import ShapeModel
from ..photo.input_error import InputError
from ..photo.lights import checked_light, parse_light
from ..relight.nodes import photo_nodes
from ..relight.products import relit_photos
from .inputs import expand_inputs
from .outputs import OUTPUT_FILES, VIEW_NAME, face_record, faces_of, real_path, write_outputs
from .process import one_blas_thread, release_large_frees
from .runner import RunOptions, RunResult, run_stream
from .storage import out_folder
from .terminal import say
from .view import write_page

ARRAY_SOURCE = "<array>"  # the frame's source when the image was given as an array


@dataclass
class Products:
    """What ``fit`` recovers from one photo. Images are on the photo's pixel grid (H, W), NaN (or
    False) off the face, camera frame (x right, y up, z toward the camera; conventions.md).

    normals (H, W, 3) float32 unit; depth (H, W) float32 heights in input pixels; albedo (H, W), or
    (H, W, 3) RGB for a colour photo, at the photo's resolution; weights (H, W) the fit's robust
    weights in [0, 1]; lit (H, W) bool, not in cast or attached shadow under the input light; relit
    (H, W[, 3]) the whole photo with the face lit from ``MethodOptions.relight_light`` and put back, in
    three channels when it was given so
    (auto-exposed on the face); relit_extra: ``(light, photo)`` for each of
    ``MethodOptions.extra_lights``; quality: score, flags and signals (``method/quality.py``);
    mask (H, W) bool face; novel_view (Hm, Wm[, 3]) model grid, linear, the surface turned about the vertical
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
        return photo_mesh(self.frame)

    def save(self, folder: str | os.PathLike, arrays: str = "grid") -> dict[str, str]:
        """Write the files of one ``shadowflow run`` output folder (conventions.md) into ``folder``,
        each atomically, the fit's arrays where ``arrays`` says (``outputs.ARRAYS``: "grid" or "photo",
        as ``--arrays``); refuses to write over the input image. Returns name -> path."""
        folder = Path(folder)
        if self.frame.source != ARRAY_SOURCE:
            clash = [n for n in OUTPUT_FILES if real_path(folder / n) == real_path(self.frame.source)]
            if clash:
                raise ValueError(f"{folder / clash[0]}: is the input image; save somewhere else")
        folder.mkdir(parents=True, exist_ok=True)
        written = write_outputs(self.photo, folder, arrays)
        written[VIEW_NAME] = write_page(self.photo, folder)
        return written


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
        except (TypeError, ValueError, OverflowError):
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
    used) or an array (read as a file's samples are, ``photo_from_samples``). light: None (a sidecar's, else estimated), "auto", "yaleb"
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
    else:  # read by the loader as a file's samples are (``photo_from_samples``)
        frame = Frame(0, ARRAY_SOURCE, data={"samples": image})
    release_large_frees()
    with one_blas_thread():
        photo = Chain(photo_nodes(shape_model, opts)).process(frame)
    if not photo.ok:
        raise InputError(photo.status)
    face = faces_of(photo)[0]
    relit = relit_photos(photo)
    if np.ndim(image) == 3 and "colour" not in photo.data:  # an RGB array of a grey photo: RGB back, as given
        relit = [(light, np.repeat(np.atleast_3d(img)[..., :1], 3, axis=-1)) for light, img in relit]
    p = input_grid_products(face, relit)
    r = face.data["fit"]
    return Products(normals=p["normals"], depth=p["depth"], albedo=p["albedo"], weights=p["weights"], lit=p["lit"],
                    relit=p["relit"], relit_extra=p["relit_extra"], quality=face.meta["quality"], mask=p["mask"],
                    novel_view=face.data["novel_view"], light=np.asarray(face.data["light"], np.float64),
                    history=list(r.history), iterations=r.iterations, converged=r.converged, frame=face,
                    model=face.data["model"], faces=[face_record(photo, f, None) for f in photo.parts],
                    photo=photo)


def run(inputs: Iterable[str | os.PathLike], out: str | os.PathLike, model: ShapeModel | str | None = None,
        options: MethodOptions | None = None, record: tuple[str, ...] = ("rerun", "mcap"),
        record_every: int = 1, workers: int = 1, resume: bool = False, quiet: bool = True,
        dask: str | None = None) -> RunResult:
    """Stream image files (folders are listed, not recursed) through the method into ``out``, as
    ``shadowflow run`` does: ``out/<stem>/`` per image, ``out/summary.json``, and the recordings
    named in ``record`` (``run.rrd``, ``run.mcap``). A bad input fails its own frame only (its
    record in the result says why). ``dask``: run the frames on a Dask cluster (``--dask``: local,
    local:N, tcp://HOST:PORT). ``inputs`` may be one file or folder, as a string or path. ``quiet``: nothing is
    printed (the result and its records say everything); else notes and errors on stderr, as the command line
    says them. Returns the ``RunResult`` (summary records in input order)."""
    if isinstance(inputs, (str, bytes, os.PathLike)):  # one input, not the characters of its name
        inputs = [inputs]
    paths = expand_inputs([os.fsdecode(i) for i in inputs], note=(lambda msg: None) if quiet else say)
    run_options = RunOptions(record=tuple(record), record_options=RecordOptions(every=record_every),
                             fit_workers=workers, resume=resume, quiet=quiet, silent=quiet, dask=dask)
    return run_stream(paths, out_folder(out), _model(model), _options(options, None, None), run_options,
                      total=len(paths))
