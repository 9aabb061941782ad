"""``shadowflow eval``: accuracy on rendered held-out faces, or on Yale B photos."""
from __future__ import annotations

import argparse
import contextlib
import functools
import json
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

from ....flow.distributed import local_map, ordered_map
from ....flow.files import atomic_write_bytes
from ....flow.replay.text import one_line
from ...evaluation import foreign_shadows
from ...evaluation.people import contact_sheet, evaluate_people, figure, format_table, json_rows, people_inputs
from ...evaluation.people import summarise as people_summary
from ...evaluation.synthetic import evaluate, model_floor, table_header, table_row
from ...evaluation.yaleb_benchmark import HELD_OUT_LIGHTS, INPUT_LIGHTS, evaluate_yaleb, format_report, summarise
from ...method.options import CHOICES, MethodOptions
from ...model.default_model import train_from_recipe
from ...model.sources import load_source
from ...photo.encoding import swapped_rb
from ..cluster import DASK_METAVAR, dask_client, parse_dask
from ..outputs import png_bytes
from .arguments import (
    ALBEDO_ROUNDS_HELP,
    CONE_TRUST_HELP,
    FACE_LENGTH_HELP,
    FITS,
    at_least,
    face_length,
    fit_config,
    fit_variant,
    grid_size,
    model_arg,
)


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


def _write_report(path: str | None, report: dict) -> None:
    """The JSON report of ``eval``, written atomically, if ``--json`` asked for one."""
    if path:
        atomic_write_bytes(path, (json.dumps(report, indent=2) + "\n").encode())
        print(one_line(f"written: {path}"))


@contextmanager
def _mapper(spec: str | None):
    """How ``eval`` runs its items: here, or on the Dask cluster ``--dask SPEC`` names."""
    if spec is None:
        yield local_map
        return
    with dask_client(spec) as client:
        yield functools.partial(ordered_map, client)


def yaleb_lights(spec: str) -> list[tuple[int, int]]:
    """``--lights``: "default" (``INPUT_LIGHTS``), "held-out" (``HELD_OUT_LIGHTS``) or "A,E;A,E;..." (Yale B's
    azimuth and elevation, whole degrees)."""
    if spec == "default":
        return list(INPUT_LIGHTS)
    if spec == "held-out":
        return list(HELD_OUT_LIGHTS)
    try:
        lights = [tuple(int(v) for v in pair.split(",")) for pair in spec.split(";") if pair.strip()]
    except ValueError:
        lights = []
    if not lights or any(len(pair) != 2 for pair in lights):
        raise ValueError(f"--lights {spec!r}: default, held-out or A,E;A,E;... (whole degrees)")
    return lights


def cmd_eval_yaleb(args: argparse.Namespace) -> int:
    if not args.data:
        raise ValueError("eval yaleb needs --data DIR (the folder holding yaleB01, yaleB02, ...)")
    model = model_arg(args.model)
    options = MethodOptions(fit=fit_config(args.fit, args.modes, albedo_rounds=args.albedo_rounds,
                                            cone_trust=args.cone_trust), light="yaleb",
                            integrator=args.integrator, shadows=args.shadows, **fit_variant(args, args.fit),
                            face_length=face_length(args.face_length), foreign_shadows=args.foreign_shadows)
    t0 = time.perf_counter()
    print(one_line(f"model: {args.model or 'built-in ict'}, K={args.modes or model.n_modes}; light: Yale B names; "
                   "ground truth: photometric stereo of each subject's exposures"
                   + ("; shadows from elsewhere looked for" if args.foreign_shadows else "")))
    lights = yaleb_lights(args.lights)
    with _mapper(args.dask) as mapper:
        # the lights the method was tuned on must all be found; others include photos the finder misses
        report = evaluate_yaleb(args.data, model, options, lights=lights, mapper=mapper,
                                skip_unfound=args.lights != "default", names=_subjects(args))
    summary = summarise(report["rows"])
    print(format_report(report, summary))
    report.update(summary=summary, model=args.model or "built-in ict", albedo_rounds=options.fit.albedo_rounds,
                  seconds=time.perf_counter() - t0)
    _write_report(args.json, report)
    return 0


def cmd_eval_people(args: argparse.Namespace) -> int:
    if not args.data:
        raise ValueError("eval people needs --data DIR (a folder of photos, or one holding photos/ and clips/)")
    items = people_inputs(args.data, args.clip_frames)
    if not items:
        raise ValueError(f"{args.data}: no photos or clips to evaluate")
    model = model_arg(args.model)
    t0 = time.perf_counter()
    with _mapper(args.dask) as mapper:
        rows = evaluate_people(items, model, MethodOptions(foreign_shadows=args.foreign_shadows), mapper=mapper,
                               thumbs=bool(args.sheet))
    print(format_table(rows))
    if args.sheet:
        sheet = contact_sheet(rows, args.worst)
        if sheet is not None:
            atomic_write_bytes(args.sheet, png_bytes(swapped_rb(sheet)))
            print(one_line(f"written: {args.sheet}"))
    _write_report(args.json, {"data": str(args.data), "rows": json_rows(rows), "summary": people_summary(rows),
                              "seconds": time.perf_counter() - t0})
    return 0


def cmd_eval_clips(args: argparse.Namespace) -> int:
    """Each clip of ``--data`` run as ``shadowflow run`` runs it (into ``--out``, kept and resumed; else a
    temporary folder) and its relit clip measured against it (``clip_eval.clip_steadiness``)."""
    from ..api import run
    from ..clip_eval import clip_steadiness
    from ..clip_io import is_clip
    from ..inputs import expand_inputs

    if not args.data:
        raise ValueError("eval clips needs --data (a clip, or a folder of clips)")
    clips = [p for p in expand_inputs([args.data], note=lambda msg: None) if is_clip(p)]
    if not clips:
        raise ValueError(f"{args.data}: no clips to evaluate")
    t0 = time.perf_counter()
    with contextlib.ExitStack() as stack:
        out = args.out or stack.enter_context(tempfile.TemporaryDirectory(prefix="shadowflow-eval-"))
        result = run(clips, out, record=(), resume=bool(args.out), quiet=True)
        rows = []
        print(f"{'clip':40s} {'frames':>6s} {'face':>5s} {'flicker':>8s} {'excess':>7s} {'H med':>6s}  status")
        for rec in result.records:
            row = {"source": rec["source"], "status": rec["status"]}
            if rec.get("stem") and (Path(out) / rec["stem"] / "relit.mp4").is_file():
                row.update(clip_steadiness(rec["source"], Path(out) / rec["stem"]))
            rows.append(row)
            print(_clip_line(row))
    _write_report(args.json, {"data": str(args.data), "rows": rows, "seconds": time.perf_counter() - t0})
    return 0


def _clip_line(row: dict) -> str:
    f = figure
    return (f"{Path(row['source']).name[:40]:40s} {f(row.get('frames'), 'd'):>6s} {f(row.get('with_face'), 'd'):>5s} "
            f"{f(row.get('flicker'), '.2f'):>8s} {f(row.get('excess_change'), '.2f'):>7s} "
            f"{f(row.get('h_median'), '.1f'):>6s}  {one_line(str(row['status']))[:60]}")


def _subjects(args: argparse.Namespace) -> list[str] | None:
    """``--subjects yaleB01,...`` as a list of names, or None (all)."""
    return [s.strip() for s in args.subjects.split(",") if s.strip()] if args.subjects else None


def cmd_eval_sweep(args: argparse.Namespace) -> int:
    """Each Yale B subject of ``--data`` (``--subjects``) lit from -70 to +70 degrees and back as a clip, run as
    ``shadowflow run`` runs a clip and its photos one by one (into ``--out``, kept; else a temporary folder), and
    scored against the real frontal photo (``evaluation.sweep``)."""
    from ...evaluation import sweep
    from ...evaluation.yaleb import subject_folders

    if not args.data:
        raise ValueError("eval sweep needs --data DIR (the folder holding yaleB01, yaleB02, ...)")
    folders = subject_folders(args.data, _subjects(args))
    t0, order, model = time.perf_counter(), sweep.sweep_order(), model_arg(args.model)
    with contextlib.ExitStack() as stack:
        out = Path(args.out or stack.enter_context(tempfile.TemporaryDirectory(prefix="shadowflow-sweep-")))
        rows = [_swept(folder, order, out, model) for folder in folders]
        print(sweep.format_table(rows))
    _write_report(args.json, {"data": str(args.data), "order": order, "rows": rows,
                              "seconds": time.perf_counter() - t0})
    return 0


def _swept(folder: Path, order: list[int], out: Path, model) -> dict:
    """One Yale B subject's sweep (``evaluation.sweep``) made, run into ``out/<subject>/`` and scored."""
    from ...evaluation import sweep
    from ...evaluation.yaleb import build_ground_truth
    from ..api import run

    subject = build_ground_truth(folder)
    work = out / subject.name
    (work / "clip").mkdir(parents=True, exist_ok=True)
    photos = sweep.sweep_photos(subject, order)
    clip = sweep.write_sweep_clip(photos, order, work / "clip" / f"sweep_{subject.name}.mkv")
    stills = {a: sweep.photo_path(subject, a) for a in photos}
    result = run([clip, *stills.values()], work / "run", model=model, options=MethodOptions(frames=True), record=(),
                 quiet=True)
    summary = {r.get("stem"): r for r in result.records}
    return sweep.score_sweep(subject, photos, order, work / "run" / clip.stem,
                             {a: work / "run" / p.stem for a, p in stills.items()}, summary)


def cmd_eval_shadows(args: argparse.Namespace) -> int:
    if not args.data:
        raise ValueError("eval shadows needs --data DIR (the folder holding yaleB01, yaleB02, ...)")
    model = model_arg(args.model)
    subjects = _subjects(args)
    t0 = time.perf_counter()
    print(one_line(f"shadows the face does not cast ({', '.join(foreign_shadows.KINDS)}) laid over Yale B photos, "
                   f"seed {args.seed}; relit frontally {'without' if args.not_looked_for else 'with'} "
                   "--foreign-shadows, the light known"))
    rows = foreign_shadows.evaluate(args.data, model, subjects, args.seed, looked_for=not args.not_looked_for)
    summary = foreign_shadows.summarise(rows)
    print(foreign_shadows.format_table(rows, summary))
    _write_report(args.json, {"rows": rows, "summary": summary, "seed": args.seed,
                              "seconds": time.perf_counter() - t0})
    return 0


def cmd_eval(args: argparse.Namespace) -> int:
    if args.dask is not None:
        parse_dask(args.dask)  # before any work
    if args.benchmark == "shadows":
        return cmd_eval_shadows(args)
    if args.benchmark == "yaleb":
        return cmd_eval_yaleb(args)
    if args.benchmark == "people":
        return cmd_eval_people(args)
    if args.benchmark == "clips":
        return cmd_eval_clips(args)
    if args.benchmark == "sweep":
        return cmd_eval_sweep(args)

    size = grid_size(args.size)
    at_least(args.n_test, 1, "--n-test")
    at_least(args.n_train, 2, "--n-train")
    angles = _light_angles(args.angles)
    t0 = time.perf_counter()
    if args.model:
        model = model_arg(args.model)
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
    print(table_header())
    with _mapper(args.dask) as mapper:  # one cluster for every fit compared
        for name in fits:
            opts = MethodOptions(fit=fit_config(name, None, albedo_rounds=args.albedo_rounds,
                                                 cone_trust=args.cone_trust),
                                 integrator=args.integrator, shadows=args.shadows, **fit_variant(args, name))
            res = evaluate(model, test, albedo, angles, opts, mapper=mapper)
            report["results"][name] = res["per_angle"]
            for angle, row in res["per_angle"].items():
                print(table_row(name, angle, row))
    report["seconds"] = time.perf_counter() - t0
    _write_report(args.json, report)
    return 0


def add_parser(sub) -> None:
    """``shadowflow eval``'s arguments."""
    e = sub.add_parser("eval", help="accuracy on rendered held-out faces, or on Yale B photos (eval yaleb)")
    e.add_argument("benchmark", nargs="?", choices=["synthetic", "yaleb", "people", "clips", "shadows", "sweep"],
                   default="synthetic",
                   help="synthetic (default): rendered faces of --source; yaleb: real photos in --data; people: "
                        "photos and clips of people in --data, scored without a reference (harm H, P); clips: "
                        "the clips in --data relit and measured for steadiness (flicker, excess change, H); "
                        "shadows: a brim's, leaves' and a hand's shadows laid over Yale B photos in --data, relit "
                        "frontally with --foreign-shadows (the share of each shadow removed); sweep: each Yale B "
                        "subject in --data lit from -70 to +70 degrees and back as a clip, relit frontally as a clip "
                        "and as stills, against the real frontal photo")
    e.add_argument("--subjects", metavar="yaleB01,...",
                   help="eval yaleb, shadows, sweep: only these subjects (default: all)")
    e.add_argument("--seed", type=int, default=0, help="eval shadows: the seed the shadows are drawn with (default 0)")
    e.add_argument("--not-looked-for", action="store_true",
                   help="eval shadows: relight without --foreign-shadows (what the rest of the relighting makes of "
                        "them)")
    e.add_argument("--data", help="eval yaleb, eval shadows, eval sweep: folder holding the yaleBxx subject "
                   "folders; eval people: a folder "
                   "of photos, or one holding photos/ and clips/; eval clips: a clip or a folder of clips")
    e.add_argument("--out", help="eval clips: run the clips into this folder and keep it (an earlier run there is "
                   "resumed, its clips measured again); eval sweep: the sweep clips and their runs, kept; default: a "
                   "temporary folder")
    e.add_argument("--clip-frames", type=int, default=3, metavar="N",
                   help="eval people: frames taken from each clip (default 3; 0: none)")
    e.add_argument("--foreign-shadows", action="store_true",
                   help="eval people, eval yaleb: relight as run --foreign-shadows does (shadows the face does not "
                        "cast looked for and lifted)")
    e.add_argument("--sheet", metavar="PNG", help="eval people: write a contact sheet of the worst faces here")
    e.add_argument("--worst", type=int, default=24, metavar="N", help="eval people: faces on the sheet (default 24)")
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
    e.add_argument("--remap", choices=CHOICES["remap"], help="as run --remap")
    e.add_argument("--albedo-rounds", type=int, metavar="N", help=ALBEDO_ROUNDS_HELP)
    e.add_argument("--cone-trust", type=float, metavar="C", help=CONE_TRUST_HELP)
    e.add_argument("--face-length", default="auto", metavar="auto|off|F", help="eval yaleb: " + FACE_LENGTH_HELP)
    e.add_argument("--integrator", choices=CHOICES["integrator"], default=MethodOptions.integrator, help="as run --integrator")
    e.add_argument("--shadows", choices=CHOICES["shadows"], default=MethodOptions.shadows, help="as run --shadows")
    e.add_argument("--albedo-fill", choices=CHOICES["albedo_fill"], help="as run --albedo-fill")
    e.add_argument("--lights", default="default", metavar="default|held-out|A,E;...",
                   help="eval yaleb: the input lights: the eight the method was tuned on (default), 23 it was not "
                        "(held-out; photos whose face is not found are left out and named), or Yale B's azimuth, "
                        "elevation pairs")
    e.add_argument("--json", help="write the report here")
    e.add_argument("--dask", nargs="?", const="env", metavar=DASK_METAVAR,
                   help="spread the faces and lights (synthetic) or the subjects (yaleb) over a Dask cluster; "
                        "the report is the same")
    e.set_defaults(func=cmd_eval)
