"""The photo relit with every face: each face's layers (``PhotoRelightNode``'s ``photo_layers``) composed into
it, made when asked and not kept (a 4-megapixel photo relit is 48 MB); and a face's albedo measured on the photo
brought back to the model grid (``albedo_on_grid``, for the novel view), as is the map of the shadows the face does not
cast (``foreign_on_grid``, for the recordings)."""
from __future__ import annotations

import numpy as np

from ...flow.frame import Frame
from ..method.products import photo_8bit, photo_channels, to_8bit
from ..photo.align import Alignment, to_model_grid
from ..photo.encoding import linear_to_srgb
from .compose import FaceLayer, compose


def relit_lights(frame: Frame) -> list[np.ndarray]:
    """The lights the frame's photo is relit by (``relight_light``, then each of ``extra_lights``), (3,) each."""
    return [light for light, _ in _relit_faces(frame)[0].data["photo_layers"]]


def _relit_faces(frame: Frame) -> list[Frame]:
    """The faces whose layers go into the photo: its parts that came through (a frame of one face without
    parts: its own)."""
    return [p for p in frame.parts if p.ok and "photo_layers" in p.data] or [frame]


def relit_photo(frame: Frame, index: int) -> np.ndarray:
    """(H, W, C) float32 in [0, 1]: the frame's photo relit by its ``index``-th light (``relit_lights``), the
    layers of every face that came through composed in, in the photo's own encoding (``meta["encoding"]``):
    the relighting is done in linear light, and an sRGB photo's pixels no face changes keep the file's
    values exactly. Made when asked, not kept: a 4-megapixel photo relit is 48 MB."""
    if frame.meta.get("encoding", "linear") != "srgb":
        return compose(photo_channels(frame), _layers(frame, index))
    (y0, y1, x0, x1), encoded = _encoded_faces(frame, index)
    image = photo_8bit(frame).astype(np.float32)
    image /= np.float32(255.0)
    image[y0:y1, x0:x1] = encoded
    return image


def relit_photo_8bit(frame: Frame, index: int) -> np.ndarray:
    """(H, W, C) uint8 RGB (C = 1 for grey): ``relit_photo`` as its PNG holds it (rounded), made without the
    float copy of the whole photo where it can be: an sRGB photo's file values with its faces' box encoded in."""
    if frame.meta.get("encoding", "linear") != "srgb":
        return to_8bit(relit_photo(frame, index))
    (y0, y1, x0, x1), encoded = _encoded_faces(frame, index)
    image = photo_8bit(frame).copy()
    image[y0:y1, x0:x1] = to_8bit(encoded)
    return image


def _layers(frame: Frame, index: int) -> list[FaceLayer]:
    """The ``index``-th light's layer of every face that came through."""
    return [f.data["photo_layers"][index][1] for f in _relit_faces(frame)]


def _encoded_faces(frame: Frame, index: int) -> tuple[tuple[int, int, int, int], np.ndarray]:
    """An sRGB photo's faces relit by its ``index``-th light: ``(box, values)``, the box ``(y0, y1, x0, x1)``
    around every face's layer and the photo there with the layers composed in linear light, sRGB-encoded
    (h, w, C) float32. Beyond the box the relit photo is the file's values."""
    layers = _layers(frame, index)
    y0, y1, x0, x1 = _around(layers)
    return (y0, y1, x0, x1), linear_to_srgb(compose(photo_channels(frame)[y0:y1, x0:x1], _shifted(layers, y0, x0)))


def relit_photos(frame: Frame) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(light, relit_photo)`` for each of the frame's lights (``relit_lights``): all of them at once, for
    callers that want them held (the API, benchmarks); a run writes them one at a time."""
    return [(light, relit_photo(frame, i)) for i, light in enumerate(relit_lights(frame))]


def _around(layers: list[FaceLayer]) -> tuple[int, int, int, int]:
    """The box ``(y0, y1, x0, x1)`` around every layer's box."""
    return (min(layer.box[0] for layer in layers), max(layer.box[1] for layer in layers),
            min(layer.box[2] for layer in layers), max(layer.box[3] for layer in layers))


def _shifted(layers: list[FaceLayer], y0: int, x0: int) -> list[FaceLayer]:
    """The layers with their boxes in a crop whose corner is ``(y0, x0)``."""
    return [FaceLayer((b[0] - y0, b[1] - y0, b[2] - x0, b[3] - x0), layer.inside, layer.relit, layer.gain, layer.alpha)
            for layer in layers for b in [layer.box]]


def albedo_on_grid(albedo: np.ndarray, box: tuple[int, int, int, int], alignment: Alignment,
                   grid: tuple[int, int]) -> np.ndarray:
    """(Hm, Wm, C) a face's albedo measured on the photo (``FaceRelight.albedo``: (h, w, C) in ``box``
    ``(y0, y1, x0, x1)``, NaN off the face) brought to the model grid, area-averaged over what is known;
    NaN where its box knows nothing. alignment: model pixel -> photo pixel (the whole photo's)."""
    y0, _, x0, _ = box
    al = alignment.cropped(x0, y0)
    known = np.isfinite(albedo[..., 0]).astype(np.float32)
    weight = to_model_grid(known, al, grid)
    # (one channel comes back from OpenCV without its axis)
    measured = to_model_grid(np.nan_to_num(albedo).astype(np.float32) * known[..., None], al, grid)
    out = measured.reshape(weight.shape + (albedo.shape[-1],)) / np.maximum(weight, 1e-6)[..., None]
    return np.where((weight > 0.5)[..., None], out, np.nan).astype(np.float32)


def foreign_on_grid(frame: Frame) -> np.ndarray | None:
    """(Hm, Wm) float32 in [0, 1]: how far each pixel of the model grid is in the shadows the face does not cast
    (``photo_foreign``, on the photo's box) brought to the grid as ``albedo_on_grid`` brings the albedo, NaN off
    the face; None when they were not looked for."""
    d = frame.data
    if "photo_foreign" not in d:
        return None
    on_face = np.isfinite(d["photo_albedo"][..., :1])  # the face's pixels of the box, as its albedo has them
    values = np.where(on_face, np.asarray(d["photo_foreign"], np.float32)[..., None], np.float32(np.nan))
    return albedo_on_grid(values, d["photo_box"], d["alignment"], d["model"].grid)[..., 0]
