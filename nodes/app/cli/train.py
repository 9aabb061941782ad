"""``shadowflow train``: a needle-map model from a face source."""
from __future__ import annotations

import argparse
import time

from ....flow.replay.text import one_line
from ...model.default_model import train_from_recipe
from ...model.shape_model import save_model
from ...model.sources import SOURCES_HELP
from .arguments import at_least, grid_size


def cmd_train(args: argparse.Namespace) -> int:
    size = list(grid_size(args.size))
    at_least(args.n, 2, "--n")
    at_least(args.modes, 1, "--modes")
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
    print(one_line(f"trained {model.n_modes} modes over {model.n_pixels} pixels from {args.n} faces of {args.source} "
                   f"in {time.perf_counter() - t0:.1f} s -> {args.out}"))
    return 0


def add_parser(sub) -> None:
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
