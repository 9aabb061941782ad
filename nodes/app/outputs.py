"""Writer: map a frame's model-grid products back to the input grid and write the layout of
``conventions.md`` (``OUT/<stem>/...`` and ``OUT/summary.json``), every file atomically."""
from __future__ import annotations

import errno
import io
import itertools
import json
import os
import re
import unicodedata
from collections.abc import MutableSet
from pathlib import Path
from typing import Callable, Iterable

import cv2
import numpy as np

from ...flow.files import atomic_write_bytes, atomic_write_chunks, json_array_chunks
from ...flow.frame import Frame
from ...flow.jsonsafe import json_safe
from ...flow.manifest import RunManifest
from ..geometry.reflectance import light_tag
from ..method.products import (face_products, grid_placement, grid_products, in_encoding, on_photo, photo_mesh)
from ..relight.products import relit_lights, relit_photo_8bit
from ..method.products import to_8bit as rounded_8bit  # (this module's to_8bit also turns RGB to BGR)
from ..photo.align import Alignment, scalar_to_input
from ..photo.loader import MAX_PIXELS, MAX_SIDE
from ..photo.encoding import swapped_rb
from ..model.shape_model import MAX_GRID_SIDE
from .counts import status_lines  # noqa: F401 (the tests take it from here)

# a face's files; its photo's folder holds the largest face's and the photo relit (``relit.png``)
FACE_FILES = ("normals.npy", "mask.png", "weights.npy", "depth.npy", "grid.json", "albedo.png", "shadow.png",
              "novel_view.png", "mesh.ply")
# where normals.npy, weights.npy and depth.npy are: on the fit's model grid, as the fit has them (``grid.json``
# places it on the photo), or on the photo's pixel grid (conventions.md's first layout: 48 MB of normals for a
# 4-megapixel photo, holding the same 128 x 128 fit resampled)
ARRAYS = ("grid", "photo")
VIEW_NAME = "view.html"  # the photo's page (``view.PageNode``)
OUTPUT_FILES = (*FACE_FILES, "relit.png", VIEW_NAME)
# a face's files written only with an option: how far each pixel is in a shadow the face does not cast (0-255), with
# --foreign-shadows
OPTIONAL_FACE_FILES = ("foreign_shadow.png",)


def real_path(path: str | Path) -> Path:
    """Absolute path with symlinks resolved as far as they go (a symlink loop stops there)."""
    try:
        return Path(path).resolve()
    except (OSError, RuntimeError):  # a symlink loop: its own name is the best we know
        return Path(os.path.abspath(path))


# what a run writes beside the output folders: a folder may not take one of these names
RUN_FILES = ("summary.json", "manifest.json", "report.html", "run.mcap", "run.rrd", ".journal.jsonl", ".run.sqlite",
             ".lock")
_RUN_PART = re.compile(r"run(\.[a-z0-9_-]+)*\.(mcap|rrd)")  # run.part2.mcap, run.s3.rrd, run.worker-0.mcap


def reserved(name: str) -> bool:
    """Whether an output folder may not be called ``name``: one of the run's own files (``RUN_FILES``,
    a recording part)."""
    low = name.lower()
    return low in RUN_FILES or _RUN_PART.fullmatch(low) is not None


def safe_stem(path: str, taken: MutableSet[str], free: Callable[[str], bool] = lambda name: True) -> str:
    """A file-system-safe, unique output folder name for an input path.

    Keeps letters, digits, ``.``, ``_``, ``+`` and ``-`` (after Unicode NFKD folding: a +50 and a
    -50 photo of one face stay a pair), never starts with ``.``, ``+`` or ``-``, and appends ``-2``,
    ``-3``... when the name is already in ``taken`` (lower-case names, a set or one on disk; the name
    then joins it), is one of the run's own files (``reserved``: an input called
    ``summary.json.png`` gets ``summary.json-2``) or is not ``free`` (a user's own file or folder there).
    """
    stem = Path(path).stem
    stem = unicodedata.normalize("NFKD", stem).encode("ascii", "ignore").decode("ascii")
    stem = re.sub(r"[^A-Za-z0-9._+-]+", "_", stem).lstrip(".-_+") or "input"
    stem = stem[:120]
    name, k = stem, 2
    while name.lower() in taken or reserved(name) or not free(name):
        name, k = f"{stem}-{k}", k + 1
    taken.add(name.lower())
    return name


_FACE_FOLDER = re.compile(r"face-[0-9]+")
_RELIT_FILE = re.compile(r"relit_A[+-][0-9]{3}E[+-][0-9]{2}\.(png|mp4)")
CLIP_FILES = ("relit.mp4", "frames.jsonl")  # a clip's folder (``clips``): its relit clip and its lines
CLIP_NAMES = (*CLIP_FILES, "frames")  # and with --frames, each frame's files in frames/
_TEMPORARY = re.compile(r"\..+\.tmp")  # an atomic write's, left by a kill


def run_output_folder(path: Path) -> bool:
    """Whether ``path`` may be written as a photo's output folder, being nobody else's: absent; or a real folder
    holding nothing but what a run writes there (its files, ``face-<k>/`` folders, a killed write's temporary
    files), with the first file a run writes (``normals.npy``) among them unless it holds none. A user's own file
    or folder of that name (``README/`` beside ``README.png``, holding a ``relit.png`` of their own) is not."""
    if not os.path.lexists(path):
        return True
    if path.is_symlink() or not path.is_dir():
        return False
    try:
        names = [entry.name for entry in os.scandir(path)]
    except OSError:
        return False
    ours = [n for n in names if not _TEMPORARY.fullmatch(n)]
    if not all(_run_name(n) for n in ours):
        return False
    # (a clip's folder stopped mid-way with --frames holds its frames/ alone: --resume takes it back)
    return not ours or any(n in ours for n in ("normals.npy", *CLIP_NAMES))


def drop_temporaries(targets: list[Path]) -> None:
    """Removes from the folders ``targets`` are written into (a photo's output folder and its faces' folders, about
    to be written again whole; one not made yet is passed over) the temporary files of an atomic write that was
    killed (``_TEMPORARY``: a Dask worker killed mid-write, ``kill -9``)."""
    for folder in dict.fromkeys(t.parent for t in targets):
        try:
            entries = list(os.scandir(folder))
        except OSError:  # not made yet
            continue
        for entry in entries:
            if _TEMPORARY.fullmatch(entry.name) and entry.is_file(follow_symlinks=False):
                Path(entry.path).unlink(missing_ok=True)


def _run_name(name: str) -> bool:
    """Whether a run writes a file or folder of this name in an output folder (a photo's or a clip's)."""
    return name in OUTPUT_FILES or name in OPTIONAL_FACE_FILES or name in CLIP_NAMES or bool(
        _RELIT_FILE.fullmatch(name) or _FACE_FOLDER.fullmatch(name))


_LOCK_HOLDER = re.compile(rb"pid [0-9]+ on \S")  # what a run writes in its folder's ``.lock``: pid N on HOST, ...
_SEGMENT = re.compile(r"run(\.part[0-9]+)?\.s[0-9]+\.rrd")  # a long run's Rerun files after its first


def foreign_run_files(out: Path) -> list[str]:
    """The files in ``out`` that a run writes over (``summary.json``, ``report.html``, ``run.mcap``...; never a
    resumed run's parts, which take free names) when ``out`` is not a run's folder: it has neither the ``.lock``
    every run leaves (``pid N on HOST, started ...``) nor a manifest of shadowflow's. Empty for a run's folder,
    or one holding none of those names."""
    try:
        names = [entry.name for entry in os.scandir(out)]
    except OSError:  # absent, or not a folder: check_writable says what is wrong
        return []
    clashing = sorted(n for n in names if n in RUN_FILES or _SEGMENT.fullmatch(n))
    holder = b""
    if ".lock" in clashing:
        try:
            with open(out / ".lock", "rb", opener=lambda p, f: os.open(p, f | os.O_NOFOLLOW | os.O_NONBLOCK)) as fh:
                holder = fh.read(4096)
        except OSError:
            holder = b"?"
        if _LOCK_HOLDER.match(holder):
            return []
        if not holder:  # (a run killed before it said who it was)
            clashing.remove(".lock")
    if not clashing:
        return []
    manifest = RunManifest.load(out)
    return [] if manifest is not None and manifest.config.get("tool") == "shadowflow" else clashing


def _npy_bytes(arr: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, arr, allow_pickle=False)
    return buf.getvalue()


# zlib's fastest level, each row differenced from the one above, runs of equal bytes: measured on 46 photos'
# outputs (docs/speed.md) 8 % faster to encode and 7 % smaller than OpenCV's default (rows differenced from
# their left neighbours)
PNG_PARAMS = [cv2.IMWRITE_PNG_COMPRESSION, 1, cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_UP,
              cv2.IMWRITE_PNG_STRATEGY, cv2.IMWRITE_PNG_STRATEGY_RLE]


def png_bytes(img8: np.ndarray) -> bytes:
    ok, enc = cv2.imencode(".png", img8, PNG_PARAMS)
    if not ok:
        raise OSError("PNG encoding failed")
    return enc.tobytes()


def mesh_ply_bytes(m: dict[str, np.ndarray]) -> bytes:
    """A mesh (``surface_mesh``'s dict) as a binary PLY with vertex colours."""
    import trimesh

    colours = np.column_stack([m["colours"], np.full(len(m["colours"]), 255, np.uint8)])
    mesh = trimesh.Trimesh(vertices=m["vertices"], faces=m["triangles"], vertex_colors=colours, process=False)
    return mesh.export(file_type="ply")


def bgr(rgb8: np.ndarray) -> np.ndarray:
    """(H, W, 3) RGB -> OpenCV's BGR; (H, W, 1) -> (H, W)."""
    return rgb8[..., 0] if rgb8.shape[-1] == 1 else swapped_rb(rgb8)


def to_8bit(values: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
    """[0, 1] floats (H, W) or RGB (H, W, 3) -> uint8 (``products.to_8bit``; RGB becomes OpenCV's BGR), 0 off
    the mask."""
    v = rounded_8bit(values)
    if mask is not None:
        v = np.where(mask[..., None] if v.ndim == 3 else mask, v, np.uint8(0))
    return bgr(v) if v.ndim == 3 else v


def faces_of(frame: Frame) -> list[Frame]:
    """The face frames of a photo's frame that came through (its ``parts``; a frame of one face: itself),
    largest first: the first is the photo's face (``face_folder``)."""
    if not frame.parts:
        return [frame] if "fit" in frame.data else []
    return [p for p in frame.parts if p.ok]


def face_folder(frame: Frame, face: Frame) -> str:
    """The output folder of one of ``frame``'s faces, relative to the photo's: ``""`` for the first face
    that came through (the largest; a larger candidate the fit found no face in does not take its place),
    ``face-<k>`` for the photo's k-th face (``meta["face"]``) after it."""
    faces = faces_of(frame)
    return "" if faces and face is faces[0] else f"face-{int(face.meta.get('face', 1))}"


def relit_name(light: np.ndarray, suffix: str = ".png") -> str:
    """The file of the photo relit by a ``--relight`` light: ``relit_A<az>E<el>.png`` (``light_tag``; a clip's
    ``.mp4``)."""
    return f"relit_{light_tag(light)}{suffix}"


def write_outputs(frame: Frame, folder: Path, arrays: str = "grid", keep_relit: bool = False) -> dict[str, str]:
    """Write every output file of one photo's frame into ``folder``: the photo relit with every face
    (``relit.png``, ``relit_<light>.png``), the largest face's files beside them and each other face's
    in ``face-<k>/``; returns name (relative to ``folder``) -> path. Each file is encoded, written and
    let go before the next (a large photo's files are not all held at once, nor its relit photos), each relit
    photo composed by the relighting when its turn comes (``relight.products.relit_photo_8bit``). arrays: where
    the fit's arrays are written (``ARRAYS``, ``write_face``). The photo's page (``VIEW_NAME``) is the page's
    own step (``view.PageNode``), the report's pictures the report's (``report.CardNode``): ``keep_relit`` keeps
    the first relit photo as written (``data["relit_8bit"]``) for it, so it is composed once."""
    written = {}
    for face in faces_of(frame):
        sub = face_folder(frame, face)
        for name, path in write_face(face, folder / sub if sub else folder, arrays).items():
            written[f"{sub}/{name}" if sub else name] = path
    def relit_png(i: int) -> bytes:
        relit = relit_photo_8bit(frame, i)
        if i == 0 and keep_relit:
            frame.data["relit_8bit"] = relit
        return png_bytes(bgr(relit))

    encoders = {"relit.png" if i == 0 else relit_name(light): lambda i=i: relit_png(i)
                for i, light in enumerate(relit_lights(frame))}
    for name, encode in encoders.items():
        atomic_write_bytes(folder / name, encode())
        written[name] = str(folder / name)
    return written


def novel_view_8bit(face: Frame) -> np.ndarray:
    """``novel_view.png``'s pixels: the turned face in the photo's own encoding (as its albedo), 0 beside it."""
    view = face.data["novel_view"]
    seen = view > 0 if view.ndim == 2 else np.any(view > 0, axis=-1)
    return to_8bit(in_encoding(face, view), seen)


def write_face(face: Frame, folder: Path, arrays: str = "grid") -> dict[str, str]:
    """One face's files (``FACE_FILES``, and ``foreign_shadow.png`` when the face's shadows from elsewhere were looked
    for) into ``folder``; returns name -> path. The images are on the
    photo's pixel grid, made from the face's box (``face_products``); the fit's arrays (normals, weights,
    depth) on its model grid (``grid_products``, placed on the photo by ``grid.json``), or with ``arrays``
    "photo" on the photo's pixel grid."""
    if arrays not in ARRAYS:
        raise ValueError(f"arrays {arrays!r}: choose from {', '.join(ARRAYS)}")
    on_grid = arrays == "grid"
    box, p = face_products(face, arrays=not on_grid)
    shape = face.data["image"].shape[:2]
    mask = p["mask"]
    if on_grid:
        p.update(grid_products(face))

    def png(values8: np.ndarray) -> bytes:
        return png_bytes(on_photo(values8, box, shape))

    def npy(name: str) -> bytes:
        values = p.pop(name)
        return _npy_bytes(values if on_grid else on_photo(values, box, shape))

    encoders = {
        "normals.npy": lambda: npy("normals"),
        "mask.png": lambda: png(np.where(mask, 255, 0).astype(np.uint8)),
        "weights.npy": lambda: npy("weights"),
        "depth.npy": lambda: npy("depth"),
        "grid.json": lambda: (json.dumps(grid_placement(face), indent=1) + "\n").encode(),
        "albedo.png": lambda: png(to_8bit(p.pop("albedo"), mask)),  # colour for a colour photo
        "shadow.png": lambda: png(np.where(p.pop("lit"), 255, 0).astype(np.uint8)),
        "novel_view.png": lambda: png_bytes(novel_view_8bit(face)),
        "mesh.ply": lambda: mesh_ply_bytes(photo_mesh(face)),  # the fit's resolution, the photo's frame
    }
    if "foreign" in p:
        encoders["foreign_shadow.png"] = lambda: png(
            np.round(255.0 * np.clip(p.pop("foreign"), 0.0, 1.0)).astype(np.uint8))
    folder.mkdir(parents=True, exist_ok=True)
    written = {}
    for name, encode in encoders.items():
        atomic_write_bytes(folder / name, encode())
        written[name] = str(folder / name)
    return written


def read_arrays(folder: str | Path, on_photo_grid: bool = False) -> dict[str, np.ndarray]:
    """A face's output folder's arrays: normals (3 channels), weights, depth, as written, or with
    ``on_photo_grid`` on its photo's pixel grid (H, W[, 3]) whichever way they were written: model-grid
    arrays are brought there through ``grid.json`` as ``--arrays photo`` brings them (``align.scalar_to_input``:
    bilinear, renormalised at the face's edge; normals made unit again), NaN off ``mask.png``. Read without
    pickles; ``grid.json`` and ``mask.png`` are checked before anything photo-sized is made (``ValueError``
    naming the file): a photo within the loader's limits, of ``mask.png``'s size, the arrays of one grid."""
    folder = Path(folder)
    for name in ("normals.npy", "weights.npy", "depth.npy", *(("grid.json", "mask.png") if on_photo_grid else ())):
        if not (folder / name).is_file():  # (a pipe would never let the read end)
            raise ValueError(f"{folder / name}: " + ("not a regular file" if (folder / name).exists() else "missing"))
    arrays = {name: np.load(folder / f"{name}.npy", allow_pickle=False) for name in ("normals", "weights", "depth")}
    if not on_photo_grid:
        return arrays
    (h, w), al = _photo_placement(folder)
    if arrays["depth"].shape == (h, w):  # written on the photo's grid already
        return arrays
    grid = arrays["depth"].shape
    if arrays["weights"].shape != grid or arrays["normals"].shape != (*grid, 3) or max(grid) > MAX_GRID_SIDE:
        raise ValueError(f"{folder}: normals.npy {arrays['normals'].shape}, weights.npy {arrays['weights'].shape} "
                         f"and depth.npy {grid} are not the arrays of one model grid, nor of the photo ({h}, {w})")
    mask = _mask(folder, (h, w))
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    y0, y1, x0, x1 = (rows[0], rows[-1] + 1, cols[0], cols[-1] + 1) if rows.size else (0, 0, 0, 0)
    box, known = al.cropped(x0, y0), np.isfinite(arrays["depth"])

    def on_photo_grid(values: np.ndarray) -> np.ndarray:  # (the grid's vectors are the photo's already)
        out = np.full((h, w), np.nan, np.float32)  # brought into the face's box only: the rest is off the face
        if y1 > y0:
            out[y0:y1, x0:x1] = np.where(mask[y0:y1, x0:x1], scalar_to_input(values, known, box, (y1 - y0, x1 - x0)),
                                         np.nan)
        return out

    normals = np.stack([on_photo_grid(arrays["normals"][..., i]) for i in range(3)], axis=-1)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    return {"normals": normals, "weights": on_photo_grid(arrays["weights"]), "depth": on_photo_grid(arrays["depth"])}


def _photo_placement(folder: Path) -> tuple[tuple[int, int], Alignment]:
    """``grid.json``'s photo (height, width) and its placement of the model grid, checked: two whole numbers
    within the loader's limits (``MAX_PIXELS``, ``MAX_SIDE``), and a finite (2, 3) matrix."""
    path = folder / "grid.json"
    try:
        place = json.loads(path.read_bytes()[:1 << 20])
        h, w = (int(v) if isinstance(v, int) and not isinstance(v, bool) else -1 for v in place["photo"])
        matrix = np.asarray(place["to_photo"], np.float64)
    except (ValueError, TypeError, KeyError, OverflowError, RecursionError) as exc:
        raise ValueError(f"{path}: not a grid.json shadowflow wrote ({' '.join(str(exc).split())})") from None
    if not (0 < h <= MAX_SIDE and 0 < w <= MAX_SIDE and h * w <= MAX_PIXELS):
        raise ValueError(f"{path}: photo {place['photo']} is not a photo within the {MAX_PIXELS // 1_000_000}-"
                         f"megapixel, {MAX_SIDE}-pixel limits")
    if matrix.shape != (2, 3) or not np.all(np.isfinite(matrix)):
        raise ValueError(f"{path}: to_photo is not a finite 2 x 3 matrix")
    return (h, w), Alignment(matrix, "grid.json")


def _mask(folder: Path, shape: tuple[int, int]) -> np.ndarray:
    """``mask.png`` as a boolean (H, W), once its header says it is the photo's ``shape``."""
    from PIL import Image

    path = folder / "mask.png"
    try:
        with Image.open(path) as probe:  # the header only
            size = probe.size
    except (OSError, ValueError, Image.DecompressionBombError) as exc:
        raise ValueError(f"{path}: not a readable mask ({' '.join(str(exc).split())})") from None
    if size != (shape[1], shape[0]):
        raise ValueError(f"{path}: {size[0]}x{size[1]}, not the {shape[1]}x{shape[0]} photo grid.json gives")
    mask = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if mask is None or mask.shape != shape:
        raise ValueError(f"{path}: not a readable mask")
    return mask > 0


def writes_files(frame: Frame) -> bool:
    """Whether a frame's own files are written: a photo's always, a clip's frame's with ``--frames`` only."""
    clip = frame.meta.get("clip")
    return not clip or bool(clip.get("files"))


class WriteNode:
    """Writes ``OUT/<frame.meta['stem']>/``; refuses to write over any input file, or into ``out_dir`` once
    ``still_ours`` (the run's lock) says it was removed or replaced under the run (an ``OSError`` of ``ESTALE``,
    which stops the run)."""

    name = "write"

    def __init__(self, out_dir: Path, protected: set[Path], arrays: str = "grid",
                 still_ours: Callable[[], bool] | None = None):
        self.out_dir, self.protected, self.arrays = out_dir, protected, arrays
        self.still_ours = still_ours

    def __call__(self, frame: Frame) -> Frame:
        if not writes_files(frame):
            return frame  # a clip's frame goes into its relit clips (``clips``), its files only with --frames
        if self.still_ours is not None and not self.still_ours():
            raise OSError(errno.ESTALE, "removed or replaced during the run; nothing more is written there",
                          str(self.out_dir))
        folder = self.out_dir / frame.meta["stem"]
        if not run_output_folder(folder):  # (made by someone else since the photo was named)
            raise ValueError(f"{frame.source}: {folder} is not a folder a run made; refusing to write into it")
        targets = [folder / n for n in (*OUTPUT_FILES, *(relit_name(light) for light in relit_lights(frame)[1:]))]
        for face in faces_of(frame):
            sub = face_folder(frame, face)
            if sub:
                targets += [folder / sub, *(folder / sub / n for n in FACE_FILES)]
        for path in (folder, *targets):
            if path.is_symlink():  # would write outside --out, or over whatever the link names
                raise ValueError(f"{frame.source}: {path} is a symbolic link; refusing to write through it")
        clash = [t for t in targets if real_path(t) in self.protected]
        if clash:
            raise ValueError(f"{frame.source}: writing {clash[0]} would overwrite an input")
        drop_temporaries(targets)
        write_outputs(frame, folder, self.arrays, keep_relit=True)
        frame.meta["outputs"] = str(folder)
        return frame


# what summary.json says of a face, from its frame's meta
FACE_FIELDS = ("quality", "light", "light_source", "alignment", "iterations", "converged", "final_sigma")


# summary.json's "harm" of a face, from the relighting's report: its name there -> its name in the report
HARM_FIELDS = {"h": "harm", "added_edges": "added_edges", "colour_blotches": "colour_blotches",
               "flattened": "flattened"}


def face_status(face: Frame) -> str:
    """``ok``, ``doubtful: <flags>`` (outputs written, to be looked at) or the reason it failed."""
    flags = (face.meta.get("quality") or {}).get("flags")
    return "doubtful: " + "; ".join(flags) if face.ok and flags else face.status


def face_record(frame: Frame, face: Frame, stem: str | None) -> dict:
    """One of ``frame``'s faces as ``summary.json``'s ``faces`` lists it: where it is (box, eyes: photo pixels,
    image-left eye first), its pose (degrees), status, quality, light and the folder of its outputs
    (relative to --out)."""
    rec = dict(face.meta.get("placement") or {})
    q = face.meta.get("quality") or {}
    rec.update(status=face_status(face), quality={"score": q.get("score"), "flags": q.get("flags", [])} if q else None,
               light=face.meta.get("light"))
    relit = face.meta.get("relight") or {}
    harm = {name: relit[key] for name, key in HARM_FIELDS.items() if key in relit}
    if harm:  # what the honesty step measured (``relight.nodes.harm_flag``)
        rec["harm"] = harm
    if "foreign_shadows" in face.meta:  # with --foreign-shadows: how many, and their share of the face
        rec["foreign_shadows"] = face.meta["foreign_shadows"]
    if face.ok and stem is not None:
        sub = face_folder(frame, face)
        rec["dir"] = f"{stem}/{sub}" if sub else stem
    return rec


def summary_record(frame: Frame) -> dict:
    """One ``summary.json`` record (conventions.md) for a finished or failed frame: the input's, with
    its largest face's fields (quality, light, alignment, the fit), and ``faces``, one entry per face
    found (``face_record``)."""
    m = frame.meta
    # the photo's face: the first that came through (a larger candidate refused as no face does not speak for it)
    first = next(iter(faces_of(frame)), frame.parts[0] if frame.parts else frame)
    rec = {
        "source": frame.source,
        "stem": m.get("stem"),
        "status": frame.status if not frame.ok else face_status(first),
        **{k: first.meta.get(k) for k in FACE_FIELDS},
        "seconds": round(float(sum(m.get("timings", {}).values())), 4),
    }
    rec["faces"] = [face_record(frame, p, m.get("stem")) for p in frame.parts]
    if m.get("reduced"):
        rec["reduced"] = m["reduced"]
    if frame.failed_in:
        rec["failed_in"] = frame.failed_in
    return json_safe(rec)  # a NaN (a fit's sigma, a signal) is null, not bare NaN that no JSON reader takes


def write_summary(out_dir: Path, records: Iterable[dict]) -> None:
    """``out_dir/summary.json``: the records (input order) as a JSON list, written atomically and
    record by record (a run's records come from its store on disk, never all in memory)."""
    chunks = json_array_chunks(records, indent=2)
    atomic_write_chunks(out_dir / "summary.json", itertools.chain(chunks, [b"\n"]))
