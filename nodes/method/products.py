"""A face's products mapped from the model grid back onto the input photo's pixel grid
(``conventions.md``): what the output files hold and what benchmarks on photos score; and the
photo relit with every face (``relit_photos``)."""
from __future__ import annotations

import numpy as np

from ...flow.frame import Frame
from ..geometry.raster import polygon_mask
from ..model.shape_model import ShapeModel
from ..photo.align import mask_to_input, normals_to_input, scalar_to_input
from .photo_relight import compose
from .relight import surface_mesh


def face_mask(frame: Frame, model: ShapeModel, shape: tuple[int, int]) -> np.ndarray:
    """(H, W) bool over a photo (H, W): the model's face under the frame's alignment, within the
    face's own outline when its landmarks gave one (``placement.outlines["oval"]``)."""
    d = frame.data
    mask = mask_to_input(model.mask, d["alignment"], shape)
    placement = d.get("placement")
    if placement is not None and placement.outlines:
        mask &= polygon_mask(placement.outlines["oval"][0], shape)
    return mask


def input_grid_products(frame: Frame, model: ShapeModel, relit: list | None = None) -> dict[str, np.ndarray]:
    """One face's results on the INPUT image's pixel grid (see ``conventions.md``): mask,
    normals, weights, depth (input pixels), lit (H, W); albedo (H, W) or (H, W, 3) for a colour
    photo, NaN off the face; relit: the photo relit by ``relight_light`` (H, W[, 3]), the face
    feathered into the untouched photo; relit_extra: ``(light, image)`` for each of ``extra_lights``.
    frame: the face's frame; relit: the photo's relit images with every face (``relit_photos`` of
    the photo's frame), default this face's alone."""
    d = frame.data
    al = d["alignment"]
    shape = d["image"].shape[:2]
    m = model.mask
    mask = face_mask(frame, model, shape)
    weights = scalar_to_input(model.to_image(d["fit"].weights.astype(np.float32)), m, al, shape)
    depth = scalar_to_input(d["depth"], m, al, shape) * al.scale
    y0, y1, x0, x1 = d["photo_box"]
    channels = d["photo_albedo"].shape[-1]
    albedo = np.full(shape + (channels,), np.nan, np.float32)
    albedo[y0:y1, x0:x1] = d["photo_albedo"]
    shadow = np.zeros(shape, bool)
    shadow[y0:y1, x0:x1] = d["photo_shadow"]
    relit = relit_photos(frame) if relit is None else relit
    return {
        "mask": mask,
        "normals": np.where(mask[..., None], normals_to_input(d["normals"], m, al, shape), np.nan).astype(np.float32),
        "weights": np.where(mask, np.clip(weights, 0, 1), np.nan).astype(np.float32),
        "depth": np.where(mask, depth, np.nan).astype(np.float32),
        "albedo": squeeze_channels(np.where(mask[..., None], albedo, np.nan)),
        "lit": mask & ~shadow,
        "relit": squeeze_channels(relit[0][1]),
        "relit_extra": [(light, squeeze_channels(r)) for light, r in relit[1:]],
    }


def relit_photos(frame: Frame) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(light, (H, W, C) photo)`` per light: the frame's photo with the layers of its faces that came
    through (its parts' ``photo_layers``; a frame of one face without parts: its own) composed in."""
    if "photo_relit" in frame.data:
        return frame.data["photo_relit"]
    d = frame.data
    photo = d["colour"] if "colour" in d else d["image"][..., None]
    faces = [p for p in frame.parts if p.ok and "photo_layers" in p.data] or [frame]
    lights = [light for light, _ in faces[0].data["photo_layers"]]
    return [(light, compose(photo, [f.data["photo_layers"][i][1] for f in faces])) for i, light in enumerate(lights)]


def squeeze_channels(image: np.ndarray) -> np.ndarray:
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
