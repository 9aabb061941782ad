"""A face relit live: the few arrays a browser needs to relight one face for any light, at a preview's
resolution, and ``render_live``, the reference the page's script (``nodes/app/view.js``) follows step for step.

The live face is the product's relighting (``face.FaceRelight``) with its light-independent parts measured once
by the product: the light the photo shows (``shown``), the room's light a new light adds to (``more``), the albedo
a fill paints with (``fill``), how well each pixel's light is known (``relative``) and where a fill may paint
(``paint``). Per light the page computes what the product does: the new light's shading and cast shadow, the change
of light (its coarse part averaged, as ``lift.smooth_change``), how far the photo stays as it is
(``lift.shadows_kept``), the exposure, what is not skin held to the skin around it (one scale of
``lift.held_to_skin``'s two), the fill where the photo cannot be lifted (``lift.usable``), and the face's change of
light carried into the photo around it (``compose.outside_gain``). It leaves out what needs a second look at the
photo per light: the photo's shine, the colour a lifted pixel takes, a fill's level met to the photo beside it, and
the side lit less raised toward its mirror; the two agree to a few grey levels (``tests/app/test_view.py``). The
blurs are done as the page does them (``gaussian_blur``: three boxes).

Arrays are on the preview's pixel grid (h, w), a face's layer box of the photo (the face and its feather) scaled to at
most ``LIVE_SIDE`` pixels a side; ``C`` is 1 (grey) or 3 (RGB); light directions in the camera frame.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from ..method.shadow import cast_margin, soft_cast
from ..photo.align import Alignment, scalar_to_input
from ..photo.encoding import linear_to_srgb, srgb_to_linear
from .albedo import lifted
from .compose import RIM_SHARE, beyond_ratio, beyond_reach, face_rim
from .fields import brightness, smoothstep
from .lift import LIT_SHADING, MAX_GAIN, exposure_gain, shadows_kept, usable
from .light_colour import tinted
from .shine import shine_kept, shine_lobe

LIVE_SIDE = 384  # pixels, the preview's longer side: a drag redraws it in a few milliseconds
HELD_MARGIN = 1.25  # what is not skin is lifted at most this x the skin around it (``lift.held_to_skin``)

# ``LiveFace.flags``: the face, its skin, its rim (``face_rim``), the face's own skin beyond the model
# (``outside_gain``'s ``beyond``)
FACE, SKIN, RIM, BEYOND = 1, 2, 32, 64


@dataclass(frozen=True)
class LiveFace:
    """What relights one face for any light, as the page receives it. box: ``(y0, y1, x0, x1)`` the photo's pixels the
    preview shows; photo8 (h, w, C) uint8, the photo in its own ``encoding`` ("srgb" or "linear"); shown (h, w, C)
    float32, the light the photo shows; more (h, w, C) float32, the room's light a new light adds to; fill (h, w, C)
    float32, the albedo a fill paints with; relative (h, w) float32, how well each pixel's light is known
    (``lift.precision``); paint8 (h, w) uint8, how far a fill may paint there; normals16 (h, w, 3) int16, camera
    frame, x 32767; flags (h, w) uint8 (``FACE``, ``SKIN``, ``RIM``: where the face's change of light is measured for
    the photo around it, ``BEYOND``: the face's own skin past the model, which takes that change in full); alpha8
    (h, w) uint8, how much of the relit face shows (``compose.inner_alpha``); want: the exposure of the photo's lit
    skin (``lift.exposure_target``) or None; ambient: the room's share of the light; photo_light (3,); depth (Hm, Wm)
    float32 the fit's height field, NaN off its mask; to_preview (2, 3) model pixel -> preview pixel; fade8 (h, w)
    uint8, how far the face's change of light reaches a pixel around it (``outside_gain``'s fade; 0 on the face and
    beyond the feather); reach8 (h, w) uint8, how far that change may pass ``RATIO_OUTSIDE`` (``beyond_reach``);
    sigma: the preview pixels the change of light is averaged over at the face's border; change_sigma, held_sigma:
    the preview pixels the change of light and the skin's lift are averaged over; raise_ratio (h, w, C) float32 and
    raise8 (h, w) uint8, or None: how far the side lit less may be raised toward its mirror (``albedo.mirror_raise``'s
    ratio and strength); shine (h, w, C) float32 or None: the photo's shine, in light (``shine.sheen``), which a new
    light keeps as far as ``shine.shine_kept`` says; kept (h, w, C) float32 or None: how much the shadows the face does
    not cast are lifted under any light (``FaceRelight.foreign_lift``; None: none looked for); tint (h, w, 3) float32 or
    None: the lamp's colour over the light's each pixel shows (``light_colour.light_tint``; None: a grey photo)."""

    box: tuple[int, int, int, int]
    photo8: np.ndarray
    shown: np.ndarray
    more: np.ndarray
    fill: np.ndarray
    relative: np.ndarray
    paint8: np.ndarray
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
    change_sigma: float
    held_sigma: float
    raise_ratio: np.ndarray | None = None
    raise8: np.ndarray | None = None
    shine: np.ndarray | None = None
    kept: np.ndarray | None = None
    tint: np.ndarray | None = None

    @property
    def size(self) -> tuple[int, int]:
        return self.flags.shape


@dataclass(frozen=True)
class LiveArrays:
    """The product's arrays for a face's live page, on its layer box (h, w): photo, shown, more, fill (h, w, C); normals
    (h, w, 3); relative, paint (h, w) float; face, skin (h, w) bool; alpha (h, w); beyond (h, w) bool or None, the
    face's own skin past the face; person (h, w) float or None (``compose.outside_gain``); raise_ratio (h, w, C),
    raise_strength (h, w), or None (``albedo.mirror_raise``); foreign_lift (h, w, C) or None
    (``FaceRelight.foreign_lift``); tint (h, w, 3) or None (``light_colour.light_tint``)."""

    photo: np.ndarray
    shown: np.ndarray
    more: np.ndarray
    fill: np.ndarray
    normals: np.ndarray
    relative: np.ndarray
    paint: np.ndarray
    face: np.ndarray
    skin: np.ndarray
    alpha: np.ndarray
    beyond: np.ndarray | None
    person: np.ndarray | None
    raise_ratio: np.ndarray | None = None
    raise_strength: np.ndarray | None = None
    shine: np.ndarray | None = None
    foreign_lift: np.ndarray | None = None
    tint: np.ndarray | None = None


def live_relight_data(box: tuple[int, int, int, int], arrays: LiveArrays, want: float | None, ambient: float,
                      photo_light: np.ndarray, depth: np.ndarray, grid_mask: np.ndarray, to_box: np.ndarray,
                      encoding: str, feather_px: float, change_px: float, held_px: float,
                      side: int = LIVE_SIDE) -> LiveFace:
    """A ``LiveFace`` from the relighting's ``arrays`` on the photo's layer box ``box``: to_box (2, 3) model pixel ->
    box pixel; feather_px, change_px, held_px: the photo pixels the face's change of light fades over around it, its
    coarse part is averaged over, and the skin's lift is averaged over. Scaled (area-averaged) to at most ``side``
    pixels a side."""
    h, w = arrays.face.shape
    k = min(1.0, side / max(h, w))
    size = (max(1, round(w * k)), max(1, round(h * k)))  # (width, height) as OpenCV takes it
    kx, ky = size[0] / w, size[1] / h

    def area(a: np.ndarray) -> np.ndarray:
        a = np.asarray(a, np.float32)
        out = a if k == 1.0 else cv2.resize(a, size, interpolation=cv2.INTER_AREA)
        return out.reshape(size[1], size[0], *a.shape[2:])

    f = area(arrays.face) >= 0.5
    n = area(np.where(arrays.face[..., None], arrays.normals, 0.0))
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-6)
    n = np.where(f[..., None], n, 0.0)
    shown = area(np.atleast_3d(arrays.photo))
    shown = linear_to_srgb(shown) if encoding == "srgb" else np.clip(shown, 0.0, 1.0)
    flags = f * FACE + ((area(arrays.skin) >= 0.5) & f) * SKIN
    feather = max(feather_px * k, 1.0)
    sigma = max(feather / 2.0, 1.0)
    flags = flags + face_rim(f, RIM_SHARE * feather) * RIM
    b = np.zeros_like(f) if arrays.beyond is None else (area(arrays.beyond) >= 0.5) & ~f
    reach = beyond_reach(b, feather)
    reach = np.zeros(f.shape, np.float32) if reach is None else reach
    flags = flags + b * BEYOND
    distance = cv2.distanceTransform((~(f | b)).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    fade = np.where(f | b, 0.0, 1.0 - smoothstep(distance, 0.0, feather))
    if arrays.person is not None:
        fade = fade * area(arrays.person)
    inside = lambda a: np.where(f[..., None], area(np.atleast_3d(a)), 1.0).astype(np.float32)
    # pixel centres: preview (x + 0.5) = k (box x + 0.5)
    to_preview = np.array([[kx, 0.0, 0.5 * kx - 0.5], [0.0, ky, 0.5 * ky - 0.5]]) @ np.vstack([to_box, [0, 0, 1.0]])
    return LiveFace(box=tuple(int(v) for v in box), photo8=(shown * 255.0 + 0.5).astype(np.uint8),
                    shown=inside(arrays.shown), more=np.where(f[..., None], area(np.atleast_3d(arrays.more)), 0.0
                                                             ).astype(np.float32),
                    fill=np.where(f[..., None], area(np.atleast_3d(arrays.fill)), 0.0).astype(np.float32),
                    relative=np.where(f, area(arrays.relative), 0.0).astype(np.float32),
                    paint8=np.round(np.where(f, area(arrays.paint), 0.0) * 255.0).astype(np.uint8),
                    normals16=np.round(n * 32767.0).astype(np.int16), flags=flags.astype(np.uint8),
                    alpha8=np.round(np.where(f, area(arrays.alpha), 0.0) * 255.0).astype(np.uint8),
                    want=want, ambient=float(ambient), photo_light=np.asarray(photo_light, np.float64),
                    depth=np.where(grid_mask, depth, np.nan).astype(np.float32), to_preview=to_preview,
                    encoding=encoding, fade8=np.round(fade * 255.0).astype(np.uint8),
                    reach8=np.round(reach * 255.0).astype(np.uint8), sigma=float(sigma),
                    change_sigma=float(max(change_px * k, 0.5)), held_sigma=float(max(held_px * k, 0.5)),
                    raise_ratio=None if arrays.raise_ratio is None else
                    np.where(f[..., None], area(np.atleast_3d(arrays.raise_ratio)), 1.0).astype(np.float32),
                    raise8=None if arrays.raise_strength is None else
                    np.round(np.where(f, area(arrays.raise_strength), 0.0) * 255.0).astype(np.uint8),
                    shine=None if arrays.shine is None else
                    np.where(f[..., None], area(np.atleast_3d(arrays.shine)), 0.0).astype(np.float32),
                    kept=None if arrays.foreign_lift is None else inside(arrays.foreign_lift),
                    tint=None if arrays.tint is None else inside(arrays.tint))


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


def normalised_blur(values: np.ndarray, weight: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """``(average, support)``: ``values`` (h, w[, C]) averaged over ``weight`` (h, w) by ``gaussian_blur``, and the weight
    around each pixel (the average is meaningless where it is ~0)."""
    w = np.asarray(weight, np.float32)
    v = np.asarray(values, np.float32)
    wv = v * (w[..., None] if v.ndim == 3 else w)
    den = gaussian_blur(w, sigma)
    num = gaussian_blur(wv, sigma)
    safe = np.maximum(den, 1e-9)
    return num / (safe[..., None] if v.ndim == 3 else safe), den


def live_cast(live: LiveFace, light: np.ndarray) -> np.ndarray:
    """(h, w) float32 in [0, 1]: how much of each preview pixel is in ``light``'s cast shadow, traced on
    the fit's height field (its model grid, as the product does) and brought to the preview."""
    al = Alignment(live.to_preview, "live")
    margin = cast_margin(live.depth, al.vector_to_model(light))
    return soft_cast(scalar_to_input(margin, np.isfinite(live.depth), al, live.size))


def live_gain(live: LiveFace, light: np.ndarray, cast: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The face's change of light for ``light`` (3,) on the preview: ``(g (h, w, C), painted (h, w, C), weight (h, w),
    keep (h, w))``, as ``FaceRelight.relit`` makes them (module docstring): keep is how much of the photo's shine the
    light keeps. cast: ``live_cast``, traced when None."""
    s = np.asarray(light, np.float64) / np.linalg.norm(light)
    cast = live_cast(live, s) if cast is None else cast
    face, skin = (live.flags & FACE) > 0, (live.flags & SKIN) > 0
    photo = _linear_photo(live)
    n = live.normals16.astype(np.float32) / np.float32(32767.0)
    lambert = np.clip(n @ s.astype(np.float32), 0.0, None) * face
    a = np.float32(live.ambient)
    unshadowed = a + (np.float32(1.0) - a) * lambert
    direct = (np.float32(1.0) - cast) * lambert
    cast_share = (a + (np.float32(1.0) - a) * direct) / unshadowed
    new = unshadowed[..., None] + live.more
    same = np.float32(shadows_kept(live.photo_light, s))
    keep = shine_kept(brightness(live.shown), brightness(new) * cast_share, shine_lobe(n, live.photo_light, s))
    # the coarse part of the change averaged, the fine part the photo's own (``FaceRelight.relit``)
    log_smooth, _ = normalised_blur(np.log(np.maximum(live.shown, np.float32(1e-4))), face, live.change_sigma)
    smooth = np.where(face[..., None], np.exp(log_smooth), np.float32(1.0))
    log_change, _ = normalised_blur(np.log(np.maximum(new / smooth, np.float32(1e-4))), face, live.change_sigma)
    change = np.exp(log_change) * (smooth / live.shown) * cast_share[..., None]
    if live.raise_ratio is not None:  # the side lit less raised toward its mirror as far as the new light brightens it
        change = change * lifted(live.raise_ratio, live.raise8 / np.float32(255.0), brightness(new) / brightness(live.shown))
    kept = np.float32(1.0) if live.kept is None else live.kept  # the shadows from elsewhere lifted under any light
    g = same * kept + (np.float32(1.0) - same) * change
    g = np.where(face[..., None], g, np.float32(1.0))
    shown_well = usable(live.relative, brightness(g), live.encoding) > 0.9
    gain = np.float32(exposure_gain(live.want, _kept(live, photo, g, keep), skin & (direct >= LIT_SHADING) & shown_well))
    g = gain * g
    lift = brightness(g)
    around, support = normalised_blur(lift, skin, live.held_sigma)
    bound = np.where(support > 0.05, np.float32(HELD_MARGIN) * around, np.float32(np.inf))
    held = np.where(skin, np.float32(1.0), np.minimum(np.float32(1.0), bound / np.maximum(lift, np.float32(1e-6))))
    g = g * held[..., None]
    weight = (np.float32(1.0) - usable(live.relative, brightness(g), live.encoding)) * (live.paint8 / np.float32(255.0))
    painted = gain * live.fill * new * (same + (np.float32(1.0) - same) * cast_share[..., None])
    g = np.where(face[..., None], tinted(g, live.tint), g)  # the light added is the lamp's colour
    return g.astype(np.float32), painted.astype(np.float32), (weight * face).astype(np.float32), keep


def _kept(live: LiveFace, photo: np.ndarray, g: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """(h, w, C) the photo lifted by ``g`` (at most ``MAX_GAIN``), its shine kept as far as ``keep`` (h, w) says
    (``lift.relit_face``)."""
    g = np.minimum(g, np.float32(MAX_GAIN))
    if live.shine is None:
        return photo * g
    sh = np.minimum(live.shine, photo)
    return (photo - sh) * g + sh * keep[..., None]


def _linear_photo(live: LiveFace) -> np.ndarray:
    photo = live.photo8.astype(np.float32) / np.float32(255.0)
    return srgb_to_linear(photo) if live.encoding == "srgb" else photo


def render_live(live: LiveFace, light: np.ndarray, cast: np.ndarray | None = None) -> np.ndarray:
    """(h, w, C) float32 in [0, 1], in the photo's encoding: the preview with its face relit by ``light`` (3,), camera
    frame: the photo times the face's change of light (``live_gain``), painted where it cannot be lifted, faded by
    ``alpha`` into the photo times the face's change of light at its border, which the photo around the face follows
    over the feather (``fade8``). cast: the light's cast shadow (``live_cast``), traced when None."""
    photo = _linear_photo(live)
    g, painted, weight, keep = live_gain(live, light, cast)
    face = (live.flags & FACE) > 0
    relit = _kept(live, photo, g, keep)
    w = weight[..., None]
    face_image = np.clip(relit + w * (painted - relit), 0.0, 1.0)
    # the face's change of light at its border, carried into the photo there (``compose.outside_gain``)
    rim = ((live.flags & RIM) > 0).astype(np.float32)
    support = gaussian_blur(rim, live.sigma)[..., None]
    num = gaussian_blur(face_image * rim[..., None], live.sigma)
    ratio = num / np.maximum(gaussian_blur(photo * rim[..., None], live.sigma), np.maximum(1e-3 * support, 1e-12))
    reach = (live.reach8.astype(np.float32) / np.float32(255.0))[..., None]
    ratio = beyond_ratio(ratio, photo, num / np.maximum(support, 1e-12), reach)
    fade = (live.fade8.astype(np.float32) / np.float32(255.0))[..., None]
    alpha = (live.alpha8.astype(np.float32) / np.float32(255.0))[..., None]
    beyond = ((live.flags & BEYOND) > 0)[..., None]
    around = np.where(face[..., None] | beyond, ratio, 1.0 + fade * (ratio - 1.0)).astype(np.float32)
    out = np.where(face[..., None], alpha * face_image + (1.0 - alpha) * photo * around, photo * around)
    out = np.clip(out, 0.0, 1.0)
    return (linear_to_srgb(out) if live.encoding == "srgb" else out).astype(np.float32)
