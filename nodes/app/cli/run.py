"""``shadowflow run``: its arguments, their checks, and the run."""
from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from ....flow.pipeline import wait_for_abandoned
from ....flow.recording import RecordOptions
from ...evaluation.scenes import write_shadowed_face
from ...geometry.reflectance import light_from_angles
from ...method.options import CHOICES, MAX_VIEW_SIZE, RANGES, MethodOptions
from ...photo.lights import parse_light
from ...photo.loader import MAX_WORK_PIXELS
from ..cluster import DASK_HELP, DASK_METAVAR, parse_dask
from ..counts import tally_text
from ..inputs import IMAGE_SUFFIXES, FolderWatch, expand_inputs
from ..outputs import real_path
from ..runner import DEFAULT_FRAME_TIMEOUT, RunOptions, run_stream
from ..storage import check_out, out_folder, refuse_link
from ..terminal import say
from .arguments import (
    ALBEDO_ROUNDS_HELP,
    CONE_TRUST_HELP,
    FACE_LENGTH_HELP,
    FITS,
    MODEL_HELP,
    face_length,
    fit_config,
    fit_variant,
    model_arg,
)


def _check_run_arguments(args: argparse.Namespace) -> None:
    """One line and exit 2 for an argument that cannot work, before anything runs."""
    if args.workers < 1:
        raise ValueError(f"--workers must be 1 or more, not {args.workers}")
    if args.dask is not None:
        parse_dask(args.dask)
    if args.record_every < 1:
        raise ValueError(f"--record-every must be 1 or more, not {args.record_every}")
    if not (args.frame_timeout >= 0 and math.isfinite(args.frame_timeout)):
        raise ValueError(f"--frame-timeout must be a finite number of seconds (0: no limit), not {args.frame_timeout}")
    if not (args.settle >= 0 and math.isfinite(args.settle)):
        raise ValueError(f"--settle must be a finite number of seconds, not {args.settle}")
    if args.idle_exit is not None and not (args.idle_exit >= 0 and math.isfinite(args.idle_exit)):
        raise ValueError(f"--idle-exit must be a finite number of seconds, not {args.idle_exit}")


def _max_pixels(megapixels: float) -> int | None:
    """``--max-megapixels`` as ``MethodOptions.max_pixels``: 0 means never reduce (None)."""
    return None if megapixels == 0 else int(megapixels * RANGES["max_pixels"].per)


def write_demo_inputs(out: Path, count: int = 3) -> list[str]:
    """Synthetic shadowed faces with sidecar lights, as PNGs in ``out/demo-inputs``: random ICT-FaceKit identities
    (drawn apart from the default model's training faces, seed 2024 vs 0) under side lights. Never through a
    link: a ``demo-inputs`` that is one, or leads out of ``out``, is refused (``ValueError``), and each file
    replaces whatever link is at its name."""
    folder = out / "demo-inputs"
    refuse_link(folder)
    folder.mkdir(parents=True, exist_ok=True)
    if real_path(folder).parent != real_path(out):
        raise ValueError(f"{folder}: leads out of --out; shadowflow writes nothing outside it")
    rng = np.random.default_rng(2024)
    lights = [(45, 0), (-60, 0), (30, 25), (-75, 0), (60, -10)]
    paths = []
    for i in range(count):
        az, el = lights[i % len(lights)]
        path = folder / f"demo-{i + 1}_A{az:+04d}E{el:+03d}.png"
        paths.append(str(write_shadowed_face(path, rng, light_from_angles(az, el), source="ict")))
    return paths


def run_options(args: argparse.Namespace) -> RunOptions:
    """How ``run`` runs (recordings, workers, resume, time limit), from its arguments."""
    record = tuple(x for x in args.record.split(",") if x and x != "none")
    unknown = set(record) - {"rerun", "mcap"}
    if unknown:
        raise ValueError(f"--record takes rerun, mcap or none, not {', '.join(sorted(unknown))}")
    return RunOptions(record=record, record_options=RecordOptions(args.record_every, args.record_float16),
                      fit_workers=args.workers, resume=args.resume, quiet=args.quiet,
                      frame_timeout=args.frame_timeout or None, dask=args.dask)


def _given_eyes(text: str) -> np.ndarray | None:
    """``--eyes``: None for auto or centre, else the (2, 2) eye centres of ``X1,Y1,X2,Y2``."""
    if text in ("auto", "centre"):
        return None
    try:
        eyes = np.array([float(t) for t in text.split(",")], np.float64).reshape(2, 2)
    except ValueError:
        raise ValueError(f"--eyes {text!r}: give auto, centre or four numbers X1,Y1,X2,Y2") from None
    if not np.all(np.isfinite(eyes)) or np.linalg.norm(eyes[1] - eyes[0]) < 1.0:
        raise ValueError(f"--eyes {text!r}: four finite numbers, two distinct eye centres")
    return eyes


def method_options(args: argparse.Namespace) -> MethodOptions:
    """What the method computes, from ``run``'s arguments (checked by ``MethodOptions`` itself)."""
    light: str | np.ndarray = args.light if args.light in ("auto", "yaleb") else parse_light(args.light)
    fit = fit_config(args.fit, args.modes, args.max_iterations, args.albedo_rounds, args.cone_trust)
    return MethodOptions(fit=fit, **fit_variant(args, args.fit),
                         integrator=args.integrator, light=light, eyes=_given_eyes(args.eyes),
                         find_faces=args.eyes == "auto", shadows=args.shadows,
                         face_length=face_length(args.face_length),
                         extra_lights=tuple(parse_light(x) for x in args.relight or ()),
                         novel_yaw_deg=args.view_angle, novel_size=args.view_size,
                         eye_contrast=args.eye_contrast, fill_detail=args.fill_detail, mirror_lift=args.mirror_lift,
                         foreign_shadows=args.foreign_shadows, max_pixels=_max_pixels(args.max_megapixels),
                         encoding=args.encoding, arrays=args.arrays, frames=args.frames)


def _no_input(args: argparse.Namespace) -> str | None:
    """Why ``run``'s named inputs hold no image (a pattern matching nothing, a folder without images), or
    None; asked before ``--out`` is made, so such a run writes nothing."""
    inputs = list(args.inputs)
    if not inputs or args.watch:
        return None
    notes: list[str] = []
    if expand_inputs(inputs, notes.append):
        return None
    unmatched = [n for n in notes if n.endswith("no file matches")]
    if len(inputs) == 1 and unmatched:
        return unmatched[0]
    # a folder's folders are not read (a newcomer's first try: the data folder above photos/ and clips/)
    inner = [f"{f.name}/" for i in inputs if Path(i).is_dir() for f in sorted(Path(i).iterdir())
             if f.is_dir() and not f.name.startswith(".")]
    hint = f" (folders inside are not read: name them, e.g. {', '.join(inner[:3])})" if inner else ""
    return f"{' '.join(inputs)} holds no image file{hint}"


def _input_stream(args: argparse.Namespace, inputs: list[str],
                  note) -> tuple[Iterable[str], int | None, FolderWatch | None]:
    """The paths to run (a list, or the named ones then a watched folder's newcomers), their number when
    known, and the watch."""
    if not args.watch:
        paths = expand_inputs(inputs, note)
        return paths, len(paths), None
    paths = expand_inputs(inputs, note) if inputs else []
    watch = FolderWatch(Path(args.watch), IMAGE_SUFFIXES, args.idle_exit, settle=args.settle)
    return (p for src in (paths, watch) for p in src), None, watch


def _run_exit_code(result, watch_error: str | None) -> int:
    """130 stopped by a signal; 0 every frame done; 1 a frame failed or is doubtful, the folder took no more,
    the cluster or the watched folder went away (said here for the watch)."""
    if watch_error:
        say(f"error: {watch_error}")
    if result.stopped:
        return 130
    fine = result.not_ok == 0 and result.storage_error is None and result.cluster_error is None and not watch_error
    return 0 if fine else 1


def cmd_run(args: argparse.Namespace) -> int:
    out = out_folder(args.out)
    _check_run_arguments(args)  # before any work or any file is written
    options = method_options(args)  # each option checked by its own rule (``method.options``, ``FitConfig``)
    why = _no_input(args)
    if why is not None:
        say(f"shadowflow run: no input image: {why}")
        return 2
    if not args.inputs and not args.demo and not args.watch:
        say("shadowflow run: no input given (name images or folders, use --demo or --watch DIR)")
        return 2
    run = run_options(args)
    model = model_arg(args.model)  # a model file that cannot be used is refused before anything is written
    if args.demo:  # (run_stream checks --out itself, after what the inputs are)
        check_out(out)  # before the demo's inputs are written there
    inputs = (write_demo_inputs(out) if args.demo else []) + list(args.inputs)
    note = (lambda msg: None) if args.quiet else say
    stream, total, watch = _input_stream(args, inputs, note)
    t0 = time.perf_counter()
    result = run_stream(stream, out, model, options, run, total)
    done = (f"{tally_text(result.counts)}; done" if result.counts
            else f"{result.frames - result.not_ok} of {result.frames} done")
    note(f"{done} in {time.perf_counter() - t0:.1f} s"
         + (f"; report: {result.report}" if result.report is not None else "")
         + (f"; recordings: {', '.join(run.record)} in {out}" if run.record else ""))
    code = _run_exit_code(result, watch.error if watch is not None else None)
    if wait_for_abandoned(30.0):  # a step that overran --frame-timeout still runs: do not wait on it
        say("note: a step abandoned by --frame-timeout is still running; exiting without it")
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def _relight_arguments(r: argparse.ArgumentParser) -> None:
    """``shadowflow run``'s arguments that say how a face is relit."""
    r.add_argument("--relight", action="append", metavar="A,E|X,Y,Z",
                   help="also relight toward this light (angles in degrees or a vector, as --light; repeatable): "
                        "relit_A<az>E<el>.png per light, beside relit.png (frontal)")
    r.add_argument("--eye-contrast", type=float, default=MethodOptions.eye_contrast, metavar="C",
                   help="with detected eyes, an eye in shadow or grazing light gets the lit eye's detail (irises, "
                        f"lids) at this contrast (default {MethodOptions.eye_contrast:g}; 0: off, the eye stays the smooth fill; "
                        "1: as the photo shows it)")
    r.add_argument("--fill-detail", type=float, default=MethodOptions.fill_detail, metavar="C",
                   help="a frontal face's shadowed side, filled from the fit's smooth albedo, gets the detail its lit "
                        f"side shows across the face (nostrils, lips, skin) at this strength (default {MethodOptions.fill_detail:g}; "
                        "0: off, the smooth fill)")
    r.add_argument("--mirror-lift", type=float, default=1.0, metavar="C",
                   help="the side of a frontal face the photo's light reaches less keeps its measured albedo no darker "
                        "than the other side's, seen across the face, at this strength (default 1; 0: off, as measured)")
    r.add_argument("--foreign-shadows", action="store_true",
                   help="also find the shadows the face does not cast (a hat's brim, leaves, a hand) and lift them "
                        "under any light, the photo's own too (off by default: on ordinary photos a smile's cheeks, "
                        "a temple or stubble can be taken for one)")


def add_parser(sub) -> None:
    """``shadowflow run``'s arguments."""
    r = sub.add_parser("run", help="recover shape, albedo and shadows of face images")
    r.add_argument("inputs", nargs="*", metavar="INPUT", help="image files, folders or glob patterns")
    r.add_argument("--out", required=True, help="output folder (OUT/<stem>/..., OUT/summary.json)")
    r.add_argument("--demo", action="store_true", help="also run on built-in synthetic shadowed faces")
    r.add_argument("--model", help=MODEL_HELP)
    r.add_argument("--light", default="auto",
                   help="auto | yaleb | A,E (azimuth, elevation in degrees: azimuth > 0 toward the image's left, "
                        "elevation > 0 up, as Yale B's) | X,Y,Z (a vector toward the light, camera frame); write "
                        "--light=-30,10 for a negative first number; a sidecar light wins")
    r.add_argument("--fit", choices=FITS, default="gauss-newton",
                   help="gauss-newton (default) or irls: the same robust fit, reached by Gauss-Newton steps "
                        "or by the paper's alternation; paper: the paper's one-step formula throughout")
    r.add_argument("--modes", type=int, help="use only the model's first K modes")
    r.add_argument("--max-iterations", type=int, help="cap on fit iterations (default 100)")
    r.add_argument("--albedo-rounds", type=int, metavar="N", help=ALBEDO_ROUNDS_HELP)
    r.add_argument("--cone-trust", type=float, metavar="C", help=CONE_TRUST_HELP)
    r.add_argument("--face-length", default="auto", metavar="auto|off|F", help=FACE_LENGTH_HELP)
    r.add_argument("--remap", choices=CHOICES["remap"],
                   help="brightness scale: median ratio to the mean face (default) or the brightest point "
                        "(the paper's; the default with --fit paper)")
    r.add_argument("--integrator", choices=CHOICES["integrator"], default=MethodOptions.integrator,
                   help="masked least squares (default) or Frankot-Chellappa (the paper's)")
    r.add_argument("--shadows", choices=CHOICES["shadows"], default=MethodOptions.shadows,
                   help="cast shadows traced and checked against the image (default) or traced only (paper)")
    r.add_argument("--albedo-fill", choices=CHOICES["albedo_fill"],
                   help="albedo under shadow: mirrored or interpolated, never brighter than the face's typical "
                        "measured albedo (default) or mirrored as measured (the paper's; the default with --fit paper)")
    r.add_argument("--eyes", default="auto",
                   help="auto (default): find every face by its landmarks (MediaPipe's detector and face mesh); "
                        "centre: take the image as one frontal face framed like the model grid; "
                        "X1,Y1,X2,Y2: one face with these eye centres, in the image; a sidecar's eyes win")
    _relight_arguments(r)
    r.add_argument("--view-angle", type=float, default=45.0, metavar="DEG",
                   help="novel_view.png: the surface turned this far about the vertical axis (default 45; -90..90)")
    r.add_argument("--view-size", type=int, metavar="PX",
                   help=f"novel_view.png's height and width in pixels, 32 to {MAX_VIEW_SIZE} (default: the model grid's)")
    r.add_argument("--encoding", choices=CHOICES["encoding"], default=MethodOptions.encoding,
                   help="how the photos' values relate to light: auto (default; colour photos are sRGB, grey ones "
                        "linear), srgb or linear; the method works in linear light, outputs keep the photo's encoding")
    r.add_argument("--arrays", choices=CHOICES["arrays"], default=MethodOptions.arrays,
                   help="normals.npy, weights.npy, depth.npy: on the fit's model grid (default: what the fit holds, "
                        "with grid.json placing it on the photo; shadowflow.read_arrays brings them there) or on "
                        "the photo's pixel grid (a 4-megapixel photo's normals.npy is then 48 MB)")
    r.add_argument("--frames", action="store_true",
                   help="clips: also write each frame's files (OUT/<stem>/frames/<index>/), not only relit.mp4 and "
                        "frames.jsonl")
    r.add_argument("--max-megapixels", type=float, default=MAX_WORK_PIXELS / 1e6, metavar="MP",
                   help="read larger photos reduced to this size, outputs at that size (default 4; 0: full size, "
                        "memory grows with the photo, see README)")
    r.add_argument("--record", default="rerun,mcap", help="rerun,mcap | rerun | mcap | none (files run.rrd, run.mcap in --out)")
    r.add_argument("--record-every", type=int, default=1, metavar="N",
                   help="record fit iterations 1, 1+N, ... and the last (default: every one)")
    r.add_argument("--record-float16", action="store_true", help="store recorded float arrays as float16")
    r.add_argument("--workers", type=int, default=1, help="threads for the fit and the relighting (two frames at once on two cores)")
    r.add_argument("--dask", nargs="?", const="env", metavar=DASK_METAVAR, help=DASK_HELP)
    r.add_argument("--frame-timeout", type=float, default=DEFAULT_FRAME_TIMEOUT, metavar="SECONDS",
                   help=f"fail a frame when one step takes longer than this on it (default {DEFAULT_FRAME_TIMEOUT:g}; "
                        "0: no limit)")
    r.add_argument("--resume", action="store_true", help="skip inputs whose outputs in --out are complete")
    r.add_argument("--watch", metavar="DIR", help="keep processing new images that appear in DIR")
    r.add_argument("--idle-exit", type=float, metavar="SECONDS", help="with --watch: stop after this long with nothing new")
    r.add_argument("--settle", type=float, default=1.0, metavar="SECONDS",
                   help="with --watch: take a file once its size and time have not changed for this long (default 1)")
    r.add_argument("--quiet", action="store_true", help="no progress line and no notes; errors still shown")
    r.set_defaults(func=cmd_run)
