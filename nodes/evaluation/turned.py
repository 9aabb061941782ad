"""Turned heads: ICT-FaceKit identities rendered as a photo of a head turned by a yaw and a pitch, with
painted eyes, brows and lips (so the face finder's landmarks find them) and their true normals, and the
score of a run of the whole photo path on them against that truth (docs/accuracy.md, "Turned heads").

A render (``render_turned``): the identity placed on a square grid as the model's training faces are
(its iris centres on the grid's canonical eye pixels), turned (``model.faces.ict.placed``), rendered
nearest surface first with each pixel's point on the frontal face as an attribute; the albedo is a
painting on the frontal face looked up there, Lambertian under the light with cast and attached
shadows, on a grey background, sRGB-encoded as a camera's photo. The face's truth is the visible part
of what the model calls the face: the pixels whose frontal point lies on the frontal model's mask.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage

from ..geometry.integrate import fill_holes
from ..geometry.normals import angle_deg, normals_from_depth
from ..geometry.raster import polygon_mask, rasterize
from ..geometry.reflectance import lambertian
from ..method.shadow import shadow_maps
from ..model.faces.ict import LANDMARKS, IctBasis, placed
from ..model.shape_model import ShapeModel
from ..photo.encoding import linear_to_srgb

SKIN = (0.62, 0.42, 0.32)  # linear RGB albedos
LIPS = (0.45, 0.16, 0.15)
BROWS = (0.05, 0.035, 0.03)
SCLERA = (0.65, 0.62, 0.6)
IRIS = (0.09, 0.06, 0.04)
MOUTH = (0.06, 0.02, 0.02)
BACKGROUND = 0.18
AMBIENT = 0.1  # a share of each albedo lit by the room (shadows are then dark, not black)


@dataclass
class TurnedRender:
    """A photo of a turned head and its truth. photo: (S, S, 3) uint8 sRGB; normals: (S, S, 3) true
    normals, camera frame, NaN off the head; face: (S, S) bool, the visible face (module docstring);
    light: (3,) toward the light; view: (yaw, pitch) degrees."""

    photo: np.ndarray
    normals: np.ndarray
    face: np.ndarray
    light: np.ndarray
    view: tuple[float, float]


def _painting(landmarks: np.ndarray, size: int) -> np.ndarray:
    """(size, size, 3) linear albedo painted on the frontal face placed on a ``size`` grid, from its 68
    landmarks (68, 2) ``(col, row)`` there (NaN: a landmark the source does not have): skin, the eyes (sclera,
    iris and lashes) within the eye-lid landmarks, brows along theirs, lips between the outer and inner lip
    lines."""
    lm = np.asarray(landmarks, np.float64)
    iod = float(np.linalg.norm(lm[45] - lm[36]) / 1.6)
    img = np.empty((size, size, 3), np.float32)
    img[:] = SKIN

    def px(pts: np.ndarray) -> np.ndarray:  # 4 fractional bits; the landmarks a source lacks left out
        pts = np.asarray(pts)
        return np.round(pts[np.all(np.isfinite(pts), axis=1)] * 16).astype(np.int32)

    kw = {"lineType": cv2.LINE_AA, "shift": 4}
    for a, b in ((36, 42), (42, 48)):
        eye = lm[a:b]
        cv2.fillPoly(img, [px(eye)], SCLERA, **kw)
        clip = np.zeros((size, size), np.uint8)
        cv2.fillPoly(clip, [px(eye)], 1, **kw)
        iris = img.copy()
        cv2.circle(iris, tuple(px(eye.mean(axis=0, keepdims=True))[0]), int(0.13 * iod * 16), IRIS, -1, **kw)
        img = np.where(clip[..., None] > 0, iris, img)
        cv2.polylines(img, [px(eye[:4])], False, BROWS, max(1, round(0.03 * iod)), **kw)  # the upper lid's lashes
    for a, b in ((17, 22), (22, 27)):
        cv2.polylines(img, [px(lm[a:b])], False, BROWS, max(2, round(0.09 * iod)), **kw)
    cv2.fillPoly(img, [px(lm[48:60])], LIPS, **kw)
    cv2.fillPoly(img, [px(lm[60:68])], MOUTH, **kw)
    return img


def render_turned(basis: IctBasis, w_identity: np.ndarray, view: tuple[float, float], light: np.ndarray,
                  model: ShapeModel, size: int = 320, pad: int = 80) -> TurnedRender:
    """One ICT identity (weights ``w_identity``) turned by ``view`` (yaw, pitch) degrees under ``light``
    (3,) (``render_turned_mesh``)."""
    verts, eyes = basis.face(w_identity)
    return render_turned_mesh(verts, basis.triangles, eyes, verts[list(LANDMARKS)], view, light, model, size, pad)


def render_turned_mesh(verts: np.ndarray, triangles: np.ndarray, eyes: np.ndarray, landmarks: np.ndarray,
                       view: tuple[float, float], light: np.ndarray, model: ShapeModel, size: int = 320,
                       pad: int = 80) -> TurnedRender:
    """A face mesh (verts (V, 3), any unit, x right, y up, z toward the viewer; triangles (T, 3); its iris
    centres ``eyes`` (2, 3), image-left first; its 68 iBUG landmarks (68, 3), NaN where the mesh has none)
    turned by ``view`` (yaw, pitch) degrees under ``light`` (3,), on a ``size`` grid framed like the model's,
    with ``pad`` pixels of background around it; the visible face is the frontal ``model``'s (module
    docstring)."""
    grid = (size, size)
    frontal = placed(verts, eyes, grid)
    turned = placed(verts, eyes, grid, view)
    depth, at = rasterize(turned, triangles, grid, attributes=frontal[:, :2])
    region = ndimage.binary_fill_holes(np.isfinite(depth))  # the eyes' and mouth's openings: filled smoothly
    depth = fill_holes(depth, region)
    at = np.stack([fill_holes(at[..., c], region) for c in range(2)], axis=-1)
    normals = normals_from_depth(depth)
    shadows = shadow_maps(depth, normals, light)
    shading = lambertian(np.nan_to_num(normals), light) * shadows.lit
    lm = np.where(np.isfinite(landmarks), landmarks, 0.0)
    lm_px = np.where(np.isfinite(landmarks[:, :2]), placed(lm, eyes, grid)[:, :2], np.nan)
    paint = _painting(lm_px, size)
    albedo = cv2.remap(paint, np.nan_to_num(at[..., 0], nan=-1).astype(np.float32),
                       np.nan_to_num(at[..., 1], nan=-1).astype(np.float32), cv2.INTER_LINEAR,
                       borderMode=cv2.BORDER_CONSTANT, borderValue=SKIN)
    head = np.isfinite(depth)
    linear = np.where(head[..., None], albedo * (AMBIENT + (1.0 - AMBIENT) * shading[..., None]), BACKGROUND)
    linear = linear.astype(np.float32)
    photo = np.full((size + 2 * pad, size + 2 * pad, 3), BACKGROUND, np.float32)
    photo[pad:pad + size, pad:pad + size] = linear
    outline = face_outline(lm_px, frontal[:, :2])
    face = visible_face(at, head, model, outline, size)

    def full(a: np.ndarray, fill) -> np.ndarray:
        return np.pad(a, [(pad, pad), (pad, pad)] + [(0, 0)] * (a.ndim - 2), constant_values=fill)

    return TurnedRender(photo=(linear_to_srgb(np.clip(photo, 0, 1)) * 255 + 0.5).astype(np.uint8),
                        normals=full(normals, np.nan), face=full(face, False), light=np.asarray(light, np.float64),
                        view=(float(view[0]), float(view[1])))


def face_outline(landmarks: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(n, 2) the face's own outline from its 68 landmarks ``(col, row)`` (NaN: missing) on the frontal grid:
    the jaw line (0-16), closed over the forehead along the brows (26-17) raised by half the eyes' distance
    (the skin below the hairline). A source without the jaw line (the Surrey model's contour is not fixed
    vertices): the outline of the mesh's ``points`` (P, 2) on the same grid from that forehead line down."""
    lm = np.asarray(landmarks, np.float64)
    iod = float(np.linalg.norm(lm[42:48].mean(axis=0) - lm[36:42].mean(axis=0)))
    brows = lm[26:16:-1] - [0.0, 0.5 * iod]
    if np.all(np.isfinite(lm[0:17])):
        return np.vstack([lm[0:17], brows])
    below = points[points[:, 1] >= np.nanmin(brows[:, 1])]
    return cv2.convexHull(below.astype(np.float32))[:, 0].astype(np.float64)


def visible_face(at: np.ndarray, head: np.ndarray, model: ShapeModel, outline: np.ndarray, size: int) -> np.ndarray:
    """(S, S) bool: the head's pixels whose frontal point (``at`` (S, S, 2) column, row on the ``size``
    grid) lies on the frontal ``model``'s mask and within the face's ``outline`` (``face_outline``, on the
    same frontal grid)."""
    inside = polygon_mask(outline, (size, size))
    k = model.grid[1] / size
    c = np.rint(np.nan_to_num(at[..., 0], nan=-1)).astype(np.int64)
    r = np.rint(np.nan_to_num(at[..., 1], nan=-1)).astype(np.int64)
    ok = head & (c >= 0) & (c < size) & (r >= 0) & (r < size)
    mc = np.clip(np.rint((c + 0.5) * k - 0.5).astype(np.int64), 0, model.grid[1] - 1)
    mr = np.clip(np.rint((r + 0.5) * k - 0.5).astype(np.int64), 0, model.grid[0] - 1)
    out = np.zeros(head.shape, bool)
    out[ok] = model.mask[mr[ok], mc[ok]] & inside[r[ok], c[ok]]
    return out


def score_turned(normals: np.ndarray, truth: np.ndarray, face: np.ndarray) -> dict[str, float]:
    """Mean angular error (degrees) of ``normals`` (S, S, 3, NaN where the fit did not cover) against
    ``truth`` over the covered pixels of ``face`` (S, S) bool, and the share of ``face`` covered."""
    covered = face & np.all(np.isfinite(normals), axis=-1)
    err = angle_deg(np.nan_to_num(normals), np.nan_to_num(truth))
    return {"error": float(np.mean(err[covered])) if covered.any() else float("nan"),
            "coverage": float(np.mean(covered[face])) if face.any() else 0.0}


def score_view(faces: list, view: tuple[float, float], light: np.ndarray, model: ShapeModel) -> tuple:
    """Each face of ``faces`` (``render_turned_mesh``'s first four arguments) rendered at ``view`` (yaw, pitch)
    degrees under ``light`` and run through the photo path: one (error, coverage, read yaw, read pitch, status)
    per face, NaNs and the reason for a face refused."""
    import shadowflow

    rows = []
    for verts, tris, eyes, landmarks in faces:
        r = render_turned_mesh(verts, tris, eyes, landmarks, view, light, model)
        try:
            result = shadowflow.fit(r.photo, light=light)
        except ValueError as exc:
            rows.append((np.nan, 0.0, np.nan, np.nan, str(exc).split(": ", 1)[-1]))
            continue
        s, pose = score_turned(result.normals, r.normals, r.face), result.faces[0]["pose"]
        rows.append((s["error"], s["coverage"], pose["yaw"], pose["pitch"], result.faces[0]["status"]))
    return rows


def _arguments(argv: list[str] | None, doc: str | None):
    """``main``'s arguments, its view choices applied (``--frontal-only``, ``--frontal-pitch``,
    ``--max-view-pitch``: for comparisons with a former reach)."""
    import argparse

    from ..method import turned
    from ..model import default_model as views

    ap = argparse.ArgumentParser(description=doc)
    ap.add_argument("--identities", type=int, default=3)
    ap.add_argument("--frontal-only", action="store_true", help="fit every face with the frontal model")
    ap.add_argument("--surrey", metavar="PATH", help="faces of this eos model (sfm_shape_3448.bin), not ICT's")
    ap.add_argument("--view", metavar="Y,P", action="append", dest="views",
                    help="a true view (yaw, pitch degrees) to render, as --view=-30,20; repeat for more")
    ap.add_argument("--frontal-pitch", type=float, metavar="DEG",
                    help="a face within 7.5 deg of frontal in yaw is fitted at a pitched view from this pitch on")
    ap.add_argument("--max-view-pitch", type=float, metavar="DEG", help="the pitched views' reach")
    ap.add_argument("--lights", default="45", metavar="A,A,...",
                    help="the lights' azimuths in degrees (toward the image's left), each a table's rows; several: "
                         "also the yaw read against the truth, true yaw x light (default 45)")
    args = ap.parse_args(argv)
    if args.frontal_only:
        turned.views_near = lambda yaw, pitch: [(0.0, 0.0)]
    if args.frontal_pitch is not None:
        turned.FRONTAL_PITCH = args.frontal_pitch
    if args.max_view_pitch is not None:
        views.MAX_VIEW_PITCH = args.max_view_pitch
    return args


def main(argv: list[str] | None = None) -> None:
    """``python -m shadowflow.nodes.evaluation.turned [--identities N] [--frontal-only] [--view=Y,P ...]``: the
    tables of docs/accuracy.md, "Turned heads" (normals error and coverage per view, means over the identities)."""
    from ..geometry.reflectance import light_from_angles
    from ..model.default_model import default_model
    from ..model.faces.ict import shipped_basis
    from ..model.sources import eos_samples

    args = _arguments(argv, main.__doc__)
    basis, model = shipped_basis(), default_model()
    if args.surrey:
        faces = eos_samples(args.surrey, args.identities, 1000)
    else:
        rng = np.random.default_rng(1000)  # the model's identities are drawn with seed 0
        faces = []
        for _ in range(args.identities):
            verts, eyes = basis.face(rng.standard_normal(basis.n_identity))
            faces.append((verts, basis.triangles, eyes, verts[list(LANDMARKS)]))
    views = [tuple(int(float(a)) for a in v.split(",")) for v in args.views] if args.views else [
        (0, 0), (-10, 0), (10, 0), (20, 0), (-20, 0), (30, 0), (-30, 0), (0, 10), (0, -10), (50, 0), (-50, 0)]
    azimuths = [int(float(a)) for a in args.lights.split(",")]
    print("| view | light | normals | coverage | read yaw | read pitch | status |\n|---|---|---|---|---|---|---|")
    read = {}
    for view in views:
        for azimuth in azimuths:
            rows = score_view(faces, view, light_from_angles(float(azimuth), 0.0), model)
            read[view, azimuth] = [x[2] for x in rows]
            print(_row(view, azimuth, rows), flush=True)
    if len(azimuths) > 1:
        print(yaw_table(read, azimuths))


def _row(view: tuple[int, int], azimuth: int, rows: list) -> str:
    """One row of ``main``'s table: the means over the faces, each face's read yaw and pitch, the statuses."""
    err = [x[0] for x in rows if np.isfinite(x[0])]
    return (f"| {view[0]:+d}, {view[1]:+d} | {azimuth:+d} | {np.mean(err) if err else float('nan'):.2f} | "
            f"{np.mean([x[1] for x in rows]):.3f} | {', '.join(f'{x[2]:+.0f}' for x in rows)} | "
            f"{', '.join(f'{x[3]:+.0f}' for x in rows)} | {'; '.join(sorted({x[4] for x in rows}))} |")


def yaw_table(read: dict, azimuths: list[int]) -> str:
    """The yaw read against the truth: a row per true view, a column per light's azimuth, each cell the mean read
    over the faces and its difference from the truth (refused faces left out, and counted)."""
    lines = ["| true yaw | " + " | ".join(f"light {a:+d}" for a in azimuths) + " |",
             "|---|" + "---|" * len(azimuths)]
    for view in dict.fromkeys(v for v, _ in read):
        cells = []
        for a in azimuths:
            got = [y for y in read[view, a] if np.isfinite(y)]
            mean = float(np.mean(got)) if got else float("nan")
            refused = len(read[view, a]) - len(got)
            cells.append(f"{mean:+.1f} ({mean - view[0]:+.1f})" + (f", {refused} refused" if refused else ""))
        lines.append(f"| {view[0]:+d}" + (f", {view[1]:+d}" if view[1] else "") + " | " + " | ".join(cells) + " |")
    return "\n".join(lines)


if __name__ == "__main__":
    main()
