"""`lightcal warmup`: compile the numba kernels now (once per install), with progress.

Every command that needs the kernels does this itself when they are not cached yet;
running it ahead (scripts/setup.sh does) moves the wait to set-up time.
"""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "warmup",
        help="compile the numba kernels now (once per install) instead of in the first command",
        description=(
            "Compile and cache every numba kernel the commands and the app use, by running a "
            "tiny synthetic calibration per kernel family in a temporary folder. Takes one to "
            "a few minutes the first time, a second once cached."
        ),
    )
    p.add_argument(
        "--force", action="store_true", help="run the synthetic calibrations even when cached"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from lightcal.cli.progress import console, ensure_kernels
    from lightcal.warmup import kernels_ready, warm_up

    if args.force:
        seconds = warm_up()
        console.print(f"kernels ready ({seconds:.1f} s)", highlight=False)
        return 0
    if kernels_ready():
        console.print("kernels already compiled and cached", highlight=False)
        return 0
    ensure_kernels()
    return 0
