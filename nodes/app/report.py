"""``OUT/report.html``: a run at a glance. The frames that failed with their reasons; for each
photo (the first ``LARGE_PHOTOS``) its faces before and after, large, under a slider, their boxes
and eyes drawn and a doubtful face marked with its reason, with a link to its ``view.html`` (relit
live); a contact sheet of every frame (its input, weights, shadow map, relighting, novel view and
albedo); and the fit's convergence plot.

One HTML file with relative links to the frames' PNGs under ``OUT/<stem>/``; the pictures that
are not PNG outputs (the input, the weights, the before/after crops) and the plot are embedded,
so the report opens from the folder with nothing else to serve it. Everything taken from a file
name or a record is HTML-escaped.
"""
from __future__ import annotations

import base64
import html
import io
import itertools
import json
import os
import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import quote

import cv2
import numpy as np

from ...flow.files import atomic_write_chunks
from ...flow.frame import Frame
from ...flow.recording import RecordingError
from ..method.products import photo_8bit
from ..photo.encoding import swapped_rb
from ..photo.input_error import InputError
from ..photo.loader import read_photo
from .counts import photo_status, tally, tally_text
from .channels import CONVERGENCE, CONVERGENCE_LABELS, CONVERGENCE_MARKS, CONVERGENCE_PLOTS
from .record import frame_name
from .outputs import VIEW_NAME, bgr
from .view import SLIDER_SCRIPT, SLIDER_STYLE, face_marks, faces_crop

REPORT_NAME = "report.html"
THUMB = 128  # pixels, the longer side of a picture in the contact sheet
LARGE_PHOTOS = 60  # photos shown large (before/after) at the top; every frame has its row in the sheet below
LARGE_SIDE = 640  # pixels, the longer side of a large before/after
PLOT_FRAMES = 200  # convergence curves drawn at most (the first ones of the run)
LINKED = (("shadow", "shadow.png"), ("relit", "relit.png"), ("novel view", "novel_view.png"),
          ("albedo", "albedo.png"))


def write_report(out: Path, records: Iterable[dict], recording: Path | None = None, title: str = "shadowflow run",
                 series: list[tuple[str, dict]] | None = None, cards: dict[str, CardPictures] | None = None) -> Path:
    """Write ``out/report.html`` for the run whose summary records are ``records`` (input order; read
    twice, so a list or a re-iterable view such as ``RunStore.records``).
    The convergence plot draws ``series`` (``(frame name, {iteration: scalars})`` per frame, as the
    run kept them, ``ScalarsTap``) when given, else reads ``recording`` (the run's MCAP, a file or
    the folder); neither, or unreadable: the report says so. ``cards``: stem -> the card's pictures the
    run made (``card_pictures``); a photo without them is read back from its input and relit file.
    Returns the report's path."""
    cards = cards or {}
    n_ok = 0
    failed = []  # (input, step, reason) of each frame without outputs
    odd = set()  # the file names of doubtful frames: drawn in colour in a crowded convergence plot
    for r in records:
        if _written(out, r):
            n_ok += 1
            if _frame_status(r) == "doubtful":  # as its row says: any face doubtful, not the largest only
                odd.add(_file_name(r.get("source")))
        else:
            failed.append((r.get("source"), r.get("failed_in", ""), r.get("status")))
    if series is None and recording is not None:
        series = _recorded_series(recording)
    plot = _convergence_png(series, odd) if series else None
    parts = [_HEAD.format(title=html.escape(title)),
             f"<h1>{html.escape(title)}</h1>",
             # counted as the terminal counts them (``counts.tally``): doubtful photos and faces have their outputs
             f"<p class=meta>{tally_text(tally(records))}; doubtful ones are written, look before trusting them. "
             f"Written {time.strftime('%Y-%m-%d %H:%M')}; <a href=summary.json>summary.json</a>.</p>"]
    parts.append("<h2>Convergence</h2>")
    if plot:
        parts.append(f'<img class=plot alt="convergence of the fit" src="data:image/png;base64,{plot}">')
    else:
        parts.append("<p class=meta>No recording to plot (run with <code>--record mcap</code>).</p>")
    if failed:
        parts.append(f"<h2>Failed ({len(failed)})</h2><table class=failed><tr><th>input<th>step<th>reason</tr>")
        parts += [f"<tr><td title=\"{_text(source)}\">{_text(_file_name(source))}<td>{_text(step)}"
                  f"<td>{_text(_reason(source, status))}" for source, step, status in failed]
        parts.append("</table>")
    head = "\n".join(parts)
    # the sheet scrolls within its own box: wider than a laptop's window, it gave the whole page a scrollbar
    sheet = (f"<h2>Every frame ({n_ok})</h2><div class=wide><table class=sheet><tr><th>frame<th>input<th>weights"
             + "".join(f"<th>{name}" for name, _ in LINKED) + "</tr>")

    def page():  # card by card and row by row: 2,000 frames' embedded pictures are tens of MB
        yield head.encode()
        shown = 0
        thumbs: dict[str, np.ndarray | None] = {}  # the inputs the cards read, for their rows (read once)
        for r in records:  # read again, a card at a time
            if shown < LARGE_PHOTOS and _written(out, r):
                if shown == 0:
                    yield (f"\n<h2>Photos{f' (the first {LARGE_PHOTOS})' if n_ok > LARGE_PHOTOS else ''}</h2>"
                           "<p class=meta>Drag across a picture to compare the photo (left) with it relit "
                           "(right); <i>relight live</i> opens the photo to move the light yourself.</p>").encode()
                shown += 1
                yield ("\n" + _card(out, r, thumbs, cards.get(r["stem"]))).encode()
        yield ("\n" + sheet).encode()
        for r in records:  # and again, a row at a time
            if _written(out, r):
                yield ("\n" + _row(out, r, thumbs.pop(r["stem"], None))).encode()
        yield f"\n</table></div><script>{SLIDER_SCRIPT}</script></body></html>\n".encode()

    return atomic_write_chunks(out / REPORT_NAME, page())


def _written(out: Path, record: dict) -> bool:
    """The frame's outputs exist (ok or doubtful): it gets a row of pictures."""
    stem = record.get("stem")
    return isinstance(stem, str) and bool(stem) and (out / stem / "relit.png").is_file()


def _frame_status(r: dict) -> str:
    """"ok" when every face of a frame's record that counts is ok (``counts.photo_status``), else "doubtful"."""
    return "ok" if photo_status(r) == "ok" else "doubtful"


def _row(out: Path, r: dict, thumb: np.ndarray | None = None) -> str:
    """A frame's row of the contact sheet; ``thumb``: its input's thumbnail when its card made it."""
    stem = r["stem"]
    q = r.get("quality") or {}
    flags = q.get("flags") or []
    status = _frame_status(r)
    light = r.get("light")
    facts = [f"<b>{html.escape(stem)}</b>", f"<span class={status}>{status}</span>",
             f"quality {_num(q.get('score'))}", f"{_num(r.get('iterations'))} iterations"
             + ("" if r.get("converged") else " (not converged)"),
             f"σ {_num(r.get('final_sigma'), 4)}",
             "light " + (", ".join(_num(x, 2) for x in light) if isinstance(light, list) else "-")
             + f" ({_text(r.get('light_source', ''))})"]
    facts += [f"<span class=flag>{_text(f)}</span>" for f in flags]
    cells = [f"<td class=facts>{'<br>'.join(facts)}",
             f"<td>{_embedded(thumb if thumb is not None else _input_thumb(r.get('source')), 'input')}",
             f"<td>{_embedded(_weights_thumb(out / stem / 'weights.npy'), 'weights')}"]
    for name, file in LINKED:
        rel = quote(f"{stem}/{file}")
        cells.append(f'<td><a href="{rel}"><img loading=lazy alt="{name}" src="{rel}" width={THUMB}></a>')
    return "<tr>" + "".join(cells) + "</tr>"


def _input_thumb(source) -> np.ndarray | None:
    """The input as its file shows it (colour or grey, BGR), at most THUMB pixels a side (a large JPEG
    is decoded reduced)."""
    shown = _shown(source, 4 * THUMB * THUMB)
    return None if shown is None else _fit(shown)


def _shown(source, max_pixels: int | None) -> np.ndarray | None:
    """The input ``source`` as its file shows it: uint8 BGR for colour, grey otherwise (in its own
    encoding), reduced to ``max_pixels``; None when it cannot be read (any more)."""
    if not isinstance(source, str):
        return None
    try:
        photo = read_photo(source, max_pixels=max_pixels)
    except (InputError, OSError, ValueError):
        return None
    values = swapped_rb(photo.colour) if photo.colour is not None else photo.grey  # read as linear: the file's values
    return np.ascontiguousarray(np.clip(values * 255 + 0.5, 0, 255).astype(np.uint8))


@dataclass(frozen=True)
class CardPictures:
    """A photo's pictures on its card: ``crop`` (c0, r0, c1, r1) the part of the photo around its faces,
    ``before`` and ``after`` that part of the photo and of its relit file (base64 JPEGs, at most LARGE_SIDE
    a side), ``thumb`` the photo at most THUMB a side (BGR or grey uint8), for its contact-sheet row."""

    crop: tuple[int, int, int, int]
    before: str
    after: str
    thumb: np.ndarray


def card_pictures(before: np.ndarray, after: np.ndarray, boxes: list) -> CardPictures:
    """``CardPictures`` of a photo (``before``, as its file shows it: uint8 BGR or grey) and its relit file
    (``after``, the same), ``boxes`` its faces' ``[x0, y0, x1, y1]`` (photo pixels; None for a face without
    one). A run makes them while it holds both (``CardNode``), so the report reads neither back."""
    before, after = _alike(before, after)
    h, w = after.shape[:2]
    x0, y0, x1, y1 = faces_crop(boxes, (w, h))
    c0, r0, c1, r1 = int(x0), int(y0), int(np.ceil(x1)), int(np.ceil(y1))
    k = min(1.0, LARGE_SIDE / max(c1 - c0, r1 - r0))

    def crop(img: np.ndarray) -> str:
        part = img[r0:r1, c0:c1]
        if k < 1.0:
            part = cv2.resize(part, (max(1, round((c1 - c0) * k)), max(1, round((r1 - r0) * k))),
                              interpolation=cv2.INTER_AREA)
        ok, enc = cv2.imencode(".jpg", part, [cv2.IMWRITE_JPEG_QUALITY, 90])
        return base64.b64encode(enc.tobytes()).decode() if ok else ""

    return CardPictures((c0, r0, c1, r1), crop(before), crop(after), _fit(before))


class CardNode:
    """The report's pictures of a run's first ``LARGE_PHOTOS`` photos that came through, made while the run holds
    each photo (``card_pictures`` of the photo as its file shows it and of it relit, as ``relit.png`` holds it), in
    ``frame.meta["card"]`` for the run to hand to ``write_report``; later photos' cards are read back from their
    files by the report, if at all."""

    name = "card"
    thread_safe = True

    def __init__(self, limit: int = LARGE_PHOTOS):
        self.left = itertools.count(limit, -1)

    def __call__(self, frame: Frame) -> Frame:
        relit = frame.data.get("relit_8bit")  # as the writer composed it for relit.png (a clip's frame: none)
        if relit is not None and next(self.left) > 0:
            boxes = [(p.meta.get("placement") or {}).get("box") for p in (frame.parts or [frame])]
            frame.meta["card"] = card_pictures(bgr(photo_8bit(frame)), bgr(relit), boxes)
        return frame


def _card(out: Path, r: dict, thumbs: dict | None = None, pictures: CardPictures | None = None) -> str:
    """A photo large: its faces before and after under a slider (the part of the photo around its
    faces, at most LARGE_SIDE a side), the faces' boxes and eyes, a line per face, and its links.
    ``pictures``: made by the run (``card_pictures``), else made here from the input and its relit file.
    ``thumbs``: the input's contact-sheet thumbnail is put there under its stem (the input is read once)."""
    stem = r["stem"]
    folder = out / stem
    faces = r.get("faces") or []
    if pictures is None:
        after = cv2.imread(str(folder / "relit.png"), cv2.IMREAD_UNCHANGED)
        # the photo read at the size the run worked at (a 33 MP JPEG decoded reduced, as the run read it)
        before = _shown(r.get("source"), None if after is None else after.shape[0] * after.shape[1])
        if after is not None and before is not None:
            pictures = card_pictures(before, after, [f.get("box") for f in faces])
    if thumbs is not None and pictures is not None:
        thumbs[stem] = pictures.thumb
    lines = [_face_line(k, f) for k, f in enumerate(faces, 1)]
    links = (f'<a href="{quote(f"{stem}/{VIEW_NAME}")}">relight live</a> · '
             f'<a href="{quote(f"{stem}/relit.png")}">relit.png</a> · <a href="{quote(stem)}/">files</a>')
    head = (f"<div class=card><h3>{html.escape(stem)}</h3><p class=meta title=\"{_text(r.get('source'))}\">"
            f"{_text(_file_name(r.get('source')))} · {links}</p><ul class=faces>{''.join(lines)}</ul>")
    if pictures is None:
        return head + "<p class=meta>(the photo or its relit file cannot be read)</p></div>"
    c0, r0, c1, r1 = pictures.crop
    cw, ch = c1 - c0, r1 - r0
    # the crops fill the stage: its size is the crop's, the marks shifted into it
    shifted = [dict(f, box=[f["box"][0] - c0, f["box"][1] - r0, f["box"][2] - c0, f["box"][3] - r0] if f.get("box")
                    else None, eyes=[[x - c0, y - r0] for x, y in f.get("eyes") or []]) for f in faces]
    return head + (
        f'<div class=compare data-size="{cw} {ch}" data-crop="0 0 {cw} {ch}">'
        f'<div class=stage><img alt="relit" src="data:image/jpeg;base64,{pictures.after}"></div>'
        f'<div class=before><div class=stage><img alt="photo" src="data:image/jpeg;base64,{pictures.before}"></div></div>'
        f'<div class=stage><svg viewBox="0 0 {cw} {ch}" preserveAspectRatio="none">{face_marks(shifted, (cw, ch))}'
        f'</svg></div><div class=divider></div><span class=tag style="left: 6px">photo</span>'
        f'<span class=tag style="right: 6px">relit</span>'
        f'<input type=range min=0 max=100 value=50 aria-label="before / after"></div></div>')


def _face_line(k: int, f: dict) -> str:
    """A face's line on its photo's card: its status, how it was found, how far it is turned and tilted, the view
    of the model it was fitted with when not the frontal one, and, when they were looked for, the shadows from
    elsewhere it lifted."""
    status = str(f.get("status", ""))
    cls = "ok" if status == "ok" else "doubtful"
    pose = f.get("pose") or {}
    turn = "".join(f", {word} {round(pose[key]):+d}°" for word, key in (("turned", "yaw"), ("tilted", "pitch"))
                   if isinstance(pose.get(key), (int, float)) and np.isfinite(pose[key]))
    view = f.get("model_view") or {}
    if isinstance(view.get("yaw"), (int, float)) and isinstance(view.get("pitch"), (int, float)):
        turn += f"; fitted with heads at {round(view['yaw']):+d}°, {round(view['pitch']):+d}°"  # "+0", never "-0"
    foreign = f.get("foreign_shadows")
    lifted = ""
    if isinstance(foreign, dict) and isinstance(foreign.get("count"), int):  # looked for (--foreign-shadows)
        share = foreign.get("area") if isinstance(foreign.get("area"), (int, float)) else 0.0
        lifted = (f"<br><span class=meta>shadows from elsewhere: {foreign['count']}, over {100 * share:.0f} % of "
                  "the face, lifted</span>" if foreign["count"] else
                  "<br><span class=meta>shadows from elsewhere: none found</span>")
    return (f"<li><span class={cls}>face {k}: {_text(status)}</span> <span class=meta>"
            f"({_text(f.get('found', ''))}{turn})</span>{lifted}")


def _alike(before: np.ndarray, after: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The photo and its relit file at one size (the photo is read whole, the run may have reduced it) and
    both grey or both colour."""
    h, w = after.shape[:2]
    if before.shape[:2] != (h, w):  # read reduced, as the run did
        before = cv2.resize(before, (w, h), interpolation=cv2.INTER_AREA)
    if before.ndim != after.ndim:  # a grey photo relit in grey, or colour: show both alike
        before = cv2.cvtColor(before, cv2.COLOR_GRAY2BGR) if before.ndim == 2 else before
        after = cv2.cvtColor(after, cv2.COLOR_GRAY2BGR) if after.ndim == 2 else after
    return before, after


def _file_name(source) -> str:
    return os.path.basename(source) if isinstance(source, str) else str(source)


def _reason(source, status) -> str:
    """A failed frame's status without its file's path in front (the table names the file)."""
    status = str(status)
    prefix = f"{source}: "
    return status[len(prefix):] if isinstance(source, str) and status.startswith(prefix) else status


def _weights_thumb(path: Path) -> np.ndarray | None:
    """The fit's weights (1 trusted .. 0 ignored) in a colour map, black off the face."""
    try:
        w = np.load(path, allow_pickle=False)
    except (OSError, ValueError):
        return None
    if w.ndim != 2 or not w.size:
        return None
    # shrunk before it is coloured: values averaged over the face only (NaN off it), black where mostly off it
    on = np.isfinite(w).astype(np.float32)
    k = THUMB / max(w.shape)
    size = (max(1, round(w.shape[1] * k)), max(1, round(w.shape[0] * k)))
    share = cv2.resize(on, size, interpolation=cv2.INTER_AREA)
    total = cv2.resize(np.where(on > 0, w, 0).astype(np.float32), size, interpolation=cv2.INTER_AREA)
    mean = total / np.maximum(share, 1e-6)
    img = cv2.applyColorMap(np.clip(mean * 255 + 0.5, 0, 255).astype(np.uint8), cv2.COLORMAP_VIRIDIS)
    img[share < 0.5] = 0
    return img


def _fit(img: np.ndarray) -> np.ndarray:
    h, w = img.shape[:2]
    k = THUMB / max(h, w)
    return cv2.resize(img, (max(1, round(w * k)), max(1, round(h * k))), interpolation=cv2.INTER_AREA)


def _embedded(img: np.ndarray | None, alt: str) -> str:
    """A picture inside the page, as a JPEG (a 128-pixel one is 3-5 kB: 2,000 frames make a 16 MB page)."""
    if img is None:
        return "<span class=meta>-</span>"
    ok, enc = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 88])
    return f'<img alt="{alt}" src="data:image/jpeg;base64,{base64.b64encode(enc.tobytes()).decode()}">' if ok else "-"


def _recorded_series(recording: Path) -> list[tuple[str, dict]] | None:
    """The convergence scalars of PLOT_FRAMES frames of a recording (the first of each part in
    turn), in frame id order; None if unreadable. The parts are read one after another, not
    merged: merging a job's parts by frame id reads every part whole first (86 s for the workers'
    parts of a 2,000-frame Dask run), and a plot needs only some frames."""
    from ...flow.recording import FrameStream
    from ...flow.replay import open_frames

    found: dict[int, tuple[str, dict]] = {}
    try:
        for part in open_frames(recording, arrays=False).parts:
            for fr in FrameStream(part, arrays=False):
                if len(found) >= PLOT_FRAMES:
                    break
                if fr.scalars.get(CONVERGENCE) and fr.frame not in found:
                    found[fr.frame] = (frame_name(fr), fr.scalars[CONVERGENCE])
    except RecordingError:
        return None
    return [found[f] for f in sorted(found)]


def _convergence_png(series: list[tuple[str, dict]], highlight: set[str]) -> str:
    """The convergence plot of ``series`` (at most PLOT_FRAMES of them; those named in ``highlight``
    in colour when there are many; the albedo's round marked, ``CONVERGENCE_MARKS``), base64 PNG."""
    from ...flow.replay import convergence_figure

    buf = io.BytesIO()
    convergence_figure(series[:PLOT_FRAMES], CONVERGENCE_PLOTS, CONVERGENCE_LABELS,
                       highlight=highlight, marks=CONVERGENCE_MARKS).savefig(buf, format="png")
    return base64.b64encode(buf.getvalue()).decode()


def _num(x, digits: int = 3) -> str:
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not np.isfinite(x):
        return "-"
    return str(x) if isinstance(x, int) else f"{x:.{digits}g}"


def _text(x) -> str:
    """``x`` as HTML text; bytes of a file name that were not UTF-8 show as U+FFFD."""
    from ...flow.replay import printable

    return html.escape(printable(x if isinstance(x, str) else json.dumps(x, default=str)))


_HEAD = """<!doctype html><html lang=en><head><meta charset=utf-8><title>{title}</title>
<style>""" + SLIDER_STYLE.replace("{", "{{").replace("}", "}}") + """
body {{ font: 14px/1.4 system-ui, sans-serif; margin: 24px; color: #222; }}
h1 {{ font-size: 22px; margin: 0 0 4px; }} h2 {{ font-size: 17px; margin: 24px 0 8px; }}
.meta {{ color: #666; }} .plot {{ max-width: 100%; }} .wide {{ overflow-x: auto; max-width: 100%; }}
table {{ border-collapse: collapse; }} td, th {{ padding: 4px 6px; vertical-align: top; text-align: left; }}
.sheet tr:nth-child(even) {{ background: #f4f4f4; }} .sheet img {{ display: block; image-rendering: pixelated; }}
.facts {{ min-width: 210px; font-size: 13px; }} .ok {{ color: #1a7f37; }} .doubtful {{ color: #b35900; }}
.flag {{ color: #b35900; font-size: 12px; }} .failed td {{ border-top: 1px solid #ddd; }}
.card {{ margin: 0 0 28px; max-width: 640px; }} .card h3 {{ margin: 0; font-size: 16px; }}
.card .compare {{ max-width: 640px; }} ul.faces {{ margin: 2px 0 6px; padding-left: 18px; }}
</style></head><body>"""

