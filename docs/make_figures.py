"""Regenerate the README's figures from faces the project renders (ICT-FaceKit identities) and from
scikit-image's public-domain ``astronaut`` (NASA), never from evaluation data:
``python docs/make_figures.py`` (writes docs/astronaut.png, docs/demo.png, docs/portrait.png, and with
Debian's ``chromium`` docs/view.png and docs/report.png; needs scikit-image, in the ``eval`` and ``test``
extras)."""
from __future__ import annotations

import json
import shutil
import subprocess
import tempfile
from pathlib import Path

import cv2
import numpy as np

import shadowflow
from shadowflow.nodes.evaluation.scenes import draw_face, write_shadowed_face
from shadowflow.nodes.geometry.reflectance import light_from_angles
from shadowflow.nodes.photo.encoding import linear_to_srgb

DOCS = Path(__file__).resolve().parent


def _grey8(img: np.ndarray) -> np.ndarray:
    g = np.clip(np.nan_to_num(img), 0, 1)
    if g.ndim == 3:
        g = g[..., ::-1]  # RGB -> BGR
    else:
        g = cv2.cvtColor(g.astype(np.float32), cv2.COLOR_GRAY2BGR)
    return (g * 255 + 0.5).astype(np.uint8)


def _label(img: np.ndarray, text: str) -> np.ndarray:
    """``img`` (BGR uint8) with ``text`` on a dark band along its top."""
    out = img.copy()
    cv2.rectangle(out, (0, 0), (out.shape[1], 26), (0, 0, 0), -1)
    cv2.putText(out, text, (8, 19), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def astronaut_figure(folder: Path) -> np.ndarray:
    """scikit-image's astronaut: the photo with the face the finder found (box, eyes, outline), relit
    frontally, relit from 60 degrees to the image's right and to its left (``--relight``), each a
    crop around her head and shoulders, doubled."""
    from skimage import data

    rgb = np.ascontiguousarray(data.astronaut())
    path = folder / "astronaut.png"
    cv2.imwrite(str(path), rgb[..., ::-1])
    r = shadowflow.fit(path, options=shadowflow.MethodOptions(
        extra_lights=(light_from_angles(-60, 10), light_from_angles(60, 10))))
    relit = [r.relit, *(img for _, img in r.relit_extra)]
    found = rgb[..., ::-1].copy()
    face = r.faces[0]
    x0, y0, x1, y1 = (int(round(v)) for v in face["box"])
    cv2.rectangle(found, (x0, y0), (x1, y1), (80, 220, 80), 1, cv2.LINE_AA)
    for poly in r.frame.data["placement"].outlines["oval"] + r.frame.data["placement"].outlines["eyes"]:
        cv2.polylines(found, [np.round(poly).astype(np.int32)], True, (255, 200, 0), 1, cv2.LINE_AA)
    for x, y in face["eyes"]:
        cv2.drawMarker(found, (int(round(x)), int(round(y))), (0, 0, 255), cv2.MARKER_CROSS, 7, 1, cv2.LINE_AA)
    crop = (slice(24, 280), slice(100, 356))

    def panel(bgr: np.ndarray, text: str) -> np.ndarray:
        return _label(cv2.resize(bgr[crop], None, fx=2, fy=2, interpolation=cv2.INTER_CUBIC), text)

    pose = face["pose"]
    return np.hstack([panel(rgb[..., ::-1], "photo"),
                      panel(found, f"face found (yaw {pose['yaw']:+.0f}, pitch {pose['pitch']:+.0f})"),
                      panel(_grey8(relit[0]), "relit frontally"),
                      panel(_grey8(relit[1]), "relit from the right (-60, 10)"),
                      panel(_grey8(relit[2]), "relit from the left (60, 10)")])


def demo_figure(folder: Path) -> np.ndarray:
    """The three --demo faces: input, shadow map, robust weights, relit frontally, novel view, albedo."""
    rng = np.random.default_rng(2024)  # the --demo inputs' generator
    rows = []
    for az, el in [(45, 0), (-60, 0), (30, 25)]:
        path = write_shadowed_face(folder / f"demo_{az}_{el}.png", rng, light_from_angles(az, el), source="ict")
        r = shadowflow.fit(path)
        weights = np.where(r.mask, np.nan_to_num(r.weights), 0)
        view = cv2.resize(r.novel_view, r.mask.shape[::-1])
        photo = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE) / 255.0
        rows.append(np.hstack([_grey8(x) for x in (photo, ~r.shadow & r.mask, weights, r.relit, view, r.albedo)]))
    return np.vstack(rows)


def portrait_figure(folder: Path) -> np.ndarray:
    """A colour portrait in a larger frame, lit from the side: the photo, relit frontally and put
    back, relit from the other side (``--relight``), and the albedo."""
    face_png = write_shadowed_face(folder / "face.png", np.random.default_rng(8), light_from_angles(50), source="ict")
    grey = cv2.imread(str(face_png), cv2.IMREAD_GRAYSCALE) / 255.0
    h, w = 200, 240
    yy, xx = np.mgrid[0:h, 0:w] / max(h, w)
    frame = np.dstack([0.25 + 0.3 * xx, 0.45 - 0.15 * yy, 0.35 + 0.15 * xx * yy])
    top, left = 40, 56
    region = frame[top:top + 128, left:left + 128]
    _, on, _ = draw_face(np.random.default_rng(8), source="ict")  # the face write_shadowed_face drew, shadows too
    region[on] = (0.06 + 0.94 * grey[on])[:, None] * np.array([1.0, 0.78, 0.62])  # a little ambient, as in a photo
    photo = folder / "portrait.png"
    cv2.imwrite(str(photo), _grey8(linear_to_srgb(frame)))  # saved as a camera would: sRGB-encoded
    side = json.loads(face_png.with_suffix(".json").read_text())
    eyes = (np.array(side["eyes"]) + [left, top]).tolist()
    photo.with_suffix(".json").write_text(json.dumps({"light": side["light"], "eyes": eyes}))
    options = shadowflow.MethodOptions(extra_lights=(light_from_angles(-45),))
    r = shadowflow.fit(photo, options=options)
    other = r.relit_extra[0][1]
    return np.hstack([_grey8(linear_to_srgb(frame)), _grey8(r.relit), _grey8(other),
                      _grey8(np.where(r.mask[..., None], r.albedo, 0))])


def screenshot(url: str, path: Path, size: tuple[int, int]) -> bool:
    """A page in headless Chromium saved as ``path``; False when there is no Chromium."""
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        return False
    subprocess.run([exe, "--headless=new", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                    "--virtual-time-budget=20000", f"--screenshot={path}", f"--window-size={size[0]},{size[1]}", url],
                   check=True, capture_output=True, timeout=120)
    return True


def page_figures(folder: Path) -> list[Path]:
    """The astronaut's ``view.html`` relit live from 40 deg to the left and 15 up, the slider at 40 %
    (docs/view.png), and the report of a run over her, a three-person frame of her and a side-lit
    render (docs/report.png)."""
    from skimage import data

    from shadowflow.nodes.app.cli import main

    inputs = folder / "pages"
    inputs.mkdir()
    rgb = data.astronaut()
    cv2.imwrite(str(inputs / "astronaut.png"), rgb[..., ::-1])
    head = cv2.resize(rgb[40:240, 130:330], None, fx=0.7, fy=0.7, interpolation=cv2.INTER_AREA)
    group = np.full((300, 600, 3), (90, 120, 150), np.uint8)
    for k, x in enumerate((20, 220, 430)):
        small = cv2.resize(head, None, fx=1.0 - 0.1 * k, fy=1.0 - 0.1 * k, interpolation=cv2.INTER_AREA)
        group[40:40 + small.shape[0], x:x + small.shape[1]] = small
    cv2.imwrite(str(inputs / "group.png"), group[..., ::-1])
    write_shadowed_face(inputs / "side-lit.png", np.random.default_rng(7), light_from_angles(50), source="ict")
    out = folder / "out"
    main(["run", str(inputs), "--out", str(out), "--quiet", "--record", "mcap"])
    made = []
    if screenshot((out / "astronaut" / "view.html").as_uri() + "#light=40,15&cut=40", DOCS / "view.png", (1000, 1180)):
        made.append(DOCS / "view.png")
    if screenshot((out / "report.html").as_uri(), DOCS / "report.png", (1000, 1500)):
        made.append(DOCS / "report.png")
    return made


if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as tmp:
        cv2.imwrite(str(DOCS / "astronaut.png"), astronaut_figure(Path(tmp)))
        cv2.imwrite(str(DOCS / "demo.png"), demo_figure(Path(tmp)))
        cv2.imwrite(str(DOCS / "portrait.png"), portrait_figure(Path(tmp)))
        pages = page_figures(Path(tmp))
    print(f"wrote {DOCS / 'astronaut.png'}, {DOCS / 'demo.png'}, {DOCS / 'portrait.png'}",
          *(str(p) for p in pages))
