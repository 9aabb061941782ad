"""``OUT/report.html``: a run at a glance. A contact sheet of every frame (its input, shadow map,
weights, frontal relighting, novel view and albedo, with its summary row and quality flags), the
fit's convergence plot, and the frames that failed with their reasons.

One HTML file with relative links to the frames' PNGs under ``OUT/<stem>/``; the pictures that
are not PNG outputs (the input, the weights) and the plot are embedded as small images, so the
report opens from the folder with nothing else to serve it. Everything taken from a file name or
a record is HTML-escaped.
"""
from __future__ import annotations

import base64
import html
import io
import json
import time
from collections.abc import Iterable
from pathlib import Path
from urllib.parse import quote

import cv2
import numpy as np

from ...flow.files import atomic_write_chunks
from ...flow.recording import RecordingError
from ..photo.loader import InputError, read_photo
from .record import CONVERGENCE, CONVERGENCE_LABELS, CONVERGENCE_PLOTS, frame_name

REPORT_NAME = "report.html"
THUMB = 128  # pixels, the longer side of a picture in the contact sheet
PLOT_FRAMES = 200  # convergence curves drawn at most (the first ones of the run)
LINKED = (("shadow", "shadow.png"), ("relit", "relit.png"), ("novel view", "novel_view.png"),
          ("albedo", "albedo.png"))


def write_report(out: Path, records: Iterable[dict], recording: Path | None = None, title: str = "shadowflow run",
                 series: list[tuple[str, dict]] | None = None) -> Path:
    """Write ``out/report.html`` for the run whose summary records are ``records`` (input order; read
    twice, so a list or a re-iterable view such as ``RunStore.records``).
    The convergence plot draws ``series`` (``(frame name, {iteration: scalars})`` per frame, as the
    run kept them, ``ScalarsTap``) when given, else reads ``recording`` (the run's MCAP, a file or
    the folder); neither, or unreadable: the report says so. Returns the report's path."""
    frames = n_ok = doubtful = 0
    failed = []  # (input, step, reason) of each frame without outputs
    for r in records:
        frames += 1
        if _written(out, r):
            n_ok += 1
            doubtful += str(r.get("status", "")).startswith("doubtful")
        else:
            failed.append((r.get("source"), r.get("failed_in", ""), r.get("status")))
    if series is None and recording is not None:
        series = _recorded_series(recording)
    plot = _convergence_png(series) if series else None
    parts = [_HEAD.format(title=html.escape(title)),
             f"<h1>{html.escape(title)}</h1>",
             f"<p class=meta>{frames} frames: {n_ok - doubtful} ok, {doubtful} doubtful (outputs written, "
             f"look before trusting them), {len(failed)} failed. Written {time.strftime('%Y-%m-%d %H:%M')}; "
             f"<a href=summary.json>summary.json</a>.</p>"]
    parts.append("<h2>Convergence</h2>")
    if plot:
        parts.append(f'<img class=plot alt="convergence of the fit" src="data:image/png;base64,{plot}">')
    else:
        parts.append("<p class=meta>No recording to plot (run with <code>--record mcap</code>).</p>")
    if failed:
        parts.append(f"<h2>Failed ({len(failed)})</h2><table class=failed><tr><th>input<th>step<th>reason</tr>")
        parts += [f"<tr><td>{_text(source)}<td>{_text(step)}<td>{_text(status)}" for source, step, status in failed]
        parts.append("</table>")
    parts.append(f"<h2>Frames ({n_ok})</h2><table class=sheet><tr><th>frame<th>input<th>weights"
                 + "".join(f"<th>{name}" for name, _ in LINKED) + "</tr>")

    def page():  # row by row: 2,000 frames' embedded thumbnails are tens of MB
        yield "\n".join(parts).encode()
        for r in records:  # read again, a row at a time
            if _written(out, r):
                yield ("\n" + _row(out, r)).encode()
        yield b"\n</table></body></html>\n"

    return atomic_write_chunks(out / REPORT_NAME, page())


def _written(out: Path, record: dict) -> bool:
    """The frame's outputs exist (ok or doubtful): it gets a row of pictures."""
    stem = record.get("stem")
    return isinstance(stem, str) and bool(stem) and (out / stem / "relit.png").is_file()


def _row(out: Path, r: dict) -> str:
    stem = r["stem"]
    q = r.get("quality") or {}
    flags = q.get("flags") or []
    status = "doubtful" if flags else "ok"
    light = r.get("light")
    facts = [f"<b>{html.escape(stem)}</b>", f"<span class={status}>{status}</span>",
             f"quality {_num(q.get('score'))}", f"{_num(r.get('iterations'))} iterations"
             + ("" if r.get("converged") else " (not converged)"),
             f"σ {_num(r.get('final_sigma'), 4)}",
             "light " + (", ".join(_num(x, 2) for x in light) if isinstance(light, list) else "-")
             + f" ({_text(r.get('light_source', ''))})"]
    facts += [f"<span class=flag>{_text(f)}</span>" for f in flags]
    cells = [f"<td class=facts>{'<br>'.join(facts)}",
             f"<td>{_embedded(_input_thumb(r.get('source')), 'input')}",
             f"<td>{_embedded(_weights_thumb(out / stem / 'weights.npy'), 'weights')}"]
    for name, file in LINKED:
        rel = quote(f"{stem}/{file}")
        cells.append(f'<td><a href="{rel}"><img loading=lazy alt="{name}" src="{rel}" width={THUMB}></a>')
    return "<tr>" + "".join(cells) + "</tr>"


def _input_thumb(source) -> np.ndarray | None:
    """The input, grey, at most THUMB pixels a side (a large JPEG is decoded reduced)."""
    if not isinstance(source, str):
        return None
    try:
        grey = read_photo(source, max_pixels=4 * THUMB * THUMB).grey
    except (InputError, OSError, ValueError):
        return None
    return _fit(np.clip(grey * 255 + 0.5, 0, 255).astype(np.uint8))


def _weights_thumb(path: Path) -> np.ndarray | None:
    """The fit's weights (1 trusted .. 0 ignored) in a colour map, black off the face."""
    try:
        w = np.load(path, allow_pickle=False)
    except (OSError, ValueError):
        return None
    if w.ndim != 2:
        return None
    img = cv2.applyColorMap(np.clip(np.nan_to_num(w) * 255 + 0.5, 0, 255).astype(np.uint8), cv2.COLORMAP_VIRIDIS)
    img[~np.isfinite(w)] = 0
    return _fit(img)


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


def _convergence_png(series: list[tuple[str, dict]]) -> str:
    """The convergence plot of ``series`` (at most PLOT_FRAMES of them), base64 PNG."""
    from ...flow.replay import convergence_figure

    buf = io.BytesIO()
    convergence_figure(series[:PLOT_FRAMES], CONVERGENCE_PLOTS, CONVERGENCE_LABELS).savefig(buf, format="png")
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
<style>
body {{ font: 14px/1.4 system-ui, sans-serif; margin: 24px; color: #222; }}
h1 {{ font-size: 22px; margin: 0 0 4px; }} h2 {{ font-size: 17px; margin: 24px 0 8px; }}
.meta {{ color: #666; }} .plot {{ max-width: 100%; }}
table {{ border-collapse: collapse; }} td, th {{ padding: 4px 6px; vertical-align: top; text-align: left; }}
.sheet tr:nth-child(even) {{ background: #f4f4f4; }} .sheet img {{ display: block; image-rendering: pixelated; }}
.facts {{ min-width: 210px; font-size: 13px; }} .ok {{ color: #1a7f37; }} .doubtful {{ color: #b35900; }}
.flag {{ color: #b35900; font-size: 12px; }} .failed td {{ border-top: 1px solid #ddd; }}
</style></head><body>"""

