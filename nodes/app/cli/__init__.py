"""``shadowflow`` command line: run, train, eval, replay, diff (see ``shadowflow COMMAND --help``); one
module a command, this one parses and dispatches."""
from __future__ import annotations

import argparse
import sys

from ..process import one_blas_thread
from ..runner import tool_version
from ..terminal import say
from . import evaluate, recordings, run, train
from .run import method_options, run_options

__all__ = ["build_parser", "main", "method_options", "run_options"]


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="shadowflow", description=__doc__)
    p.add_argument("--version", action="version", version=f"shadowflow {tool_version()}")
    sub = p.add_subparsers(dest="command", required=True)
    run.add_parser(sub)
    train.add_parser(sub)
    evaluate.add_parser(sub)
    recordings.add_parsers(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        with one_blas_thread():  # train, eval: the same small matrices
            return int(args.func(args) or 0)
    except (ValueError, OSError, RuntimeError) as exc:
        say(f"shadowflow {args.command}: {exc}")  # one line, whatever the exception's text holds
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
