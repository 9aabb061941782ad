"""A frame's products mapped from the model grid back onto the input photo's pixel grid
(``conventions.md``): what the output files hold and what benchmarks on photos score."""
from __future__ import annotations

import numpy as np

from ...flow.frame import Frame
from ..model.shape_model import ShapeModel
from ..photo.align import mask_to_input, normals_to_input, scalar_to_input


def input_grid_products(frame: Frame, model: ShapeModel) -> dict[str, np.ndarray]:
    """The frame's results on the INPUT image's pixel grid (see ``conventions.md``)."""
    d = frame.data
    al = d["alignment"]
    shape = d["image"].shape[:2]
    m = model.mask
    mask = mask_to_input(m, al, shape)
    weights = scalar_to_input(model.to_image(d["fit"].weights.astype(np.float32)), m, al, shape)
    depth = scalar_to_input(d["depth"], m, al, shape) * al.scale
    lit = scalar_to_input(d["shadow"].lit.astype(np.float32), m, al, shape, nearest=True)
    out = {
        "mask": mask,
        "normals": np.where(mask[..., None], normals_to_input(d["normals"], m, al, shape), np.nan).astype(np.float32),
        "weights": np.where(mask, np.clip(weights, 0, 1), np.nan).astype(np.float32),
        "depth": np.where(mask, depth, np.nan).astype(np.float32),
        "albedo": np.where(mask, scalar_to_input(d["albedo"], m, al, shape), np.nan),
        "lit": mask & (np.nan_to_num(lit) >= 0.5),
        "relit": np.where(mask, scalar_to_input(d["relit"], m, al, shape), np.nan),
    }
    return out
