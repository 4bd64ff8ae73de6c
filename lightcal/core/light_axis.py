"""Charts of a light's axis: angles <-> the unit axis in the camera frame, and rotations.

Frames (see docs/conventions.md): the light frame L has its origin at the emitter, +z along
the light's central axis. The light axis in the camera frame is
`axis_camera = R_camera_light[:, 2]`.

Two charts of the light axis are defined here:

- The solver's angles `(a_rad, b_rad)`: the azimuthal-equidistant chart (the exponential
  map of the sphere at +z). With `theta = hypot(a, b)`,
  `axis = (sinc(theta) a, sinc(theta) b, cos(theta))`, `sinc(t) = sin(t)/t`. `theta` is
  the angle between the axis and the camera's optical axis, and `(a, b)/theta` the
  direction in which it tilts, so `a` tilts towards +x and `b` towards +y. The chart is
  smooth everywhere except at `theta = pi` (the axis -z); lights point roughly along +z,
  where it is best behaved.
- The paper's angles `(roll_rad, pitch_rad)` (for reports only), see
  `paper_angles_from_axis`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lightcal.core.rotations import (
    UNIT_NORM_TOL,
    as_finite_array,
    check_rotation_matrix,
    matrix_from_rotvec,
    skew,
)
from lightcal.errors import InputError

_SERIES_THRESHOLD_RAD = 1e-2
"""Below this angle the chart's coefficient functions use their Taylor series."""


# --------------------------------------------------------------------------- input checks


def _finite_scalar(value: Any, *, name: str) -> float:
    """`value` as a Python float; raises `InputError` unless it is a finite real scalar."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(name, f"expected a finite real number, got {value!r}") from exc
    if array.shape != ():
        raise InputError(name, f"expected a scalar, got an array of shape {array.shape}")
    result = float(array)
    if not math.isfinite(result):
        raise InputError(name, f"expected a finite real number, got {result}")
    return result


def _unit_vector(value: ArrayLike, *, name: str) -> NDArray[np.float64]:
    """`value` as a (3,) float64 unit vector (re-normalised); checks shape, finiteness, norm."""
    vector = as_finite_array(value, (3,), name=name)
    norm = float(np.linalg.norm(vector))
    if abs(norm - 1.0) > UNIT_NORM_TOL:
        raise InputError(
            name, f"expected a unit vector (norm 1 within {UNIT_NORM_TOL:g}), got norm {norm:.6g}"
        )
    return vector / norm


def _format_vector(vector: NDArray[np.float64]) -> str:
    return "(" + ", ".join(f"{float(c):.6g}" for c in vector) + ")"


# ------------------------------------------------------------- the (a, b) chart of the axis


def _sinc_and_derivative_ratio(theta: float) -> tuple[float, float]:
    """`s = sin(t)/t` and `c = s'(t)/t = (t cos t - sin t)/t^3` at `t = theta >= 0`."""
    if theta < _SERIES_THRESHOLD_RAD:
        t2 = theta * theta
        s = 1.0 - t2 / 6.0 * (1.0 - t2 / 20.0 * (1.0 - t2 / 42.0))
        c = -1.0 / 3.0 + t2 / 30.0 * (1.0 - t2 / 28.0 * (1.0 - t2 / 54.0))
        return s, c
    sin_t = math.sin(theta)
    return sin_t / theta, (theta * math.cos(theta) - sin_t) / theta**3


def axis_from_angles(a_rad: float, b_rad: float) -> NDArray[np.float64]:
    """Unit light axis (camera frame) of the chart angles `(a, b)`.

    `theta = hypot(a, b)`, `axis = (sinc(theta) a, sinc(theta) b, cos(theta))`: the axis makes
    the angle `theta` with the optical axis +z and tilts towards `(a, b, 0)`. `(0, 0)` is +z;
    `a = pi/2, b = 0` is +x. Smooth in `(a, b)` everywhere; one-to-one for `theta < pi`.

    Args:
        a_rad: Tilt component towards camera +x, radians.
        b_rad: Tilt component towards camera +y, radians.

    Returns:
        axis_camera: (3,) unit vector.
    """
    a = _finite_scalar(a_rad, name="a_rad")
    b = _finite_scalar(b_rad, name="b_rad")
    theta = math.hypot(a, b)
    s, _ = _sinc_and_derivative_ratio(theta)
    return np.array([s * a, s * b, math.cos(theta)])


def angles_from_unit_axis(axis: NDArray[np.float64], *, name: str) -> tuple[float, float]:
    x, y, z = (float(c) for c in axis)
    rho = math.hypot(x, y)
    if rho == 0.0:
        if z < 0.0:
            raise InputError(
                name,
                "expected an axis other than -z (where the angles (a, b) are singular), "
                f"got {_format_vector(axis)}",
            )
        return 0.0, 0.0
    theta_over_rho = math.atan2(rho, z) / rho
    return theta_over_rho * x, theta_over_rho * y


def angles_from_axis(axis_camera: ArrayLike) -> tuple[float, float]:
    """Chart angles `(a, b)` of a unit axis: the inverse of `axis_from_angles`.

    Args:
        axis_camera: (3,) unit vector (norm within `UNIT_NORM_TOL` of 1), not -z.

    Returns:
        (a_rad, b_rad) with `hypot(a, b) = angle to +z` in [0, pi).

    Raises:
        InputError: Not a finite unit (3,) vector, or the antipode -z.
    """
    axis = _unit_vector(axis_camera, name="axis_camera")
    return angles_from_unit_axis(axis, name="axis_camera")


def axis_jacobian(a_rad: float, b_rad: float) -> NDArray[np.float64]:
    """Analytic `d axis_from_angles(a, b) / d(a, b)`, exact and smooth at `a = b = 0`.

    With `s = sin(t)/t`, `c = (t cos t - sin t)/t^3` (series near `t = 0`, `c(0) = -1/3`):
    `[[s + a^2 c, a b c], [a b c, s + b^2 c], [-s a, -s b]]`.

    Args:
        a_rad: See `axis_from_angles`.
        b_rad: See `axis_from_angles`.

    Returns:
        J: (3, 2), columns d/da and d/db.
    """
    a = _finite_scalar(a_rad, name="a_rad")
    b = _finite_scalar(b_rad, name="b_rad")
    s, c = _sinc_and_derivative_ratio(math.hypot(a, b))
    return np.array([[s + a * a * c, a * b * c], [a * b * c, s + b * b * c], [-s * a, -s * b]])


def rotation_from_axis(axis_camera: ArrayLike) -> NDArray[np.float64]:
    """The minimal rotation taking +z to `axis_camera`: a canonical `R_camera_light`.

    A rotationally symmetric light's roll about its own axis is unobservable; this fixes it
    by rotating about `e_z x axis` (no twist). It equals `matrix_from_rotvec((-b, a, 0))` for
    `(a, b) = angles_from_axis(axis_camera)`.

    Args:
        axis_camera: (3,) unit vector, not -z.

    Returns:
        R_camera_light: (3, 3) with `R_camera_light[:, 2] == axis_camera`.

    Raises:
        InputError: Not a finite unit (3,) vector, or the antipode -z (no unique minimal rotation).
    """
    axis = _unit_vector(axis_camera, name="axis_camera")
    x, y, z = (float(c) for c in axis)
    rho2 = x * x + y * y
    if rho2 == 0.0 and z < 0.0:
        raise InputError(
            "axis_camera",
            "expected an axis other than -z (where the minimal rotation from +z is not unique), "
            f"got {_format_vector(axis)}",
        )
    # R = I + K + K^2 / (1 + z) with K = skew(e_z x axis); 1/(1 + z) = (1 - z)/rho^2 avoids the
    # cancellation in 1 + z when the axis points backwards.
    inv_one_plus_z = 1.0 / (1.0 + z) if z >= 0.0 else (1.0 - z) / rho2
    K = skew(np.array([-y, x, 0.0]))
    return np.eye(3) + K + inv_one_plus_z * (K @ K)


def axis_roll_from_rotation(R_camera_light: ArrayLike) -> tuple[float, float, float]:
    """`(a_rad, b_rad, roll_rad)` of a light orientation, the inverse of
    `rotation_from_axis_roll`: the axis chart's angles (`angles_from_axis`) and the
    roll about the axis relative to the minimal rotation from +z (`rotation_from_axis`).

    Args:
        R_camera_light: (3, 3) rotation, light frame -> camera frame.
    """
    R = check_rotation_matrix(R_camera_light, name="R_camera_light")
    axis = R[:, 2] / np.linalg.norm(R[:, 2])
    a, b = angles_from_axis(axis)
    twist = rotation_from_axis(axis).T @ R  # a rotation about +z
    return a, b, math.atan2(float(twist[1, 0]), float(twist[0, 0]))


def rotation_from_axis_roll(a_rad: float, b_rad: float, roll_rad: float) -> NDArray[np.float64]:
    """`R_camera_light` (3, 3) of the axis chart's angles (a, b) and a roll about the axis."""
    axis = axis_from_angles(a_rad, b_rad)
    roll = _finite_scalar(roll_rad, name="roll_rad")
    return rotation_from_axis(axis) @ matrix_from_rotvec(np.array([0.0, 0.0, roll]))


# ----------------------------------------------------------------------- the paper's angles


def paper_angles_from_axis(axis_camera: ArrayLike) -> tuple[float, float]:
    """The paper's two angles of the light axis: `(roll_rad, pitch_rad)`.

    Song et al. (2020) report the light orientation as two rotations of the light axis. Our
    reading of those angles: `axis = R_x(roll) @ R_y(pitch) @ (0, 0, 1)`, i.e. first a pitch
    about the camera y axis (positive tilts the axis towards +x), then a roll about the camera
    x axis (positive tilts it towards -y, up in the image):
    `axis = (sin(pitch), -sin(roll) cos(pitch), cos(roll) cos(pitch))`. Both zero means the
    light points along the camera's optical axis.

    Args:
        axis_camera: (3,) unit vector.

    Returns:
        (roll_rad, pitch_rad) with roll in (-pi, pi], pitch in [-pi/2, pi/2]. At the gimbal
        singularity `axis = (+-1, 0, 0)` the roll is undefined and returned as 0.
    """
    x, y, z = (float(c) for c in _unit_vector(axis_camera, name="axis_camera"))
    pitch = math.atan2(x, math.hypot(y, z)) + 0.0  # + 0.0 turns -0.0 into 0.0
    roll = math.atan2(-y, z) + 0.0 if (y != 0.0 or z != 0.0) else 0.0
    return roll, pitch


def axis_from_paper_angles(roll_rad: float, pitch_rad: float) -> NDArray[np.float64]:
    """Unit light axis `R_x(roll) @ R_y(pitch) @ (0, 0, 1)`; see `paper_angles_from_axis`.

    Args:
        roll_rad: Rotation about the camera x axis, radians.
        pitch_rad: Rotation about the camera y axis, radians.

    Returns:
        axis_camera: (3,) unit vector.
    """
    roll = _finite_scalar(roll_rad, name="roll_rad")
    pitch = _finite_scalar(pitch_rad, name="pitch_rad")
    cos_pitch = math.cos(pitch)
    return np.array([math.sin(pitch), -math.sin(roll) * cos_pitch, math.cos(roll) * cos_pitch])
