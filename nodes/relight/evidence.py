"""The light the photo shows on a face, read off its skin where the fitted shape lets a shadow fall.

Where the fitted shape is lit (out of the ``gate``), the photo's light is the fitted shading with the room's light:
a new light's shading over it changes only what the new light changes, and the fit's own errors cancel. Where the
shape lets a shadow fall (its attached side, its cast shadows, the band around its terminator, all placed roughly:
the ``gate``), the fitted shape says too little, and the light is read off the skin: its brightness over the skin's
expected albedo lit by the fitted shading (``q``).

- The photo's own shadows (``region``): skin darker than ``DARK`` of its fitted light, its gaps closed (the dark
  albedo inside a shadow: a brow, stubble, a nostril) and specks dropped. Their edge is the photo's (``membership``,
  read off ``q`` across the penumbra), and their light is the room's (``shade``: averaged over their skin as it is,
  per colour channel, not against the shape: darker and of another colour than the lit skin).
- Elsewhere in the gate the fitted shading is corrected by the skin (``correction``: ``q`` averaged over the skin
  around each pixel, per colour channel, smooth, so the photo's own detail stays its own: the room brighter or darker
  than measured, the shape turning from the light too soon or too late). The shadows' skin is left out of that
  average, so a sharp cast shadow does not darken the lit skin beside it.

What is not skin (``skin``: the skin is told by its colour, in its shade too, its smoothness, and being off the eyes,
brows, lips, nostrils and hair) takes its light from the skin around it: a beard, stubble, brows, lashes, eye
sockets, nostrils, lips, glasses and moles are dark by their albedo and are not read; in a shadow they take the
shadow's light from the skin beside them as far as they are dark themselves, and are lifted with it. ``membership``
also says how far each pixel is in a shadow for ``shadow.png``.

Shadows the face does not cast (``foreign``: a brim's, a hand's, found by ``foreign.foreign_shadows``) join the
photo's own; their light is read across their edge (``_foreign_shade``) and how far each pixel is in them is their
region blurred by their penumbra (``_half_in``, ``_penumbra``).

Arrays are on the face's box at the photo's resolution (h, w[, C]), linear; lengths in interocular distances.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage

from .fields import blur, brightness, grow, local_average, smoothstep, weighted_blur

# where the fitted shape lets a shadow fall: its own shadows and the pixels it turns from the light under this
# n . s (its terminator's band), grown by this many interocular distances (the fit places them roughly), faded over
# this many
GATE_DIRECT = 0.35
GATE_MARGIN = 0.1
GATE_FADE = 0.05
# the fitted shading is corrected by the skin over this many interocular distances (no finer: a darker patch of
# skin, a freckle, is the skin's own), within this range
CORRECT_SIGMA = 0.05
CORRECT_RANGE = (0.02, 10.0)
# skin in a shadow keeps under this share of its fitted light
DARK = 0.6
# the skin's light is read averaged over this many interocular distances (pores and noise are not a shadow's edge)
DENOISE = 0.015
# a shadow's gaps this wide are closed (the dark albedo inside it: a brow, stubble, a nostril), and shadows
# smaller than a square this wide are dropped (a dark speck: a mole, a nostril)
CLOSE = 0.03
MIN_SIDE = 0.05
# the band around a shadow whose skin is read for its soft edge (and left out of the correction), and over how much
# skin what is not skin takes its membership (a beard beside or inside a shadow)
PENUMBRA = 0.05
ACROSS = 0.06
# what is not skin this many interocular distances from a shadow from elsewhere (an eye in a brim's shade) takes the
# skin's membership around it
FEATURE_REACH = 0.3
# a shadow from elsewhere's share of the light is read over rings this wide either side of its edge, averaged along it
# over this many interocular distances
EDGE_RING = 0.05
EDGE_SIGMA = 0.1
# a pixel of a shadow from elsewhere's region that shows less than this share of the way from the lit light down to
# the shade is lit itself (a gap between leaves, a lid lit between them), where the shade is at most this share of the
# lit light (where the shape turns from the light, its light is no brighter than the shade's and says nothing), in
# gaps at least this many interocular distances a side (a lit pore is the skin's texture)
LIT_ITSELF = 0.25
LIT_ITSELF_TOLD = 0.6
LIT_GAP_SIDE = 0.04
# the widths a shadow from elsewhere's penumbra may have, interocular distances (a brim's edge near the face is sharp,
# leaves' far from it soft)
PENUMBRAS = (0.004, 0.01, 0.02, 0.035, 0.05, 0.075)
# a shadow's light is averaged over this many interocular distances of its skin
DEPTH_SIGMA = 0.08


@dataclass(frozen=True)
class ShadowEvidence:
    """The light a face's box (h, w) shows, read off its skin. skin (h, w) bool: where the photo's light is read;
    gate (h, w) float32 in [0, 1]: where the fitted shape lets a shadow fall (faded at its edge); correction (h, w, C)
    float32: what the fitted shading is off by there out of the shadows, smoothly (1 out of the gate); membership
    (h, w) float32 in [0, 1]: how far each pixel is in the photo's own shadows; shade (h, w, C) float32: the light in
    them; foreign (h, w) float32 in [0, 1]: how far each pixel is in shadows the face does not cast (a brim's, a
    hand's: ``foreign.foreign_shadows``), part of ``membership``."""

    skin: np.ndarray
    gate: np.ndarray
    correction: np.ndarray
    membership: np.ndarray
    shade: np.ndarray
    foreign: np.ndarray

    def corrected(self, lighting: np.ndarray) -> np.ndarray:
        """(h, w, C) float32 the fitted shading with the room's light (``lighting`` (h, w)) as the skin corrects it out
        of the shadows: ``L c``."""
        return (np.asarray(lighting, np.float32)[..., None] * self.correction).astype(np.float32)

    def lighting(self, lighting: np.ndarray) -> np.ndarray:
        """(h, w, C) float32 the light the photo shows: ``(1 - m) L c + m s``, the corrected fitted shading out of the
        shadows, their own light in them."""
        return self._lit(lighting, self.membership)

    def without_foreign(self, lighting: np.ndarray) -> np.ndarray:
        """(h, w, C) float32 the light the photo would show without the shadows the face does not cast (``lighting``
        with ``membership - foreign``)."""
        return self._lit(lighting, self.membership - self.foreign)

    def _lit(self, lighting: np.ndarray, membership: np.ndarray) -> np.ndarray:
        m = np.asarray(membership, np.float32)[..., None]
        return ((np.float32(1.0) - m) * self.corrected(lighting) + m * self.shade).astype(np.float32)

    @property
    def found(self) -> bool:
        return bool((self.membership > 0.5).any())


def shadow_gate(fit_shadow: np.ndarray, direct: np.ndarray, face: np.ndarray, iod_px: float) -> np.ndarray:
    """(h, w) bool: where the fitted shape lets a shadow fall on the face (``face`` (h, w) bool): its own shadows
    (``fit_shadow`` (h, w) bool: cast or attached on the model grid, brought to the photo) and its terminator's band
    (``direct`` (h, w) ``max(n . s, 0)`` under ``GATE_DIRECT``), grown by ``GATE_MARGIN``."""
    return grow(np.asarray(fit_shadow, bool) | (np.asarray(direct) < GATE_DIRECT), GATE_MARGIN * iod_px) & face


def closed(seeds: np.ndarray, radius: float) -> np.ndarray:
    """``seeds`` (h, w) bool closed by a disc of ``radius`` pixels, holes filled."""
    r = max(1, round(radius))
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    padded = np.pad(seeds.astype(np.uint8), r)  # closing at the box's edge: as if the shadow stopped there
    closed = cv2.morphologyEx(padded, cv2.MORPH_CLOSE, disc)[r:-r, r:-r] > 0
    return ndimage.binary_fill_holes(closed)


def without_specks(mask: np.ndarray, min_area: float) -> np.ndarray:
    """``mask`` (h, w) bool without its 8-connected parts of fewer than ``min_area`` pixels."""
    labels, n = ndimage.label(mask, structure=np.ones((3, 3), bool))
    if n == 0:
        return mask
    area = np.bincount(labels.ravel(), minlength=n + 1)
    keep = area >= min_area
    keep[0] = False
    return keep[labels]


def shadow_evidence(photo: np.ndarray, albedo: np.ndarray, lighting: np.ndarray, direct: np.ndarray,
                    skin: np.ndarray, gate: np.ndarray, face: np.ndarray, iod_px: float,
                    foreign: np.ndarray | None = None) -> ShadowEvidence:
    """The light the photo shows (module docstring). photo (h, w, C) linear; albedo (h, w, C): the skin's expected
    albedo (``albedo.expected_albedo``); lighting (h, w): the fitted shading with the room's light (no cast shadows);
    direct (h, w): its ``max(n . s, 0)`` (unused but for the fitted shape's own attached shadow in ``membership``);
    skin (h, w) bool: the pixels whose light is read; gate (h, w) bool (``shadow_gate``); face (h, w) bool; iod_px:
    the face's interocular distance in pixels; foreign (h, w) bool or None: the shadows the face does not cast
    (``foreign.foreign_shadows``), out of the gate: they join the photo's own, their penumbra read as theirs is."""
    img = np.atleast_3d(np.asarray(photo, np.float32))
    rho = np.maximum(np.nan_to_num(np.atleast_3d(np.asarray(albedo, np.float32))), np.float32(1e-4))
    fitted = np.maximum(np.asarray(lighting, np.float32), np.float32(1e-4))[..., None]
    read = np.asarray(skin, bool) & face
    gate = np.asarray(gate, bool)
    fade = (blur(gate.astype(np.float32), GATE_FADE * iod_px) * face).astype(np.float32)
    ones = np.ones_like(img)
    attached = (np.float32(1.0) - smoothstep(direct, 0.0, 0.02)) * face
    none = np.zeros(face.shape, np.float32)
    elsewhere = np.zeros(face.shape, bool) if foreign is None else np.asarray(foreign, bool) & face
    if read.sum() < 20:
        return ShadowEvidence(read, fade, ones, attached.astype(np.float32), fitted * ones, none)
    shown = np.maximum(img, 1e-5) / rho  # the light each pixel shows, were it the skin's
    log_q = np.log(brightness(shown) / fitted[..., 0])
    level, support = weighted_blur(np.where(read, log_q, 0.0), read.astype(np.float32), max(DENOISE * iod_px, 1.0))
    seeds = read & gate & (support > 0.05) & (level < np.log(DARK))
    own = without_specks(closed(seeds, CLOSE * iod_px) & face & gate, (MIN_SIDE * iod_px) ** 2)
    region = own | elsewhere
    clear = read & ~grow(region, PENUMBRA * iod_px)
    # the correction is of the light's level only, the same in every channel: out of the shadows the skin's colour is
    # its albedo's, and a colour read into the light (a skin pinker than the expected albedo) made the change of
    # light tint the relit skin: pink brightened turned grey-green, and back again from frame to frame
    log_c = local_average(np.log(brightness(shown) / fitted[..., 0])[..., None], clear.astype(np.float32),
                          CORRECT_SIGMA * iod_px, np.zeros_like(img[..., :1]))
    log_c = np.broadcast_to(log_c, img.shape)
    correction = np.exp(fade[..., None] * np.clip(log_c, *np.log(CORRECT_RANGE))).astype(np.float32)
    if not region.any():
        return ShadowEvidence(read, fade, correction, attached.astype(np.float32), fitted * ones, none)
    lit = brightness(correction) * fitted[..., 0]  # the light out of the shadows
    # each skin pixel's own light across a penumbra (a 3 x 3 median: a pore is no shadow's edge; averaged wider, the
    # lit skin beside a sharp edge took the shadow's light and shone)
    level = cv2.medianBlur(np.ascontiguousarray(brightness(shown), np.float32), 3)
    # a shadow from elsewhere's penumbra and the dark albedo beside it are read as the photo's own shadows' are
    near = elsewhere
    if elsewhere.any():
        near = grow(elsewhere, (PENUMBRA + ACROSS) * iod_px) | (grow(elsewhere, FEATURE_REACH * iod_px) & ~read & face)
    membership, shade = _in_shadows(shown, img, rho, read, gate | near, region, level, lit, iod_px)
    if elsewhere.any():
        # their edge first, with the light their skin shows on average; then their light read across that edge
        # (twice: the light their skin shows on average is no edge's, and puts the edge off)
        clear_of_own = read & ~grow(own, PENUMBRA * iod_px)  # the lit skin beside them is out of the photo's own
        # the light each face pixel would show with the skin's typical albedo (what is not skin is told lit by it)
        typical = np.float32(np.median(brightness(rho)[read]))
        plain = np.where(face, cv2.medianBlur(np.ascontiguousarray(brightness(img) / typical, np.float32), 3),
                         np.float32(np.nan))
        for _ in range(2):
            half = _half_in(level, read, elsewhere, near, shade, lit, iod_px, plain)
            sigma = _penumbra(half, level, read, lit, brightness(shade), iod_px)
            shade = np.where(near[..., None], _foreign_shade(img, clear_of_own, half, lit, sigma, iod_px), shade)
        half = _half_in(level, read, elsewhere, near, shade, lit, iod_px, plain)
        membership = np.where(near, blur(half.astype(np.float32), sigma), membership)
    theirs = np.where(near & ~(own & ~elsewhere), membership, np.float32(0.0)).astype(np.float32)
    return ShadowEvidence(read, fade, correction, np.maximum(membership, attached).astype(np.float32), shade, theirs)


def _foreign_shade(photo: np.ndarray, read: np.ndarray, region: np.ndarray, lit: np.ndarray, penumbra_px: float,
                   iod_px: float) -> np.ndarray:
    """(h, w, C) float32 the light in the shadows from elsewhere ``region`` (h, w) bool: the share of the ``lit``
    (h, w) light they leave, read off the ``photo`` (h, w, C) across their edge: its skin (``read``) just inside over
    just outside, on rings ``EDGE_RING`` wide beyond their penumbra (``penumbra_px``) either side, averaged along the
    edge over ``EDGE_SIGMA`` and carried inward. There the skin and the shape are the same on both sides, and what
    the fitted shading and albedo get wrong (a forehead brighter than the model's) cancels. A share, not a level:
    the shape's shading goes on in such a shadow as the photo shows it (the room's light, a window's, the sky's,
    comes from a side too), and the lifted skin keeps it."""
    # the photo's own light, not over the expected albedo: that is matched to the lit skin outside and carried in,
    # and a step across the edge is the skin's albedo beside the shadow against the face's elsewhere
    log_share = np.log(np.maximum(photo, 1e-5)) - np.log(np.maximum(lit, 1e-5))[..., None]
    gap = max(1, round(2.0 * penumbra_px))
    ring = max(1, round(EDGE_RING * iod_px))
    inner = ndimage.binary_erosion(region, iterations=gap) & ~ndimage.binary_erosion(region, iterations=gap + ring)
    outer = grow(region, gap + ring) & ~grow(region, gap)
    inner, outer = inner & read, outer & read
    inside = read & region
    if inner.sum() < 5 or outer.sum() < 5:  # too thin to read across: its skin against the lit light
        inner, outer = inside, np.zeros_like(inside)
    if inner.sum() < 5:
        return (lit[..., None] * np.ones_like(photo)).astype(np.float32)
    zero = np.zeros(photo.shape[-1], np.float32)
    typical_in = np.median(log_share[inner], axis=0).astype(np.float32)
    typical_out = np.median(log_share[outer], axis=0).astype(np.float32) if outer.any() else zero
    sigma = EDGE_SIGMA * iod_px
    inside_level = local_average(log_share, inner.astype(np.float32), sigma, np.broadcast_to(typical_in, photo.shape))
    outside_level = local_average(log_share, outer.astype(np.float32), sigma,
                                  np.broadcast_to(typical_out, photo.shape)) if outer.any() else 0.0
    return (lit[..., None] * np.exp(np.minimum(inside_level - outside_level, 0.0))).astype(np.float32)


def _half_in(level: np.ndarray, read: np.ndarray, region: np.ndarray, near: np.ndarray, shade: np.ndarray,
             lit: np.ndarray, iod_px: float, plain: np.ndarray) -> np.ndarray:
    """(h, w) bool the shadows ``region`` (h, w) bool to the middle of their penumbra: within ``near`` (h, w) bool,
    where their skin (``read``) shows less than half-way between the ``lit`` (h, w) light and the ``shade`` (h, w, C)
    (``level`` (h, w) the light its skin shows, 3 x 3 median), gaps closed. What is not skin (an eye, a brow, a
    beard) is in as far as the skin around it is: a shadow covers all alike. But a pixel that shows the lit light
    itself is out, skin or not (``LIT_ITSELF``; what is not skin by ``plain`` (h, w), the light it would show with the
    skin's typical albedo, NaN off the face). Blurred by the penumbra it is how far each pixel is in them, smooth, so
    the skin's own texture (pores, freckles) stays its own and is lifted with it."""
    dark = brightness(shade)
    # how far down from the lit light to the shade each pixel shows: skin by its own light, what is not skin by
    # ``plain`` (its own expected albedo may hold its darkness, a brow's)
    shows = np.clip((lit - np.where(read, level, plain)) / np.maximum(lit - dark, 1e-4), 0.0, 1.0)
    around = local_average(np.where(read, shows, 0.0), read.astype(np.float32), ACROSS * iod_px,
                           region.astype(np.float32))
    half = np.where(read, shows, around) > 0.5
    # lit itself, whatever encloses it: leaves' gaps; a lid lit between them, taken in by the skin around it, was
    # lifted white
    lit_itself = without_specks((shows < LIT_ITSELF) & (dark < LIT_ITSELF_TOLD * lit), (LIT_GAP_SIDE * iod_px) ** 2)
    return (closed(half & near, CLOSE * iod_px) | region) & ~lit_itself


def _penumbra(half: np.ndarray, level: np.ndarray, read: np.ndarray, lit: np.ndarray, dark: np.ndarray,
              iod_px: float) -> float:
    """The Gaussian width in pixels (one of ``PENUMBRAS`` interocular distances) whose blur of the shadows ``half``
    (h, w) bool best explains the skin's light across their edge: the least mean absolute log error between
    ``level`` (h, w) and ``(1 - m) lit + m dark`` over the ``read`` skin near the edge."""
    widths = [w * iod_px for w in PENUMBRAS]
    edge = read & grow(half, 2.0 * widths[-1]) & ~ndimage.binary_erosion(half, iterations=max(1, round(2 * widths[-1])))
    if edge.sum() < 20:
        return widths[0]
    observed = np.log(np.maximum(level[edge], 1e-5))
    errors = []
    for w in widths:
        m = blur(half.astype(np.float32), w)[edge]
        predicted = np.log(np.maximum((1.0 - m) * lit[edge] + m * dark[edge], 1e-5))
        errors.append(float(np.mean(np.abs(observed - predicted))))  # (a median is the flat skin's either side)
    return widths[int(np.argmin(errors))]


def _in_shadows(shown: np.ndarray, img: np.ndarray, rho: np.ndarray, read: np.ndarray, gate: np.ndarray,
                region: np.ndarray, level: np.ndarray, lit: np.ndarray, iod_px: float) -> tuple[np.ndarray, np.ndarray]:
    """``(membership (h, w), shade (h, w, C))`` of the shadows ``region`` (h, w) bool: ``shown`` (h, w, C) the light each
    pixel shows, were it the skin's; ``level`` (h, w) its brightness denoised over the skin ``read`` (h, w) bool;
    ``lit`` (h, w) the light there out of the shadows."""
    inside = read & region
    log_shown = np.log(shown)
    if inside.sum() >= 5:
        typical = np.median(log_shown[inside], axis=0)
    else:  # a shadow whose skin is all edge: its darkest skin says how deep it is
        typical = np.percentile(log_shown[read & grow(region, 2.0)], 10, axis=0)
    # the light in a shadow is the room's, whatever way the surface faces: averaged as it is, not against the shape
    depth = local_average(log_shown, inside.astype(np.float32), DEPTH_SIGMA * iod_px,
                          np.broadcast_to(typical.astype(np.float32), log_shown.shape))
    shade = np.exp(depth).astype(np.float32)
    # the skin across the penumbra: how far it is in, by how much light it shows between the two
    band = grow(region, PENUMBRA * iod_px) & gate
    dark = brightness(shade)
    partial = np.clip((lit - level) / np.maximum(lit - dark, 1e-4), 0.0, 1.0)
    # skin is in as far as its own light says, in the shadow as across its edge (a lit island a closed shadow encloses,
    # the dark albedo the closing took in, is its own)
    on_skin = np.where(region | band, partial, np.float32(0.0)).astype(np.float32)
    # what is not skin takes the membership of the skin around it (a beard in a shadow), as far as it is dark itself:
    # the lit wing of a nose beside the nose's shadow took the shadow's light and shone
    around, support = weighted_blur(np.where(read, on_skin, 0.0), read.astype(np.float32), ACROSS * iod_px)
    own = np.clip((lit - brightness(shown)) / np.maximum(lit - dark, 1e-4), 0.0, 1.0)
    others = np.minimum(np.where(support > 1e-3, around, 0.0), own) * gate
    membership = np.where(read, on_skin, np.where(region, np.minimum(np.float32(1.0), np.maximum(own, 0.5)), others))
    return np.clip(membership, 0.0, 1.0).astype(np.float32), shade
