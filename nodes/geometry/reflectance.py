"""Lambertian reflectance: rendering and the reflectance-cone constraint.

A Lambertian pixel of unit albedo with brightness ``I`` under light ``s`` has a normal on
the cone of axis ``s`` and opening angle ``arccos I`` (Worthington & Hancock).
"""
from __future__ import annotations

import numpy as np

from .normals import normalize


def lambertian(normals: np.ndarray, light: np.ndarray, albedo: np.ndarray | float = 1.0) -> np.ndarray:
    """``albedo * max(n . s, 0)``. normals (..., 3); light (3,) unit; returns (...) float32."""
    shade = np.clip(np.tensordot(normals, np.asarray(light, np.float64), axes=([-1], [0])), 0.0, None)
    return (albedo * shade).astype(np.float32)


def project_to_cone(
    normals: np.ndarray,
    light: np.ndarray,
    intensity: np.ndarray,
    fallback: np.ndarray | None = None,
) -> np.ndarray:
    """Rotate each normal to the closest direction on its reflectance cone.

    normals: (N, 3) unit; light: (3,) unit; intensity: (N,) in [0, 1] (unit albedo).
    The rotation stays in the plane spanned by ``s`` and the normal, so the azimuth about
    ``s`` is kept and the polar angle becomes ``arccos I``. Where a normal is parallel to
    ``s`` its azimuth is undefined and is taken from ``fallback`` (N, 3) (default +z
    projected off ``s``). Returns (N, 3).
    """
    s = np.asarray(light, np.float64)
    cos_a = np.clip(intensity, 0.0, 1.0)
    sin_a = np.sqrt(1.0 - cos_a * cos_a)
    u = normals - (normals @ s)[:, None] * s
    un = np.sqrt(np.einsum("ij,ij->i", u, u))
    bad = un < 1e-9
    if np.any(bad):
        alt = np.broadcast_to(np.array([0.0, 0.0, 1.0]), normals.shape) if fallback is None else fallback
        alt = alt[bad] - (alt[bad] @ s)[:, None] * s
        alt_n = np.linalg.norm(alt, axis=1)
        # s is +z itself: any tangent direction is as good as another
        alt[alt_n < 1e-9] = np.cross(s, [1.0, 0.0, 0.0]) if abs(s[0]) < 0.9 else np.cross(s, [0.0, 1.0, 0.0])
        u[bad] = alt
        un = np.linalg.norm(u, axis=1)
    out = u * (sin_a / un)[:, None]
    out += cos_a[:, None] * s
    return out


def project_to_halfspace(normals: np.ndarray, light: np.ndarray) -> np.ndarray:
    """Closest direction to each normal with ``n . s <= 0`` (attached shadow).

    A normal already facing away from the light is kept; one facing it is rotated onto the
    terminator ``n . s = 0``. normals (N, 3) unit, light (3,) unit. Returns (N, 3).
    """
    s = np.asarray(light, np.float64)
    d = normals @ s
    out = normals.copy()
    lit = d > 0
    if np.any(lit):
        out[lit] = project_to_cone(normals[lit], s, np.zeros(int(lit.sum())))
    return out


def light_from_angles(azimuth_deg: float, elevation_deg: float = 0.0) -> np.ndarray:
    """Light direction for a source ``azimuth_deg`` toward the image's left, elevated upward.

    Uses the Extended Yale B convention of ``conventions.md``:
    ``s = (-sin A cos E, sin E, cos A cos E)``. Returns (3,) float64 unit.
    """
    a, e = np.radians(azimuth_deg), np.radians(elevation_deg)
    return normalize(np.array([-np.sin(a) * np.cos(e), np.sin(e), np.cos(a) * np.cos(e)]))


def light_tag(light: np.ndarray) -> str:
    """A light's name, Yale B style: ``A+030E-10`` (azimuth, elevation in whole degrees; azimuth positive
    toward the image's left, as ``light_from_angles``)."""
    s = np.asarray(light, np.float64) / np.linalg.norm(light)
    el = np.degrees(np.arcsin(np.clip(s[1], -1, 1)))
    az = np.degrees(np.arctan2(-s[0], s[2]))
    return f"A{int(round(az)):+04d}E{int(round(el)):+03d}"


def irradiance_constraint(
    normals: np.ndarray,
    light: np.ndarray,
    intensity: np.ndarray,
    dark: np.ndarray | None = None,
    fallback: np.ndarray | None = None,
) -> np.ndarray:
    """Re-impose Lambert's law on normals: the "rotate back onto the cone" step.

    normals (N, 3) unit; light (3,) unit; intensity (N,) in [0, 1] (unit albedo).
    Pixels flagged ``dark`` (N,) bool are attached shadow: they only need ``n . s <= 0``
    (``project_to_halfspace``) rather than lying on the 90-degree cone. With ``dark=None``
    every pixel goes to its cone, as in the paper. Returns (N, 3).
    """
    out = project_to_cone(normals, light, intensity, fallback)
    if dark is not None and np.any(dark):
        out[dark] = project_to_halfspace(normals[dark], light)
    return out
