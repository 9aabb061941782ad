"""A frame's products mapped from the model grid back onto the input photo's pixel grid
(``conventions.md``): what the output files hold and what benchmarks on photos score."""
from __future__ import annotations

import numpy as np

from ...flow.frame import Frame
from ..model.shape_model import ShapeModel
from ..photo.align import mask_to_input, normals_to_input, scalar_to_input
from .relight import surface_mesh


def input_grid_products(frame: Frame, model: ShapeModel) -> dict[str, np.ndarray]:
    """The frame's results on the INPUT image's pixel grid (see ``conventions.md``): mask,
    normals, weights, depth (input pixels), lit (H, W); albedo (H, W) or (H, W, 3) for a colour
    photo, NaN off the face; relit: the photo relit by ``relight_light`` (H, W[, 3]), the face
    feathered into the untouched photo; relit_extra: ``(light, image)`` for each of ``extra_lights``."""
    d = frame.data
    al = d["alignment"]
    shape = d["image"].shape[:2]
    m = model.mask
    mask = mask_to_input(m, al, shape)
    weights = scalar_to_input(model.to_image(d["fit"].weights.astype(np.float32)), m, al, shape)
    depth = scalar_to_input(d["depth"], m, al, shape) * al.scale
    out = {
        "mask": mask,
        "normals": np.where(mask[..., None], normals_to_input(d["normals"], m, al, shape), np.nan).astype(np.float32),
        "weights": np.where(mask, np.clip(weights, 0, 1), np.nan).astype(np.float32),
        "depth": np.where(mask, depth, np.nan).astype(np.float32),
        "albedo": _squeeze(d["photo_albedo"]),
        "lit": mask & ~d["photo_shadow"],
        "relit": _squeeze(d["photo_relit"][0][1]),
        "relit_extra": [(light, _squeeze(r)) for light, r in d["photo_relit"][1:]],
    }
    return out


def _squeeze(image: np.ndarray) -> np.ndarray:
    """(H, W, 1) -> (H, W); colour (H, W, 3) stays."""
    return image[..., 0] if image.ndim == 3 and image.shape[2] == 1 else image


def photo_mesh(frame: Frame, model: ShapeModel) -> dict[str, np.ndarray]:
    """The recovered surface as a mesh at the fit's own resolution (one vertex per model pixel, so
    its size is what the fit knows, whatever the photo's), placed in the photo's pixel frame:
    vertices (V, 3) float32 (x = input column, y = -input row, z = height in input pixels),
    triangles (T, 3) uint32, colours (V, 3) uint8 grey albedo."""
    d = frame.data
    al = d["alignment"]
    mesh = surface_mesh(d["depth"], d["albedo"])
    v = mesh["vertices"].astype(np.float64)
    cols, rows = v[:, 0], -v[:, 1]
    x, y = (al.matrix @ np.vstack([cols, rows, np.ones_like(cols)]))
    mesh["vertices"] = np.column_stack([x, -y, v[:, 2] * al.scale]).astype(np.float32)
    return mesh
