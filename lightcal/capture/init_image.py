"""One photo of `lightcal init` (`lightcal.capture.project_init`): read, markers found,
pose checked, mask staged; or the reason it is rejected.

How the photos are read (`Reading`): black and white levels as given; 8-bit data (JPEG,
8-bit PNG or TIFF) only through the camera's response curve (`lightcal response`) or when
the user vouches that it is linear (`assume_linear`). An 8-bit photo given with neither
is not a rejection of that photo but an error of the whole run (`GammaEncodedImage`): no
8-bit photo could be used, and the fix is one argument.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from lightcal.capture.init_checks import NOT_FINITE, fit_problem
from lightcal.capture.marker_pose import (
    MarkerBoard,
    MarkerPose,
    estimate_pose,
    pose_intrinsics_jacobian,
    pose_report,
)
from lightcal.core.camera import Camera
from lightcal.errors import InputError
from lightcal.io.atomic import atomic_write_bytes
from lightcal.io.exif import Exposure
from lightcal.io.images import read_image
from lightcal.io.linear_image import LinearImage
from lightcal.io.response import ResponseCurve

__all__ = ["GAMMA_ENCODED", "GammaEncodedImage", "ImageOutcome", "Reading", "process_image"]

GAMMA_ENCODED = (
    "8-bit image values are gamma-encoded by the camera, not proportional to light: give "
    "init_project the camera's response curve (response_path=..., a file of lightcal "
    "response) or assume_linear=True if the camera wrote linear values"
)
"""`GammaEncodedImage`'s message (the CLI names its own options instead)."""


class GammaEncodedImage(InputError):
    """An 8-bit photo, and neither a response curve nor `assume_linear` was given."""


@dataclass(frozen=True, eq=False)
class Reading:
    """How `lightcal init` reads each photo (what the project's `sensor` says).

    Attributes:
        black_level: Black level (source units; linear units with a response curve).
        white_level: White level (source units).
        assume_linear: 8-bit data taken as linear.
        response: The curve that linearises 8-bit data.
    """

    black_level: float | None = None
    white_level: float | None = None
    assume_linear: bool = False
    response: ResponseCurve | None = None


@dataclass(frozen=True, eq=False)
class ImageOutcome:
    """What `init_project` made of one image.

    Attributes:
        name: The image's name in the project (its file stem, or file name when stems clash).
        path: The image file.
        pose: The marker pose, None when the image was rejected.
        reason: Why the image was rejected, None when it was accepted.
        exposure: EXIF exposure settings, None when absent (or the image was rejected).
        mask_path: The mask of an accepted image (in `masks/`, where it is moved with
            the project file at the end of `init_project`), else None.
        d_pose_d_intrinsics: (6, p) how the pose moves with the camera's intrinsics
            (`marker_pose.pose_intrinsics_jacobian`), when the camera file has an
            intrinsics covariance, else None.
        bit_depth: Bits per sample of an accepted image, else None.
    """

    name: str
    path: Path
    pose: MarkerPose | None
    reason: str | None
    exposure: Exposure | None = None
    mask_path: Path | None = None
    d_pose_d_intrinsics: np.ndarray | None = None
    bit_depth: int | None = None

    @property
    def accepted(self) -> bool:
        """True when the image is in the project."""
        return self.pose is not None

    def report_line(self) -> str:
        """One line: markers, reprojection RMS and camera position, or the rejection."""
        if self.pose is not None:
            return pose_report([dataclasses.replace(self.pose, source=self.path.name)])
        return pose_report([InputError(self.path.name, self.reason or "rejected")])


def _camera_for(image: LinearImage, camera: Camera, name: str) -> Camera:
    """The camera of the image as read (binned when the reader binned a raw file)."""
    height, width = image.shape
    if (width, height) == (camera.width, camera.height):
        return camera
    b = image.binning
    if b > 1 and (width, height) == (camera.width // b, camera.height // b):
        return camera.binned(b)
    raise InputError(
        name,
        f"image is {width}x{height} px, expected {camera.width}x{camera.height} px "
        "(the camera's size)",
    )


def _encode_mask(mask: np.ndarray) -> bytes:
    ok, encoded = cv2.imencode(".png", np.where(mask, 255, 0).astype(np.uint8))
    if not ok:  # pragma: no cover - OpenCV always encodes an 8-bit PNG
        raise InputError("mask", "OpenCV could not encode a PNG")
    return bytes(encoded.tobytes())


def process_image(
    path: Path,
    name: str,
    camera: Camera,
    board: MarkerBoard | list[MarkerBoard],
    print_polygons: np.ndarray,
    staging_dir: Path,
    masks_dir: Path,
    *,
    min_markers: int,
    mask_margin_px: float,
    max_rms_px: float,
    reading: Reading,
) -> ImageOutcome:
    """Read, detect, check and mask one image; an input problem rejects it with the reason.

    The mask is written into `staging_dir`; the outcome names its final place in
    `masks_dir` (see `MaskStaging`).

    Raises:
        GammaEncodedImage: An 8-bit image read without a response curve or `assume_linear`.
    """
    try:
        image = read_image(
            path,
            black_level=reading.black_level,
            white_level=reading.white_level,
            response=reading.response,
            # Only 8-bit data depends on it; such data without either is refused below.
            assume_linear=reading.assume_linear or reading.response is None,
        )
    except InputError as exc:
        return ImageOutcome(name, path, None, exc.detail)
    if image.bit_depth == 8 and not reading.assume_linear and reading.response is None:
        raise GammaEncodedImage(path, GAMMA_ENCODED)
    try:
        image_camera = _camera_for(image, camera, name)
        pose = estimate_pose(
            image.values, image_camera, board, min_markers=min_markers, source=name
        )
    except InputError as exc:
        return ImageOutcome(name, path, None, exc.detail)
    problem = fit_problem(pose, max_rms_px)
    if problem is not None:
        return ImageOutcome(name, path, None, problem)
    d_pose = None
    if camera.intrinsics_covariance is not None:
        d_pose = pose_intrinsics_jacobian(
            pose.points_world,
            pose.points_image,
            camera,
            binning=1 if image_camera is camera else image.binning,
            source=name,
        )
        if not np.all(np.isfinite(d_pose)):
            return ImageOutcome(name, path, None, NOT_FINITE)
    height, width = image.shape
    everything = dataclasses.replace(pose, mask_polygons_world=print_polygons)
    mask = everything.marker_mask(height, width, margin_px=mask_margin_px)
    filename = f"{name}.png"
    atomic_write_bytes(staging_dir / filename, _encode_mask(mask))
    return ImageOutcome(
        name, path, pose, None, image.exposure, masks_dir / filename, d_pose, image.bit_depth
    )
