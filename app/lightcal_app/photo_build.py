"""Build a project from a staging area's files, as `lightcal camera calibrate` and
`lightcal init` do (the build of `lightcal_app.photo_project.PhotoStaging`).

`build_project` takes the intrinsics from the chessboard photos first when no camera file
was given (`lightcal.capture.intrinsics.calibrate_intrinsics`, written as `camera.yaml`
beside the project), then runs `lightcal.capture.project_init.init_project` on the wall
photos, telling `progress` each image ("image 3 of 12"), and reads the new project's
images (`lightcal.pipeline.load_images`). Its errors name what the page knows (the
photo, "wall photos", "chessboard photos"), never the server's folders.

The staging area's layout is defined here: one folder per kind of file.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from lightcal.capture.boards import CharucoBoard, Chessboard
from lightcal.capture.intrinsics import calibrate_intrinsics
from lightcal.capture.project_init import ImageOutcome, init_project
from lightcal.errors import InputError
from lightcal.io.board_file import read_board
from lightcal.io.camera_file import write_camera
from lightcal.io.images import read_image
from lightcal.io.project import load_project
from lightcal.pipeline import load_images
from lightcal_app.photo_records import (
    CameraSource,
    PhotoBuild,
    PhotoOptions,
    PhotoOutcome,
    Staged,
)

# The staging area's folders: one per kind of file (a board's by its type).
WALL_DIR, CHESSBOARD_DIR, CAMERA_DIR, LIGHT_DIR = "photos", "chessboard", "camera", "light"
BOARD_DIRS = {
    "aruco_grid": "board-aruco_grid",
    "charuco": "board-charuco",
    "chessboard": "board-chessboard",
}
BUILD_PREFIX = "build-"
"""Each build writes its project into a fresh `build-<id>/` folder of the area."""

Progress = Callable[[str], None]
"""`progress(text)`: what the build does now, in a few words ("image 3 of 12")."""


def build_project(
    area: Path, out_dir: Path, staged: Staged, progress: Progress, options: PhotoOptions
) -> PhotoBuild:
    """Build the project of the staging area `area` into `out_dir` (an empty folder of it).

    Args:
        area: the staging area's folder (its layout: the `*_DIR` names above).
        out_dir: where the project, its masks and a calibrated camera file go.
        staged: what the area holds (complete: `staged.missing` is empty).
        progress: told each step.
        options: `lightcal init`'s choices besides the files.

    Raises:
        InputError: the chessboard photos give no intrinsics, no wall photo is usable, or
            the initial guess is behind the wall (named as the page knows them).
    """
    if staged.camera is not None:
        camera_path = area / CAMERA_DIR / staged.camera
        camera = CameraSource(staged.camera)
    else:
        camera_path, camera = _calibrate(area, out_dir, staged, progress)
    wall_board = staged.wall_board
    assert wall_board is not None
    board_path = area / BOARD_DIRS[wall_board[0]] / wall_board[1]
    light = None if staged.light is None else area / LIGHT_DIR / staged.light
    # Without a light file nor a half angle, init_project takes 30 degrees and says so.
    half = options.half_angle_deg if light is None else None
    n = len(staged.wall_photos)
    done = [0]

    def on_image(outcome: ImageOutcome) -> None:
        done[0] += 1
        if done[0] < n:
            progress(f"image {done[0] + 1} of {n}")

    progress(f"image 1 of {n}")
    try:
        result = init_project(
            area / WALL_DIR,
            camera_path=camera_path,
            board_path=board_path,
            out_path=out_dir / "project.json",
            light_file=light,
            half_angle_deg=half,
            initial_position_m=options.initial_position_m,
            initial_axis_camera=options.initial_axis_camera,
            min_markers=options.min_markers,
            black_level=options.black_level,
            white_level=options.white_level,
            on_image=on_image,
        )
    except InputError as exc:
        raise _build_error(exc, area) from exc
    photos = tuple(PhotoOutcome.of(o) for o in result.images)
    progress(f"reading the {len(result.accepted)} accepted images")
    project = load_project(result.project_path)
    loaded = load_images(project)
    return PhotoBuild(project, loaded, photos, camera, tuple(result.warnings))


def _calibrate(
    area: Path, out_dir: Path, staged: Staged, progress: Progress
) -> tuple[Path, CameraSource]:
    """The intrinsics from the chessboard photos, as `lightcal camera calibrate`."""
    board_entry = staged.chessboard_board
    assert board_entry is not None
    board = read_board(area / BOARD_DIRS[board_entry[0]] / board_entry[1])
    assert isinstance(board, Chessboard | CharucoBoard)
    images = []
    names = []
    unreadable: list[tuple[str, str]] = []
    n = len(staged.chessboard_photos)
    for k, name in enumerate(staged.chessboard_photos):
        progress(f"reading chessboard photo {k + 1} of {n}")
        try:
            image = read_image(
                area / CHESSBOARD_DIR / name, channel="luminance", assume_linear=True
            )
        except InputError as exc:
            unreadable.append((name, exc.detail))
            continue
        images.append(image.values)
        names.append(name)
    progress(f"calibrating the camera from {len(images)} chessboard photos")
    try:
        result = calibrate_intrinsics(images, board, sources=names)
    except InputError as exc:
        reasons = "".join(f"; {p}: {why}" for p, why in unreadable)
        raise InputError("chessboard photos", exc.detail + reasons) from exc
    path = out_dir / "camera.yaml"
    write_camera(result.camera, path)
    order = {name: i for i, name in enumerate(staged.chessboard_photos)}
    rejected = sorted([*result.rejected, *unreadable], key=lambda item: order[item[0]])
    return path, CameraSource(None, result.rms_px, result.used, tuple(rejected))


def _build_error(exc: InputError, area: Path) -> InputError:
    """`init_project`'s error with the staging area's paths as the page knows them."""
    source = Path(exc.source)
    try:
        rel = source.resolve().relative_to(area.resolve())
    except (ValueError, OSError):
        return exc
    parts = rel.parts
    if parts and parts[0] == WALL_DIR:
        where = "wall photos" if len(parts) == 1 else parts[-1]
    elif parts and parts[0].startswith(BUILD_PREFIX):
        where = "new project"
    else:
        where = parts[-1] if parts else "new project"
    detail = exc.detail.replace(str(area.resolve()) + "/", "").replace(str(area) + "/", "")
    return InputError(where, detail)
