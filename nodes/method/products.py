"""A face's products mapped from the model grid back onto the input photo's pixel grid
(``conventions.md``): what the output files hold and what benchmarks on photos score; and the
photo relit with every face (``relit_photos``)."""
from __future__ import annotations

import numpy as np

from ...flow.frame import Frame
from ..geometry.raster import polygon_mask
from ..model.shape_model import ShapeModel
from ..photo.align import mask_to_input, normals_to_input, scalar_to_input
from ..photo.encoding import linear_to_srgb
from .photo_relight import FaceLayer, compose
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
    photo, NaN off the face, in the photo's encoding; relit: the photo relit by ``relight_light`` (H,
    W[, 3]) in its encoding, the face feathered into the untouched photo; relit_extra: ``(light, image)`` for each of ``extra_lights``.
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
        "albedo": squeeze_channels(in_encoding(frame, np.where(mask[..., None], albedo, np.nan))),
        "lit": mask & ~shadow,
        "relit": squeeze_channels(relit[0][1]),
        "relit_extra": [(light, squeeze_channels(r)) for light, r in relit[1:]],
    }


def relit_photos(frame: Frame) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(light, (H, W, C) photo)`` per light: the frame's photo with the layers of its faces that came
    through (its parts' ``photo_layers``; a frame of one face without parts: its own) composed in,
    float32 in [0, 1] in the photo's own encoding (``meta["encoding"]``): the relighting is done in
    linear light, and an sRGB photo's pixels no face changes keep the file's values exactly."""
    if "photo_relit" in frame.data:
        return frame.data["photo_relit"]
    d = frame.data
    photo = d["colour"] if "colour" in d else d["image"][..., None]
    faces = [p for p in frame.parts if p.ok and "photo_layers" in p.data] or [frame]
    lights = [light for light, _ in faces[0].data["photo_layers"]]
    encoding = frame.meta.get("encoding", "linear")
    out = []
    for i, light in enumerate(lights):
        layers = [f.data["photo_layers"][i][1] for f in faces]
        if encoding != "srgb":
            out.append((light, compose(photo, layers)))
            continue
        # only the faces' boxes are composed and encoded; the rest is the file's values (8 bits)
        y0, x0 = min(layer.box[0] for layer in layers), min(layer.box[2] for layer in layers)
        y1, x1 = max(layer.box[1] for layer in layers), max(layer.box[3] for layer in layers)
        shifted = [FaceLayer((b[0] - y0, b[1] - y0, b[2] - x0, b[3] - x0), layer.inside, layer.relit, layer.gain)
                   for layer in layers for b in [layer.box]]
        image = (d["rgb8"] if d["rgb8"].shape[-1] == photo.shape[-1] else d["rgb8"][..., :1]).astype(np.float32)
        image /= np.float32(255.0)
        image[y0:y1, x0:x1] = linear_to_srgb(compose(photo[y0:y1, x0:x1], shifted))
        out.append((light, image))
    return out


def in_encoding(frame: Frame, linear: np.ndarray) -> np.ndarray:
    """Linear values of the frame's photo (e.g. its albedo) in the photo's own encoding; NaN stays NaN."""
    if frame.meta.get("encoding", "linear") != "srgb":
        return linear
    return np.where(np.isfinite(linear), linear_to_srgb(np.nan_to_num(linear)), np.nan).astype(np.float32)


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
