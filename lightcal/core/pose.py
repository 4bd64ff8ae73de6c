"""Parameterisations of the light pose `T_camera_light` for the solver.

Frames (see docs/conventions.md): the light frame L has its origin at the emitter, +z along the
light's central axis and +x as the azimuth reference. The unknown mount is
`R_camera_light` (3, 3), mapping light-frame vectors to camera-frame vectors, and
`t_camera_light` (3,), the emitter position in the (OpenCV) camera frame, metres.
The light axis in the camera frame is therefore `axis_camera = R_camera_light[:, 2]`.

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

Three parameterisations share the `PoseParameterization` interface:

| class | params | rotation |
|---|---|---|
| `IsotropicPose` | `(x_m, y_m, z_m)` | identity (orientation unobservable) |
| `SymmetricPose` | `(x_m, y_m, z_m, a_rad, b_rad)` | minimal rotation taking +z to the axis |
| `GeneralPose` | `(x_m, y_m, z_m, dx_rad, dy_rad, dz_rad)` | `exp(delta) @ R_ref` |
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from typing import Any, Literal, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lightcal.core.rotations import (
    UNIT_NORM_TOL,
    as_finite_array,
    check_rotation_matrix,
    left_jacobian_so3,
    matrix_from_rotvec,
    quaternion_wxyz_from_matrix,
    rotvec_from_matrix,
    skew,
)
from lightcal.errors import InputError

PoseKind = Literal["isotropic", "symmetric", "general"]
"""The three kinds of light: which parts of the pose are observable."""

POSITION_NAMES = ("x_m", "y_m", "z_m")
"""Names of the three position parameters, the emitter position in the camera frame."""

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


def _angles_from_unit_axis(axis: NDArray[np.float64], *, name: str) -> tuple[float, float]:
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
    return _angles_from_unit_axis(axis, name="axis_camera")


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


# ------------------------------------------------------------------- the parameterisations


def _directions(v_light: ArrayLike) -> NDArray[np.float64]:
    """`v_light` as (3,) or (N, 3) finite float64."""
    try:
        v = np.array(v_light, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError("v_light", f"expected shape (3,) or (N, 3), got {v_light!r}") from exc
    if v.shape != (3,) and not (v.ndim == 2 and v.shape[1] == 3):
        raise InputError("v_light", f"expected shape (3,) or (N, 3), got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise InputError("v_light", "expected finite values, got NaN or infinity")
    return v


def _rotated_direction_jacobian(
    R_camera_light: NDArray[np.float64],
    v_light: NDArray[np.float64],
    B: NDArray[np.float64],
) -> NDArray[np.float64]:
    """`-skew(R v) @ B` for v (3,) or (N, 3): (3, k) or (N, 3, k) with B (3, k)."""
    u = v_light @ R_camera_light.T  # (3,) or (N, 3): R v
    # -skew(u) @ B[:, j] = B[:, j] x u
    columns = np.cross(B.T, u[..., None, :])  # (k, 3) or (N, k, 3)
    return np.swapaxes(columns, -1, -2)


class PoseParameterization(ABC):
    """A chart of the light pose: a flat parameter vector <-> `(R_camera_light, t_camera_light)`.

    Attributes:
        kind: Which light this is for: "isotropic", "symmetric" or "general".
        n_params: Length of the parameter vector (3, 5, 6).
        names: (n_params,) name of each parameter; the first three are `x_m, y_m, z_m`,
            `t_camera_light` in metres.
    """

    kind: PoseKind
    n_params: int
    names: tuple[str, ...]

    @property
    def n_rot(self) -> int:
        """Number of rotation parameters (0, 2, 3): `n_params - 3`."""
        return self.n_params - 3

    def check_params(self, params: ArrayLike) -> NDArray[np.float64]:
        """`params` as a finite (n_params,) float64 array, or `InputError`."""
        return as_finite_array(params, (self.n_params,), name="params")

    @abstractmethod
    def rotation(self, params: ArrayLike) -> NDArray[np.float64]:
        """`R_camera_light` (3, 3) of `params` (n_params,)."""

    def to_pose(self, params: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Pose of the parameters.

        Args:
            params: (n_params,).

        Returns:
            R_camera_light: (3, 3) rotation, light frame -> camera frame.
            t_camera_light: (3,) emitter position in the camera frame, metres.
        """
        p = self.check_params(params)
        return self.rotation(p), p[:3].copy()

    @abstractmethod
    def from_pose(
        self, R_camera_light: ArrayLike, t_camera_light: ArrayLike
    ) -> NDArray[np.float64]:
        """Parameters of a pose (the part of it this kind of light can observe).

        Args:
            R_camera_light: (3, 3) rotation.
            t_camera_light: (3,) metres.

        Returns:
            params: (n_params,).
        """

    @abstractmethod
    def jacobian_direction(self, params: ArrayLike, v_light: ArrayLike) -> NDArray[np.float64]:
        """`d (R_camera_light @ v_light) / d (rotation params)` for fixed light-frame vectors.

        For the light-frame image of a fixed camera-frame vector `w`, `v = R^T w`, use
        `dv = -R^T (d(R v) with v held fixed)`, i.e. `-R_camera_light.T @ J`.

        Args:
            params: (n_params,).
            v_light: (3,) or (N, 3) vectors in the light frame.

        Returns:
            J: (3, n_rot) or (N, 3, n_rot).
        """


class IsotropicPose(PoseParameterization):
    """Position only: `params = (x_m, y_m, z_m)`; `R_camera_light = I` (unobservable)."""

    kind: PoseKind = "isotropic"
    n_params = 3
    names = POSITION_NAMES

    def rotation(self, params: ArrayLike) -> NDArray[np.float64]:
        self.check_params(params)
        return np.eye(3)

    def from_pose(
        self, R_camera_light: ArrayLike, t_camera_light: ArrayLike
    ) -> NDArray[np.float64]:
        check_rotation_matrix(R_camera_light, name="R_camera_light")
        return as_finite_array(t_camera_light, (3,), name="t_camera_light")

    def jacobian_direction(self, params: ArrayLike, v_light: ArrayLike) -> NDArray[np.float64]:
        self.check_params(params)
        v = _directions(v_light)
        return np.zeros((*v.shape, 0))


class SymmetricPose(PoseParameterization):
    """Position and axis: `params = (x_m, y_m, z_m, a_rad, b_rad)`.

    `R_camera_light = rotation_from_axis(axis_from_angles(a, b))`, computed as the equal
    `matrix_from_rotvec((-b, a, 0))`, which stays smooth even at `hypot(a, b) = pi`. The roll
    about the light axis is fixed to the minimal rotation from +z (unobservable for a
    symmetric light); `from_pose` discards it.
    """

    kind: PoseKind = "symmetric"
    n_params = 5
    names = (*POSITION_NAMES, "a_rad", "b_rad")

    _DW_DAB = np.array([[0.0, -1.0], [1.0, 0.0], [0.0, 0.0]])
    """d rotvec / d(a, b) for rotvec = (-b, a, 0)."""

    def rotation(self, params: ArrayLike) -> NDArray[np.float64]:
        p = self.check_params(params)
        return matrix_from_rotvec(np.array([-p[4], p[3], 0.0]))

    def from_pose(
        self, R_camera_light: ArrayLike, t_camera_light: ArrayLike
    ) -> NDArray[np.float64]:
        R = check_rotation_matrix(R_camera_light, name="R_camera_light")
        t = as_finite_array(t_camera_light, (3,), name="t_camera_light")
        axis = R[:, 2] / np.linalg.norm(R[:, 2])
        a, b = _angles_from_unit_axis(axis, name="R_camera_light")
        return np.array([*t, a, b])

    def jacobian_direction(self, params: ArrayLike, v_light: ArrayLike) -> NDArray[np.float64]:
        p = self.check_params(params)
        v = _directions(v_light)
        rotvec = np.array([-p[4], p[3], 0.0])
        B = left_jacobian_so3(rotvec) @ self._DW_DAB
        return _rotated_direction_jacobian(matrix_from_rotvec(rotvec), v, B)


class GeneralPose(PoseParameterization):
    """Full pose around a reference rotation: `params = (x_m, y_m, z_m, dx_rad, dy_rad, dz_rad)`.

    `R_camera_light = exp(delta) @ R_ref_camera_light`, `delta` a rotation vector in the camera
    frame (left perturbation). The chart is smooth for `|delta| < pi` around any reference;
    `recentered` moves the reference to the current estimate so `delta` stays small.

    Args:
        R_ref_camera_light: (3, 3) reference rotation; identity by default.
    """

    kind: PoseKind = "general"
    n_params = 6
    names = (*POSITION_NAMES, "dx_rad", "dy_rad", "dz_rad")

    def __init__(self, R_ref_camera_light: ArrayLike | None = None) -> None:
        if R_ref_camera_light is None:
            self._R_ref = np.eye(3)
        else:
            self._R_ref = check_rotation_matrix(R_ref_camera_light, name="R_ref_camera_light")
        self._R_ref.setflags(write=False)

    @property
    def R_ref_camera_light(self) -> NDArray[np.float64]:
        """(3, 3) the reference rotation (read-only)."""
        return self._R_ref

    def __repr__(self) -> str:
        return f"GeneralPose(R_ref_camera_light={self._R_ref.tolist()!r})"

    def rotation(self, params: ArrayLike) -> NDArray[np.float64]:
        p = self.check_params(params)
        return matrix_from_rotvec(p[3:]) @ self._R_ref

    def from_pose(
        self, R_camera_light: ArrayLike, t_camera_light: ArrayLike
    ) -> NDArray[np.float64]:
        R = check_rotation_matrix(R_camera_light, name="R_camera_light")
        t = as_finite_array(t_camera_light, (3,), name="t_camera_light")
        return np.concatenate([t, rotvec_from_matrix(R @ self._R_ref.T)])

    def jacobian_direction(self, params: ArrayLike, v_light: ArrayLike) -> NDArray[np.float64]:
        p = self.check_params(params)
        v = _directions(v_light)
        delta = p[3:]
        R = matrix_from_rotvec(delta) @ self._R_ref
        return _rotated_direction_jacobian(R, v, left_jacobian_so3(delta))

    def recentered(self, params: ArrayLike) -> tuple[GeneralPose, NDArray[np.float64]]:
        """The same pose in a chart centred on it.

        Args:
            params: (6,) in this chart.

        Returns:
            chart: `GeneralPose` whose reference is the pose of `params`.
            params: (6,) in the new chart: the same position, `delta = 0`.
        """
        p = self.check_params(params)
        R = self.rotation(p)
        # Re-orthonormalise so that references stay exact rotations after many recentrings.
        u, _, vt = np.linalg.svd(R)
        return GeneralPose(u @ vt), np.concatenate([p[:3], np.zeros(3)])


def pose_parameterization(
    kind: PoseKind, *, R_ref_camera_light: ArrayLike | None = None
) -> PoseParameterization:
    """The parameterisation for a kind of light.

    Args:
        kind: "isotropic", "symmetric" or "general".
        R_ref_camera_light: (3, 3) reference rotation for "general" (identity if None);
            must be None for the other kinds.

    Returns:
        The parameterisation object.
    """
    if kind == "general":
        return GeneralPose(R_ref_camera_light)
    if R_ref_camera_light is not None:
        raise InputError(
            "R_ref_camera_light", f"expected None for a {kind!r} light (only 'general' uses it)"
        )
    if kind == "isotropic":
        return IsotropicPose()
    if kind == "symmetric":
        return SymmetricPose()
    raise InputError("kind", f"expected 'isotropic', 'symmetric' or 'general', got {kind!r}")


# --------------------------------------------------------------------------------- reports


def describe_pose(R_camera_light: ArrayLike, t_camera_light: ArrayLike) -> dict[str, Any]:
    """A JSON-ready description of a light pose, for result files and the app.

    Args:
        R_camera_light: (3, 3) rotation, light frame -> camera frame.
        t_camera_light: (3,) emitter position in the camera frame, metres.

    Returns:
        dict with
            position_m: [x, y, z] emitter position in the camera frame, metres;
            R_camera_light: 3 x 3 nested list;
            quaternion_wxyz: [w, x, y, z] of `R_camera_light`, `w >= 0`;
            axis_camera: [x, y, z] unit light axis in the camera frame;
            roll_deg, pitch_deg: the paper's angles (see `paper_angles_from_axis`);
            axis_angle_from_optical_axis_deg: angle between the light axis and camera +z.
    """
    R = check_rotation_matrix(R_camera_light, name="R_camera_light")
    t = as_finite_array(t_camera_light, (3,), name="t_camera_light")
    axis = R[:, 2] / np.linalg.norm(R[:, 2])
    roll, pitch = paper_angles_from_axis(axis)
    off_axis = math.atan2(math.hypot(float(axis[0]), float(axis[1])), float(axis[2]))
    return {
        "position_m": [float(c) for c in t],
        "R_camera_light": cast(list[list[float]], R.tolist()),
        "quaternion_wxyz": [float(c) for c in quaternion_wxyz_from_matrix(R)],
        "axis_camera": [float(c) for c in axis],
        "roll_deg": math.degrees(roll),
        "pitch_deg": math.degrees(pitch),
        "axis_angle_from_optical_axis_deg": math.degrees(off_axis),
    }
