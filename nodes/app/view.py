"""``OUT/<stem>/view.html``: one photo to look at and relight by hand. The photo before and after
(a slider over the two), its faces' boxes and eyes drawn with their status (a doubtful one marked
with its reason), and each face relit live in the browser: drag the light on the sphere and the
page redraws the faces from their normals, albedo and height field (``method/live_relight.py``,
whose ``render_live`` this page's script follows step for step).

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

import cv2
import numpy as np

from ...flow.frame import Frame
from ...flow.replay import printable
from ..method.live_relight import BEYOND, CLIPPED_BIT, FACE, RIM, SKIN, LiveFace
from ..method.photo_relight import (
    CLIP_RATIO_FLOOR,
    DETAIL_SHARE,
    LIT_SHADING,
    RATIO_BEYOND,
    RATIO_OUTSIDE,
    SHINE_LOBE,
)
from ..method.shadow import SOFT_CAST_REACH
from ..photo.align import FIELD_REACH, Alignment
from ..photo.encoding import linear_to_srgb, swapped_rb

VIEW_NAME = "view.html"
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
    return {"box": list(live.box), "h": h, "w": w, "c": int(live.albedo16.shape[-1]), "encoding": live.encoding,
            "albedo_scale": live.albedo_scale, "want": live.want, "ambient": live.ambient,
            "photo_light": [float(x) for x in live.photo_light], "grid": list(live.depth.shape),
            "rotation": Alignment(live.to_preview, "live").rotation.tolist(), "to_model": to_model.tolist(),
            "sigma": live.sigma,
            "arrays": {"photo8": _packed(live.photo8), "albedo16": _packed(live.albedo16), "sheen16": _packed(live.sheen16),
                       "normals16": _packed(live.normals16), "flags": _packed(live.flags),
                       "alpha8": _packed(live.alpha8), "depth": _packed(live.depth), "fade8": _packed(live.fade8),
                       "reach8": _packed(live.reach8)}}


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
    constants = {"FACE": FACE, "SKIN": SKIN, "CLIPPED_BIT": CLIPPED_BIT, "RIM": RIM, "LIT_SHADING": LIT_SHADING,
                 "CLIP_RATIO_FLOOR": CLIP_RATIO_FLOOR, "FIELD_REACH": FIELD_REACH, "RATIO_OUTSIDE": list(RATIO_OUTSIDE),
                 "BEYOND": BEYOND, "RATIO_BEYOND": RATIO_BEYOND, "DETAIL_SHARE": DETAIL_SHARE,
                 "CAST_REACH": SOFT_CAST_REACH, "SHINE_LOBE": SHINE_LOBE}
    page = _PAGE.format(
        title=html.escape(f"{stem} · shadowflow"), stem=html.escape(stem), source=html.escape(printable(frame.source)),
        name=html.escape(printable(os.path.basename(frame.source))),
        w=w, h=h, crop=crop, before=before, relit=html.escape(relit_file), marks=marks, rows="\n".join(rows),
        data=json.dumps({"faces": payload, "constants": constants}).replace("</", "<\\/"), script=_SCRIPT,
        style=SLIDER_STYLE + _STYLE)
    return page.encode("utf-8")


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

_SCRIPT = SLIDER_SCRIPT + r"""
const DATA = JSON.parse(document.getElementById('data').textContent);
const K = DATA.constants;
const srgbToLinear = v => v <= 0.04045 ? v / 12.92 : Math.pow((v + 0.055) / 1.055, 2.4);
const linearToSrgb = v => { v = Math.min(Math.max(v, 0), 1);
  return v <= 0.0031308 ? v * 12.92 : 1.055 * Math.pow(v, 1 / 2.4) - 0.055; };

async function unpack(b64, Type) {
  const bytes = Uint8Array.from(atob(b64), c => c.charCodeAt(0));
  const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream('deflate'));
  return new Type(await new Response(stream).arrayBuffer());
}

// cast_margin (nodes/method/shadow.py) on the model grid: how far each pixel's ray toward the light passes under
// the (bilinear) height field, less the bias, within [-reach, reach] (> 0: in the cast shadow); NaN off the surface
function castMargin(z, H, W, s, bias = 0.05, reach = K.CAST_REACH) {
  const out = new Float32Array(H * W).fill(NaN);
  const horiz = Math.hypot(s[0], s[1]);
  let zmin = Infinity, zmax = -Infinity;
  for (const v of z) if (!Number.isNaN(v)) { zmin = Math.min(zmin, v); zmax = Math.max(zmax, v); }
  if (zmax === -Infinity) return out;
  const flat = horiz < 1e-6 ? -reach : (s[2] <= 0 ? reach : null);  // no cast shadow, or all of it
  if (flat !== null) { for (let i = 0; i < H * W; i++) if (!Number.isNaN(z[i])) out[i] = flat; return out; }
  const dc = s[0] / horiz, dr = -s[1] / horiz, rise = s[2] / horiz, low = zmin - 1e6, top = zmax - bias + reach;
  const at = (r, c) => { const v = z[r * W + c]; return Number.isNaN(v) ? low : v; };
  for (let row = 0; row < H; row++) for (let col = 0; col < W; col++) {
    const z0 = z[row * W + col];
    if (Number.isNaN(z0)) continue;
    let best = -Infinity;
    for (let t = 1; ; t++) {
      const ray = z0 + t * rise;
      if (ray >= top) break;
      const r = row + t * dr, c = col + t * dc;
      if (r < 0 || r > H - 1 || c < 0 || c > W - 1) break;
      const r0 = Math.min(Math.floor(r), H - 2 < 0 ? 0 : H - 2), c0 = Math.min(Math.floor(c), W - 2 < 0 ? 0 : W - 2);
      const fr = r - r0, fc = c - c0, r1 = Math.min(r0 + 1, H - 1), c1 = Math.min(c0 + 1, W - 1);
      const zs = (1 - fr) * ((1 - fc) * at(r0, c0) + fc * at(r0, c1)) + fr * ((1 - fc) * at(r1, c0) + fc * at(r1, c1));
      best = Math.max(best, zs - (ray + bias));
      if (best > reach) break;
    }
    out[row * W + col] = Math.min(Math.max(best, -reach), reach);
  }
  return out;
}

// the margin brought to the preview as scalar_to_input does (renormalised bilinear, known where the mask reaches
// FIELD_REACH) and made the share of each preview pixel in shadow there (soft_cast)
function castOnPreview(f, margin) {
  const [Hm, Wm] = f.grid, out = new Float32Array(f.h * f.w), M = f.to_model, reach = K.CAST_REACH;
  const sample = (arr, u, v) => {  // bilinear, zero outside
    const c0 = Math.floor(u), r0 = Math.floor(v), fc = u - c0, fr = v - r0;
    let s = 0;
    for (const [r, c, wt] of [[r0, c0, (1 - fr) * (1 - fc)], [r0, c0 + 1, (1 - fr) * fc],
                              [r0 + 1, c0, fr * (1 - fc)], [r0 + 1, c0 + 1, fr * fc]])
      if (r >= 0 && r < Hm && c >= 0 && c < Wm) s += wt * arr[r * Wm + c];
    return s;
  };
  const mask = new Float32Array(Hm * Wm), val = new Float32Array(Hm * Wm);
  for (let i = 0; i < Hm * Wm; i++) { mask[i] = Number.isNaN(f.depth[i]) ? 0 : 1; val[i] = mask[i] ? margin[i] : 0; }
  for (let y = 0; y < f.h; y++) for (let x = 0; x < f.w; x++) {
    const u = M[0][0] * x + M[0][1] * y + M[0][2], v = M[1][0] * x + M[1][1] * y + M[1][2];
    const wts = sample(mask, u, v);
    if (wts >= K.FIELD_REACH)
      out[y * f.w + x] = Math.min(Math.max(0.5 + 0.5 * (sample(val, u, v) / Math.max(wts, 1e-6)) / reach, 0), 1);
  }
  return out;
}

// render_live (nodes/method/live_relight.py), step for step
function render(f, light) {
  const n = Math.hypot(...light), s = light.map(v => v / n);
  const R = f.rotation;  // vector_to_model: camera y is up, rows go down
  const sx = s[0], sy = -s[1];
  const sm = [sx * R[0][0] + sy * R[1][0], -(sx * R[0][1] + sy * R[1][1]), s[2]];
  const cast = castOnPreview(f, castMargin(f.depth, f.grid[0], f.grid[1], sm));
  const N = f.h * f.w, C = f.c, scale = f.albedo_scale / 65535, a = f.ambient;
  const lighting = new Float32Array(N), unexposed = new Float32Array(N * C), skinLit = [];
  const pl = f.photo_light, old = new Float32Array(N), keep = new Float32Array(N);
  // shine_lobe: the halfway vectors of the photo's light and the new one with the view (+z)
  const half = l => {
    const v = [l[0], l[1], l[2] + 1], m = Math.max(Math.hypot(...v), 1e-9);
    return v.map(x => x / m);
  };
  const h = half(pl), h2 = half(s);
  for (let i = 0; i < N; i++) {
    const nx = f.normals16[3 * i] / 32767, ny = f.normals16[3 * i + 1] / 32767, nz = f.normals16[3 * i + 2] / 32767;
    const face = f.flags[i] & K.FACE;
    const shade = face ? (1 - cast[i]) * Math.max(nx * s[0] + ny * s[1] + nz * s[2], 0) : 0;
    lighting[i] = a + (1 - a) * shade;
    old[i] = a + (1 - a) * Math.max(nx * pl[0] + ny * pl[1] + nz * pl[2], 0);
    // without_sheen: the photo's shine taken out as far as the new light darkens the skin or moves its highlight
    const nh = nx * h[0] + ny * h[1] + nz * h[2], nh2 = Math.max(nx * h2[0] + ny * h2[1] + nz * h2[2], 0);
    const lobe = nh > 1e-3 ? Math.pow(Math.min(nh2 / nh, 1), K.SHINE_LOBE) : 1;
    const drop = Math.min(Math.max(1 - Math.min(lighting[i] / Math.max(old[i], 1e-3), lobe), 0), 1);
    keep[i] = 1 - drop;
    let mean = 0;
    for (let c = 0; c < C; c++) {
      const albedo = Math.max(f.albedo16[C * i + c] * scale - f.sheen16[C * i + c] * scale * drop, 0);
      const u = albedo * lighting[i]; unexposed[C * i + c] = u; mean += u;
    }
    if ((f.flags[i] & K.SKIN) && shade >= K.LIT_SHADING) skinLit.push(mean / C);
  }
  let gain = 1;
  if (f.want !== null && skinLit.length >= 50) {
    skinLit.sort((p, q) => p - q);
    const m = skinLit.length, have = m % 2 ? skinLit[(m - 1) / 2] : 0.5 * (skinLit[m / 2 - 1] + skinLit[m / 2]);
    if (have > 1e-6) gain = f.want / have;
  }
  // the relit face (linear), and the photo (linear)
  const relit = new Float32Array(N * C), photo = new Float32Array(N * C), w = new Float32Array(N);
  const rim = new Float32Array(N);  // where the face's change of light is measured for the photo around it
  for (let i = 0; i < N; i++) {
    // no darker than the clipping proves, less the shine the light takes (clipped_floor): a pixel clipped in
    // any channel is bounded in all, its unclipped channels by their own values
    const over = 1 / Math.max(old[i], K.CLIP_RATIO_FLOOR);
    let bounded = false;
    for (let c = 0; c < C; c++) if (f.flags[i] & (K.CLIPPED_BIT << c)) bounded = true;
    w[i] = f.flags[i] & K.FACE ? 1 : 0;
    rim[i] = f.flags[i] & K.RIM ? 1 : 0;
    for (let c = 0; c < C; c++) {
      let p = f.photo8[C * i + c] / 255;
      if (f.encoding === 'srgb') p = srgbToLinear(p);
      photo[C * i + c] = p;
      let v = gain * unexposed[C * i + c];
      if (bounded) {
        const top = (f.flags[i] & (K.CLIPPED_BIT << c) ? 1 : p) * over;
        const diffuse = Math.min(top, (f.albedo16[C * i + c] - f.sheen16[C * i + c]) * scale);
        v = Math.max(v, gain * lighting[i] * (diffuse + (top - diffuse) * keep[i]));
      }
      relit[C * i + c] = Math.min(Math.max(v, 0), 1);
    }
  }
  // outside_gain: the face's change of light at its border, carried into the photo around it over the feather
  const radius = blurRadius(f.sigma);
  const weighted = (a) => { const out = new Float32Array(N * C);
    for (let i = 0; i < N; i++) for (let c = 0; c < C; c++) out[C * i + c] = a[C * i + c] * rim[i]; return out; };
  if (!f.den) {  // what does not change with the light, once per face
    f.den = gaussianBlur(weighted(photo), f.h, f.w, C, radius);
    f.support = gaussianBlur(rim, f.h, f.w, 1, radius);
  }
  if (f.smooth === undefined) f.smooth = f.reach8.some((v) => v > 0)  // quieted: the photo's smooth part, once
    ? gaussianBlur(photo, f.h, f.w, C, blurRadius(f.sigma * K.DETAIL_SHARE)) : null;
  const num = gaussianBlur(weighted(relit), f.h, f.w, C, radius), den = f.den, support = f.support;
  const [lo, hi] = K.RATIO_OUTSIDE;
  const ring = new ImageData(f.w, f.h), inside = new ImageData(f.w, f.h);
  for (let i = 0; i < N; i++) {
    const face = w[i] > 0, alpha = f.alpha8[i] / 255, fade = f.fade8[i] / 255;
    const beyond = (f.flags[i] & K.BEYOND) > 0, high = hi * Math.pow(K.RATIO_BEYOND / hi, f.reach8[i] / 255);
    for (let c = 0; c < 3; c++) {
      const ch = C === 1 ? 0 : c, j = C * i + ch;
      // beyond_ratio: past RATIO_OUTSIDE (the face's own skin beyond the model) no brighter than the relit rim
      let ratio = Math.min(Math.max(num[j] / Math.max(den[j], Math.max(1e-3 * support[i], 1e-12)), lo), high);
      ratio = Math.min(ratio, Math.max(hi, num[j] / Math.max(support[i], 1e-12) / Math.max(photo[j], 1e-6)));
      let gain = face || beyond ? ratio : 1 + fade * (ratio - 1);
      if (f.smooth && gain > hi) {  // quieted: past RATIO_OUTSIDE the detail is lifted by its top only
        const sm = f.smooth[j];
        gain = Math.max(gain * sm + hi * (photo[j] - sm), 0) / Math.max(photo[j], 1e-4);
      }
      let out = face ? alpha * relit[j] + (1 - alpha) * photo[j] * gain : photo[j] * gain;
      out = Math.min(Math.max(out, 0), 1);
      if (f.encoding === 'srgb') out = linearToSrgb(out);
      ring.data[4 * i + c] = Math.floor(out * 255 + 0.5);
      if (face) inside.data[4 * i + c] = ring.data[4 * i + c];
    }
    // each face's own pixels on top of every face's ring (the product: no feather touches another face); the
    // ring holds the face's pixels too, so where the browser scales the face's canvas and its edge turns half
    // transparent the face shows beneath it, not the photo (a light seam along the border, one pixel wide)
    ring.data[4 * i + 3] = face || beyond || fade > 0 ? 255 : 0;
    inside.data[4 * i + 3] = face ? 255 : 0;
  }
  return [ring, inside];
}

// a face's preview as the page shows it (its photo, its ring, its own pixels), as a PNG data URL
function shown(f, ring, face) {
  const c = document.createElement('canvas'), g = c.getContext('2d'), img = new ImageData(f.w, f.h);
  c.width = f.w; c.height = f.h;
  for (let i = 0; i < f.w * f.h; i++) {
    for (let k = 0; k < 3; k++) img.data[4 * i + k] = f.photo8[f.c * i + (f.c === 1 ? 0 : k)];
    img.data[4 * i + 3] = 255;
  }
  g.putImageData(img, 0, 0);
  g.drawImage(ring, 0, 0);
  g.drawImage(face, 0, 0);
  return c.toDataURL('image/png');
}

// live_relight.gaussian_blur: three passes of a box (blur_radius) along rows, then along columns, zero beyond the
// edges, by running sums
function blurRadius(sigma) { return Math.max(1, Math.round((Math.sqrt(4 * sigma * sigma + 1) - 1) / 2)); }

function gaussianBlur(src, h, w, C, r) {
  let v = Float64Array.from(src);
  const n = 2 * r + 1;
  const pass = (len, count, at) => {  // at(line, i, c) -> index into v
    const out = new Float64Array(v.length);
    for (let line = 0; line < count; line++) for (let c = 0; c < C; c++) {
      let sum = 0;
      for (let i = 0; i <= Math.min(r, len - 1); i++) sum += v[at(line, i, c)];
      for (let i = 0; i < len; i++) {
        out[at(line, i, c)] = sum / n;
        if (i + r + 1 < len) sum += v[at(line, i + r + 1, c)];
        if (i - r >= 0) sum -= v[at(line, i - r, c)];
      }
    }
    v = out;
  };
  for (let k = 0; k < 3; k++) pass(w, h, (y, x, c) => C * (y * w + x) + c);
  for (let k = 0; k < 3; k++) pass(h, w, (x, y, c) => C * (y * w + x) + c);
  return v;
}

const compare = document.getElementById('compare'), layers = document.getElementById('layers');
const after = document.getElementById('after'), afterTag = document.getElementById('aftertag');
const relitSrc = after.src, photoSrc = document.querySelector('.compare .before img').src;
const [W, H] = compare.dataset.size.split(' ').map(Number);
const faces = [];
let light = null, pending = null;

async function prepare() {
  for (const f of DATA.faces) {
    const A = f.arrays;
    Object.assign(f, { photo8: await unpack(A.photo8, Uint8Array), albedo16: await unpack(A.albedo16, Uint16Array),
      sheen16: await unpack(A.sheen16, Uint16Array),
      normals16: await unpack(A.normals16, Int16Array), flags: await unpack(A.flags, Uint8Array),
      alpha8: await unpack(A.alpha8, Uint8Array), depth: await unpack(A.depth, Float32Array),
      fade8: await unpack(A.fade8, Uint8Array), reach8: await unpack(A.reach8, Uint8Array) });
    const make = (part) => {
      const canvas = document.createElement('canvas');
      canvas.width = f.w; canvas.height = f.h; canvas.className = 'layer'; canvas.dataset.face = f.k;
      canvas.dataset.part = part;
      const [y0, y1, x0, x1] = f.box;
      Object.assign(canvas.style, { left: 100 * x0 / W + '%', top: 100 * y0 / H + '%',
        width: 100 * (x1 - x0) / W + '%', height: 100 * (y1 - y0) / H + '%', display: 'none' });
      return canvas;
    };
    faces.push([f, make('ring'), make('face')]);
  }
  // every face's ring below every face's own pixels
  for (const [, ring] of faces) layers.appendChild(ring);
  for (const [, , face] of faces) layers.appendChild(face);
}

function draw() {
  pending = null;
  const live = light !== null;
  after.src = live ? photoSrc : relitSrc;
  afterTag.textContent = live ? 'relit live' : 'relit (file)';
  for (const [f, ring, face] of faces) {
    ring.style.display = face.style.display = live ? 'block' : 'none';
    if (!live) continue;
    const [around, inside] = render(f, light);
    ring.getContext('2d').putImageData(around, 0, 0);
    face.getContext('2d').putImageData(inside, 0, 0);
  }
  const t = document.getElementById('lighttext');
  if (!live) { t.textContent = 'light: as written (relit.png)'; drawSphere([0, 0, 1], false); return; }
  const az = Math.atan2(-light[0], light[2]) * 180 / Math.PI, el = Math.asin(light[1]) * 180 / Math.PI;
  t.textContent = `light: azimuth ${az.toFixed(0)}°, elevation ${el.toFixed(0)}°  (${light.map(v => v.toFixed(2)).join(', ')})`;
  drawSphere(light, true);
}

function setLight(s) {
  light = s === null ? null : (n => s.map(v => v / n))(Math.hypot(...s));
  if (!pending) pending = requestAnimationFrame(draw);
}

function drawSphere(s, marked) {
  const c = document.getElementById('sphere'), g = c.getContext('2d'), r = c.width / 2 - 2;
  const img = g.createImageData(c.width, c.height);
  for (let y = 0; y < c.height; y++) for (let x = 0; x < c.width; x++) {
    const u = (x + 0.5 - c.width / 2) / r, v = -(y + 0.5 - c.height / 2) / r, q = u * u + v * v, i = 4 * (y * c.width + x);
    if (q > 1) { img.data[i + 3] = 0; continue; }
    const shade = Math.max(u * s[0] + v * s[1] + Math.sqrt(1 - q) * s[2], 0);
    const level = Math.round(255 * linearToSrgb(0.12 + 0.88 * shade));
    img.data[i] = img.data[i + 1] = img.data[i + 2] = level; img.data[i + 3] = 255;
  }
  g.putImageData(img, 0, 0);
  if (marked) { g.beginPath(); g.arc(c.width / 2 + s[0] * r, c.height / 2 - s[1] * r, 5, 0, 2 * Math.PI);
    g.fillStyle = '#ff9f1a'; g.fill(); }
}

function fromHash() {
  const m = /light=([-0-9.eE]+(?:,[-0-9.eE]+){1,2})/.exec(location.hash);
  if (!m) return null;
  const v = m[1].split(',').map(Number);
  if (v.length === 3) return v;
  const A = v[0] * Math.PI / 180, E = v[1] * Math.PI / 180;
  return [-Math.sin(A) * Math.cos(E), Math.sin(E), Math.cos(A) * Math.cos(E)];
}

const sphere = document.getElementById('sphere');
function onPointer(e) {
  if (e.type === 'pointerdown') sphere.setPointerCapture(e.pointerId);
  else if (!sphere.hasPointerCapture(e.pointerId)) return;
  const b = sphere.getBoundingClientRect(), r = b.width / 2 - 2;
  let u = (e.clientX - b.left - b.width / 2) / r, v = -(e.clientY - b.top - b.height / 2) / r;
  const q = Math.hypot(u, v);
  if (q > 0.995) { u *= 0.995 / q; v *= 0.995 / q; }
  setLight([u, v, Math.sqrt(Math.max(1 - u * u - v * v, 0))]);
}
sphere.addEventListener('pointerdown', onPointer);
sphere.addEventListener('pointermove', onPointer);
document.getElementById('frontal').onclick = () => setLight([0, 0, 1]);
const zoom = document.getElementById('zoom');
let whole = false;
zoom.onclick = () => { whole = !whole; zoom.textContent = whole ? 'the faces' : 'the whole photo';
  frame(compare, whole ? [0, 0, W, H] : compare.dataset.crop.split(' ').map(Number)); };
document.getElementById('file').onclick = () => setLight(null);
document.getElementById('own').onclick = () => setLight(DATA.faces.length ? DATA.faces[0].photo_light : [0, 0, 1]);

const cutAt = /cut=([0-9.]+)/.exec(location.hash);
if (cutAt) { const range = compare.querySelector('input[type=range]'); range.value = cutAt[1];
  range.dispatchEvent(new Event('input')); }
prepare().then(() => {
  light = fromHash();
  draw();
  if (/dump/.test(location.hash)) {
    const pre = document.createElement('pre');
    pre.id = 'dump';
    // and the share of the face's own pixels its ring is opaque beneath (the browser's scaling of the face's
    // canvas shows what is beneath its edge)
    const beneath = (f, ring) => { const a = ring.getContext('2d').getImageData(0, 0, f.w, f.h).data;
      let n = 0, under = 0;
      for (let i = 0; i < f.w * f.h; i++) if (f.flags[i] & K.FACE) { n++; if (a[4 * i + 3] === 255) under++; }
      return n ? under / n : 0; };
    pre.textContent = JSON.stringify(faces.map(([f, ring, face]) => ({ k: f.k, png: shown(f, ring, face),
                                                                       ring_under_face: beneath(f, ring) })));
    document.body.appendChild(pre);
  }
});
"""
