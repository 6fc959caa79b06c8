"""The flip command's parser, built from the subcommands' modules, and its exit code."""
from __future__ import annotations

import argparse
import sys

from . import __doc__ as FLIP_DOC
from . import plan, record, request, run, sim, stand, study, summarize, sweep
from .common import EXIT_USAGE

#: the subcommands in the order `flip --help` lists them
SUBCOMMANDS = (run, sim, stand, plan, request, record, summarize, study, sweep)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="flip", description=FLIP_DOC.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    for module in SUBCOMMANDS:
        module.add_parser(sub)
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except SystemExit as e:
        # SystemExit("reason") is a refused argument (checked before anything starts): exit 2 as
        # argparse does, not Python's 1 (the code of "did not land")
        if isinstance(e.code, str):
            print(f"flip {args.cmd}: error: {e.code}", file=sys.stderr)
            return EXIT_USAGE
        raise
