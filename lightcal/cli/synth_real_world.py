"""`lightcal synth OUT_DIR --real-world`: photos as a user's camera gives them, no project.

The dataset of `lightcal.synthetic.real_world` (issue 25's rig): 8-bit sRGB JPEGs of four
AprilTags tag36h11 at the corners of a 1.2 x 0.7 m rectangle, a 14-degree beam that
overexposes the tag nearest its centre, the room light on, sensor noise; an exposure
bracket for `lightcal response`, camera.yaml, markers.yaml and truth.json. The scene is
the preset's: only --views, --width, --height, --seed, --force and --quiet apply; any other
option given is refused, naming it.
"""

from __future__ import annotations

import argparse
import sys

from lightcal.errors import InputError

__all__ = ["APPLIES", "register_real_world", "run_real_world"]

APPLIES = frozenset({"out_dir", "views", "width", "height", "seed", "force", "quiet", "real_world"})
"""The options (argparse dests) that apply with --real-world."""

_DEFAULTS = {"views": 8, "width": 800, "height": 600}
"""The preset's values of the options whose synth defaults suit the other datasets."""


def register_real_world(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--real-world",
        action="store_true",
        help="photos as a user's camera gives them, and no project (the path is lightcal "
        "response, init, calibrate): 8-bit sRGB JPEGs (quality 90) of four AprilTags "
        "tag36h11 at the corners of a 1.2 x 0.7 m rectangle (markers.yaml), a 14-degree beam "
        "that overexposes the tag nearest its centre, room light, sensor noise, EXIF "
        "exposure times; bracket/ holds 9 JPEGs of one view 1 stop apart for lightcal "
        "response; truth.json the light's pose. Only --views (8), --width (800), --height "
        "(600), --seed, --force and --quiet apply",
    )


def _given(args: argparse.Namespace, parser_defaults: dict[str, tuple[object, str]]) -> list[str]:
    """The options given that do not apply with --real-world."""
    return [
        option
        for dest, (default, option) in parser_defaults.items()
        if dest not in APPLIES and getattr(args, dest, default) != default
    ]


def run_real_world(args: argparse.Namespace, parser_defaults: dict[str, tuple[object, str]]) -> int:
    """Write the dataset; InputError naming an option that does not apply."""
    from pathlib import Path

    from lightcal.synthetic.real_world import RealWorldConfig, write_real_world

    refused = _given(args, parser_defaults)
    if refused:
        raise InputError(
            refused[0],
            "does not apply with --real-world (its scene is the preset's; --views, --width, "
            "--height, --seed, --force and --quiet do)",
        )
    given = {
        dest: getattr(args, dest)
        for dest in _DEFAULTS
        if getattr(args, dest) != parser_defaults[dest][0]
    }
    values = {**_DEFAULTS, **given}
    names = {"views": "--views", "width": "--width", "height": "--height", "seed": "--seed"}
    try:
        config = RealWorldConfig(
            width=values["width"],
            height=values["height"],
            n_views=values["views"],
            seed=args.seed,
        )
    except InputError as exc:
        source = {"n_views": "views"}.get(str(exc.source), str(exc.source))
        raise InputError(names.get(source, source), exc.detail) from exc
    if not args.out_dir.strip():
        raise InputError("OUT_DIR", f"expected the path of a dataset folder, got {args.out_dir!r}")

    def progress(line: str) -> None:
        print(f"lightcal synth: {line}", file=sys.stderr, flush=True)

    from lightcal.cli.progress import ensure_kernels
    from lightcal.synthetic.dataset_files import check_target

    check_target(Path(args.out_dir), force=args.force)  # before compiling and rendering
    ensure_kernels(quiet=args.quiet)
    dataset = write_real_world(
        args.out_dir, config, force=args.force, progress=None if args.quiet else progress
    )
    print(
        f"wrote {len(dataset.image_paths)} photos to {dataset.folder / 'images'}, a bracket of "
        f"{len(dataset.bracket_paths)} to {dataset.folder / 'bracket'}, {dataset.camera_path}, "
        f"{dataset.board_path} and {dataset.truth_path} (no project: lightcal response, init, "
        "calibrate)"
    )
    return 0
