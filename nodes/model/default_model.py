"""The built-in models, built deterministically on first use and cached.

``ict`` (the default) is trained from random identities of ICT-FaceKit, a morphable model learnt
from light-stage scans of real people (MIT licence; its compact face-area basis ships in
``nodes/data/``). ``procedural`` is trained from the project's own anthropometric generator
(``nodes/model/faces/facegen.py``). Each is built from its recipe on first use (a few seconds) and
cached under ``$SHADOWFLOW_CACHE`` (default ``$XDG_CACHE_HOME/shadowflow`` or
``~/.cache/shadowflow``), keyed by the recipe and, for ICT, the shipped basis' bytes. No
download is involved, so both work offline on a fresh machine.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from .faces.ict import SHIPPED
from .shape_model import ShapeModel, load_model, save_model, train_shape_model
from .sources import training_faces

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
    optionally ``expressions``: an ICT face's chance of each expression blendshape)."""

    from threadpoolctl import threadpool_limits

    grid = tuple(recipe["size"])
    # on one BLAS thread, always: the decomposition's last bits depend on BLAS's threads, and a model built
    # under two of them differed in one of its 915,600 mode values from one built under one (so did the fits)
    with threadpool_limits(limits=1, user_api="blas"):
        depths, mouth = training_faces(recipe["source"], recipe["n"], recipe["seed"], grid,
                                       recipe.get("expressions", 0.0))
        return train_shape_model(depths, recipe["modes"], source=json.dumps(recipe, sort_keys=True), mouth=mouth)


def _cache_key(recipe: dict) -> str:
    h = hashlib.sha1(json.dumps(recipe, sort_keys=True).encode())
    if recipe["source"] == "ict":
        h.update(SHIPPED.read_bytes())
    return h.hexdigest()[:12]


def built_in_model(name: str = DEFAULT) -> ShapeModel:
    """Load a built-in model (``ict`` or ``procedural``), building and caching it first if needed."""
    if name not in RECIPES:
        raise ValueError(f"unknown built-in model {name!r}: {' or '.join(BUILT_IN)}")
    recipe = RECIPES[name]
    path = cache_dir() / f"{name}-{_cache_key(recipe)}.npz"
    if path.exists() or path.is_symlink():
        try:
            return load_model(path)
        except ValueError:  # damaged (truncated, a flipped bit), or not a regular file: rebuilt below
            try:
                path.unlink()
            except OSError:
                pass
    model = train_from_recipe(recipe)
    try:
        save_model(model, path)
    except OSError:
        pass  # a read-only cache only costs the rebuild next time
    return model


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
