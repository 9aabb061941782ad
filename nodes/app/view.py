"""``OUT/<stem>/view.html``: one photo to look at and relight by hand. The photo before and after
(a slider over the two), its faces' boxes and eyes drawn with their status (a doubtful one marked
with its reason), and each face relit live in the browser: drag the light on the sphere and the
page redraws the faces from the light their photo shows, their normals and height field (``relight/live.py``,
whose ``render_live`` the page's script ``view.js`` follows step for step).

One self-contained file: the photo and the faces' arrays are embedded (zlib, base64), the relit
photo is linked beside it; plain JavaScript, no network. ``#light=x,y,z`` (camera frame) or
``#light=A,E`` (azimuth, elevation in degrees, Yale B's convention) opens it relit by that light;
``#cut=P`` puts the slider at P % (0: all relit); ``#dump`` adds each face's drawing as a PNG data
URL to the page (``<pre id=dump>``), and the share of its face its ring is opaque beneath, for tests.
"""
from __future__ import annotations

import base64
import html
import json
import os
import zlib
from pathlib import Path

import cv2
import numpy as np

from ...flow.files import atomic_write_bytes
from ...flow.frame import Frame
from ...flow.replay import printable
from ..method.shadow import SOFT_CAST_REACH
from ..photo.align import FIELD_REACH, Alignment
from ..photo.encoding import linear_to_srgb, swapped_rb
from ..relight import lift
from ..relight.albedo import LIFT_AMPLIFICATION
from ..relight.compose import RATIO_BEYOND, RATIO_OUTSIDE
from ..relight.live import BEYOND, FACE, HELD_MARGIN, RIM, SKIN, LiveFace
from ..relight.nodes import live_face
from ..relight.shine import SHINE_LOBE
from .outputs import VIEW_NAME, face_record

BEFORE_SIDE = 1600  # pixels, the embedded photo's longer side at most


def _packed(a: np.ndarray) -> str:
    """An array's bytes (little-endian, C order), zlib-compressed at level 1, base64: a 1 MP photo's face packs in
    15 ms at level 1 against 24 ms at 6, 2 % larger (753 against 739 kB)."""
    a = np.ascontiguousarray(a)
    return base64.b64encode(zlib.compress(a.astype(a.dtype.newbyteorder("<")).tobytes(), 1)).decode("ascii")


def live_payload(live: LiveFace) -> dict:
    """What the page's script needs of one face (``LiveFace``), JSON-ready."""
    h, w = live.size
    to_model = np.linalg.inv(np.vstack([live.to_preview, [0.0, 0.0, 1.0]]))[:2]
    return {"box": list(live.box), "h": h, "w": w, "c": int(live.shown.shape[-1]), "encoding": live.encoding,
            "want": live.want, "ambient": live.ambient,
            "photo_light": [float(x) for x in live.photo_light], "grid": list(live.depth.shape),
            "rotation": Alignment(live.to_preview, "live").rotation.tolist(), "to_model": to_model.tolist(),
            "sigma": live.sigma, "change_sigma": live.change_sigma, "held_sigma": live.held_sigma,
            "arrays": {name: _packed(getattr(live, name)) for name in
                       ("photo8", "shown", "more", "fill", "relative", "paint8", "normals16", "flags", "alpha8",
                        "depth", "fade8", "reach8", "raise_ratio", "raise8", "shine", "kept", "tint")
                       if getattr(live, name) is not None}}


def _photo_jpeg(frame: Frame) -> tuple[str, tuple[int, int]]:
    """The photo as its file shows it (``rgb8``, or its grey in its encoding), JPEG base64, at most
    ``BEFORE_SIDE`` a side; and the working size (W, H) it stands for."""
    d = frame.data
    if "rgb8" in d:
        img = d["rgb8"]
    else:
        grey = d["image"] if frame.meta.get("encoding") != "srgb" else linear_to_srgb(d["image"])
        img = np.clip(grey * 255.0 + 0.5, 0, 255).astype(np.uint8)
    h, w = img.shape[:2]
    k = min(1.0, BEFORE_SIDE / max(h, w))
    small = img if k == 1.0 else cv2.resize(img, (round(w * k), round(h * k)), interpolation=cv2.INTER_AREA)
    bgr = swapped_rb(small) if small.ndim == 3 else small
    ok, enc = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 90])
    if not ok:
        raise OSError("JPEG encoding failed")
    return base64.b64encode(enc.tobytes()).decode("ascii"), (w, h)


def face_marks(records: list[dict], size: tuple[int, int]) -> str:
    """SVG (in the photo's pixels, ``size`` (W, H)) for each face record: its box, its eyes and its
    number, orange and dashed when it is not ``ok`` (the reason is in the table beside it)."""
    font = 0.03 * max(size)  # user units: the label keeps its size against the picture, whatever the photo's
    out = []
    for k, rec in enumerate(records, 1):
        box, eyes, status = rec.get("box"), rec.get("eyes"), str(rec.get("status", ""))
        if not box:
            continue
        x0, y0, x1, y1 = box
        cls = "good" if status == "ok" else "doubt"
        label = f"{k}" if status == "ok" else f"{k} {'doubtful' if status.startswith('doubtful') else 'failed'}"
        out.append(f'<rect class={cls} x="{x0:.1f}" y="{y0:.1f}" width="{x1 - x0:.1f}" height="{y1 - y0:.1f}"/>')
        for ex, ey in eyes or []:
            out.append(f'<circle class={cls} cx="{ex:.1f}" cy="{ey:.1f}" r="{max(1.5, 0.03 * (x1 - x0)):.1f}"/>')
        ty = y0 - 0.3 * font if y0 >= 1.2 * font else y0 + 1.1 * font  # above the box, or inside it at the top
        out.append(f'<text class={cls} x="{x0:.1f}" y="{ty:.1f}" font-size="{font:.1f}">{html.escape(label)}</text>')
    return "".join(out)


def view_html(frame: Frame, faces: list[tuple[dict, LiveFace | None]], relit_file: str = "relit.png") -> bytes:
    """The page for one photo's ``frame`` (its working image): ``faces`` as ``(face_record, LiveFace
    or None)`` largest first; ``relit_file`` the relit photo beside the page."""
    before, (w, h) = _photo_jpeg(frame)
    crop = " ".join(f"{v:.1f}" for v in faces_crop([rec.get("box") for rec, _ in faces], (w, h)))
    stem = str(frame.meta.get("stem") or "photo")
    payload = [live_payload(live) | {"k": k + 1} for k, (_, live) in enumerate(faces) if live is not None]
    marks = face_marks([rec for rec, _ in faces], (w, h))
    rows = []
    for k, (rec, _) in enumerate(faces):
        pose = rec.get("pose") or {}
        rows.append(f"<tr><td>{k + 1}<td class={'good' if rec.get('status') == 'ok' else 'doubt'}>"
                    f"{html.escape(printable(str(rec.get('status', ''))))}<td>{html.escape(str(rec.get('found', '')))}"
                    f"<td>{_deg(pose.get('yaw'))} / {_deg(pose.get('pitch'))} / {_deg(pose.get('roll'))}"
                    f"<td>{_light_text(rec.get('light'))}<td><a href=\"{html.escape(_face_dir(k + 1))}\">files</a>")
    constants = {"FACE": FACE, "SKIN": SKIN, "RIM": RIM, "BEYOND": BEYOND, "LIT_SHADING": lift.LIT_SHADING,
                 "FIELD_REACH": FIELD_REACH, "RATIO_OUTSIDE": list(RATIO_OUTSIDE), "RATIO_BEYOND": RATIO_BEYOND,
                 "CAST_REACH": SOFT_CAST_REACH, "KEEP_ANGLE": list(lift.KEEP_ANGLE),
                 "ELEVATION_WEIGHT": lift.ELEVATION_WEIGHT, "FILE_NOISE": lift.FILE_NOISE,
                 "NOISE_SHOWN": list(lift.NOISE_SHOWN), "RELATIVE_NOISE": list(lift.RELATIVE_NOISE),
                 "LIFTED": list(lift.LIFTED), "MAX_GAIN": lift.MAX_GAIN, "HELD_MARGIN": HELD_MARGIN,
                 "LIFT_AMPLIFICATION": list(LIFT_AMPLIFICATION), "SHINE_LOBE": SHINE_LOBE}
    page = _PAGE.format(
        title=html.escape(f"{stem} · shadowflow"), stem=html.escape(stem), source=html.escape(printable(frame.source)),
        name=html.escape(printable(os.path.basename(frame.source))),
        w=w, h=h, crop=crop, before=before, relit=html.escape(relit_file), marks=marks, rows="\n".join(rows),
        data=json.dumps({"faces": payload, "constants": constants}).replace("</", "<\\/"), script=_SCRIPT,
        style=SLIDER_STYLE + _STYLE)
    return page.encode("utf-8")


def write_page(frame: Frame, folder: Path) -> str:
    """``folder/VIEW_NAME``: the page of one photo's ``frame``, every face (the failed ones marked) as
    ``summary.json`` records it; returns its path."""
    stem = frame.meta.get("stem")
    faces = [(face_record(frame, p, stem), live_face(p) if p.ok else None) for p in (frame.parts or [frame])]
    path = folder / VIEW_NAME
    atomic_write_bytes(path, view_html(frame, faces))
    return str(path)


class PageNode:
    """Writes the photo's page beside the files ``WriteNode`` wrote (``meta["outputs"]``), after it: the writer
    has checked every file of that folder, this page's included (``outputs.OUTPUT_FILES``), and written them."""

    name = "page"
    thread_safe = True

    def __call__(self, frame: Frame) -> Frame:
        if "outputs" not in frame.meta:  # a clip's frame without files of its own
            return frame
        write_page(frame, Path(frame.meta["outputs"]))
        return frame


def faces_crop(boxes: list, size: tuple[int, int], grow: float = 0.6, most: float = 0.5) -> tuple[float, ...]:
    """``(x0, y0, x1, y1)``: the part of a photo of ``size`` (W, H) to show its faces in: the union of
    their ``boxes`` (``[x0, y0, x1, y1]``, None for a face without one) grown by ``grow`` of its longer
    side each way, within the photo; the whole photo when that is most of it (over ``most`` of its
    area) or no face has a box."""
    w, h = size
    known = np.array([b for b in boxes if b], np.float64).reshape(-1, 4)
    if not len(known):
        return 0.0, 0.0, float(w), float(h)
    x0, y0 = known[:, :2].min(axis=0)
    x1, y1 = known[:, 2:].max(axis=0)
    g = grow * max(x1 - x0, y1 - y0)
    x0, y0, x1, y1 = max(0.0, x0 - g), max(0.0, y0 - g), min(float(w), x1 + g), min(float(h), y1 + g)
    if (x1 - x0) * (y1 - y0) > most * w * h:
        return 0.0, 0.0, float(w), float(h)
    return x0, y0, x1, y1


def _face_dir(k: int) -> str:
    return "." if k <= 1 else f"face-{k}/"


def _deg(x) -> str:
    return "-" if not isinstance(x, (int, float)) else f"{x:.0f}°"


def _light_text(light) -> str:
    """A light (x, y, z) as Yale B's azimuth and elevation."""
    if not isinstance(light, (list, tuple)) or len(light) != 3 or not all(isinstance(v, (int, float)) for v in light):
        return "-"
    x, y, z = light
    return f"A {np.degrees(np.arctan2(-x, z)):.0f}°, E {np.degrees(np.arcsin(np.clip(y, -1, 1))):.0f}°"


# the before/after slider, shared with report.html: the "before" layer is clipped to the slider's share
SLIDER_STYLE = """
.compare { position: relative; width: 100%; max-width: 960px; overflow: hidden; user-select: none; background: #222; }
.compare .stage { position: absolute; }
.compare .stage img, .compare .stage canvas, .compare .stage svg, .compare #layers {
  position: absolute; left: 0; top: 0; width: 100%; height: 100%; }
.compare .stage canvas { position: absolute; }
.compare .before { position: absolute; inset: 0; clip-path: inset(0 calc(100% - var(--cut, 50%)) 0 0); }
.compare .divider { position: absolute; top: 0; bottom: 0; left: var(--cut, 50%); width: 2px; background: #fff;
  box-shadow: 0 0 3px #000; pointer-events: none; }
.compare input[type=range] { position: absolute; left: 0; top: 0; width: 100%; height: 100%; margin: 0;
  opacity: 0; cursor: ew-resize; }
.compare .tag { position: absolute; top: 6px; padding: 1px 6px; font-size: 12px; color: #fff;
  background: rgba(0, 0, 0, .55); border-radius: 3px; pointer-events: none; }
svg rect { fill: none; stroke-width: 2; vector-effect: non-scaling-stroke; }
svg circle { fill: none; stroke-width: 1.5; vector-effect: non-scaling-stroke; }
svg .good { stroke: #3fd46b; } svg .doubt { stroke: #ff9f1a; stroke-dasharray: 6 4; }
svg text { font-family: system-ui, sans-serif; font-weight: bold; stroke: none; }
svg text.good { fill: #3fd46b; } svg text.doubt { fill: #ff9f1a; }
"""

# the slider's behaviour, shared with report.html: every .compare's range input moves its cut
SLIDER_SCRIPT = """
// every .compare shows the part of the photo its data-crop names ("x0 y0 x1 y1" of data-size "W H"): the stages
// are sized so that part fills the box; its range input moves the cut between before and after
function frame(box, crop) {
  const [W, H] = box.dataset.size.split(' ').map(Number);
  const [x0, y0, x1, y1] = crop;
  box.style.aspectRatio = `${x1 - x0} / ${y1 - y0}`;
  for (const stage of box.querySelectorAll('.stage'))
    Object.assign(stage.style, { left: -100 * x0 / (x1 - x0) + '%', top: -100 * y0 / (y1 - y0) + '%',
                                 width: 100 * W / (x1 - x0) + '%', height: 100 * H / (y1 - y0) + '%' });
}
for (const box of document.querySelectorAll('.compare')) {
  frame(box, box.dataset.crop.split(' ').map(Number));
  const range = box.querySelector('input[type=range]');
  const cut = () => box.style.setProperty('--cut', range.value + '%');
  range.addEventListener('input', cut); cut();
}
"""

_STYLE = """
body { font: 14px/1.45 system-ui, sans-serif; margin: 20px; color: #222; }
h1 { font-size: 20px; margin: 0 0 2px; } .meta { color: #666; }
.live { display: flex; gap: 18px; align-items: flex-start; margin: 12px 0; flex-wrap: wrap; }
#sphere { width: 160px; height: 160px; cursor: crosshair; touch-action: none; border-radius: 50%; }
.controls button { margin: 4px 4px 0 0; } #lighttext { font-variant-numeric: tabular-nums; }
table { border-collapse: collapse; margin-top: 8px; } td, th { padding: 3px 8px; text-align: left; }
td.good { color: #1a7f37; } td.doubt { color: #b35900; }
"""

_PAGE = """<!doctype html><html lang=en><head><meta charset=utf-8><title>{title}</title>
<meta name=viewport content="width=device-width, initial-scale=1"><style>{style}</style></head><body>
<h1>{stem}</h1>
<p class=meta title="{source}">{name} · drag the slider to compare; drag on the sphere to move the light.</p>
<div class=compare id=compare data-size="{w} {h}" data-crop="{crop}">
  <div class=stage><img id=after alt="relit" src="{relit}"><div id=layers></div></div>
  <div class=before><div class=stage><img alt="photo" src="data:image/jpeg;base64,{before}"></div></div>
  <div class=stage><svg viewBox="0 0 {w} {h}" preserveAspectRatio="none">{marks}</svg></div>
  <div class=divider></div>
  <span class=tag style="left: 6px">photo</span><span class=tag id=aftertag style="right: 6px">relit (file)</span>
  <input type=range min=0 max=100 value=50 aria-label="before / after">
</div>
<p><button id=zoom>the whole photo</button></p>
<div class=live>
  <canvas id=sphere width=160 height=160></canvas>
  <div class=controls><div id=lighttext>light: as written</div>
    <button id=frontal>frontal</button><button id=own>the photo's light</button><button id=file>as written</button>
    <p class=meta>Live: each face drawn from its normals, albedo and height field with the new light's cast
    shadows; its change of light runs on into the photo around it, as in the relit files.</p></div>
</div>
<table><tr><th>face<th>status<th>found<th>yaw / pitch / roll<th>light (fitted)<th>outputs</tr>
{rows}</table>
<script id=data type=application/json>{data}</script>
<script>{script}</script>
</body></html>
"""

_SCRIPT = SLIDER_SCRIPT + (Path(__file__).resolve().parent / "view.js").read_text(encoding="utf-8")

