"""Parameterisations of the light pose `T_camera_light` for the solver.

Frames (see docs/conventions.md): the light frame L has its origin at the emitter, +z along the
light's central axis and +x as the azimuth reference. The unknown mount is
`R_camera_light` (3, 3), mapping light-frame vectors to camera-frame vectors, and
`t_camera_light` (3,), the emitter position in the (OpenCV) camera frame, metres.
The light axis in the camera frame is therefore `axis_camera = R_camera_light[:, 2]`.

The charts of the light axis (the solver's angles `(a_rad, b_rad)`, the paper's angles)
are in `lightcal.core.light_axis`; this module exports them too.

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

from lightcal.core.light_axis import (
    angles_from_axis,
    angles_from_unit_axis,
    axis_from_angles,
    axis_from_paper_angles,
    axis_jacobian,
    axis_roll_from_rotation,
    paper_angles_from_axis,
    rotation_from_axis,
    rotation_from_axis_roll,
)
from lightcal.core.rotations import (
    as_finite_array,
    check_rotation_matrix,
    left_jacobian_so3,
    matrix_from_rotvec,
    quaternion_wxyz_from_matrix,
    rotvec_from_matrix,
)
from lightcal.errors import InputError

__all__ = [
    "POSITION_NAMES",
    "GeneralPose",
    "IsotropicPose",
    "PoseKind",
    "PoseParameterization",
    "SymmetricPose",
    "angles_from_axis",
    "axis_from_angles",
    "axis_from_paper_angles",
    "axis_jacobian",
    "axis_roll_from_rotation",
    "describe_pose",
    "paper_angles_from_axis",
    "pose_parameterization",
    "rotation_from_axis",
    "rotation_from_axis_roll",
]

PoseKind = Literal["isotropic", "symmetric", "general"]
"""The three kinds of light: which parts of the pose are observable."""

POSITION_NAMES = ("x_m", "y_m", "z_m")
"""Names of the three position parameters, the emitter position in the camera frame."""


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
        a, b = angles_from_unit_axis(axis, name="R_camera_light")
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


def pose_column_map(kind: PoseKind, p: np.ndarray) -> np.ndarray:
    """(6, k) the map from a light's (d/dt, d/d delta) (camera frame: translation, left
    rotation perturbation) to the derivatives of its k pose parameters `p` (k,) of `kind`."""
    k = len(p)
    M = np.zeros((6, k))
    M[:3, :3] = np.eye(3)
    if kind == "symmetric":
        axis = axis_from_angles(p[3], p[4])
        M[3:, 3:] = np.cross(axis[:, None], axis_jacobian(p[3], p[4]), axis=0)
    elif kind == "general":
        M[3:, 3:] = left_jacobian_so3(p[3:6])
    return M
