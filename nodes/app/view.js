// view.html's script: the photo before and after, and each face relit live as the light is dragged.
// Its relighting follows nodes/relight/live.py (render_live, live_gain) step for step; tests/app/test_view.py
// checks the two against each other and against the product's relit files in headless Chromium.
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

// shadow.cast_margin (nodes/method/shadow.py) on the model grid: how far each pixel's ray toward the light passes under
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

const smoothstep = (x, lo, hi) => { const t = Math.min(Math.max((x - lo) / (hi - lo), 0), 1); return t * t * (3 - 2 * t); };

// lift.shadows_kept: how far the photo stays as it is under a light this far from its own (an elevation's degrees
// count ELEVATION_WEIGHT as much as an azimuth's)
function shadowsKept(l, s) {
  const angles = v => { const m = Math.hypot(...v);
    return [Math.atan2(-v[0], v[2]) * 180 / Math.PI, Math.asin(Math.min(Math.max(v[1] / m, -1), 1)) * 180 / Math.PI]; };
  const [az, el] = angles(l), [az2, el2] = angles(s);
  return 1 - smoothstep(Math.hypot(az - az2, K.ELEVATION_WEIGHT * (el - el2)), K.KEEP_ANGLE[0], K.KEEP_ANGLE[1]);
}

// lift.usable: how far a pixel known to `rel` of its light can be lifted by `lift` and still be shown
function usable(rel, lift, encoding) {
  const g = Math.max(lift, 1), raised = encoding === 'srgb' ? Math.pow(g, 1 / 2.4) : g;
  const shown = 1 - smoothstep(K.FILE_NOISE * raised, K.NOISE_SHOWN[0], K.NOISE_SHOWN[1]);
  const known = 1 - smoothstep(rel, K.RELATIVE_NOISE[0], K.RELATIVE_NOISE[1]) * smoothstep(g, K.LIFTED[0], K.LIFTED[1]);
  return shown * known;
}

// live.normalised_blur: values (N x C) averaged over a weight (N) by three boxes; [average, support]
function normalisedBlur(values, weight, h, w, C, r) {
  const wv = new Float32Array(values.length);
  for (let i = 0; i < h * w; i++) for (let c = 0; c < C; c++) wv[C * i + c] = values[C * i + c] * weight[i];
  const num = gaussianBlur(wv, h, w, C, r), den = gaussianBlur(weight, h, w, 1, r);
  const avg = new Float32Array(values.length);
  for (let i = 0; i < h * w; i++) for (let c = 0; c < C; c++) avg[C * i + c] = num[C * i + c] / Math.max(den[i], 1e-9);
  return [avg, den];
}

function median(values) {
  values.sort((p, q) => p - q);
  const m = values.length;
  return m % 2 ? values[(m - 1) / 2] : 0.5 * (values[m / 2 - 1] + values[m / 2]);
}

// shine.shine_kept with shine.shine_lobe: how much of the photo's shine the new light keeps at a pixel
function halfway(l) { const v = [l[0], l[1], l[2] + 1], m = Math.max(Math.hypot(...v), 1e-9); return v.map(x => x / m); }
function shineKept(nx, ny, nz, h, h2, old, neu) {
  const nh = nx * h[0] + ny * h[1] + nz * h[2], nh2 = Math.max(nx * h2[0] + ny * h2[1] + nz * h2[2], 0);
  const lobe = nh > 1e-3 ? Math.pow(Math.min(nh2 / Math.max(nh, 1e-3), 1), K.SHINE_LOBE) : 1;
  return Math.min(Math.max(Math.min(neu / Math.max(old, 1e-3), lobe), 0), 1);
}

// live._kept: the photo lifted by g (at most MAX_GAIN), its shine kept as far as keep says
function kept(f, j, i, g, keep) {
  const p = f.linear[j], gj = Math.min(g[j], K.MAX_GAIN);
  if (!f.shine) return p * gj;
  const sh = Math.min(f.shine[j], p);
  return (p - sh) * gj + sh * keep[i];
}

// live.live_gain (nodes/relight/live.py), step for step: the face's change of light, what is painted, and how far
function liveGain(f, s, cast) {
  const N = f.h * f.w, C = f.c, a = f.ambient, photo = f.linear, keep = new Float32Array(N);
  if (!f.smooth) {  // the light the photo shows, its coarse part (the change's fine part is the photo's own), once
    const faceMask = new Float32Array(N), logShown = new Float32Array(N * C);
    for (let i = 0; i < N; i++) {
      faceMask[i] = f.flags[i] & K.FACE ? 1 : 0;
      for (let c = 0; c < C; c++) logShown[C * i + c] = Math.log(Math.max(f.shown[C * i + c], 1e-4));
    }
    const [avg] = normalisedBlur(logShown, faceMask, f.h, f.w, C, blurRadius(f.change_sigma));
    f.smooth = new Float32Array(N * C);
    for (let i = 0; i < N; i++) for (let c = 0; c < C; c++) f.smooth[C * i + c] = faceMask[i] ? Math.exp(avg[C * i + c]) : 1;
  }
  const h = halfway(f.photo_light), h2 = halfway(s);
  const face = new Float32Array(N), skin = new Float32Array(N), direct = new Float32Array(N);
  const castShare = new Float32Array(N), neu = new Float32Array(N * C), logChange = new Float32Array(N * C);
  for (let i = 0; i < N; i++) {
    face[i] = f.flags[i] & K.FACE ? 1 : 0;
    skin[i] = f.flags[i] & K.SKIN ? 1 : 0;
    const nx = f.normals16[3 * i] / 32767, ny = f.normals16[3 * i + 1] / 32767, nz = f.normals16[3 * i + 2] / 32767;
    const lambert = face[i] * Math.max(nx * s[0] + ny * s[1] + nz * s[2], 0);
    const unshadowed = a + (1 - a) * lambert;
    direct[i] = (1 - cast[i]) * lambert;
    castShare[i] = (a + (1 - a) * direct[i]) / unshadowed;
    let bn = 0, bs = 0;
    for (let c = 0; c < C; c++) {
      neu[C * i + c] = unshadowed + f.more[C * i + c];
      logChange[C * i + c] = Math.log(Math.max(neu[C * i + c] / f.smooth[C * i + c], 1e-4));
      bn += neu[C * i + c]; bs += f.shown[C * i + c];
    }
    keep[i] = shineKept(nx, ny, nz, h, h2, bs / C, bn / C * castShare[i]);
  }
  const same = shadowsKept(f.photo_light, s);
  const [avg] = normalisedBlur(logChange, face, f.h, f.w, C, blurRadius(f.change_sigma));
  const g = new Float32Array(N * C), lit = [];
  for (let i = 0; i < N; i++) {
    let mean = 0, k = 0, lift0 = 0;
    if (f.raise_ratio) {  // albedo.lifted: the side lit less raised toward its mirror as the new light brightens it
      let a = 0, b = 0;
      for (let c = 0; c < C; c++) { a += neu[C * i + c]; b += f.shown[C * i + c]; }
      k = f.raise8[i] / 255 * smoothstep(a / b, K.LIFT_AMPLIFICATION[0], K.LIFT_AMPLIFICATION[1]);
    }
    for (let c = 0; c < C; c++) {
      const j = C * i + c, raise = k ? Math.pow(f.raise_ratio[j], k) : 1;
      // the shadows from elsewhere (f.kept) lifted under any light, the photo's own too
      g[j] = face[i] ? same * (f.kept ? f.kept[j] : 1)
        + (1 - same) * Math.exp(avg[j]) * (f.smooth[j] / f.shown[j]) * castShare[i] * raise : 1;
      mean += kept(f, j, i, g, keep);
      lift0 += g[j] / C;
    }
    // the exposure is met on skin the new light lights and the photo shows well enough to lift
    if (skin[i] && direct[i] >= K.LIT_SHADING && usable(f.relative[i], lift0, f.encoding) > 0.9) lit.push(mean / C);
  }
  let gain = 1;
  if (f.want !== null && lit.length >= 50) { const have = median(lit); if (have > 1e-6) gain = f.want / have; }
  const lift = new Float32Array(N);
  for (let i = 0; i < N; i++) {
    let m = 0;
    for (let c = 0; c < C; c++) { g[C * i + c] *= gain; m += g[C * i + c]; }
    lift[i] = m / C;
  }
  // lift.held_to_skin: what is not skin lifted at most HELD_MARGIN x the skin around it
  const [around, support] = normalisedBlur(lift, skin, f.h, f.w, 1, blurRadius(f.held_sigma));
  const painted = new Float32Array(N * C), weight = new Float32Array(N);
  for (let i = 0; i < N; i++) {
    if (!skin[i] && support[i] > 0.05) {
      const held = Math.min(1, K.HELD_MARGIN * around[i] / Math.max(lift[i], 1e-6));
      let m = 0;
      for (let c = 0; c < C; c++) { g[C * i + c] *= held; m += g[C * i + c]; }
      lift[i] = m / C;
    }
    weight[i] = face[i] * (1 - usable(f.relative[i], lift[i], f.encoding)) * f.paint8[i] / 255;
    for (let c = 0; c < C; c++) {
      const j = C * i + c;
      painted[j] = gain * f.fill[j] * neu[j] * (same + (1 - same) * castShare[i]);
      // light_colour.tinted: the light added is the lamp's colour
      if (f.tint && face[i] && g[j] > 1) g[j] = 1 + (g[j] - 1) * f.tint[j];
    }
  }
  return [g, painted, weight, keep];
}

// live.render_live (nodes/relight/live.py), step for step
function render(f, light) {
  const n = Math.hypot(...light), s = light.map(v => v / n);
  const R = f.rotation;  // vector_to_model: camera y is up, rows go down
  const sx = s[0], sy = -s[1];
  const sm = [sx * R[0][0] + sy * R[1][0], -(sx * R[0][1] + sy * R[1][1]), s[2]];
  const cast = castOnPreview(f, castMargin(f.depth, f.grid[0], f.grid[1], sm));
  const N = f.h * f.w, C = f.c, photo = f.linear;
  const [g, painted, weight, keep] = liveGain(f, s, cast);
  const relit = new Float32Array(N * C), rim = new Float32Array(N);
  for (let i = 0; i < N; i++) {
    rim[i] = f.flags[i] & K.RIM ? 1 : 0;
    for (let c = 0; c < C; c++) {
      const j = C * i + c, lifted = kept(f, j, i, g, keep);
      relit[j] = Math.min(Math.max(lifted + weight[i] * (painted[j] - lifted), 0), 1);
    }
  }
  // compose.outside_gain: the face's change of light at its border, carried into the photo around it over the feather
  const radius = blurRadius(f.sigma);
  const weighted = (a) => { const out = new Float32Array(N * C);
    for (let i = 0; i < N; i++) for (let c = 0; c < C; c++) out[C * i + c] = a[C * i + c] * rim[i]; return out; };
  if (!f.den) {  // what does not change with the light, once per face
    f.den = gaussianBlur(weighted(photo), f.h, f.w, C, radius);
    f.support = gaussianBlur(rim, f.h, f.w, 1, radius);
  }
  const num = gaussianBlur(weighted(relit), f.h, f.w, C, radius), den = f.den, support = f.support;
  const [lo, hi] = K.RATIO_OUTSIDE;
  const ring = new ImageData(f.w, f.h), inside = new ImageData(f.w, f.h);
  for (let i = 0; i < N; i++) {
    const face = (f.flags[i] & K.FACE) > 0, alpha = f.alpha8[i] / 255, fade = f.fade8[i] / 255;
    const beyond = (f.flags[i] & K.BEYOND) > 0, high = hi * Math.pow(K.RATIO_BEYOND / hi, f.reach8[i] / 255);
    for (let c = 0; c < 3; c++) {
      const ch = C === 1 ? 0 : c, j = C * i + ch;
      // beyond_ratio: past RATIO_OUTSIDE (the face's own skin beyond the model) no brighter than the relit rim
      let ratio = Math.min(Math.max(num[j] / Math.max(den[j], Math.max(1e-3 * support[i], 1e-12)), lo), high);
      ratio = Math.min(ratio, Math.max(hi, num[j] / Math.max(support[i], 1e-12) / Math.max(photo[j], 1e-6)));
      const gain = face || beyond ? ratio : 1 + fade * (ratio - 1);
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

// live.gaussian_blur: three passes of a box (blur_radius) along rows, then along columns, zero beyond the
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
    Object.assign(f, { photo8: await unpack(A.photo8, Uint8Array), shown: await unpack(A.shown, Float32Array),
      more: await unpack(A.more, Float32Array), fill: await unpack(A.fill, Float32Array),
      relative: await unpack(A.relative, Float32Array), paint8: await unpack(A.paint8, Uint8Array),
      normals16: await unpack(A.normals16, Int16Array), flags: await unpack(A.flags, Uint8Array),
      alpha8: await unpack(A.alpha8, Uint8Array), depth: await unpack(A.depth, Float32Array),
      fade8: await unpack(A.fade8, Uint8Array), reach8: await unpack(A.reach8, Uint8Array),
      raise_ratio: A.raise_ratio ? await unpack(A.raise_ratio, Float32Array) : null,
      raise8: A.raise8 ? await unpack(A.raise8, Uint8Array) : null,
      shine: A.shine ? await unpack(A.shine, Float32Array) : null,
      kept: A.kept ? await unpack(A.kept, Float32Array) : null,
      tint: A.tint ? await unpack(A.tint, Float32Array) : null });
    f.linear = Float32Array.from(f.photo8, v => f.encoding === 'srgb' ? srgbToLinear(v / 255) : v / 255);
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
