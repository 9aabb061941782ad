"""Procedural faces: anatomically plausible height fields with population variation.

Each face is a smooth height field built from anatomical parts (skull dome, forehead, brow
ridge, eye sockets and eyeballs, nose dorsum / tip / alae, cheekbones, lips, mentolabial
sulcus, chin, jaw taper). Its proportions are drawn from normal distributions whose means and
standard deviations follow published adult anthropometry (Farkas, "Anthropometry of the Head
and Face", 1994, North American white adults; interpupillary distance from Dodgson, SPIE 5291,
2004), as a 50/50 mix of the male and female tables. Nothing here is fitted to any 3D scan set.

Face coordinates are millimetres: origin midway between the eye centres, X to the image
right, Y up, Z toward the viewer. A face is placed on a pixel grid by the similarity that puts
its eye centres on the grid's canonical eye pixels.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..canonical import canonical_eyes

# (male mean, female mean, standard deviation), millimetres.
ANTHROPOMETRY = {
    "ipd": (64.0, 61.7, 3.6),  # interpupillary distance (Dodgson 2004)
    "face_width": (137.0, 130.0, 5.0),  # zy-zy bizygomatic width
    "jaw_width": (105.0, 94.0, 6.0),  # go-go bigonial width
    "face_height": (121.0, 112.0, 6.0),  # n-gn morphological face height
    "nose_height": (54.8, 50.6, 3.2),  # n-sn
    "nose_width": (34.9, 31.4, 2.1),  # al-al
    "nose_protrusion": (19.5, 19.0, 1.8),  # sn-prn
    "mouth_width": (54.5, 50.2, 3.2),  # ch-ch
    "upper_lip_height": (22.2, 20.1, 2.0),  # sn-sto
    "forehead_height": (61.0, 58.0, 6.0),  # tr-n (only the lower part is in the crop)
}
# Relief of soft-tissue parts: (male mean, female mean, sd), millimetres.
RELIEF = {
    "face_depth": (95.0, 90.0, 6.0),  # dome depth of the face mask's outline to its centre
    "socket_depth": (9.0, 8.0, 1.5),
    "brow_ridge": (4.5, 2.5, 1.0),
    "cheekbone": (4.0, 3.5, 1.0),
    "lip_protrusion": (5.0, 5.5, 1.0),
    "chin_protrusion": (6.0, 4.5, 1.5),
    "nasal_bridge": (6.0, 5.0, 1.3),  # height of the nasion above the sockets' floor line
}


@dataclass(frozen=True)
class FaceParams:
    """Proportions of one face, millimetres (see ``ANTHROPOMETRY`` and ``RELIEF``)."""

    ipd: float
    face_width: float
    jaw_width: float
    face_height: float
    nose_height: float
    nose_width: float
    nose_protrusion: float
    mouth_width: float
    upper_lip_height: float
    forehead_height: float
    face_depth: float
    socket_depth: float
    brow_ridge: float
    cheekbone: float
    lip_protrusion: float
    chin_protrusion: float
    nasal_bridge: float
    nose_tip_round: float  # 0..1, bulbous vs sharp tip
    skin_albedo: float  # base reflectance of skin, 0..1


def sample_face(rng: np.random.Generator) -> FaceParams:
    """Draw one face from the 50/50 male/female anthropometric population."""
    male = rng.random() < 0.5
    # Body size shares variance across measures (r ~ 0.4 in Farkas' tables): a common factor.
    size = rng.standard_normal()
    vals = {}
    for table in (ANTHROPOMETRY, RELIEF):
        for name, (m, f, sd) in table.items():
            z = 0.5 * size + np.sqrt(1 - 0.25) * rng.standard_normal()
            vals[name] = (m if male else f) + sd * z
    vals["nose_tip_round"] = float(np.clip(rng.normal(0.5, 0.18), 0.05, 0.95))
    vals["skin_albedo"] = float(np.clip(rng.normal(0.8, 0.06), 0.55, 0.95))
    return FaceParams(**{k.name: float(vals[k.name]) for k in fields(FaceParams)})


def _g(x: np.ndarray, y: np.ndarray, cx: float, cy: float, sx: float, sy: float) -> np.ndarray:
    return np.exp(-0.5 * (((x - cx) / sx) ** 2 + ((y - cy) / sy) ** 2))


def _smoothstep(a: float, b: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - a) / (b - a), 0.0, 1.0)
    return t * t * (3 - 2 * t)


def face_height_mm(p: FaceParams, X: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Height field (mm) and face mask of face ``p`` at face coordinates ``X, Y`` (mm)."""
    e = p.ipd / 2
    y_nasion = 5.0
    y_chin = y_nasion - p.face_height  # gnathion
    y_sub = y_nasion - p.nose_height  # subnasale
    y_tip = y_sub + 0.18 * p.nose_height  # pronasale sits a little above subnasale
    y_sto = y_sub - p.upper_lip_height  # stomion (mouth line)
    y_top = y_nasion + 0.85 * p.forehead_height

    # Outline: half-width tapers from the cheekbones to the jaw, then rounds off to the chin.
    half_w = 0.5 * p.face_width
    jaw = 0.5 * p.jaw_width
    t = _smoothstep(y_sub + 10.0, y_sto - 20.0, Y)
    a = half_w * (1 - t) + jaw * t
    y_jaw = y_sto - 20.0
    below = np.clip((y_jaw - Y) / max(y_jaw - y_chin, 1e-6), 0.0, 1.0)
    a = a * np.sqrt(np.clip(1.0 - below**2, 0.0, None)) + 0.25 * jaw * below
    a = a * (1 - 0.12 * _smoothstep(y_nasion + 10, y_top, Y))  # temples narrow a little
    rx = X / np.maximum(a, 1e-6)
    mask = (np.abs(rx) < 0.95) & (Y < y_top) & (Y > y_chin)
    # Base surface: a face curves strongly across (cheeks wrap back toward the ears) and only
    # gently from forehead to chin, which recede a little from the cheekbone plane.
    y_mid = 0.5 * (y_top + y_chin)
    half_h = 0.5 * (y_top - y_chin)
    cross = np.sqrt(np.clip(1.0 - np.minimum(rx**2, 1.0), 0.0, None)) ** 0.8
    z = 0.5 * p.face_depth * cross - 10.0 * ((Y - y_mid) / half_h) ** 2
    z -= 6.0 * _smoothstep(y_sto, y_chin, Y) ** 2  # the chin sets back under the lips
    z -= 6.0 * _smoothstep(y_nasion + 25, y_top + 10, Y) ** 2  # the upper forehead slopes back
    # Eye sockets and eyeballs.
    for sx in (-e, e):
        z -= p.socket_depth * _g(X, Y, sx, 0.5, 13.0, 9.0)
        z += 0.45 * p.socket_depth * _g(X, Y, sx, 0.0, 6.5, 5.0)  # eyeball under the lids
        z += p.brow_ridge * _g(X, Y, sx * 0.95, 12.0, 16.0, 4.5)  # brow ridge
        z += p.cheekbone * _g(X, Y, sx * 1.25, -22.0, 13.0, 10.0)  # zygoma
        z -= 1.5 * _g(X, Y, sx * 0.95, y_sto - 2, 9.0, 14.0)  # nasolabial hollow
    z += 0.6 * p.brow_ridge * _g(X, Y, 0.0, 14.0, 12.0, 6.0)  # glabella
    # Nose: dorsum ramps from the nasion to the tip, width grows toward the alae.
    s = np.clip((y_nasion - Y) / max(y_nasion - y_tip, 1e-6), 0.0, None)
    ramp = np.where(s <= 1.0, p.nasal_bridge + (p.nose_protrusion + 2.0 - p.nasal_bridge) * s ** 1.15, 0.0)
    below = Y < y_tip
    drop = np.exp(-0.5 * ((Y - y_tip) / (2.5 + 3.0 * p.nose_tip_round)) ** 2)
    ramp = np.where(below, (p.nose_protrusion + 2.0) * drop, ramp)
    ramp = ramp * _smoothstep(y_nasion + 8, y_nasion - 2, Y)
    width = 4.5 + (0.5 * p.nose_width - 9.0) * np.clip(s, 0, 1) ** 2 * 0.6 + 2.0 * p.nose_tip_round
    z += ramp * np.exp(-0.5 * (X / np.maximum(width, 1e-3)) ** 2)
    for sx in (-1, 1):
        z += 5.0 * _g(X, Y, sx * (0.5 * p.nose_width - 5.0), y_sub + 5.0, 5.0, 4.5)  # alae
    # Lips, philtrum, mouth line, mentolabial sulcus, chin.
    mw = 0.5 * p.mouth_width
    lip_x = np.exp(-0.5 * (X / (0.55 * mw)) ** 4)
    z += p.lip_protrusion * lip_x * _g(X, Y, 0.0, y_sto + 5.0, 100.0, 4.0)
    z += 0.9 * p.lip_protrusion * lip_x * _g(X, Y, 0.0, y_sto - 5.5, 100.0, 4.5)
    z -= 1.5 * lip_x * _g(X, Y, 0.0, y_sto, 100.0, 1.2)
    z -= 1.0 * _g(X, Y, 0.0, y_sub - 7.0, 3.0, 5.0)
    z -= 2.5 * _g(X, Y, 0.0, y_sto - 17.0, 0.45 * mw, 4.0)
    z += p.chin_protrusion * _g(X, Y, 0.0, y_chin + 14.0, 14.0, 9.0)
    return z, mask


def face_albedo(p: FaceParams, X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """Reflectance (0..1) of face ``p``: skin with darker brows, eyes and lips."""
    e = p.ipd / 2
    y_sub = 5.0 - p.nose_height
    y_sto = y_sub - p.upper_lip_height
    alb = np.full(X.shape, p.skin_albedo)
    for sx in (-e, e):
        alb -= 0.45 * _g(X, Y, sx * 1.0, 14.0, 14.0, 2.5)  # brows
        alb -= 0.5 * _g(X, Y, sx, 0.0, 5.5, 2.5)  # iris and lashes
    mw = 0.5 * p.mouth_width
    alb -= 0.25 * np.exp(-0.5 * (X / (0.55 * mw)) ** 4) * _g(X, Y, 0.0, y_sto, 100.0, 6.0)  # lips
    return np.clip(alb, 0.05, 1.0)


def render_face(
    p: FaceParams,
    grid: tuple[int, int] = (128, 128),
    eyes: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Place face ``p`` on a pixel grid with its eye centres on ``eyes`` (default canonical).

    Returns ``(depth (H, W) float32 in pixel units, NaN off the face; mask (H, W) bool;
    albedo (H, W) float32)``.
    """
    h, w = grid
    eyes = canonical_eyes(grid) if eyes is None else np.asarray(eyes, float)
    centre = eyes.mean(axis=0)
    scale = np.linalg.norm(eyes[1] - eyes[0]) / p.ipd  # pixels per millimetre
    cols, rows = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    X = (cols - centre[0]) / scale
    Y = -(rows - centre[1]) / scale
    z_mm, mask = face_height_mm(p, X, Y)
    depth = (z_mm * scale).astype(np.float32)
    depth[~mask] = np.nan
    albedo = face_albedo(p, X, Y).astype(np.float32)
    return depth, mask, albedo
