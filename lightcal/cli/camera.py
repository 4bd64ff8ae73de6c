"""`lightcal camera calibrate | import`: camera intrinsics files.

- `lightcal camera calibrate IMAGES... --board BOARD --out camera.yaml [--n-dist 5] [--force]`:
  intrinsics from views of a chessboard or ChArUco board
  (`lightcal.capture.intrinsics.calibrate_intrinsics`); prints the reprojection RMS of every
  view used and the reason for every view rejected, and writes an OpenCV-compatible YAML
  (or XML, or JSON, by the suffix of `--out`).
- `lightcal camera import FILE --out camera.yaml [--force]`: converts an OpenCV
  YAML/XML/JSON file or a COLMAP cameras.txt (principal point shifted by half a pixel, see
  `lightcal.io.camera_file.read_camera`) to the format of `--out`.

IMAGES may name files or folders (every image directly in a folder, sorted by name;
a photo named twice is refused). Images are read as grey values (camera raw: demosaiced
luminance at full size); 8-bit images need no response curve here, only the corners matter.

Every option is checked before any photo is read (`--out`'s suffix and place,
`--max-rms-px`, `--camera-id`). `--out` never replaces an existing file without `--force`,
and never an input (the board, a photo, the imported file), even with it. Photos that
cannot determine the intrinsics are refused (copies of one view, the board at fewer than 3
different angles) or warned about (the board nearly square-on in every view): see
`lightcal.capture.view_variety`.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import TYPE_CHECKING

from lightcal.errors import InputError

if TYPE_CHECKING:
    from lightcal.core.camera import Camera

CAMERA_SUFFIXES = (".yaml", ".yml", ".xml", ".json")
"""Suffixes `lightcal.io.camera_file.write_camera` writes (`--out`)."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("camera", help="calibrate or import camera intrinsics")
    actions = p.add_subparsers(dest="camera_command", metavar="ACTION", required=True)

    c = actions.add_parser(
        "calibrate",
        help="intrinsics from images of a chessboard or ChArUco board",
        description=(
            "Find the board's corners in every image, calibrate the camera "
            "(cv2.calibrateCamera), reject views with a poor fit and write the intrinsics."
        ),
    )
    c.add_argument("images", type=Path, nargs="+", metavar="IMAGES", help="image files or folders")
    c.add_argument("--board", type=Path, required=True, help="board file (chessboard, charuco)")
    c.add_argument(
        "--out", type=Path, required=True, help="camera file to write (.yaml, .yml, .xml, .json)"
    )
    c.add_argument(
        "--force", action="store_true", help="replace an existing --out file (never an input)"
    )
    c.add_argument(
        "--n-dist",
        type=int,
        choices=(4, 5, 8),
        default=5,
        help="distortion coefficients to fit: 4 (k1 k2 p1 p2), 5 (+k3), 8 (rational) (5)",
    )
    c.add_argument(
        "--max-rms-px",
        type=float,
        default=1.0,
        help="views above max(3 x median, this) reprojection RMS are rejected (1)",
    )
    c.set_defaults(func=run_calibrate)

    i = actions.add_parser(
        "import",
        help="convert an OpenCV YAML/XML/JSON file or a COLMAP cameras.txt",
        description="Read a camera file and write it in the format of --out's suffix.",
    )
    i.add_argument("file", type=Path, metavar="FILE", help="camera file to read")
    i.add_argument(
        "--out", type=Path, required=True, help="camera file to write (.yaml, .yml, .xml, .json)"
    )
    i.add_argument(
        "--force", action="store_true", help="replace an existing --out file (never FILE)"
    )
    i.add_argument(
        "--camera-id", type=int, default=None, help="COLMAP: which camera of cameras.txt"
    )
    i.set_defaults(func=run_import)


def _check_out_suffix(out: Path) -> None:
    """`--out` in a format `write_camera` writes (its own message), before any work."""
    if out.suffix.lower() not in CAMERA_SUFFIXES:
        raise InputError(
            out, f"unsupported file suffix {out.suffix!r}: expected .yaml, .yml, .xml or .json"
        )


def _write(camera: Camera, out: Path, *, force: bool) -> None:
    """`write_camera` to `--out`: replacing an existing file only with `--force` (one that
    appeared since the check is refused too, never replaced)."""
    from lightcal.io.camera_file import write_camera

    try:
        write_camera(camera, out, replace=force)
    except FileExistsError:
        raise InputError(out, "--out: exists; use --force to replace it") from None


def _expand(inputs: list[Path]) -> list[Path]:
    """Files as given; folders replaced by their image files (sorted). A photo reached
    twice (named twice, or named and in a folder named) is refused: it would count as
    two views."""
    from lightcal.capture.project_init import list_images

    paths: list[Path] = []
    for item in inputs:
        if item.is_dir():
            paths += list_images(item)
        elif item.exists():
            paths.append(item)
        else:
            raise InputError(item, "image file not found")
    seen: set[Path] = set()
    for path in paths:
        if path.resolve() in seen:
            raise InputError(
                path, "given twice: expected each photo once (a copy adds no information)"
            )
        seen.add(path.resolve())
    return paths


def _display_names(paths: list[Path]) -> list[str]:
    """File names, or the paths as given where two files share a name."""
    names = [p.name for p in paths]
    return [p.name if names.count(p.name) == 1 else str(p) for p in paths]


def _describe(camera: Camera) -> str:
    dist = ", ".join(f"{v:+.5f}" for v in camera.dist_opencv)
    return (
        f"fx {camera.fx:.3f} px, fy {camera.fy:.3f} px, cx {camera.cx:.3f} px, "
        f"cy {camera.cy:.3f} px, {camera.width}x{camera.height}, distortion [{dist}]"
    )


def _describe_sigma(camera: Camera) -> str:
    cov = camera.intrinsics_covariance
    if cov is None:
        return "1-sigma: unknown"
    sigma = [math.sqrt(max(float(cov[k, k]), 0.0)) for k in range(cov.shape[0])]
    dist = ", ".join(f"{v:.5f}" for v in sigma[4:])
    return (
        f"1-sigma: fx {sigma[0]:.3f} px, fy {sigma[1]:.3f} px, cx {sigma[2]:.3f} px, "
        f"cy {sigma[3]:.3f} px, distortion [{dist}] (the full covariance is in the file)"
    )


def run_calibrate(args: argparse.Namespace) -> int:
    from lightcal.capture.boards import ArucoGridBoard, CharucoBoard, Chessboard
    from lightcal.capture.intrinsics import calibrate_intrinsics
    from lightcal.io.board_file import read_board
    from lightcal.io.images import read_image
    from lightcal.io.outputs import check_output_file

    # Before any work: every option's value (--out: below, once the inputs are known).
    if not (math.isfinite(args.max_rms_px) and args.max_rms_px > 0.0):
        raise InputError(
            "--max-rms-px", f"expected a finite value > 0 pixels, got {args.max_rms_px:g}"
        )
    board = read_board(args.board)
    if not isinstance(board, Chessboard | CharucoBoard):
        what = "an ArUco grid" if isinstance(board, ArucoGridBoard) else "a markers board"
        raise InputError(
            args.board,
            f"{what} gives too few points per view for intrinsics: expected a "
            "chessboard or charuco board",
        )
    paths = _expand(list(args.images))
    all_names = _display_names(paths)
    # Before any work: --out is never the board file or one of the photos it reads.
    inputs = {args.board.resolve(): "the board file"}
    for path, name in zip(paths, all_names, strict=True):
        inputs.setdefault(path.resolve(), f"image {name}")
    check_output_file(
        args.out, option="--out", inputs=inputs, force=args.force, inputs_of="the calibration"
    )
    _check_out_suffix(args.out)
    images = []
    names = []
    unreadable: dict[str, str] = {}
    for path, name in zip(paths, all_names, strict=True):
        try:
            image = read_image(path, channel="luminance", assume_linear=True)
        except InputError as exc:
            unreadable[name] = exc.detail
            continue
        images.append(image.values)
        names.append(name)
    try:
        result = calibrate_intrinsics(
            images, board, n_dist=args.n_dist, max_rms_px=args.max_rms_px, sources=names
        )
    except InputError:
        for name, reason in unreadable.items():
            print(f"{name}: rejected: {reason}")
        raise
    rms = dict(zip(result.used, result.per_image_rms_px, strict=True))
    reasons = {**dict(result.rejected), **unreadable}
    for name in all_names:
        if name in rms:
            print(f"{name}: reprojection RMS {rms[name]:.3f} px")
        else:
            print(f"{name}: rejected: {reasons[name]}")
    for warning in result.warnings:
        print(f"warning: {warning}")
    _write(result.camera, args.out, force=args.force)
    print(_describe(result.camera))
    print(_describe_sigma(result.camera))
    print(
        f"{len(result.used)} views used, {len(all_names) - len(result.used)} rejected, "
        f"reprojection RMS {result.rms_px:.3f} px; camera written to {args.out}"
    )
    return 0


def run_import(args: argparse.Namespace) -> int:
    from lightcal.io.camera_file import read_camera
    from lightcal.io.outputs import check_output_file

    if args.camera_id is not None and args.file.suffix.lower() != ".txt":
        raise InputError(
            "--camera-id",
            f"applies only to a COLMAP cameras.txt, got {args.file.name} (it holds one camera)",
        )
    inputs = {args.file.resolve(): "the camera file"}
    check_output_file(
        args.out, option="--out", inputs=inputs, force=args.force, inputs_of="the import"
    )
    _check_out_suffix(args.out)
    try:
        camera = read_camera(args.file, camera_id=args.camera_id)
    except InputError as exc:  # the reader names its argument camera_id: say the option
        if "camera_id" not in exc.detail:
            raise
        detail = exc.detail.replace("camera_id", "--camera-id")
        raise InputError(exc.source, detail, line=exc.line) from exc
    _write(camera, args.out, force=args.force)
    print(_describe(camera))
    print(f"camera written to {args.out}")
    return 0
