"""Build a project from a staging area's files, as `lightcal camera calibrate` and
`lightcal init` do (the build of `lightcal_app.photo_project.PhotoStaging`).

`build_project` takes the intrinsics from the chessboard photos first when no camera file
was given (`lightcal.capture.intrinsics.calibrate_intrinsics`, written as `camera.yaml`
beside the project), then runs `lightcal.capture.project_init.init_project` on the wall
photos, telling `progress` each image ("image 3 of 12"), and reads the new project's
images (`lightcal.pipeline.load_images`). Its errors name what the page knows (the
photo, "wall photos", "chessboard photos"), never the server's folders.

`read_levels` reads the black and white levels a photo's file gives (what the page's
level fields are prefilled with); `project_zip_bytes` packs a built project with every
file it reads (and the board files) into a zip that `lightcal calibrate` takes unpacked.

The staging area's layout is defined here: one folder per kind of file.
"""

from __future__ import annotations

import io
import json
import zipfile
from collections.abc import Callable
from pathlib import Path

from lightcal.capture.boards import CharucoBoard, Chessboard
from lightcal.capture.init_checks import markers_problem
from lightcal.capture.intrinsics import calibrate_intrinsics
from lightcal.capture.project_init import GammaEncodedImage, ImageOutcome, init_project
from lightcal.errors import InputError
from lightcal.io.board_file import read_board
from lightcal.io.camera_file import write_camera
from lightcal.io.images import RAW_EXTENSIONS, read_image
from lightcal.io.project import load_project
from lightcal.pipeline import load_images
from lightcal_app.photo_records import (
    LABELS,
    CameraSource,
    FileLevels,
    PhotoBuild,
    PhotoOptions,
    PhotoOutcome,
    Staged,
)

# The staging area's folders: one per kind of file (a board's by its type).
WALL_DIR, CHESSBOARD_DIR, CAMERA_DIR, LIGHT_DIR = "photos", "chessboard", "camera", "light"
RESPONSE_DIR = "response"
BOARD_DIRS = {
    "aruco_grid": "board-aruco_grid",
    "markers": "board-markers",
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
    board_paths = [area / BOARD_DIRS[kind] / name for kind, name in staged.wall_boards]
    assert board_paths
    _check_min_markers(board_paths, options.min_markers)
    response = None if staged.response is None else area / RESPONSE_DIR / staged.response
    if staged.camera is not None:
        camera_path = area / CAMERA_DIR / staged.camera
        camera = CameraSource(staged.camera)
    else:
        camera_path, camera = _calibrate(area, out_dir, staged, progress)
    light = None if staged.light is None else area / LIGHT_DIR / staged.light
    # Without a light file nor a half angle, init_project estimates the cos^m exponent
    # from 30 degrees and says so.
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
            board_path=board_paths,
            out_path=out_dir / "project.json",
            light_file=light,
            half_angle_deg=half,
            initial_position_m=options.initial_position_m,
            initial_axis_camera=options.initial_axis_camera,
            min_markers=options.min_markers,
            mask_margin_px=options.mask_margin_px,
            max_rms_px=options.max_rms_px,
            black_level=options.black_level,
            white_level=options.white_level,
            assume_linear=options.assume_linear and response is None,
            response_path=response,
            pose_floor_m=options.pose_floor_m,
            pose_floor_deg=options.pose_floor_deg,
            on_image=on_image,
        )
    except GammaEncodedImage as exc:
        raise InputError(
            _build_error(exc, area).source,
            "8-bit photos are gamma-encoded by the camera, not proportional to light: upload "
            "the camera's response curve (Response curve button; lightcal response makes it "
            f"from an exposure bracket), or tick '{LABELS['assume_linear']}' if the camera "
            "wrote linear values",
        ) from exc
    except InputError as exc:
        raise _build_error(exc, area) from exc
    photos = tuple(PhotoOutcome.of(o) for o in result.images)
    progress(f"reading the {len(result.accepted)} accepted images")
    project = load_project(result.project_path)
    loaded = load_images(project)
    boards = set(board_paths)
    if staged.calibrates_camera and staged.chessboard_board is not None:
        kind, name = staged.chessboard_board
        boards.add(area / BOARD_DIRS[kind] / name)
    warnings = [*result.warnings]
    if staged.levels is not None and options.black_level is None:
        warnings.extend(black_level_warning(staged.levels))
    return PhotoBuild(project, loaded, photos, camera, tuple(warnings), tuple(sorted(boards)))


DARK_FRACTION = 0.02
"""A photo without a black level whose darkest value is above this fraction of its
brightest is warned of: a wall photo's darkest pixels are the print (albedo about 0.05)
far from the light, a small fraction of the lit wall, unless a black offset lifts them
(the sample's photos: 537 of 11836, 4.5 %, from its black level 512)."""


def black_level_warning(levels: FileLevels) -> list[str]:
    """A note when the photos' files give black level 0 and their darkest values suggest
    an offset that would be taken for light."""
    dark, bright = levels.darkest, levels.brightest
    if levels.raw or levels.black != 0.0 or dark is None or bright is None or bright <= 0.0:
        return []
    if dark <= DARK_FRACTION * bright:
        return []
    return [
        f"black level 0, while the darkest value of {levels.photo} is {dark:g} "
        f"({100.0 * dark / bright:.1f} % of its brightest, {bright:g}): if the sensor has a "
        "black level (most 14-bit sensors: 512 or so), enter it and build again, or the "
        "offset is taken for light and the light's position is wrong"
    ]


def _check_min_markers(board_paths: list[Path], min_markers: int) -> None:
    """The fewest markers against the wall boards', before any work (as `lightcal init`)."""
    boards = [read_board(path) for path in board_paths]
    marker_boards = [b for b in boards if not isinstance(b, Chessboard)]
    if len(marker_boards) == len(boards):  # else init_project says
        problem = markers_problem(min_markers, marker_boards)
        if problem is not None:
            raise InputError(LABELS["min_markers"], f"{problem}, got {min_markers}")


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
    source = CameraSource(None, result.rms_px, result.used, tuple(rejected), tuple(result.warnings))
    return path, source


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


def read_levels(path: Path) -> FileLevels:
    """The black and white levels the photo `path` gives, as `read_image` applies them
    without any given: a camera raw file's (its metadata, through rawpy), else 0 and
    2^bits - 1 for integer data (none for float data).

    Raises:
        InputError: the photo does not read.
    """
    image = read_image(path, assume_linear=True)
    black = float(image.black_level)
    suffix = path.suffix.lower()
    raw = suffix in RAW_EXTENSIONS
    if raw:
        kind = f"camera raw metadata, {image.bit_depth}-bit"
    elif image.bit_depth is None:
        kind = f"float {suffix.lstrip('.').upper()}"
    else:
        kind = f"{image.bit_depth}-bit {suffix.lstrip('.').upper()}"
    white = None if image.white_level == float("inf") else float(image.white_level) + black
    values = image.values
    return FileLevels(
        photo=path.name,
        kind=kind,
        black=black,
        white=white,
        raw=raw,
        bits=image.bit_depth,
        darkest=None if raw else float(values.min()) + black,
        brightest=None if raw else float(values.max()) + black,
    )


PROJECT_FILE = "project.json"
IMAGES_FOLDER, MASKS_FOLDER = "images", "masks"


def _unique(name: str, taken: set[str], prefix: str) -> str:
    """`name`, or `<prefix>-name` (then numbered) when a file of the zip has it already."""
    out, k = name, 1
    while out.lower() in taken:
        out = f"{prefix}-{name}" if k == 1 else f"{prefix}{k}-{name}"
        k += 1
    taken.add(out.lower())
    return out


def project_zip_bytes(build: PhotoBuild) -> bytes:
    """The built project as a zip: `project.json` (the paths relative to it), the camera
    file, the light file, the board files, `images/` and `masks/`. Unpacked, it is a
    project `lightcal calibrate project.json` solves as the page does.

    Raises:
        OSError: a file of the build is gone (a newer build replaced it).
    """
    project = build.project
    data = json.loads(project.path.read_text(encoding="utf-8"))
    folder = project.folder
    members: list[tuple[str, Path]] = []
    taken = {PROJECT_FILE, IMAGES_FOLDER, MASKS_FOLDER}

    def top(path: Path, prefix: str) -> str:
        name = _unique(path.name, taken, prefix)
        members.append((name, path))
        return name

    camera = data.get("camera", {})
    if camera.get("path"):
        camera["path"] = top(folder / camera["path"], "camera")
    for light in data.get("lights", []):
        rid = light.get("rid") or {}
        if rid.get("path"):
            rid["path"] = top(folder / rid["path"], "light")
    sensor = data.get("sensor", {})
    if sensor.get("response"):
        sensor["response"] = top(folder / sensor["response"], "response")
    # The photos are of one folder (their names differ), each mask named by its photo.
    images = data.get("images", [])
    for spec, image, mask in zip(images, project.image_paths, project.mask_paths, strict=True):
        spec["path"] = f"{IMAGES_FOLDER}/{image.name}"
        members.append((spec["path"], image))
        if mask is not None:
            spec["mask"] = f"{MASKS_FOLDER}/{mask.name}"
            members.append((spec["mask"], mask))
    for board in build.boards:
        top(board, "board")
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as zf:
        text = json.dumps(data, indent=2) + "\n"
        zf.writestr(PROJECT_FILE, text, compress_type=zipfile.ZIP_DEFLATED)
        for name, path in members:
            # Images are compressed already (PNG, raw): stored as they are.
            packed = name.startswith((IMAGES_FOLDER + "/", MASKS_FOLDER + "/"))
            kind = zipfile.ZIP_STORED if packed else zipfile.ZIP_DEFLATED
            zf.write(path, name, compress_type=kind)
    return buffer.getvalue()
