"""The shipped default model: trained from the project's own procedural faces, cached.

Built deterministically on first use (about two seconds) from ``DEFAULT_RECIPE`` and cached
under ``$SHADOWFLOW_CACHE`` (default ``$XDG_CACHE_HOME/shadowflow`` or ``~/.cache/shadowflow``).
No third-party data is involved, so it works offline on a fresh machine.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from nodes.shape_model import ShapeModel, load_model, save_model, train_shape_model

GENERATOR_VERSION = 2  # bump when nodes/synth/facegen.py changes the faces it makes
DEFAULT_RECIPE = {"source": "procedural", "n": 100, "seed": 0, "modes": 60, "size": [128, 128],
                  "generator": GENERATOR_VERSION}


def cache_dir() -> Path:
    env = os.environ.get("SHADOWFLOW_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "shadowflow"


def train_from_recipe(recipe: dict) -> ShapeModel:
    """Train the model a recipe describes (``source``, ``n``, ``seed``, ``modes``, ``size``)."""
    from nodes.synth.sources import load_source

    grid = tuple(recipe["size"])
    depths, _ = load_source(recipe["source"], recipe["n"], recipe["seed"], grid)
    return train_shape_model(depths, recipe["modes"], source=json.dumps(recipe, sort_keys=True))


def default_model() -> ShapeModel:
    """Load the default model, building and caching it first if needed."""
    key = hashlib.sha1(json.dumps(DEFAULT_RECIPE, sort_keys=True).encode()).hexdigest()[:12]
    path = cache_dir() / f"default-{key}.npz"
    if path.exists():
        try:
            return load_model(path)
        except ValueError:
            pass  # a damaged cache entry is rebuilt below
    model = train_from_recipe(DEFAULT_RECIPE)
    try:
        save_model(model, path)
    except OSError:
        pass  # a read-only cache only costs the rebuild next time
    return model
