"""A face's products mapped from the model grid back onto the input photo's pixel grid
(``conventions.md``): what the output files hold and what benchmarks on photos score. The photo relit
with every face is the relighting's (``relight.products``)."""
from __future__ import annotations

import numpy as np

from ...flow.frame import Frame
from ..geometry.raster import polygon_mask
from ..model.shape_model import ShapeModel
from ..photo.align import face_box, mask_to_input, normals_to_input, reach_margin, scalar_to_input
from ..photo.encoding import linear_to_srgb
from ..photo.placement import outline_on_grid
from .relight import surface_mesh


def face_mask(frame: Frame, shape: tuple[int, int]) -> np.ndarray:
    """(H, W) bool over a photo (H, W): the face's model under the frame's alignment, within the
    face's own outline when its landmarks gave one (``placement.outlines["oval"]``)."""
    model = frame.data["model"]
    box = product_box(frame, shape)
    return on_photo(_box_mask(frame, model, box), box, shape)


def product_box(frame: Frame, shape: tuple[int, int]) -> tuple[int, int, int, int]:
    """``(row0, row1, col0, col1)`` of the photo (H, W) that holds everything the face's products
    know: beyond it they are NaN (0 in masks), so only this box is computed."""
    al = frame.data["alignment"]
    return face_box(frame.data["model"].mask, al, shape, margin=reach_margin(al))


def _box_mask(frame: Frame, model: ShapeModel, box: tuple[int, int, int, int]) -> np.ndarray:
    y0, y1, x0, x1 = box
    mask = mask_to_input(model.mask, frame.data["alignment"].cropped(x0, y0), (y1 - y0, x1 - x0))
    placement = frame.data.get("placement")
    if placement is not None and placement.outlines:
        mask &= polygon_mask(placement.outlines["oval"][0] - [x0, y0], mask.shape)
    return mask


def _in_box(values: np.ndarray, src: tuple[int, int, int, int], dst: tuple[int, int, int, int], fill) -> np.ndarray:
    """``values`` (h, w[, C]) covering the photo's box ``src`` seen through the box ``dst``: ``fill`` where ``src``
    does not reach."""
    out = np.full((dst[1] - dst[0], dst[3] - dst[2]) + values.shape[2:], fill, values.dtype)
    r0, r1, c0, c1 = max(src[0], dst[0]), min(src[1], dst[1]), max(src[2], dst[2]), min(src[3], dst[3])
    if r1 > r0 and c1 > c0:
        out[r0 - dst[0]:r1 - dst[0], c0 - dst[2]:c1 - dst[2]] = values[r0 - src[0]:r1 - src[0], c0 - src[2]:c1 - src[2]]
    return out


def face_products(frame: Frame, arrays: bool = True
                  ) -> tuple[tuple[int, int, int, int], dict[str, np.ndarray]]:
    """One face's results on the photo's pixels inside its ``product_box`` ``(row0, row1, col0, col1)``
    (beyond it each is NaN, or False): ``(box, {mask, normals, weights, depth, albedo, lit})`` as
    ``input_grid_products`` describes them (and ``foreign`` (h, w) float32 in [0, 1] when the face's shadows from
    elsewhere were looked for), each (h, w[, C]) the box's size; without ``arrays``, only
    mask, albedo and lit (the fit's arrays are written on its own grid, ``grid_products``). Only the box
    is computed: a 4-megapixel photo's background costs nothing."""
    d = frame.data
    model = d["model"]
    box = product_box(frame, d["image"].shape[:2])
    mask = _box_mask(frame, model, box)
    # the relit box (``photo_box``) holds the photo's albedo and shadow
    albedo = _in_box(d["photo_albedo"].astype(np.float32), d["photo_box"], box, np.nan)
    shadow = _in_box(np.asarray(d["photo_shadow"], bool), d["photo_box"], box, False)
    nan = np.float32(np.nan)
    out = {"mask": mask, "albedo": squeeze_channels(in_encoding(frame, np.where(mask[..., None], albedo, nan))),
           "lit": mask & ~shadow}
    if "photo_foreign" in d:  # with foreign_shadows: how far each pixel is in the shadows the face does not cast
        out["foreign"] = np.where(mask, _in_box(np.asarray(d["photo_foreign"], np.float32), d["photo_box"], box, 0.0),
                                  np.float32(0.0))
    if not arrays:
        return box, out
    y0, y1, x0, x1 = box
    al, bshape, m = d["alignment"].cropped(x0, y0), (y1 - y0, x1 - x0), model.mask
    weights = scalar_to_input(model.to_image(d["fit"].weights.astype(np.float32)), m, al, bshape)
    depth = scalar_to_input(d["depth"], m, al, bshape) * np.float32(al.scale)
    normals = normals_to_input(d["normals"], m, al, bshape)
    out.update(normals=np.where(mask[..., None], normals, nan).astype(np.float32),
               weights=np.where(mask, np.clip(weights, 0, 1), nan).astype(np.float32),
               depth=np.where(mask, depth, nan).astype(np.float32))
    return box, out


def grid_products(frame: Frame) -> dict[str, np.ndarray]:
    """One face's fit as the fit has it, on the model grid (Hm, Wm), NaN where the fit did not see the face
    (off the model's mask, beyond the photo or the face's outline): normals (Hm, Wm, 3) float32, unit, in
    the PHOTO's camera frame (rotated with the face's roll: the same vectors ``input_grid_products`` puts on
    the photo's pixels); weights (Hm, Wm) in [0, 1]; depth (Hm, Wm) in photo pixels. ``grid_placement``
    says where each model pixel lies on the photo."""
    d = frame.data
    model, al = d["model"], d["alignment"]
    placement = d.get("placement")
    if placement is not None:  # the face's outline, as its products on the photo (the fit may trust less of it)
        seen = model.mask & outline_on_grid(placement, model, d["image"].shape[:2])
    else:
        seen = model.mask & np.asarray(d.get("grid_valid", model.mask), bool)
    nan = np.float32(np.nan)
    normals = al.vector_to_input(np.nan_to_num(d["normals"])).astype(np.float32)
    weights = np.clip(model.to_image(d["fit"].weights.astype(np.float32)), 0.0, 1.0)
    return {"normals": np.where(seen[..., None], normals, nan).astype(np.float32),
            "weights": np.where(seen, weights, nan).astype(np.float32),
            "depth": np.where(seen, d["depth"] * np.float32(al.scale), nan).astype(np.float32)}


def grid_placement(frame: Frame) -> dict:
    """Where a face's model grid lies on its photo (``grid.json``): ``grid`` [Hm, Wm]; ``to_photo`` the 2 x 3
    matrix taking a model pixel (col, row, 1) to its photo pixel (x, y), pixel centres at integers, as
    OpenCV's ``warpAffine`` takes it (``cv2.warpAffine(depth, to_photo, (W, H))`` puts a grid array on the
    photo); ``photo`` [H, W]; ``scale`` photo pixels per model pixel."""
    al = frame.data["alignment"]
    h, w = frame.data["image"].shape[:2]
    return {"grid": list(frame.data["model"].grid), "to_photo": np.round(al.matrix, 9).tolist(), "photo": [h, w],
            "scale": round(al.scale, 9), "depth_unit": "photo pixels", "normals_frame": "photo camera"}


def on_photo(values: np.ndarray, box: tuple[int, int, int, int], shape: tuple[int, int]) -> np.ndarray:
    """A box's ``values`` (h, w[, C]) placed in an array of the photo's ``shape`` (H, W): NaN (floats)
    or False / 0 elsewhere."""
    return _in_box(values, box, (0, shape[0], 0, shape[1]), np.nan if values.dtype.kind == "f" else 0)


def input_grid_products(frame: Frame, relit: list | None = None) -> dict[str, np.ndarray]:
    """One face's results on the INPUT image's pixel grid (see ``conventions.md``): mask,
    normals, weights, depth (input pixels), lit (H, W); albedo (H, W) or (H, W, 3) for a colour
    photo, NaN off the face, in the photo's encoding; relit: the photo relit by ``relight_light`` (H,
    W[, 3]) in its encoding, the face feathered into the untouched photo; relit_extra: ``(light, image)``
    for each of ``extra_lights``. frame: the face's frame; relit: the photo's relit images with every
    face (``relight.products.relit_photos`` of the photo's frame), or None: no relit images."""
    shape = frame.data["image"].shape[:2]
    box, products = face_products(frame)
    out = {name: on_photo(values, box, shape) for name, values in products.items()}
    if relit:
        out.update(relit=squeeze_channels(relit[0][1]),
                   relit_extra=[(light, squeeze_channels(r)) for light, r in relit[1:]])
    return out


def photo_channels(frame: Frame) -> np.ndarray:
    """(H, W, C) the frame's photo in linear light: its colour (C = 3; a ``Decoded8`` for 8-bit sRGB) or its
    grey with a channel axis (C = 1)."""
    d = frame.data
    return d["colour"] if "colour" in d else d["image"][..., None]


def photo_rgb8(frame: Frame) -> np.ndarray:
    """(H, W, 3) uint8 RGB of the frame's photo as its file has it (a grey one in all three channels),
    for the face finder, whose nets learnt from photos as cameras encode them."""
    if "rgb8" in frame.data:
        return frame.data["rgb8"]
    img = photo_channels(frame)
    # a linear photo (Yale B's PGMs) is shown to the nets as a camera would have encoded it: the same face
    # given linear in grey and sRGB in colour is then found at the same place
    rgb = (linear_to_srgb(img) * np.float32(255.0) + np.float32(0.5)).astype(np.uint8)
    return np.ascontiguousarray(np.broadcast_to(rgb, img.shape[:2] + (3,)))


def photo_8bit(frame: Frame) -> np.ndarray:
    """(H, W, C) uint8 RGB (C = 1 for grey): the photo as its file shows it, in its own encoding (an sRGB
    photo's file values; a linear one's values, rounded)."""
    photo = photo_channels(frame)
    if frame.meta.get("encoding", "linear") == "srgb":
        return _file_values(photo, frame.data["rgb8"])
    return to_8bit(photo)


def to_8bit(values: np.ndarray) -> np.ndarray:
    """[0, 1] floats -> uint8, rounded (NaN as 0)."""
    return np.clip(np.nan_to_num(values) * np.float32(255.0) + np.float32(0.5), 0, 255).astype(np.uint8)


def _file_values(photo: np.ndarray, rgb8: np.ndarray) -> np.ndarray:
    """The file's own 8-bit values with the photo's channels: (H, W, 3), or (H, W, 1) for a grey photo."""
    return rgb8 if rgb8.shape[-1] == photo.shape[-1] else rgb8[..., :1]


def in_encoding(frame: Frame, linear: np.ndarray) -> np.ndarray:
    """Linear values of the frame's photo (e.g. its albedo) in the photo's own encoding; NaN stays NaN."""
    if frame.meta.get("encoding", "linear") != "srgb":
        return linear
    return np.where(np.isfinite(linear), linear_to_srgb(np.nan_to_num(linear)), np.nan).astype(np.float32)


def squeeze_channels(image: np.ndarray) -> np.ndarray:
    """(H, W, 1) -> (H, W); colour (H, W, 3) stays."""
    return image[..., 0] if image.ndim == 3 and image.shape[2] == 1 else image


def photo_mesh(frame: Frame) -> dict[str, np.ndarray]:
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
