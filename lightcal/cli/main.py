"""The `lightcal` command: one subcommand per module of this package.

Each subcommand module defines `register(subparsers)`, which adds its parser and sets
`func` to a function taking the parsed arguments and returning the exit code. Errors in
the user's input (`LightcalError`) are caught here, once, and printed as one line.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from lightcal import __version__
from lightcal.errors import LightcalError

# Subcommand modules, in the order `lightcal --help` lists them.
SUBCOMMANDS = (
    "sample",
    "synth",
    "calibrate",
    "plan",
    "render",
    "schema",
    "init",
    "camera",
    "app",
    "warmup",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="lightcal",
        description="Calibrate the pose of a light source relative to the camera it is mounted on.",
    )
    parser.add_argument("--version", action="version", version=f"lightcal {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in SUBCOMMANDS:
        try:
            module = importlib.import_module(f"lightcal.cli.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"lightcal.cli.{name}":
                continue  # not built yet
            raise
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except LightcalError as exc:
        print(f"lightcal {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"lightcal {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
