"""``shadowflow eval people``: what the relighting does to real people, without a reference.

Every photo of a folder (and a few frames of each clip) runs through the photo path relit frontally and
from ``SIDE_LIGHT``; each face found is scored by ``harm`` (H, P: what the frontal relighting did besides
changing the light), whether it was lit evenly, and how far the side light moved the light
(``light_move``). The figures the issue of real people asks for (``summarise``):

- evenly lit faces relit frontally: the median and 95th percentile of H, and how many were written ``ok``
  with H over ``BAD_H``;
- every relit face: how far ``SIDE_LIGHT`` moved its light (median), and how far the frontal relighting moved its
  skin's colour (``colour_shift``'s C: median and 95th percentile, of evenly lit faces and of all);
- how many faces were found, relit, written doubtful, refused.

A contact sheet (``contact_sheet``) shows the worst faces, input beside output.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ...flow.chain import Chain
from ...flow.distributed import local_map
from ...flow.frame import Frame
from ..geometry.reflectance import light_from_angles
from ..method.options import MethodOptions
from ..method.products import photo_channels
from ..model.shape_model import ShapeModel
from ..photo.encoding import linear_to_srgb, srgb_to_linear
from ..relight.harm import colour_shift, harm, light_move
from ..relight.nodes import photo_nodes
from ..relight.products import relit_photos

SIDE_LIGHT = (45, 0)  # azimuth, elevation (degrees; azimuth toward the image's left, as Yale B's)
BAD_H = 12.0  # %: a face this harmed was visibly damaged (a person's verdicts: bad faces 14-48 %)
PHOTO_SUFFIXES = {".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".pgm", ".ppm", ".webp"}
CLIP_SUFFIXES = {".mp4", ".mov", ".avi", ".mkv", ".webm", ".gif"}
THUMB = 144  # a contact sheet's face crops, pixels square


@dataclass
class Item:
    """One input: a file, or a frame of a clip (``samples`` (H, W, 3) uint8 RGB, named ``name``)."""

    name: str
    path: str | None = None
    samples: np.ndarray | None = None


def people_inputs(data: str | Path, clip_frames: int = 3) -> list[Item]:
    """The photos of ``data`` (its ``photos/`` if it has one, else itself) and ``clip_frames`` frames spread over
    each clip of its ``clips/`` (none when 0), in name order."""
    root = Path(data)
    photos = root / "photos" if (root / "photos").is_dir() else root
    items = [Item(p.name, str(p)) for p in sorted(photos.iterdir()) if p.suffix.lower() in PHOTO_SUFFIXES]
    clips = root / "clips"
    if clip_frames > 0 and clips.is_dir():
        for clip in sorted(clips.iterdir()):
            if clip.suffix.lower() in CLIP_SUFFIXES:
                items += clip_items(clip, clip_frames)
    return items


def clip_items(clip: Path, count: int) -> list[Item]:
    """``count`` frames spread evenly over ``clip`` (decoded by OpenCV), each an ``Item`` named
    ``<clip>#f<index>``; none when OpenCV cannot read it."""
    capture = cv2.VideoCapture(str(clip))
    try:
        total = int(capture.get(cv2.CAP_PROP_FRAME_COUNT))
        items = []
        for index in np.linspace(0, max(total - 1, 0), count + 2)[1:-1].round().astype(int):
            capture.set(cv2.CAP_PROP_POS_FRAMES, int(index))
            ok, bgr = capture.read()
            if ok:
                items.append(Item(f"{clip.name}#f{index:04d}", samples=cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)))
        return items
    finally:
        capture.release()


def _linear(frame: Frame, image: np.ndarray) -> np.ndarray:
    """A relit photo (``relit_photos``: the photo's own encoding) in linear light."""
    return srgb_to_linear(image) if frame.meta.get("encoding", "linear") == "srgb" else np.asarray(image, np.float32)


def _thumb(image: np.ndarray, eyes: np.ndarray, srgb: bool) -> np.ndarray:
    """(THUMB, THUMB, 3) uint8 RGB: the face around ``eyes`` (2, 2) in a linear ``image`` (H, W, C), encoded
    for the eye (sRGB), a square 2.8 eye distances wide centred a little below the eyes."""
    e = np.asarray(eyes, np.float64)
    iod = float(np.linalg.norm(e[1] - e[0]))
    centre = e.mean(axis=0) + [0.0, 0.45 * iod]
    half = 1.4 * iod
    scale = THUMB / (2.0 * half)
    m = np.array([[scale, 0.0, THUMB / 2 - scale * centre[0]], [0.0, scale, THUMB / 2 - scale * centre[1]]])
    img = np.atleast_3d(np.asarray(image, np.float32))
    crop = cv2.warpAffine(img, m, (THUMB, THUMB), flags=cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    crop = np.atleast_3d(crop)
    if srgb:
        crop = linear_to_srgb(crop)
    crop = np.clip(crop * 255.0 + 0.5, 0, 255).astype(np.uint8)
    return np.repeat(crop, 3, axis=-1) if crop.shape[-1] == 1 else crop


def _face_rows(item: Item, photo: Frame, before: np.ndarray, relit: list, thumbs: bool) -> list[dict]:
    """One row per face of ``photo`` (its parts)."""
    srgb = photo.meta.get("encoding", "linear") == "srgb"
    rows = []
    for k, face in enumerate(photo.parts or [photo], start=1):
        placement = face.meta.get("placement") or {}
        q = face.meta.get("quality") or {}
        flags = list(q.get("flags", []))
        relit_face = face.ok and "photo_layers" in face.data
        row = {"photo": item.name, "face": k, "relit": relit_face,
               "status": ("doubtful" if flags else "ok") if face.ok else "refused",
               "reason": "; ".join(flags) if face.ok else face.status, "score": q.get("score"),
               "eyes": placement.get("eyes")}
        if relit_face and row["eyes"] is not None:
            eyes = np.asarray(row["eyes"], np.float64)
            front = harm(before, relit[0], eyes)
            row.update(iod=float(np.linalg.norm(eyes[1] - eyes[0])), h=front.h, p=front.p, halves=front.halves,
                       even=front.even, c=colour_shift(before, relit[0], eyes))
            if len(relit) > 1:
                row["move"] = light_move(before, relit[1], eyes)
            if thumbs:
                row["thumbs"] = [_thumb(img, eyes, srgb) for img in [before] + relit]
        rows.append(row)
    return rows


def evaluate_item(shared: tuple[ShapeModel, MethodOptions, bool], item: Item) -> list[dict]:
    """Rows (``_face_rows``) of one input, run through the photo path; one row with the reason when it failed
    as a whole (no face found, unreadable)."""
    model, options, thumbs = shared
    data = {} if item.samples is None else {"samples": item.samples}
    frame = Frame(0, item.path or item.name, data=data)
    photo = Chain(photo_nodes(model, options)).process(frame)
    if not photo.ok and not photo.parts:
        return [{"photo": item.name, "face": 0, "relit": False, "status": "refused", "reason": photo.status}]
    before = np.asarray(photo_channels(photo), np.float32)
    relit = [_linear(photo, image) for _, image in relit_photos(photo)] if photo.ok else []
    if not relit:
        relit = [before]
    return _face_rows(item, photo, before, relit, thumbs)


def evaluate_people(items: list[Item], model: ShapeModel, options: MethodOptions | None = None,
                    mapper=local_map, thumbs: bool = True) -> list[dict]:
    """Every face of every input (``evaluate_item``), relit frontally and from ``SIDE_LIGHT``."""
    base = options or MethodOptions()
    side = light_from_angles(*SIDE_LIGHT)
    opts = dataclasses.replace(base, extra_lights=tuple(base.extra_lights) or (side,))
    rows = []
    for item_rows in mapper(evaluate_item, items, (model, opts, thumbs)):
        rows += item_rows
    return rows


def _percentile(values: list[float], q: float) -> float | None:
    return float(np.percentile(values, q)) if values else None


def _h_figures(rows: list[dict], prefix: str) -> dict:
    """The median, 95th percentile and worst H of ``rows`` (scored faces), and how many written ``ok`` exceed
    ``BAD_H``, as ``<prefix>h_median`` ...."""
    h = [r["h"] for r in rows]
    c = [r["c"] for r in rows if "c" in r]
    return {f"{prefix}h_median": _percentile(h, 50), f"{prefix}h_p95": _percentile(h, 95),
            f"{prefix}h_worst": max(h, default=None), f"{prefix}c_median": _percentile(c, 50),
            f"{prefix}c_p95": _percentile(c, 95),
            f"{prefix}ok_over_bad": len([r for r in rows if r["status"] == "ok" and r["h"] > BAD_H])}


def summarise(rows: list[dict]) -> dict:
    """The figures of a run (module docstring)."""
    scored = [r for r in rows if "h" in r]
    even = [r for r in scored if r["even"]]
    moves = [r["move"] for r in scored if r.get("move") is not None and np.isfinite(r["move"])]
    faces = [r for r in rows if r["face"] > 0]
    statuses = [r["status"] for r in faces]
    return {"faces": len(faces), "relit": len(scored), "doubtful": statuses.count("doubtful"),
            "refused": statuses.count("refused"), "inputs_refused": len(rows) - len(faces), "even": len(even),
            **_h_figures(even, "even_"), **_h_figures(scored, ""), "move_median": _percentile(moves, 50)}


def figure(value, spec: str) -> str:
    """``value`` formatted by ``spec``, or "-" when there is none (a table's cell)."""
    return "-" if value is None else format(value, spec)


def format_table(rows: list[dict]) -> str:
    """Per face: input, face, status, score, even (halves ratio), H, P, the side light's move; then the figures."""
    lines = [f"{'input':44s} {'face':>4s} {'status':9s} {'score':>5s} {'halves':>6s} {'H %':>6s} {'P %':>6s} "
             f"{'C %':>5s} {'move':>6s}  reason"]
    for r in rows:
        lines.append(f"{r['photo'][:44]:44s} {r['face']:4d} {r['status']:9s} {figure(r.get('score'), '5.2f')} "
                     f"{figure(r.get('halves'), '6.2f')} {figure(r.get('h'), '6.1f')} {figure(r.get('p'), '6.1f')} "
                     f"{figure(r.get('c'), '5.1f')} {figure(r.get('move'), '6.2f')}  {r.get('reason', '')[:60]}")
    s = summarise(rows)
    lines += ["", f"faces {s['faces']}: relit {s['relit']}, doubtful {s['doubtful']}, refused {s['refused']} "
              f"(inputs refused whole: {s['inputs_refused']})",
              f"evenly lit (halves within 15 %): {s['even']} faces, H median {figure(s['even_h_median'], '.1f')} %, "
              f"95th percentile {figure(s['even_h_p95'], '.1f')} %, written ok above {BAD_H:g} %: "
              f"{s['even_ok_over_bad']}",
              f"every relit face: H median {figure(s['h_median'], '.1f')} %, 95th percentile "
              f"{figure(s['h_p95'], '.1f')} %, "
              f"worst {figure(s['h_worst'], '.1f')} %, written ok above {BAD_H:g} %: {s['ok_over_bad']}",
              f"colour shift C (white light: the skin's colour kept), median: evenly lit "
              f"{figure(s['even_c_median'], '.1f')} %, every relit face {figure(s['c_median'], '.1f')} %",
              f"light moved by the {SIDE_LIGHT[0]} deg light (left minus right, blurred log ratio): median "
              f"{figure(s['move_median'], '.2f')}"]
    return "\n".join(lines)


def contact_sheet(rows: list[dict], worst: int = 24, columns: int = 2) -> np.ndarray | None:
    """(H, W, 3) uint8 RGB: the ``worst`` faces by H, each as input | relit frontally | relit from the side,
    with its name, status and H; None when no face has thumbnails."""
    faces = sorted((r for r in rows if "thumbs" in r), key=lambda r: -r["h"])[:worst]
    if not faces:
        return None
    label = 18
    cells = []
    for r in faces:
        strip = np.concatenate(r["thumbs"], axis=1)
        head = np.full((label, strip.shape[1], 3), 255, np.uint8)
        text = f"{r['photo'][:28]} {r['face']} {r['status']} H {r['h']:.1f} P {r['p']:.1f}"
        cv2.putText(head, text, (3, 13), cv2.FONT_HERSHEY_SIMPLEX, 0.38, (0, 0, 0), 1, cv2.LINE_AA)
        cells.append(np.concatenate([head, strip], axis=0))
    blank = np.full_like(cells[0], 255)
    cells += [blank] * (-len(cells) % columns)
    grid = [np.concatenate(cells[i:i + columns], axis=1) for i in range(0, len(cells), columns)]
    return np.concatenate(grid, axis=0)


def json_rows(rows: list[dict]) -> list[dict]:
    """The rows without their thumbnails, for a JSON report."""
    return [{k: v for k, v in r.items() if k != "thumbs"} for r in rows]
