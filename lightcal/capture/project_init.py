"""Assemble a project file from a folder of photographs of the wall (`lightcal init`).

`init_project` reads every image of a folder (any format `lightcal.io.images.read_image`
takes), finds the board's markers and the camera pose of each image
(`lightcal.capture.marker_pose.estimate_pose`), rejects the images with too few markers or a
poor fit (each with its reason), writes one marker mask per accepted image, reads the
EXIF exposure, and writes the project (`lightcal.io.project`) with the light's RID and
its initial guess. Paths in the project are relative to the project file's folder.

Masks: `masks/<name>.png` next to the project file, 8-bit, 255 on the pixels to exclude:
every printed area of the board (all markers of an ArUco grid, detected or not, or the
whole ChArUco board) projected with the image's pose and padded by `mask_margin_px`
(`MarkerPose.marker_mask`), so that the calibration only uses the white wall. They are
written into a hidden staging folder and moved into `masks/` only with the project file
(`lightcal.capture.mask_staging`): a run that fails or is interrupted part-way leaves
neither, so the corrected re-run is not refused.

Each image's work is `lightcal.capture.init_image.process_image`. 8-bit photos (JPEG,
8-bit PNG or TIFF) are read through the camera's response curve (`response_path`, a file
of `lightcal response`) or as linear (`assume_linear`); the project says which
(`sensor.response`, `sensor.assume_linear`), so that calibrate reads them the same way.
An 8-bit photo with neither stops the run (`GammaEncodedImage`).

Every argument is checked before the first image is read. An image whose marker fit is
not finite (a NaN or infinite reprojection RMS, pose or covariance: e.g. a board file
that does not describe the printed board) is rejected with the reason, never accepted.

Exposure: when every accepted image carries EXIF exposure settings, the project gets
them (the calibration uses them relative to the first image); when none does, every
image gets exposure 1 (the same settings assumed); when only some do, a warning says so
and every image gets exposure 1.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lightcal.capture.board_set import read_marker_boards
from lightcal.capture.exif_exposures import exposure_specs
from lightcal.capture.init_checks import (
    POSE_FLOOR_DEG,
    POSE_FLOOR_M,
    check_detection,
    check_levels,
    check_pose_floor,
    initial_guess,
    markers_problem,
    with_pose_floor,
)
from lightcal.capture.init_image import (
    GammaEncodedImage,
    ImageOutcome,
    Reading,
    process_image,
)
from lightcal.capture.marker_pose import MarkerBoard
from lightcal.capture.mask_staging import MaskStaging
from lightcal.errors import InputError
from lightcal.io.camera_file import read_camera
from lightcal.io.images import SUPPORTED_EXTENSIONS
from lightcal.io.project import (
    CameraSpec,
    ImageSpec,
    InitialSpec,
    LightSpec,
    PoseSpec,
    ProjectFile,
    RIDSpec,
    SelectionSpec,
    SensorSpec,
    build_rid,
    project_from_spec,
    save_project,
)
from lightcal.io.response import ResponseCurve

__all__ = [
    "MASKS_DIR",
    "POSE_FLOOR_DEG",
    "POSE_FLOOR_M",
    "GammaEncodedImage",
    "ImageOutcome",
    "InitResult",
    "init_project",
    "list_images",
    "with_pose_floor",
]

MASKS_DIR = "masks"
"""Folder (next to the project file) of the marker masks."""

_LIGHT_FILE_TYPES = {".ies": "ies", ".ldt": "ldt"}

MAX_SELECTED_PIXELS = 300_000
"""`whole_image_selection` bins the photos to at most this many super-pixels in all."""
_BINNINGS = (1, 2, 4, 6, 8, 12, 16, 24, 32)
"""Binnings it chooses from (beyond 2, even: docs/model.md, super-pixels)."""


def whole_image_selection(pixels_per_image: int, n_images: int) -> SelectionSpec:
    """The project's selection: every pixel (`strategy: all`), binned b x b with the
    smallest b of `_BINNINGS` that leaves at most `MAX_SELECTED_PIXELS` super-pixels.

    100 random pixels per photo (the selection's default) put a handful on a narrow beam:
    on `lightcal synth --real-world` (8 photos of 800 x 600, a 14-degree beam) the light
    landed 5.6 mm from the truth with them, 0.2 mm with every pixel binned 4 x 4.
    """
    total = pixels_per_image * n_images
    binning = next((b for b in _BINNINGS if total <= MAX_SELECTED_PIXELS * b * b), _BINNINGS[-1])
    return SelectionSpec(strategy="all", binning=binning)


@dataclass(frozen=True, eq=False)
class InitResult:
    """The outcome of `init_project`.

    Attributes:
        project_path: The project file written.
        spec: Its content.
        images: One outcome per image file found, in name order.
        warnings: Things the user should know (e.g. partial EXIF exposure).
    """

    project_path: Path
    spec: ProjectFile
    images: list[ImageOutcome]
    warnings: list[str]

    @property
    def accepted(self) -> list[ImageOutcome]:
        return [o for o in self.images if o.accepted]

    @property
    def rejected(self) -> list[ImageOutcome]:
        return [o for o in self.images if not o.accepted]

    def report(self) -> str:
        """One line per image (see `ImageOutcome.report_line`)."""
        return "\n".join(o.report_line() for o in self.images)


def list_images(image_dir: str | Path) -> list[Path]:
    """The image files directly in a folder (extensions `read_image` takes), sorted by name.

    Raises:
        InputError: The folder does not exist, is not a folder, or holds no image.
    """
    folder = Path(image_dir)
    if not folder.exists():
        raise InputError(folder, "image folder not found")
    if not folder.is_dir():
        raise InputError(folder, "not a folder: expected a folder of images of the wall")
    paths = sorted(
        p
        for p in folder.iterdir()
        if p.is_file() and not p.name.startswith(".") and p.suffix.lower() in SUPPORTED_EXTENSIONS
    )
    if not paths:
        raise InputError(
            folder,
            "no images found: expected image files (.png, .jpg, .tif, .tiff, .npy, .exr or "
            "camera raw such as .dng, .cr2, .nef, .arw) directly in the folder",
        )
    return paths


def _names(paths: Sequence[Path]) -> list[str]:
    stems = [p.stem for p in paths]
    return [p.stem if stems.count(p.stem) == 1 else p.name for p in paths]


def _relative(path: Path, folder: Path) -> str:
    """`path` relative to `folder` (POSIX separators), or absolute when impossible."""
    try:
        return Path(os.path.relpath(path.resolve(), folder.resolve())).as_posix()
    except ValueError:  # another drive (Windows)
        return path.resolve().as_posix()


def _rid_spec(
    light_file: Path | None, half_angle_deg: float | None, folder: Path, out_path: Path
) -> RIDSpec:
    """The project's RID entry; the file is read once here so a bad one fails early."""
    if light_file is not None and half_angle_deg is not None:
        raise InputError("light", "give either a light file or a half angle, not both")
    if light_file is None:
        half = 30.0 if half_angle_deg is None else half_angle_deg
        if not (math.isfinite(half) and 0.0 < half < 90.0):
            raise InputError("half_angle_deg", f"expected a value in (0, 90) degrees, got {half!r}")
        return RIDSpec(type="half_angle", half_angle_deg=half)
    kind = _LIGHT_FILE_TYPES.get(light_file.suffix.lower())
    if kind is None:
        raise InputError(
            light_file,
            f"unsupported light file suffix {light_file.suffix!r}: expected .ies or .ldt",
        )
    if not light_file.is_file():
        raise InputError(light_file, "light file not found")
    spec = RIDSpec(type=kind, path=_relative(light_file, folder))  # type: ignore[arg-type]
    build_rid(spec, folder, out_path, "lights[0].rid")
    return spec


def init_project(
    image_dir: str | Path,
    *,
    camera_path: str | Path,
    board_path: str | Path | Sequence[str | Path],
    out_path: str | Path = "project.json",
    light_file: str | Path | None = None,
    half_angle_deg: float | None = None,
    initial_position_m: Sequence[float] | None = None,
    initial_axis_camera: Sequence[float] | None = None,
    min_markers: int = 4,
    mask_margin_px: float = 3.0,
    max_rms_px: float = 1.0,
    black_level: float | None = None,
    white_level: float | None = None,
    assume_linear: bool = False,
    response_path: str | Path | None = None,
    pose_floor_m: float = POSE_FLOOR_M,
    pose_floor_deg: float = POSE_FLOOR_DEG,
    on_image: Callable[[ImageOutcome], None] | None = None,
) -> InitResult:
    """Detect the markers in a folder of images and write a project file.

    Args:
        image_dir: Folder of photographs of the wall (not searched recursively).
        camera_path: Camera file (OpenCV YAML/JSON/XML or COLMAP cameras.txt) of the images.
        board_path: Board file (`lightcal.io.board_file`): an `aruco_grid`, `charuco` or
            `markers` board; or several board files of one wall, whose markers all make
            each image's pose (`lightcal.capture.board_set`: no marker on two boards).
        out_path: The project file to write (JSON, or YAML for .yaml/.yml); the masks go
            to `masks/` beside it.
        light_file: The light's IES (.ies) or EULUMDAT (.ldt) file.
        half_angle_deg: Or its half-intensity angle (a cos^m profile); 30 degrees when
            neither is given.
        initial_position_m: (3,) initial guess of the light position, camera frame, metres.
        initial_axis_camera: (3,) initial guess of the light axis, camera frame. With
            neither, the project says `initial: auto` (the guess from the beam in the
            photos, `lightcal.pipeline.auto_start`); with one, the other is (0, 0, 0) or
            the optical axis (0, 0, 1).
        min_markers: Images with fewer detected markers are rejected.
        mask_margin_px: Padding of the marker masks, pixels.
        max_rms_px: Images whose marker reprojection RMS exceeds this are rejected.
        black_level: Black level of the images (source units), written to the project.
        white_level: White level of the images (source units), written to the project.
        assume_linear: Take 8-bit photos (JPEG, 8-bit PNG or TIFF) as linear; written to
            the project (`sensor.assume_linear`), so calibrate reads them the same way.
        response_path: Or the camera's response curve (`lightcal response`), which
            linearises 8-bit photos; written to the project (`sensor.response`). 8-bit
            photos with neither are refused (`GammaEncodedImage`).
        pose_floor_m, pose_floor_deg: The systematic error of marker poses that the
            reprojection fit cannot see (printing scale, wall flatness, blur, the
            intrinsics), added in quadrature to each pose's covariance: standard
            deviation of each camera-centre coordinate (m) and of each rotation component
            (degrees).
        on_image: Called with each image's outcome as soon as it is known.

    Returns:
        What was written, with one outcome per image.

    Raises:
        InputError: A bad argument (checked before any image is read), no images, no
            usable image, an unreadable camera, board, light or response file, a
            chessboard as board, 8-bit photos without a response curve or
            `assume_linear` (`GammaEncodedImage`), or an initial guess behind the wall.
            Nothing is left written then.
    """
    out = Path(out_path)
    folder = out.parent
    if not folder.is_dir():
        raise InputError(out, f"cannot write: folder {str(folder)!r} does not exist")
    check_detection(min_markers, mask_margin_px, max_rms_px)
    auto_initial = initial_position_m is None and initial_axis_camera is None
    position, axis = initial_guess(
        (0.0, 0.0, 0.0) if initial_position_m is None else initial_position_m,
        (0.0, 0.0, 1.0) if initial_axis_camera is None else initial_axis_camera,
    )
    check_pose_floor(pose_floor_m, pose_floor_deg, ("pose_floor_m", "pose_floor_deg"))
    check_levels(black_level, white_level)
    if not isinstance(assume_linear, bool):
        raise InputError("assume_linear", f"expected True or False, got {assume_linear!r}")
    if assume_linear and response_path is not None:
        raise InputError(
            "assume_linear", "give either a response curve (response_path) or assume_linear"
        )
    if response_path is not None and white_level is not None:
        raise InputError(
            "white_level", "with a response curve the white level is code 255; do not give one"
        )

    paths = list_images(image_dir)
    camera_file = Path(camera_path)
    camera = read_camera(camera_file)
    board_paths = [board_path] if isinstance(board_path, str | Path) else list(board_path)
    boards = read_marker_boards(board_paths)
    board: MarkerBoard | list[MarkerBoard] = boards[0] if len(boards) == 1 else boards
    if (problem := markers_problem(min_markers, boards)) is not None:
        raise InputError("min_markers", f"{problem}, got {min_markers}")
    rid = _rid_spec(None if light_file is None else Path(light_file), half_angle_deg, folder, out)
    response_file = None if response_path is None else Path(response_path)
    reading = Reading(
        black_level,
        white_level,
        assume_linear,
        None if response_file is None else ResponseCurve.load(response_file),
    )
    # Room light is estimated by default: it grows with the exposure like the beam, and
    # left out it moves the light by centimetres (docs/model.md, "The sensor's estimated
    # terms"); in a dark room it costs about 1.1x in the sigma. Set it false there, or
    # declare light-off photos (images[].dark), which subtract it.
    sensor = SensorSpec(
        black_level=black_level,
        white_level=white_level,
        assume_linear=assume_linear,
        response=None if response_file is None else _relative(response_file, folder),
        estimate_ambient=True,
    )
    print_polygons = np.concatenate([b.outline_world() for b in boards])

    masks_dir = folder / MASKS_DIR
    with MaskStaging(masks_dir) as staging:
        outcomes: list[ImageOutcome] = []
        for path, name in zip(paths, _names(paths), strict=True):
            outcome = process_image(
                path,
                name,
                camera,
                board,
                print_polygons,
                staging.folder,
                masks_dir,
                min_markers=min_markers,
                mask_margin_px=mask_margin_px,
                max_rms_px=max_rms_px,
                reading=reading,
            )
            outcomes.append(outcome)
            if on_image is not None:
                on_image(outcome)
        result = _write_project(
            outcomes,
            staging,
            image_dir=image_dir,
            out=out,
            camera_file=camera_file,
            rid=rid,
            initial=None if auto_initial else InitialSpec(position_m=position, axis_camera=axis),
            no_light_given=light_file is None and half_angle_deg is None,
            sensor=sensor,
            pose_floor_m=pose_floor_m,
            pose_floor_deg=pose_floor_deg,
            pixels=camera.width * camera.height,
        )
        staging.commit()
    return result


def _write_project(
    outcomes: list[ImageOutcome],
    staging: MaskStaging,
    *,
    image_dir: str | Path,
    out: Path,
    camera_file: Path,
    rid: RIDSpec,
    initial: InitialSpec | None,
    no_light_given: bool,
    sensor: SensorSpec,
    pose_floor_m: float,
    pose_floor_deg: float,
    pixels: int,
) -> InitResult:
    """Check the project (with the staged masks), then move the masks in and write it."""
    folder = out.parent

    accepted = [o for o in outcomes if o.accepted]
    if not accepted:
        reasons = "; ".join(f"{o.path.name}: {o.reason}" for o in outcomes[:5])
        more = ", ..." if len(outcomes) > 5 else ""
        raise InputError(
            image_dir,
            f"no usable images: all {len(outcomes)} were rejected ({reasons}{more})",
        )

    warnings: list[str] = []
    if no_light_given:
        warnings.append(
            "no light file nor half angle given: the light's profile is taken as cos^m, its "
            "exponent estimated from a start at a half angle of 30 degrees (give its IES/LDT "
            "file or half angle if known)"
        )
    exposures = exposure_specs(
        [o.path.name for o in accepted], [o.exposure for o in accepted], warnings
    )
    selection = whole_image_selection(pixels, len(accepted))
    if any(o.bit_depth == 8 for o in accepted):
        # An 8-bit photo's black is not known: the curve's code 0, the room light.
        sensor = sensor.model_copy(update={"estimate_offset": True})

    def project(mask_folder: Path) -> ProjectFile:
        images = []
        for o, exposure in zip(accepted, exposures, strict=True):
            assert o.pose is not None and o.mask_path is not None
            images.append(
                ImageSpec(
                    path=_relative(o.path, folder),
                    name=o.name,
                    T_camera_world=PoseSpec(
                        R=o.pose.R_camera_world.tolist(),
                        t=o.pose.t_camera_world.tolist(),
                        covariance=with_pose_floor(
                            o.pose.covariance, pose_floor_m, pose_floor_deg
                        ).tolist(),
                        d_pose_d_intrinsics=(
                            None
                            if o.d_pose_d_intrinsics is None
                            else o.d_pose_d_intrinsics.tolist()
                        ),
                    ),
                    exposure=exposure,
                    mask=_relative(mask_folder / o.mask_path.name, folder),
                )
            )
        return ProjectFile(
            camera=CameraSpec(path=_relative(camera_file, folder)),
            sensor=sensor,
            images=images,
            selection=selection,
            lights=[
                LightSpec(
                    name="light",
                    rid=rid,
                    initial="auto" if initial is None else initial,
                    estimate_rid="cos_power" if no_light_given else "none",
                )
            ],
        )

    # The project must load (files present, initial light in front of the wall): checked
    # with the staged masks, before anything is moved into masks/.
    project_from_spec(project(staging.folder), out.resolve())
    spec = project(staging.masks_dir)
    staging.publish([o.mask_path.name for o in accepted if o.mask_path is not None])
    save_project(spec, out)
    return InitResult(project_path=out, spec=spec, images=outcomes, warnings=warnings)
