"""The built-in models, built deterministically on first use and cached.

``ict`` (the default) is trained from random identities of ICT-FaceKit, a morphable model learnt
from light-stage scans of real people (MIT licence; its compact face-area basis ships in
``nodes/data/``). ``procedural`` is trained from the project's own anthropometric generator
(``nodes/model/faces/facegen.py``). Each is built from its recipe on first use (a few seconds) and
cached under ``$SHADOWFLOW_CACHE`` (default ``$XDG_CACHE_HOME/shadowflow`` or
``~/.cache/shadowflow``), keyed by the recipe and, for ICT, the shipped basis' bytes, in a process of
its own whose BLAS runs on one thread (``_built_apart``: the same bits wherever it was first asked for). No
download is involved, so both work offline on a fresh machine. The ICT model's turned views
(``turned_model``) are built and cached the same way.
"""
from __future__ import annotations

import hashlib
import json
import os
import threading
from pathlib import Path

import numpy as np

from ...flow.blas import single_threaded_blas
from .faces.ict import SHIPPED
from .shape_model import ShapeModel, load_model, save_model, train_shape_model
from .sources import mirror_map, training_faces

GENERATOR_VERSION = 2  # bump when nodes/model/faces/facegen.py changes the faces it makes
# 200 identities, K = 60: more of either barely moves the normals (docs/tuning.md, "The default model")
RECIPES = {
    "ict": {"source": "ict", "n": 200, "seed": 0, "modes": 60, "size": [128, 128]},
    "procedural": {"source": "procedural", "n": 100, "seed": 0, "modes": 60, "size": [128, 128],
                   "generator": GENERATOR_VERSION},
}
DEFAULT = "ict"
BUILT_IN = tuple(RECIPES)


def cache_dir() -> Path:
    env = os.environ.get("SHADOWFLOW_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "shadowflow"


def train_from_recipe(recipe: dict) -> ShapeModel:
    """Train the model a recipe describes (``source``, ``n``, ``seed``, ``modes``, ``size``, and
    optionally ``expressions``: an ICT face's chance of each expression blendshape; ``view``: (yaw,
    pitch) degrees, the ICT heads turned so (``turned_model``); ``coverage``: the share of the faces that
    must cover a pixel of the model's region, default all)."""

    grid = tuple(recipe["size"])
    # on one BLAS thread, always: the decomposition's last bits depend on BLAS's threads, and a model built
    # under two of them differed in one of its 915,600 mode values from one built under one (so did the fits)
    with single_threaded_blas():
        view = tuple(float(a) for a in recipe.get("view", (0.0, 0.0)))
        depths, mouth, eyes = training_faces(recipe["source"], recipe["n"], recipe["seed"], grid,
                                             recipe.get("expressions", 0.0), view)
        model = train_shape_model(depths, recipe["modes"], eyes=eyes, source=json.dumps(recipe, sort_keys=True),
                                  mouth=mouth, view=view, min_coverage=recipe.get("coverage", 1.0))
    if view != (0.0, 0.0):
        model.mirror = mirror_map(recipe["source"], model.mask, view)
    return model


def _cache_key(recipe: dict) -> str:
    h = hashlib.sha1(json.dumps(recipe, sort_keys=True).encode())
    if recipe["source"] == "ict":
        h.update(SHIPPED.read_bytes())
    return h.hexdigest()[:12]


def built_in_model(name: str = DEFAULT) -> ShapeModel:
    """Load a built-in model (``ict`` or ``procedural``), building and caching it first if needed."""
    if name not in RECIPES:
        raise ValueError(f"unknown built-in model {name!r}: {' or '.join(BUILT_IN)}")
    return _cached(RECIPES[name], name)


def _cached(recipe: dict, name: str, note=None) -> ShapeModel:
    """The model of ``recipe`` from the cache (``name`` begins its file's name), built and cached first if
    it is not there (``note`` is told, when given, before the build)."""
    path = cache_dir() / f"{name}-{_cache_key(recipe)}.npz"
    if path.exists() or path.is_symlink():
        try:
            return load_model(path)
        except ValueError:  # damaged (truncated, a flipped bit), or not a regular file: rebuilt below
            try:
                path.unlink()
            except OSError:
                pass
    if note is not None:
        note(path)
    if _built_apart(recipe, path):
        try:
            return load_model(path)
        except ValueError:
            pass
    model = train_from_recipe(recipe)
    try:
        save_model(model, path)
    except OSError:
        pass  # a read-only cache only costs the rebuild next time
    return model


def _built_apart(recipe: dict, path: Path) -> bool:
    """Build the model of ``recipe`` into ``path`` in a Python process of its own, whose BLAS starts on one
    thread, and say whether that worked (else the caller builds it here). A model's last bits depend on
    BLAS's threads, and a process's limit is set and put back by whichever thread asks (threadpoolctl, and
    OpenBLAS ignores a frame's thread's limit while the main thread holds one): a cached model built on a
    run's frame thread, or a test's, differed from one built under one thread in 1 of 915,600 values, and so
    did every fit with it. Apart, every cached model is the same wherever it was first asked for."""
    import subprocess
    import sys

    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    code = f"import json, sys; from {__name__} import build_into; build_into(json.loads(sys.argv[1]), sys.argv[2])"
    try:
        proc = subprocess.run([sys.executable, "-c", code, json.dumps(recipe), str(path)], env=env,
                              capture_output=True, timeout=900)
    except (OSError, subprocess.SubprocessError):
        return False
    return proc.returncode == 0 and path.is_file()


def build_into(recipe: dict, path: str | os.PathLike) -> None:
    """Train the model of ``recipe`` and write it to ``path`` (``_built_apart``'s process)."""
    save_model(train_from_recipe(recipe), path)


# a turned head is fitted with the model of its heads turned to the nearest view (docs/accuracy.md, "Turned
# heads"): a view every VIEW_STEP degrees of yaw out to MAX_VIEW_YAW, and of pitch out to MAX_VIEW_PITCH
VIEW_STEP = 5.0
MAX_VIEW_YAW = 50.0
# ... and views measured (``method.turned.ViewChoiceNode``) out to this: a head turned 50 deg is read at 50 only
# if the views either side of it are compared
MEASURED_VIEW_YAW = 60.0
PITCH_STEP = 10.0
MAX_VIEW_PITCH = 30.0
# a turned model's region: the pixels at least this share of its heads cover (the others' heights filled
# smoothly there). All of them, as for the frontal model, stops at the narrowest of 200 far cheeks: 0.85 of a
# 30 deg face's visible skin against 0.87-0.90, for the same normals (docs/accuracy.md, "Turned heads")
TURNED_COVERAGE = 0.9
_views: dict[tuple[str, tuple[float, float]], ShapeModel] = {}
_views_lock = threading.Lock()


def view_of(yaw: float, pitch: float) -> tuple[float, float]:
    """The (yaw, pitch) degrees of the turned model for a head at ``yaw``, ``pitch``: yaw to the nearest
    multiple of ``VIEW_STEP`` within ``MAX_VIEW_YAW``; pitch a whole ``PITCH_STEP`` once it reaches one, within
    ``MAX_VIEW_PITCH`` (the landmarks' pitch of a level real face reads up to 9.6 deg, Yale B; a render's at 20
    and 30 deg reads 20-27 and 30-33)."""
    y = float(np.clip(VIEW_STEP * np.round(yaw / VIEW_STEP), -MAX_VIEW_YAW, MAX_VIEW_YAW))
    p = float(np.clip(PITCH_STEP * np.trunc(pitch / PITCH_STEP), -MAX_VIEW_PITCH, MAX_VIEW_PITCH))
    return y + 0.0, p + 0.0  # no -0.0


def views_near(yaw: float, pitch: float) -> list[tuple[float, float]]:
    """The views a head measured at ``yaw``, ``pitch`` degrees is compared at: the nearest (out to
    ``MEASURED_VIEW_YAW``) and its neighbours in yaw (the landmarks' yaw is good to a few degrees; the fit tells
    the rest apart, ``method.turned.ViewChoiceNode``)."""
    p = view_of(yaw, pitch)[1]
    y = float(np.clip(VIEW_STEP * np.round(yaw / VIEW_STEP), -MEASURED_VIEW_YAW, MEASURED_VIEW_YAW))
    return [(y + k * VIEW_STEP + 0.0, p) for k in (0, -1, 1) if abs(y + k * VIEW_STEP) <= MEASURED_VIEW_YAW]


def turned_model(model: ShapeModel, view: tuple[float, float], note=None) -> ShapeModel | None:
    """``model`` with its training heads turned by ``view`` (yaw, pitch) degrees: ``model`` itself for
    (0, 0); else the model of the same recipe (a built-in or ``train``'s ICT model) at that view, built on
    first use (``note`` is told the cache file it is built into, once) and cached like the built-in
    models; None for a model whose recipe is not known or not of the ICT source (a model file)."""
    view = (float(view[0]), float(view[1]))
    if view == (0.0, 0.0):
        return model
    try:
        recipe = json.loads(model.source)
    except ValueError:
        return None
    if not isinstance(recipe, dict) or recipe.get("source") != "ict" or "view" in recipe:
        return None
    key = (model.fingerprint, view)
    with _views_lock:  # a face of each fit worker may ask at once: built once
        if key not in _views:
            name = f"ict-yaw{view[0]:+03.0f}-pitch{view[1]:+03.0f}"
            _views[key] = _cached({**recipe, "view": list(view), "coverage": TURNED_COVERAGE}, name, note)
        return _views[key]


def default_model() -> ShapeModel:
    """The default model: ICT-FaceKit identities (see module docstring)."""
    return built_in_model(DEFAULT)


def resolve_model(spec: str | None) -> ShapeModel:
    """``None`` (the default), a built-in name (``ict``, ``procedural``) or a model ``.npz`` path."""
    if spec is None:
        return default_model()
    if spec in RECIPES and not Path(spec).exists():
        return built_in_model(spec)
    return load_model(spec)
