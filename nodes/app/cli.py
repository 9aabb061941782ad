"""``shadowflow`` command line: run, train, eval (see ``shadowflow COMMAND --help``)."""
from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import math
import os
import sys
import time
from collections.abc import Iterable
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ...flow.distributed import local_map, ordered_map
from ...flow.files import atomic_write_bytes
from ...flow.pipeline import wait_for_abandoned
from ...flow.recording import RecordOptions
from ...flow.replay import (
    convergence_row,
    diff_streams,
    format_table,
    open_frames,
    plot_convergence,
    relog_to_rerun,
)
from ..evaluation.scenes import write_shadowed_face
from ..evaluation.synthetic import evaluate, model_floor
from ..evaluation.yaleb_benchmark import evaluate_yaleb, summarise
from ..geometry.reflectance import light_from_angles
from ..method.eye_detail import CONTRAST as EYE_CONTRAST
from ..method.nodes import MethodOptions
from ..method.robust_fit import FitConfig
from ..model.default_model import resolve_model, train_from_recipe
from ..model.shape_model import check_grid, save_model
from ..model.sources import SOURCES_HELP, load_source
from ..photo.encoding import ENCODINGS
from ..photo.loader import IMAGE_SUFFIXES, MAX_WORK_PIXELS, parse_light
from .blueprint import default_blueprint
from .cluster import DASK_HELP, DASK_METAVAR, dask_client, parse_dask
from .inputs import FolderWatch, expand_inputs
from .process import one_blas_thread
from .channels import CONVERGENCE, CONVERGENCE_LABELS, CONVERGENCE_PLOTS
from .record import (
    CONVERGENCE_TABLE,
    DISPLAY_KINDS,
    RELOG_LEFT_OUT,
    frame_name,
    frame_source,
    stage_rank,
)
from .outputs import real_path
from .runner import DEFAULT_FRAME_TIMEOUT, RunOptions, check_writable, run_stream, tool_version

FITS = ["gauss-newton", "irls", "paper"]
MODEL_HELP = ("ict (default: built in, trained from ICT-FaceKit's real-scan identities) | procedural (built in, "
              "the project's anthropometric generator) | a model .npz written by 'shadowflow train'")


ALBEDO_ROUNDS_HELP = ("real skin: after the fit converges, divide out the smooth albedo its shape implies and fit on, "
                      "N times (default 1; 0 is the paper's one albedo everywhere, see README)")
FACE_LENGTH_HELP = ("auto (default): a found face's length (eyes to mouth) from its landmarks; off: the model's; "
                    "a number: stretch the model's face by it")
CONE_TRUST_HELP = ("output normals: blend on-cone and model normals by C x the robust weights (default 0.5; 1: the paper's "
                   "blend; 0: the model's normals; albedo and relighting always use the paper's blend)")


def _variant(args: argparse.Namespace, fit: str) -> dict:
    """``--remap`` and ``--albedo-fill`` as given, else as the fit's variant has them (``MethodOptions.paper``
    for ``--fit paper``, the defaults otherwise)."""
    base = MethodOptions.paper() if fit == "paper" else MethodOptions()
    return {"remap": args.remap or base.remap, "albedo_fill": args.albedo_fill or base.albedo_fill}


def _fit_config(name: str, modes: int | None, max_iterations: int | None = None,
                albedo_rounds: int | None = None, cone_trust: float | None = None) -> FitConfig:
    cfg = FitConfig.paper() if name == "paper" else FitConfig(solver=name)
    if cone_trust is not None:
        if not 0.0 <= cone_trust <= 1.0:
            raise ValueError(f"--cone-trust is a fraction in [0, 1], not {cone_trust}")
        cfg = dataclasses.replace(cfg, cone_trust=cone_trust)
    if albedo_rounds is not None:
        if albedo_rounds < 0:
            raise ValueError(f"--albedo-rounds must be 0 or more, not {albedo_rounds}")
        cfg = dataclasses.replace(cfg, albedo_rounds=albedo_rounds)
    if modes is not None:
        cfg = dataclasses.replace(cfg, n_modes=modes)
    if max_iterations is not None:
        cfg = dataclasses.replace(cfg, max_iterations=max_iterations)
    return cfg


def _face_length(text: str) -> str | float:
    """``--face-length``: auto, off or a stretch factor in [0.5, 2]."""
    if text in ("auto", "off"):
        return text
    try:
        f = float(text)
    except ValueError:
        f = float("nan")
    if not 0.5 <= f <= 2.0:
        raise ValueError(f"--face-length takes auto, off or a factor between 0.5 and 2, not {text!r}")
    return f


def _check_run_arguments(args: argparse.Namespace) -> None:
    """One line and exit 2 for an argument that cannot work, before anything runs."""
    if args.workers < 1:
        raise ValueError(f"--workers must be 1 or more, not {args.workers}")
    if args.dask is not None:
        parse_dask(args.dask)
    if args.max_iterations is not None and args.max_iterations < 1:
        raise ValueError(f"--max-iterations must be 1 or more, not {args.max_iterations}")
    if args.record_every < 1:
        raise ValueError(f"--record-every must be 1 or more, not {args.record_every}")
    if not (args.frame_timeout >= 0 and math.isfinite(args.frame_timeout)):
        raise ValueError(f"--frame-timeout must be a finite number of seconds (0: no limit), not {args.frame_timeout}")
    if not (args.settle >= 0 and math.isfinite(args.settle)):
        raise ValueError(f"--settle must be a finite number of seconds, not {args.settle}")
    if args.idle_exit is not None and not (args.idle_exit >= 0 and math.isfinite(args.idle_exit)):
        raise ValueError(f"--idle-exit must be a finite number of seconds, not {args.idle_exit}")
    _view_angle(args.view_angle)
    _view_size(args.view_size)
    _eye_contrast(args.eye_contrast)
    _max_pixels(args.max_megapixels)
    for light in args.relight or ():
        parse_light(light)


def _eye_contrast(c: float) -> float:
    if not (0.0 <= c <= 1.0):
        raise ValueError(f"--eye-contrast is between 0 (off) and 1, not {c:g}")
    return c


def _view_angle(deg: float) -> float:
    if not -90.0 <= deg <= 90.0:
        raise ValueError(f"--view-angle turns the face by -90 to 90 degrees, not {deg:g}")
    return deg


def _max_pixels(megapixels: float) -> int | None:
    """``--max-megapixels``: 0 means never reduce."""
    if megapixels == 0:
        return None
    if not 0.1 <= megapixels <= 40:
        raise ValueError(f"--max-megapixels is 0 (never reduce) or 0.1 to 40, not {megapixels:g}")
    return int(megapixels * 1_000_000)


def _view_size(px: int | None) -> int | None:
    if px is not None and not 32 <= px <= 4096:
        raise ValueError(f"--view-size is a side of 32 to 4096 pixels, not {px}")
    return px


def _grid_size(text: str) -> tuple[int, int]:
    """``--size H,W``: a model grid (``shape_model.check_grid``)."""
    try:
        h, w = (int(t) for t in text.split(","))
    except ValueError:
        raise ValueError(f"--size is H,W, two whole numbers of pixels, not {text!r}") from None
    return check_grid((h, w), "--size")


def _at_least(value: int, least: int, flag: str) -> int:
    if value < least:
        raise ValueError(f"{flag} must be {least} or more, not {value}")
    return value


def _light_angles(text: str) -> list[float]:
    """``--angles``: light angles from the view axis, degrees, each in [0, 90)."""
    try:
        angles = [float(t) for t in text.split(",")]
    except ValueError:
        raise ValueError(f"--angles is a list of degrees such as 45,60,75, not {text!r}") from None
    bad = [a for a in angles if not 0.0 <= a < 90.0]  # also NaN
    if bad:
        raise ValueError(f"--angles: {bad[0]:g} is not a light angle from the view axis (0 to below 90 degrees)")
    return angles


def _load_model(spec: str | None):

    return resolve_model(spec)


def write_demo_inputs(folder: Path, count: int = 3) -> list[str]:
    """Synthetic shadowed faces with sidecar lights, as PNGs: random ICT-FaceKit identities (drawn
    apart from the default model's training faces, seed 2024 vs 0) under side lights."""

    folder.mkdir(parents=True, exist_ok=True)
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
    fit = _fit_config(args.fit, args.modes, args.max_iterations, args.albedo_rounds, args.cone_trust)
    return MethodOptions(fit=fit, **_variant(args, args.fit),
                         integrator=args.integrator, light=light, eyes=_given_eyes(args.eyes),
                         find_faces=args.eyes == "auto", shadows=args.shadows,
                         face_length=_face_length(args.face_length),
                         extra_lights=tuple(parse_light(x) for x in args.relight or ()),
                         novel_yaw_deg=_view_angle(args.view_angle), novel_size=_view_size(args.view_size),
                         eye_contrast=_eye_contrast(args.eye_contrast), max_pixels=_max_pixels(args.max_megapixels),
                         encoding=args.encoding)


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
    return unmatched[0] if len(inputs) == 1 and unmatched else f"{' '.join(inputs)} holds no image file"


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
        print(f"error: {watch_error}", file=sys.stderr)
    if result.stopped:
        return 130
    fine = result.not_ok == 0 and result.storage_error is None and result.cluster_error is None and not watch_error
    return 0 if fine else 1


def cmd_run(args: argparse.Namespace) -> int:
    out = Path(args.out)
    _check_run_arguments(args)  # before any work or any file is written
    options = method_options(args)
    why = _no_input(args)
    if why is not None:
        print(f"shadowflow run: no input image: {why}", file=sys.stderr)
        return 2
    check_writable(out)
    inputs = (write_demo_inputs(out / "demo-inputs") if args.demo else []) + list(args.inputs)
    if not inputs and not args.watch:
        print("shadowflow run: no input given (name images or folders, use --demo or --watch DIR)", file=sys.stderr)
        return 2
    note = (lambda msg: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr))
    run = run_options(args)
    model = _load_model(args.model)
    stream, total, watch = _input_stream(args, inputs, note)
    t0 = time.perf_counter()
    result = run_stream(stream, out, model, options, run, total)
    note(f"{result.frames - result.not_ok} of {result.frames} done in {time.perf_counter() - t0:.1f} s"
         + (f"; report: {result.report}" if result.report is not None else "")
         + (f"; recordings: {', '.join(run.record)} in {out}" if run.record else ""))
    code = _run_exit_code(result, watch.error if watch is not None else None)
    if wait_for_abandoned(30.0):  # a step that overran --frame-timeout still runs: do not wait on it
        print("note: a step abandoned by --frame-timeout is still running; exiting without it", file=sys.stderr)
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def cmd_train(args: argparse.Namespace) -> int:
    size = list(_grid_size(args.size))
    _at_least(args.n, 2, "--n")
    _at_least(args.modes, 1, "--modes")
    if args.modes >= args.n:
        raise ValueError(f"--modes {args.modes}: {args.n} faces give at most {args.n - 1} modes (--n)")
    recipe = {"source": args.source, "n": args.n, "seed": args.seed, "modes": args.modes, "size": size}
    if args.expressions:
        if not 0.0 < args.expressions <= 1.0:
            raise ValueError(f"--expressions is a probability in (0, 1], not {args.expressions}")
        recipe["expressions"] = args.expressions
    t0 = time.perf_counter()
    model = train_from_recipe(recipe)
    save_model(model, args.out)
    print(f"trained {model.n_modes} modes over {model.n_pixels} pixels from {args.n} faces of {args.source} "
          f"in {time.perf_counter() - t0:.1f} s -> {args.out}")
    return 0


def _write_report(path: str | None, report: dict) -> None:
    """The JSON report of ``eval``, written atomically, if ``--json`` asked for one."""
    if path:
        atomic_write_bytes(path, (json.dumps(report, indent=2) + "\n").encode())
        print(f"written: {path}")


@contextmanager
def _mapper(spec: str | None):
    """How ``eval`` runs its items: here, or on the Dask cluster ``--dask SPEC`` names."""
    if spec is None:
        yield local_map
        return
    with dask_client(spec) as client:
        yield functools.partial(ordered_map, client)


def cmd_eval_yaleb(args: argparse.Namespace) -> int:

    if not args.data:
        raise ValueError("eval yaleb needs --data DIR (the folder holding yaleB01, yaleB02, ...)")
    model = _load_model(args.model)
    options = MethodOptions(fit=_fit_config(args.fit, args.modes, albedo_rounds=args.albedo_rounds,
                                            cone_trust=args.cone_trust), light="yaleb",
                            integrator=args.integrator, shadows=args.shadows, **_variant(args, args.fit),
                            face_length=_face_length(args.face_length))
    t0 = time.perf_counter()
    print(f"model: {args.model or 'built-in ict'}, K={args.modes or model.n_modes}; light: Yale B names; "
          "ground truth: photometric stereo of each subject's exposures")
    with _mapper(args.dask) as mapper:
        report = evaluate_yaleb(args.data, model, options, mapper=mapper)
    cols = [("err", "normals"), ("err_clean", "clean render"), ("err_floor", "model floor"),
            ("err_mean_shape", "mean shape"), ("err_others_mean", "others' mean"), ("psnr", "relit dB"),
            ("psnr_unmoved", "unmoved dB"), ("seam", "seam"), ("relit_level", "relit level"),
            ("shadow_iou", "shadow IoU"),
            ("psnr_input", "input dB"), ("ssim", "relit SSIM"), ("ssim_input", "input SSIM"),
            ("light_err_deg", "auto light"), ("iterations", "iterations")]
    print("per subject and light (errors in degrees):")
    print(f"{'subject':8} {'A,E':>7} " + " ".join(f"{t:>12}" for _, t in cols))
    for r in report["rows"]:
        print(f"{r['subject']:8} {r['light']:>7} " + " ".join(f"{r[k]:12.2f}" for k, _ in cols))
    print("means over the subjects:")
    summary = summarise(report["rows"])
    for s in summary:
        print(f"{'all':8} {s['lights']:>7} " + " ".join(f"{s[k]:12.2f}" for k, _ in cols))
    for f in report["frontal"]:
        print(f"{f['subject']:8} frontal photo relit frontally: {f['psnr']:.2f} dB, "
              f"{100 * f['gradient_energy']:.1f} % of its gradient energy")
    report.update(summary=summary, model=args.model or "built-in ict", albedo_rounds=options.fit.albedo_rounds,
                  seconds=time.perf_counter() - t0)
    _write_report(args.json, report)
    return 0


def cmd_eval(args: argparse.Namespace) -> int:
    if args.dask is not None:
        parse_dask(args.dask)  # before any work
    if args.benchmark == "yaleb":
        return cmd_eval_yaleb(args)

    size = _grid_size(args.size)
    _at_least(args.n_test, 1, "--n-test")
    _at_least(args.n_train, 2, "--n-train")
    angles = _light_angles(args.angles)
    t0 = time.perf_counter()
    if args.model:
        model = _load_model(args.model)
        trained_on = f"model {args.model}"
    else:
        train_src = args.train_source or args.source
        model = train_from_recipe({"source": train_src, "n": args.n_train, "seed": args.train_seed,
                                   "modes": args.modes or 60, "size": list(size)})
        trained_on = f"{args.n_train} faces of {train_src} (seed {args.train_seed})"
    test, albedo = load_source(args.source, args.n_test, args.test_seed, model.grid)
    if args.albedo == "constant":
        albedo = None
    fits = {"both": ["gauss-newton", "paper"], "all": FITS}.get(args.fit, [args.fit])
    report = {"source": args.source, "test_faces": args.n_test, "test_seed": args.test_seed,
              "model": trained_on, "modes": model.n_modes, "grid": list(model.grid), "albedo": args.albedo,
              "albedo_rounds": args.albedo_rounds or 0, "model_floor_deg": model_floor(model, test), "results": {}}
    print(f"model: {trained_on}, K={model.n_modes}, grid {model.grid[0]}x{model.grid[1]}; "
          f"test: {args.n_test} faces of {args.source} (seed {args.test_seed}), {args.albedo} albedo")
    print(f"model floor (true normals projected on the modes): {report['model_floor_deg']:.2f} deg")
    cols = ["err_all", "err_lit", "err_cast", "err_attached", "cast_iou", "shadow_iou", "depth_rmse",
            "iterations", "seconds_per_face"]
    print(f"{'fit':12} {'angle':>5} " + " ".join(f"{c:>12}" for c in cols))
    with _mapper(args.dask) as mapper:  # one cluster for every fit compared
        for name in fits:
            opts = MethodOptions(fit=_fit_config(name, None, albedo_rounds=args.albedo_rounds,
                                                 cone_trust=args.cone_trust),
                                 integrator=args.integrator, shadows=args.shadows, **_variant(args, name))
            res = evaluate(model, test, albedo, angles, opts, mapper=mapper)
            report["results"][name] = res["per_angle"]
            for angle, row in res["per_angle"].items():
                print(f"{name:12} {angle:>5} " + " ".join(f"{row[c]:12.3f}" for c in cols))
    report["seconds"] = time.perf_counter() - t0
    _write_report(args.json, report)
    return 0


def _refuse_overwriting_the_recording(target: Path, recording: Path) -> None:
    """``ValueError`` when ``replay --rrd`` would write over the recording it reads: the file given, or
    in a run's folder, any file of it."""
    real = real_path(target)
    sources = {real_path(recording)}
    if recording.is_dir():
        sources |= {real_path(p) for p in recording.iterdir()}
    if real in sources:
        raise ValueError(f"--rrd {target}: is the recording being read (or a file of its run); write it elsewhere")


def cmd_replay(args: argparse.Namespace) -> int:

    if args.rrd:
        _refuse_overwriting_the_recording(Path(args.rrd), Path(args.recording))
    stream = open_frames(args.recording, arrays=bool(args.rrd))  # one frame in memory at a time
    rows, series = [], []

    def tap(frames):
        for fr in frames:
            rows.append(convergence_row(fr, CONVERGENCE, CONVERGENCE_TABLE))
            if args.plot:  # a plot needs every frame's curves; a table only its row
                series.append((frame_name(fr), fr.scalars.get(CONVERGENCE, {})))
            yield fr

    if args.rrd:
        relog_to_rerun(tap(stream), args.rrd, DISPLAY_KINDS, default_blueprint(), RELOG_LEFT_OUT)
    else:
        for _ in tap(stream):
            pass
    print(format_table(sorted(rows, key=lambda r: r.frame), CONVERGENCE_TABLE))
    if stream.truncated:
        print(f"note: {args.recording} ends early (a killed run?); shown: everything before the cut")
    if args.plot:
        print(f"plot: {plot_convergence(series, args.plot, CONVERGENCE_PLOTS, CONVERGENCE_LABELS)}")
    if args.rrd:
        print(f"rerun: {args.rrd}")
    return 0


def cmd_diff(args: argparse.Namespace) -> int:

    # frames pair by their input's path (two inputs may share a file name), then by its file name (a run over
    # copies of the inputs elsewhere)
    report = diff_streams(open_frames(args.a), open_frames(args.b), args.atol, args.rtol, key=frame_source,
                          stage=stage_rank, fallback=frame_name)
    if not report.differences:
        print(f"same: {report.frames} frames, {report.iterations} iterations within atol={args.atol:g} "
              f"rtol={args.rtol:g}")
        return 0
    diffs = report.differences
    first = diffs[0]
    it = "-" if first.iteration is None else first.iteration
    print(f"first divergence: frame {first.frame}, iteration {it}, channel {first.channel}: "
          f"{first.what}, max |difference| {first.max_abs:.6g}")
    frames = {str(d.frame) for d in diffs}
    channels = sorted({d.channel for d in diffs})
    print(f"{len(diffs)} differing items in {len(frames)} frame(s) over channel(s): {', '.join(channels)}")
    return 1


def _add_run(sub) -> None:
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
    r.add_argument("--remap", choices=["ratio", "peak"],
                   help="brightness scale: median ratio to the mean face (default) or the brightest point "
                        "(the paper's; the default with --fit paper)")
    r.add_argument("--integrator", choices=["lsq", "fc"], default="lsq",
                   help="masked least squares (default) or Frankot-Chellappa (the paper's)")
    r.add_argument("--shadows", choices=["confirmed", "geometric"], default="confirmed",
                   help="cast shadows traced and checked against the image (default) or traced only (paper)")
    r.add_argument("--albedo-fill", choices=["ceiling", "mirror"],
                   help="albedo under shadow: mirrored or interpolated, never brighter than the face's typical "
                        "measured albedo (default) or mirrored as measured (the paper's; the default with --fit paper)")
    r.add_argument("--eyes", default="auto",
                   help="auto (default): find every face by its landmarks (MediaPipe's detector and face mesh); "
                        "centre: take the image as one frontal face framed like the model grid; "
                        "X1,Y1,X2,Y2: one face with these eye centres, in the image; a sidecar's eyes win")
    r.add_argument("--relight", action="append", metavar="A,E|X,Y,Z",
                   help="also relight toward this light (angles in degrees or a vector, as --light; repeatable): "
                        "relit_A<az>E<el>.png per light, beside relit.png (frontal)")
    r.add_argument("--eye-contrast", type=float, default=EYE_CONTRAST, metavar="C",
                   help="with detected eyes, an eye in shadow or grazing light gets the lit eye's detail (irises, "
                        f"lids) at this contrast (default {EYE_CONTRAST:g}; 0: off, the eye stays the smooth fill; "
                        "1: as the photo shows it)")
    r.add_argument("--view-angle", type=float, default=45.0, metavar="DEG",
                   help="novel_view.png: the surface turned this far about the vertical axis (default 45; -90..90)")
    r.add_argument("--view-size", type=int, metavar="PX",
                   help="novel_view.png's height and width in pixels (default: the model grid's)")
    r.add_argument("--encoding", choices=list(ENCODINGS), default="auto",
                   help="how the photos' values relate to light: auto (default; colour photos are sRGB, grey ones "
                        "linear), srgb or linear; the method works in linear light, outputs keep the photo's encoding")
    r.add_argument("--max-megapixels", type=float, default=MAX_WORK_PIXELS / 1e6, metavar="MP",
                   help="read larger photos reduced to this size, outputs at that size (default 4; 0: full size, "
                        "memory grows with the photo, see README)")
    r.add_argument("--record", default="rerun,mcap", help="rerun,mcap | rerun | mcap | none (files run.rrd, run.mcap in --out)")
    r.add_argument("--record-every", type=int, default=1, metavar="N",
                   help="record fit iterations 1, 1+N, ... and the last (default: every one)")
    r.add_argument("--record-float16", action="store_true", help="store recorded float arrays as float16")
    r.add_argument("--workers", type=int, default=1, help="threads for the robust-fit node")
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


def _add_train(sub) -> None:
    """``shadowflow train``'s arguments."""
    t = sub.add_parser("train", help="train a needle-map model")
    t.add_argument("--source", default="ict", help=SOURCES_HELP + " (default: ict)")
    t.add_argument("--expressions", type=float, metavar="P",
                   help="ICT only: give each face each of the 53 expression blendshapes with chance P (needs ict:PATH)")
    t.add_argument("--n", type=int, default=200, help="training faces to draw (default 200)")
    t.add_argument("--seed", type=int, default=0, help="random seed of the faces drawn (default 0)")
    t.add_argument("--modes", type=int, default=60, help="modes K to keep (default 60)")
    t.add_argument("--size", default="128,128", help="H,W of the model grid")
    t.add_argument("--out", required=True, help="the model file to write (.npz); use it with run --model")
    t.set_defaults(func=cmd_train)


def _add_eval(sub) -> None:
    """``shadowflow eval``'s arguments."""
    e = sub.add_parser("eval", help="accuracy on rendered held-out faces, or on Yale B photos (eval yaleb)")
    e.add_argument("benchmark", nargs="?", choices=["synthetic", "yaleb"], default="synthetic",
                   help="synthetic (default): rendered faces of --source; yaleb: real photos in --data")
    e.add_argument("--data", help="eval yaleb: folder holding the yaleBxx subject folders")
    e.add_argument("--source", default="procedural", help="test faces: procedural | eos:PATH | meshes:DIR")
    e.add_argument("--model", help="ict | procedural | a model .npz (synthetic default: train one from "
                   "--train-source; yaleb default: ict)")
    e.add_argument("--train-source", help="training faces (default: --source)")
    e.add_argument("--n-train", type=int, default=100, help="synthetic: training faces (default 100)")
    e.add_argument("--n-test", type=int, default=20, help="synthetic: held-out test faces (default 20)")
    e.add_argument("--train-seed", type=int, default=0, help="synthetic: seed of the training faces (default 0)")
    e.add_argument("--test-seed", type=int, default=1, help="synthetic: seed of the test faces (default 1)")
    e.add_argument("--modes", type=int, help="modes to train (synthetic, default 60) or to use (yaleb)")
    e.add_argument("--size", default="128,128", help="synthetic: H,W of the model grid and the renders")
    e.add_argument("--angles", default="45,60,75", help="light angles from the view axis, degrees")
    e.add_argument("--albedo", choices=["constant", "varied"], default="constant",
                   help="synthetic: the test faces' albedo, uniform (default) or varying over the face")
    e.add_argument("--fit", choices=FITS + ["both", "all"], default="gauss-newton",
                   help="both: gauss-newton and paper; all: the three")
    e.add_argument("--remap", choices=["ratio", "peak"], help="as run --remap")
    e.add_argument("--albedo-rounds", type=int, metavar="N", help=ALBEDO_ROUNDS_HELP)
    e.add_argument("--cone-trust", type=float, metavar="C", help=CONE_TRUST_HELP)
    e.add_argument("--face-length", default="auto", metavar="auto|off|F", help="eval yaleb: " + FACE_LENGTH_HELP)
    e.add_argument("--integrator", choices=["lsq", "fc"], default="lsq", help="as run --integrator")
    e.add_argument("--shadows", choices=["confirmed", "geometric"], default="confirmed", help="as run --shadows")
    e.add_argument("--albedo-fill", choices=["ceiling", "mirror"], help="as run --albedo-fill")
    e.add_argument("--json", help="write the report here")
    e.add_argument("--dask", nargs="?", const="env", metavar=DASK_METAVAR,
                   help="spread the faces and lights (synthetic) or the subjects (yaleb) over a Dask cluster; "
                        "the report is the same")
    e.set_defaults(func=cmd_eval)

def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="shadowflow", description=__doc__)
    p.add_argument("--version", action="version", version=f"shadowflow {tool_version()}")
    sub = p.add_subparsers(dest="command", required=True)
    _add_run(sub)
    _add_train(sub)
    _add_eval(sub)

    rp = sub.add_parser("replay", help="convergence table / plot / re-log to Rerun of a recording")
    rp.add_argument("recording", help="run.mcap, or a run's --out folder (its parts merged)")
    rp.add_argument("--plot", metavar="PNG", help="write a convergence plot")
    rp.add_argument("--rrd", metavar="RRD", help="re-log the recording into a Rerun file")
    rp.set_defaults(func=cmd_replay)

    d = sub.add_parser("diff", help="compare two recordings; exit 0 same, 1 different, 2 unreadable")
    d.add_argument("a", help="run.mcap, or a run's --out folder (a resumed run's parts merged)")
    d.add_argument("b", help="the recording to compare A with (a file or a folder, as A)")
    d.add_argument("--atol", type=float, default=0.0, help="absolute tolerance: equal when |a - b| <= atol + rtol |b|")
    d.add_argument("--rtol", type=float, default=0.0, help="relative tolerance (see --atol)")
    d.set_defaults(func=cmd_diff)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        with one_blas_thread():  # train, eval: the same small matrices
            return int(args.func(args) or 0)
    except (ValueError, OSError, RuntimeError) as exc:
        print(f"shadowflow {args.command}: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
