"""A face relit live: the few arrays a browser needs to relight one face for any light, at a
preview's resolution, and ``render_live``, the reference the page's JavaScript follows step for
step (``nodes/app/view.py``).

The live face is the product's relighting (``PhotoRelightNode``) without what needs the whole
photo or a second look at it: the albedo is the one ``albedo.png`` holds (the product trusts the
photo's own pixels a little further where a light changes the shading little). As the product does,
the face's change of light is carried over its border into the photo around it (``outside_gain``),
with the blurs done as the page does them (``gaussian_blur``: three boxes). The two agree to a few
grey levels (``docs/relighting.md``).

Arrays are on the preview's pixel grid (h, w), a face's layer box of the photo (the face and its
feather) scaled to at most ``LIVE_SIDE`` pixels a side; ``C`` is 1 (grey) or 3 (RGB); light
directions in the camera frame.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from ..photo.align import Alignment, scalar_to_input
from ..photo.encoding import linear_to_srgb, srgb_to_linear
from .photo_relight import (
    DETAIL_SHARE,
    LIT_SHADING,
    RIM_SHARE,
    beyond_ratio,
    beyond_reach,
    clipped_floor,
    exposure_gain,
    face_rim,
    quieted,
    shine_kept,
    shine_lobe,
    smoothstep,
    with_ambient,
    without_sheen,
)
from .shadow import cast_margin, soft_cast

LIVE_SIDE = 384  # pixels, the preview's longer side: a drag redraws it in a few milliseconds


# ``LiveFace.flags``: the face, its skin, its clipped channels (4 << c), its rim (``face_rim``), the face's own skin
# beyond the model (``outside_gain``'s ``beyond``)
FACE, SKIN, CLIPPED_BIT, RIM, BEYOND = 1, 2, 4, 32, 64


@dataclass(frozen=True)
class LiveFace:
    """What relights one face for any light, as the page receives it (integers, so the page and
    ``render_live`` start from the same numbers). box: ``(y0, y1, x0, x1)`` the photo's pixels the
    preview shows; photo8 (h, w, C) uint8, the photo in its own ``encoding`` ("srgb" or "linear");
    albedo16 (h, w, C) uint16, the linear albedo over ``albedo_scale``; sheen16 (h, w, C) uint16, the photo's
    shine in it (``photo_relight.sheen``), on the same scale; normals16 (h, w, 3) int16,
    camera frame, x 32767; flags (h, w) uint8 (``FACE``, ``SKIN``, ``CLIPPED_BIT << c``: the photo at
    the top of its range, ``RIM``: where the face's change of light is measured for the photo around it, ``BEYOND``:
    the face's own skin past the model, which takes that change in full); alpha8 (h, w) uint8, how much of the relit face shows (``inner_alpha``);
    want: the exposure of the photo's lit skin (``exposure_target``) or None; ambient: the room's share
    of the light; photo_light (3,); depth (Hm, Wm) float32 the fit's height field, NaN off its mask;
    to_preview (2, 3) model pixel -> preview pixel; fade8 (h, w) uint8, how far the face's change of
    light reaches a pixel around it (``outside_gain``'s fade; 0 on the face and beyond the feather);
    reach8 (h, w) uint8, how far that change may pass ``RATIO_OUTSIDE`` (``beyond_reach``; 0 without ``BEYOND``);
    sigma: the preview pixels the change of light is averaged over at the face's border."""

    box: tuple[int, int, int, int]
    photo8: np.ndarray
    albedo16: np.ndarray
    sheen16: np.ndarray
    albedo_scale: float
    normals16: np.ndarray
    flags: np.ndarray
    alpha8: np.ndarray
    want: float | None
    ambient: float
    photo_light: np.ndarray
    depth: np.ndarray
    to_preview: np.ndarray
    encoding: str
    fade8: np.ndarray
    reach8: np.ndarray
    sigma: float

    @property
    def size(self) -> tuple[int, int]:
        return self.flags.shape


def live_relight_data(box: tuple[int, int, int, int], photo: np.ndarray, albedo: np.ndarray, shine: np.ndarray,
                      normals: np.ndarray,
                      face: np.ndarray, alpha: np.ndarray, skin: np.ndarray, want: float | None, ambient: float,
                      photo_light: np.ndarray, clipped: np.ndarray, depth: np.ndarray, grid_mask: np.ndarray,
                      to_box: np.ndarray, encoding: str, feather_px: float, beyond: np.ndarray | None = None,
                      person: np.ndarray | None = None,
                      side: int = LIVE_SIDE) -> LiveFace:
    """A ``LiveFace`` from the relighting's arrays on the photo's layer box (h, w): photo, albedo and its
    shine (h, w, C) linear, normals (h, w, 3), face, skin (h, w) bool, alpha (h, w), clipped (h, w, C) bool; to_box
    (2, 3) model pixel -> box pixel; feather_px: the photo pixels the face's change of light fades over
    around it; beyond (h, w) bool or None, the face's own skin past ``face``; person (h, w) float or None, how
    sure a segmentation is that a pixel is the person (``outside_gain``). Scaled (area-averaged) to at most
    ``side`` pixels a side."""
    h, w = face.shape
    k = min(1.0, side / max(h, w))
    size = (max(1, round(w * k)), max(1, round(h * k)))  # (width, height) as OpenCV takes it
    kx, ky = size[0] / w, size[1] / h

    def area(a: np.ndarray) -> np.ndarray:
        a = np.asarray(a, np.float32)
        out = a if k == 1.0 else cv2.resize(a, size, interpolation=cv2.INTER_AREA)
        return out.reshape(size[1], size[0], *a.shape[2:])

    f = area(face) >= 0.5
    n = area(np.where(face[..., None], normals, 0.0))
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-6)
    n = np.where(f[..., None], n, 0.0)
    a = np.where(f[..., None], area(np.nan_to_num(np.atleast_3d(albedo))), 0.0)
    scale = float(max(a.max(), 1e-6))
    shine16 = np.round(np.clip(np.where(f[..., None], area(np.atleast_3d(shine)), 0.0), 0.0, a) / scale * 65535.0)
    shown = area(np.atleast_3d(photo))
    shown = linear_to_srgb(shown) if encoding == "srgb" else np.clip(shown, 0.0, 1.0)
    flags = f * FACE + ((area(skin) >= 0.5) & f) * SKIN
    for c, channel in enumerate(np.moveaxis(area(np.atleast_3d(clipped)).reshape(size[1], size[0], -1), -1, 0)):
        flags = flags + ((channel >= 0.5) & f) * (CLIPPED_BIT << c)
    # around the face: how far its change of light reaches (``outside_gain``'s fade; its blur, half the feather
    # wide, reaches every pixel the fade does)
    feather = max(feather_px * k, 1.0)
    sigma = max(feather / 2.0, 1.0)
    flags = flags + face_rim(f, RIM_SHARE * feather) * RIM
    b = np.zeros_like(f) if beyond is None else (area(beyond) >= 0.5) & ~f
    reach = beyond_reach(b, feather)
    reach = np.zeros(f.shape, np.float32) if reach is None else reach
    flags = flags + b * BEYOND
    # from the face's own outline (``outside_gain``)
    distance = cv2.distanceTransform((~(f | b)).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    fade = np.where(f | b, 0.0, 1.0 - smoothstep(distance, 0.0, feather))
    if person is not None:  # the change of light reaches the person around the face only (``outside_gain``)
        fade = fade * area(person)
    # pixel centres: preview (x + 0.5) = k (box x + 0.5)
    to_preview = np.array([[kx, 0.0, 0.5 * kx - 0.5], [0.0, ky, 0.5 * ky - 0.5]]) @ np.vstack([to_box, [0, 0, 1.0]])
    return LiveFace(box=tuple(int(v) for v in box), photo8=(shown * 255.0 + 0.5).astype(np.uint8),
                    albedo16=np.round(a / scale * 65535.0).astype(np.uint16), sheen16=shine16.astype(np.uint16),
                    albedo_scale=scale,
                    normals16=np.round(n * 32767.0).astype(np.int16), flags=flags.astype(np.uint8),
                    alpha8=np.round(np.where(f, area(alpha), 0.0) * 255.0).astype(np.uint8),
                    want=want, ambient=float(ambient), photo_light=np.asarray(photo_light, np.float64),
                    depth=np.where(grid_mask, depth, np.nan).astype(np.float32), to_preview=to_preview,
                    encoding=encoding, fade8=np.round(fade * 255.0).astype(np.uint8),
                    reach8=np.round(reach * 255.0).astype(np.uint8), sigma=float(sigma))


def blur_radius(sigma: float) -> int:
    """The radius of the box that, passed three times, blurs like a Gaussian of ``sigma`` pixels (three
    boxes of width w have the variance 3 (w^2 - 1) / 12)."""
    return max(1, round((math.sqrt(4.0 * sigma * sigma + 1.0) - 1.0) / 2.0))


def gaussian_blur(values: np.ndarray, sigma: float) -> np.ndarray:
    """(h, w[, C]) float32 ``values`` blurred like a Gaussian of ``sigma`` pixels: three passes of a box
    (``blur_radius``) along rows, then three along columns, zero beyond the edges. The page does the same
    with running sums, a few milliseconds a redraw whatever ``sigma``."""
    r = blur_radius(sigma)
    v = np.asarray(values, np.float64)
    for axis in (1, 0):
        v = np.moveaxis(v, axis, 0)  # the running sums along the first axis
        n = v.shape[0]
        for _ in range(3):
            c = np.cumsum(np.concatenate([np.zeros((r + 1,) + v.shape[1:]), v, np.zeros((r,) + v.shape[1:])]), axis=0)
            v = (c[2 * r + 1:2 * r + 1 + n] - c[:n]) / (2 * r + 1)
        v = np.moveaxis(v, 0, axis)
    return v.astype(np.float32)


def live_cast(live: LiveFace, light: np.ndarray) -> np.ndarray:
    """(h, w) float32 in [0, 1]: how much of each preview pixel is in ``light``'s cast shadow, traced on
    the fit's height field (its model grid, as the product does) and brought to the preview."""
    al = Alignment(live.to_preview, "live")
    margin = cast_margin(live.depth, al.vector_to_model(light))
    return soft_cast(scalar_to_input(margin, np.isfinite(live.depth), al, live.size))


def render_live(live: LiveFace, light: np.ndarray, cast: np.ndarray | None = None) -> np.ndarray:
    """(h, w, C) float32 in [0, 1], in the photo's encoding: the preview with its face relit by
    ``light`` (3,), camera frame: ``albedo x (a + (1 - a) S')`` (the albedo less the photo's shine where the light
    darkens the skin or moves its highlight away, ``without_sheen``, ``shine_lobe``; ``S'`` the new shading, less
    the share of a pixel its cast shadow covers), exposed as the photo's lit skin, clipped pixels no darker than
    the clipping proves, faded by ``alpha`` into the photo times the face's change of light at its border, which
    the photo around the face follows over the feather (``fade8``). cast: the light's cast shadow
    (``live_cast``), traced when None."""
    s = np.asarray(light, np.float64)
    s = s / np.linalg.norm(s)
    cast = live_cast(live, s) if cast is None else cast
    normals = live.normals16.astype(np.float32) / np.float32(32767.0)
    albedo = live.albedo16.astype(np.float32) * np.float32(live.albedo_scale / 65535.0)
    shine = live.sheen16.astype(np.float32) * np.float32(live.albedo_scale / 65535.0)
    face, skin = (live.flags & FACE) > 0, (live.flags & SKIN) > 0
    clipped = np.stack([(live.flags & (CLIPPED_BIT << c)) > 0 for c in range(albedo.shape[-1])], axis=-1)
    photo = live.photo8.astype(np.float32) / np.float32(255.0)
    photo = srgb_to_linear(photo) if live.encoding == "srgb" else photo
    new = np.where(face, (1.0 - cast) * np.clip(normals @ s.astype(np.float32), 0.0, None), 0.0).astype(np.float32)
    lighting = with_ambient(new, live.ambient)
    old = with_ambient(np.clip(normals @ live.photo_light.astype(np.float32), 0.0, None), live.ambient)
    keep = shine_kept(old, lighting, shine_lobe(normals, live.photo_light, s))
    unexposed = without_sheen(albedo, shine, old, lighting, keep) * lighting[..., None]  # keep <= S'/S: as is
    gain = exposure_gain(live.want, unexposed, skin & (new >= LIT_SHADING))
    face_image = np.float32(gain) * unexposed
    # no darker than the clipping proves, less the shine the light takes (``clipped_floor``)
    face_image = np.clip(clipped_floor(face_image, photo, old, lighting, gain, face, albedo - shine, keep, clipped),
                         0.0, 1.0)
    # the face's change of light at its border, carried into the photo there (``outside_gain``)
    rim = ((live.flags & RIM) > 0).astype(np.float32)
    w = rim[..., None]
    support = gaussian_blur(rim, live.sigma)[..., None]
    num = gaussian_blur(face_image * w, live.sigma)
    ratio = num / np.maximum(gaussian_blur(photo * w, live.sigma), np.maximum(1e-3 * support, 1e-12))
    reach = (live.reach8.astype(np.float32) / np.float32(255.0))[..., None]
    ratio = beyond_ratio(ratio, photo, num / np.maximum(support, 1e-12), reach)
    fade = (live.fade8.astype(np.float32) / np.float32(255.0))[..., None]
    a = (live.alpha8.astype(np.float32) / np.float32(255.0))[..., None]
    beyond = ((live.flags & BEYOND) > 0)[..., None]
    gain = np.where(face[..., None] | beyond, ratio, 1.0 + fade * (ratio - 1.0)).astype(np.float32)
    if live.reach8.any():  # past RATIO_OUTSIDE the photo's detail is lifted less than its smooth part
        gain = quieted(gain, photo, gaussian_blur(photo, live.sigma * DETAIL_SHARE))
    out = np.where(face[..., None], a * face_image + (1.0 - a) * photo * gain, photo * gain)
    out = np.clip(out, 0.0, 1.0)
    return (linear_to_srgb(out) if live.encoding == "srgb" else out).astype(np.float32)
