"""The checks of `lightcal init`'s arguments and of each image's marker fit
(`lightcal.capture.project_init`), and the systematic floor of marker poses.

Every argument is checked before the first image is read; messages name the argument as
the library's user types it (the CLI checks its options first, naming the option). A
marker fit whose RMS, pose or covariance is not finite (NaN, inf) is a rejection of the
image, never an acceptance: `NaN > max_rms_px` is False.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from lightcal.capture.marker_pose import MarkerBoard, MarkerPose
from lightcal.errors import InputError
from lightcal.io.project_spec import MAX_LIGHT_OFFSET_M

__all__ = [
    "NOT_FINITE",
    "POSE_FLOOR_DEG",
    "POSE_FLOOR_M",
    "axis_problem",
    "check_detection",
    "check_levels",
    "check_pose_floor",
    "fit_problem",
    "initial_guess",
    "markers_problem",
    "position_problem",
    "vector3",
    "with_pose_floor",
]


def check_detection(min_markers: int, mask_margin_px: float, max_rms_px: float) -> None:
    """The detection's arguments of `init_project`."""
    if isinstance(min_markers, bool) or not isinstance(min_markers, int) or min_markers < 1:
        raise InputError("min_markers", f"expected an int >= 1, got {min_markers!r}")
    if not (math.isfinite(mask_margin_px) and mask_margin_px >= 0.0):
        raise InputError("mask_margin_px", f"expected a value >= 0 pixels, got {mask_margin_px!r}")
    if not (math.isfinite(max_rms_px) and max_rms_px > 0.0):
        raise InputError("max_rms_px", f"expected a value > 0 pixels, got {max_rms_px!r}")


def vector3(name: str, values: Sequence[float]) -> list[float]:
    """Three finite numbers as floats."""
    out = [float(v) for v in values]
    if len(out) != 3 or not all(math.isfinite(v) for v in out):
        raise InputError(name, f"expected three finite numbers, got {list(values)!r}")
    return out


def position_problem(position_m: Sequence[float]) -> str | None:
    """Why an initial light position (3 finite numbers, camera frame, m) cannot go into a
    project (`InitialSpec.position_m`'s bound), or None."""
    if all(abs(v) <= MAX_LIGHT_OFFSET_M for v in position_m):
        return None
    return f"expected each coordinate within ±{MAX_LIGHT_OFFSET_M:g} m of the camera"


MAX_AXIS_LENGTH = 1e100
"""The longest initial axis (3 finite numbers) taken, and 1 / the shortest: its length
must be computable (and the axis normalised) without overflow or underflow."""


def axis_problem(axis_camera: Sequence[float]) -> str | None:
    """Why an initial light axis (3 finite numbers, camera frame) cannot go into a project,
    or None: zero, too long or short to normalise, or -z (where the project's minimal
    rotation from +z, `lightcal.core.light_axis.rotation_from_axis`, is not unique)."""
    x, y, z = (float(v) for v in axis_camera)
    length = math.hypot(x, y, z)  # scaled: no overflow where the length itself fits
    if length == 0.0:
        return "expected a non-zero direction"
    if not 1.0 / MAX_AXIS_LENGTH <= length <= MAX_AXIS_LENGTH:
        return f"expected a direction of length {1.0 / MAX_AXIS_LENGTH:g} to {MAX_AXIS_LENGTH:g}"
    x, y, z = x / length, y / length, z / length
    if x * x + y * y == 0.0 and z < 0.0:
        return (
            "expected an axis other than -z (straight back, away from the wall: there the "
            "light's initial orientation is not defined)"
        )
    return None


def markers_problem(min_markers: int, board: MarkerBoard | Sequence[MarkerBoard]) -> str | None:
    """Why a fewest-markers count can never be met on `board` (or boards), or None."""
    boards = list(board) if isinstance(board, Sequence) else [board]
    n_markers = sum(b.n_markers for b in boards)
    if min_markers <= n_markers:
        return None
    whose = "the board's" if len(boards) == 1 else f"the {len(boards)} boards'"
    return f"expected at most {whose} {n_markers} markers"


def initial_guess(
    position_m: Sequence[float], axis_camera: Sequence[float]
) -> tuple[list[float], list[float]]:
    """`init_project`'s initial light position (m) and axis, checked, as floats."""
    position = vector3("initial_position_m", position_m)
    axis = vector3("initial_axis_camera", axis_camera)
    for name, values, problem in (
        ("initial_position_m", position, position_problem(position)),
        ("initial_axis_camera", axis, axis_problem(axis)),
    ):
        if problem is not None:
            raise InputError(name, f"{problem}, got ({', '.join(f'{v:g}' for v in values)})")
    return position, axis


def check_levels(black_level: float | None, white_level: float | None) -> None:
    """Black and white levels as the project's `sensor` takes them."""
    for name, v, positive in (
        ("black_level", black_level, False),
        ("white_level", white_level, True),
    ):
        if v is None:
            continue
        if not (
            isinstance(v, int | float) and math.isfinite(v) and (v > 0 or (v == 0 and not positive))
        ):
            raise InputError(
                name, f"expected a finite value {'> 0' if positive else '>= 0'}, got {v!r}"
            )
    if black_level is not None and white_level is not None and not white_level > black_level:
        raise InputError(
            "white_level",
            f"expected a value above black_level ({black_level:g}), got {white_level:g}",
        )


#: Default systematic error of marker-based camera poses (see `init_project`): the
#: sample data's marker poses are 0.3-0.55 mm off while their reprojection fits predict
#: 0.01-0.04 mm, and printed-marker poses are typically good to about half a millimetre.
POSE_FLOOR_M = 0.0005
POSE_FLOOR_DEG = 0.05


def check_pose_floor(floor_m: float, floor_deg: float, names: tuple[str, str]) -> None:
    """The pose floor (m, degrees): finite and >= 0; `names` as the caller's user types them."""
    for name, v in zip(names, (floor_m, floor_deg), strict=True):
        if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0.0):
            raise InputError(name, f"expected a finite value >= 0, got {v!r}")


def with_pose_floor(covariance: np.ndarray, floor_m: float, floor_deg: float) -> np.ndarray:
    """(6, 6) a pose covariance (delta rad, centre m) plus the systematic floor."""
    check_pose_floor(floor_m, floor_deg, ("pose floor (m)", "pose floor (deg)"))
    floor = np.diag([math.radians(floor_deg) ** 2] * 3 + [floor_m**2] * 3)
    return np.asarray(covariance, dtype=np.float64) + floor


NOT_FINITE = (
    "the marker fit gave a non-finite pose or covariance: expected markers that fit one "
    "camera pose (check that the board file describes the printed board and the camera "
    "file this camera)"
)


def fit_problem(pose: MarkerPose, max_rms_px: float) -> str | None:
    """Why a marker fit is not good enough for the project, or None.

    A NaN or infinite RMS is a failed fit, never "at most max_rms_px" (NaN > max is False).
    """
    rms = pose.reprojection_rms_px
    if not math.isfinite(rms):
        return (
            f"marker reprojection RMS {rms} px: expected a finite RMS of at most "
            f"{max_rms_px:g} px (check that the board file describes the printed board and "
            "the camera file this camera)"
        )
    if rms > max_rms_px:
        return f"marker reprojection RMS {rms:.3f} px, expected at most {max_rms_px:g} px"
    arrays = (pose.R_camera_world, pose.t_camera_world, pose.covariance)
    if not all(np.all(np.isfinite(a)) for a in arrays):
        return NOT_FINITE
    return None
