"""`lightcal sample PATH [--force]`: write the bundled sample project into PATH.

The sample (`sample_data/` of the repository, package data when installed; see
`lightcal.resources`) is 12 photographs of a wall lit by an LED beside the camera, with
the camera file, the light's IES file, the marker masks, the board files, the
chessboard views for the intrinsics and the ground truth. PATH must be new or empty;
`--force` writes into a non-empty folder but only the files missing there: nothing is
ever overwritten.
"""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from lightcal.errors import InputError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "sample",
        help="write the bundled sample project (photos, camera, light, truth) into a folder",
        description=(
            "Copy the bundled sample calibration project into PATH (new or empty) and print "
            "the commands that calibrate it and open it in the app."
        ),
    )
    p.add_argument("path", metavar="PATH", help="folder to write (new or empty)")
    p.add_argument(
        "--force",
        action="store_true",
        help="write into a non-empty folder: add the sample's missing files, keep every "
        "existing file as it is",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from lightcal.resources import write_sample_project

    if not args.path.strip():  # ("" would be the current folder)
        raise InputError("PATH", f"expected the path of a folder to write, got {args.path!r}")
    for parent in Path(args.path).parents:  # the nearest existing one must be a folder
        if parent.exists():
            if not parent.is_dir():
                raise InputError(
                    args.path, f"{parent} is a file, not a folder; choose a new folder"
                )
            break
    try:
        copy = write_sample_project(Path(args.path), force=args.force)
    except OSError as exc:  # (the OS names the hidden folder the copy is staged in)
        raise InputError(
            args.path, f"cannot write the sample project there: {exc.strerror or exc}"
        ) from exc
    print(f"lightcal sample: wrote {_files(len(copy.written))} to {copy.folder}")
    if copy.kept:
        shown = ", ".join(p.as_posix() for p in copy.kept[:5])
        more = f" and {len(copy.kept) - 5} more" if len(copy.kept) > 5 else ""
        print(f"lightcal sample: kept {_files(len(copy.kept))} as they were: {shown}{more}")
    print(next_steps(copy.folder / "project.json"))
    return 0


def next_steps(project: Path) -> str:
    """The commands to run on the sample project next."""
    name = shlex.quote(str(project))
    return f"next:\n  lightcal calibrate {name} --out result.json\n  lightcal app {name}"


def _files(n: int) -> str:
    return f"{n} file" if n == 1 else f"{n} files"
