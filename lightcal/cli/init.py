"""`lightcal init IMAGE_DIR --camera CAM --board BOARD [--board ...]`: a project from photos.

Detects the board in every image, prints one line per image (markers, reprojection RMS
and camera position, or why it was rejected), writes the marker masks and the project
file (see `lightcal.capture.project_init`).

Every option is checked before any image is read (`check_options`; `--min-markers` against
the board's markers once `init_project` has read the board file; the messages name the
option as typed, and the initial light must fit the project file's bounds), and so are the
outputs (never an input, never replacing a project or masks without `--force`). A run
that fails or is interrupted part-way leaves no project and no `masks/` behind
(`lightcal.capture.mask_staging`).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from lightcal.cli.arguments import path_arg
from lightcal.errors import InputError

PROJECT_SUFFIXES = (".json", ".yaml", ".yml")
"""Suffixes of `--out`: JSON, or YAML for .yaml/.yml."""

GAMMA_ENCODED = (
    "8-bit image values are gamma-encoded by the camera, not proportional to light: give "
    "the camera's response curve with --response FILE (fitted from an exposure bracket by "
    "lightcal response), or --assume-linear if the camera wrote linear values"
)
"""What init says of an 8-bit photo given without --response or --assume-linear."""

MAX_MASK_MARGIN_PX = 100.0
"""Largest `--mask-margin-px`: a wider padding would mask most of the wall (and dilating
by it takes long)."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "init",
        help="assemble a project from a folder of images of the wall with markers",
        description=(
            "Detect the board's markers in every image of IMAGE_DIR, estimate each camera "
            "pose, reject images with too few markers, write masks over the markers "
            "(masks/ beside the project) and the project file."
        ),
    )
    p.add_argument("image_dir", type=Path, metavar="IMAGE_DIR", help="folder of images")
    p.add_argument("--camera", type=Path, required=True, help="camera file (intrinsics)")
    p.add_argument(
        "--board",
        type=Path,
        action="append",
        required=True,
        help="board file (aruco_grid, charuco or markers); repeat it for several boards on "
        "the wall (no marker on two boards)",
    )
    light = p.add_mutually_exclusive_group()
    light.add_argument(
        "--light-ies", type=Path, metavar="FILE", help="the light's IES (.ies) or EULUMDAT (.ldt)"
    )
    light.add_argument(
        "--half-angle-deg",
        type=float,
        default=None,
        help="the light's half-intensity angle, degrees (default 30 without --light-ies)",
    )
    p.add_argument(
        "--initial-position",
        type=float,
        nargs=3,
        default=None,
        metavar=("X", "Y", "Z"),
        help="initial light position in the camera frame (x right, y down, z forward), metres "
        "(default: with --initial-axis 0 0 0, else initial: auto, the guess from the beam)",
    )
    p.add_argument(
        "--initial-axis",
        type=float,
        nargs=3,
        default=None,
        metavar=("X", "Y", "Z"),
        help="initial light axis in the camera frame (default: with --initial-position 0 0 1, "
        "the optical axis, else initial: auto, the guess from the beam in the photos)",
    )
    p.add_argument("--out", type=Path, default=Path("project.json"), help="project file to write")
    p.add_argument(
        "--force",
        action="store_true",
        help="replace an existing --out project and the masks beside it",
    )
    p.add_argument("--min-markers", type=int, default=4, help="fewest markers per image (4)")
    p.add_argument(
        "--mask-margin-px", type=float, default=3.0, help="padding of the marker masks (3)"
    )
    p.add_argument(
        "--max-rms-px", type=float, default=1.0, help="largest marker reprojection RMS (1)"
    )
    linear = p.add_mutually_exclusive_group()
    linear.add_argument(
        "--assume-linear",
        action="store_true",
        help="take 8-bit photos (JPEG, 8-bit PNG/TIFF) as linear (written to the project)",
    )
    linear.add_argument(
        "--response",
        type=path_arg,
        metavar="FILE",
        help="the camera's response curve (from lightcal response) that linearises 8-bit "
        "photos (written to the project)",
    )
    p.add_argument("--black-level", type=float, default=None, help="black level of the images")
    p.add_argument("--white-level", type=float, default=None, help="white level of the images")
    p.add_argument(
        "--pose-floor-mm",
        type=float,
        default=0.5,
        help="systematic error of marker poses added to each pose's covariance, per camera "
        "centre coordinate (0.5 mm)",
    )
    p.add_argument(
        "--pose-floor-deg",
        type=float,
        default=0.05,
        help="the same for each rotation component (0.05 deg)",
    )
    p.set_defaults(func=run)


def _numbers(values: list[float] | tuple[float, ...]) -> str:
    return " ".join(f"{v:g}" for v in values)


def check_options(args: argparse.Namespace) -> None:
    """Every option's value, before any work; raises InputError naming the option.
    (`--out` and the masks folder: `run`, once the inputs are known.)"""
    for option, value, unit in (
        ("--pose-floor-mm", args.pose_floor_mm, "mm"),
        ("--pose-floor-deg", args.pose_floor_deg, "degrees"),
    ):
        if not (math.isfinite(value) and value >= 0.0):
            raise InputError(option, f"expected a finite value >= 0 {unit}, got {value:g}")
    if args.min_markers < 1:
        raise InputError("--min-markers", f"expected an integer >= 1, got {args.min_markers}")
    margin = args.mask_margin_px
    if not (math.isfinite(margin) and 0.0 <= margin <= MAX_MASK_MARGIN_PX):
        raise InputError(
            "--mask-margin-px",
            f"expected a padding of 0 to {MAX_MASK_MARGIN_PX:g} pixels, got {margin:g}",
        )
    if not (math.isfinite(args.max_rms_px) and args.max_rms_px > 0.0):
        raise InputError(
            "--max-rms-px", f"expected a finite value > 0 pixels, got {args.max_rms_px:g}"
        )
    half = args.half_angle_deg
    if half is not None and not (math.isfinite(half) and 0.0 < half < 90.0):
        raise InputError("--half-angle-deg", f"expected a value in (0, 90) degrees, got {half:g}")
    for option, values, unit in (
        ("--initial-position", args.initial_position or (0.0, 0.0, 0.0), " (metres)"),
        ("--initial-axis", args.initial_axis or (0.0, 0.0, 1.0), ""),
    ):
        if not all(math.isfinite(v) for v in values):
            raise InputError(option, f"expected three finite numbers{unit}, got {_numbers(values)}")
    from lightcal.capture.init_checks import axis_problem, position_problem

    position = args.initial_position or (0.0, 0.0, 0.0)
    axis = args.initial_axis or (0.0, 0.0, 1.0)
    for option, values, problem in (
        ("--initial-position", position, position_problem(position)),
        ("--initial-axis", axis, axis_problem(axis)),
    ):
        if problem is not None:
            raise InputError(option, f"{problem}, got {_numbers(values)}")
    black, white = args.black_level, args.white_level
    if black is not None and not (math.isfinite(black) and black >= 0.0):
        raise InputError("--black-level", f"expected a finite value >= 0, got {black:g}")
    if white is not None and not (math.isfinite(white) and white > 0.0):
        raise InputError("--white-level", f"expected a finite value > 0, got {white:g}")
    if black is not None and white is not None and not white > black:
        raise InputError(
            "--white-level", f"expected a value above --black-level ({black:g}), got {white:g}"
        )
    if args.response is not None and white is not None:
        raise InputError(
            "--white-level", "with --response the white level is code 255; do not give one"
        )


def run(args: argparse.Namespace) -> int:
    from lightcal.capture.project_init import GammaEncodedImage, ImageOutcome, init_project

    def on_image(outcome: ImageOutcome) -> None:
        print(outcome.report_line(), flush=True)

    from lightcal.capture.project_init import MASKS_DIR
    from lightcal.io.outputs import check_output_file, check_output_folder

    # Before any work: every option's value; the project and its masks never replace
    # existing ones without --force, and never an input (the photos, camera, board and
    # light files).
    check_options(args)
    inputs = {
        p.resolve(): f"input {p.name}"
        for p in [args.camera, *args.board, args.light_ies, args.response]
        + (sorted(args.image_dir.iterdir()) if args.image_dir.is_dir() else [])
        if p is not None and p.is_file()
    }
    check_output_file(args.out, option="--out", inputs=inputs, force=args.force)
    if args.out.suffix.lower() not in PROJECT_SUFFIXES:
        raise InputError(
            args.out,
            f"--out: unsupported project file suffix {args.out.suffix!r}: expected .json, "
            ".yaml or .yml",
        )
    masks = args.out.parent / MASKS_DIR
    if masks.exists():
        check_output_folder(masks, option="the masks folder", inputs=inputs, force=args.force)
    try:
        result = init_project(
            args.image_dir,
            camera_path=args.camera,
            board_path=args.board if len(args.board) > 1 else args.board[0],
            out_path=args.out,
            light_file=args.light_ies,
            half_angle_deg=args.half_angle_deg,
            initial_position_m=args.initial_position,
            initial_axis_camera=args.initial_axis,
            min_markers=args.min_markers,
            mask_margin_px=args.mask_margin_px,
            max_rms_px=args.max_rms_px,
            black_level=args.black_level,
            white_level=args.white_level,
            assume_linear=args.assume_linear,
            response_path=args.response,
            pose_floor_m=args.pose_floor_mm / 1000.0,
            pose_floor_deg=args.pose_floor_deg,
            on_image=on_image,
        )
    except GammaEncodedImage as exc:
        raise InputError(exc.source, GAMMA_ENCODED) from exc
    except InputError as exc:  # checked against the board once it is read, before any image
        if exc.source != "min_markers":
            raise
        raise InputError("--min-markers", exc.detail) from exc
    for warning in result.warnings:
        print(f"warning: {warning}")
    n_ok, n_all = len(result.accepted), len(result.images)
    print(
        f"{n_ok} of {n_all} images accepted, {n_all - n_ok} rejected; masks in "
        f"{result.project_path.parent / 'masks'}; project written to {result.project_path}"
    )
    return 0
