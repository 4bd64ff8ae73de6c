"""Rotations in 3-D: matrix, unit quaternion (w, x, y, z) and rotation vector.

Conventions:
    - A rotation matrix `R_a_b` (3, 3) maps vectors of frame b to frame a: `v_a = R_a_b @ v_b`.
    - Quaternions are `(w, x, y, z)`, scalar first (as viser's `wxyz`), unit norm. `q` and `-q`
      are the same rotation; the functions here return the one with `w >= 0` (when `w == 0`,
      the first non-zero of `(x, y, z)` is made positive).
    - A rotation vector `rotvec` (3,) is `angle_rad * unit_axis` (right hand), so
      `matrix_from_rotvec(rotvec)` is the exponential map `exp(skew(rotvec))` of SO(3).
    - Perturbations are on the left: `exp(delta) @ R`. Its Jacobian is `left_jacobian_so3`:
      `exp(w + d) = exp(left_jacobian_so3(w) @ d) @ exp(w) + O(|d|^2)`.

Inputs are checked at the boundary: a wrong shape, a non-finite value, a matrix that is not a
rotation or a quaternion that is not of unit norm raises `lightcal.errors.InputError` (a
`ValueError`) naming the argument and saying what was expected and what was given.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lightcal.errors import InputError

ORTHONORMAL_TOL = 1e-6
"""Largest accepted `max |R^T R - I|` for a rotation matrix."""

UNIT_NORM_TOL = 1e-6
"""Largest accepted `| |q| - 1 |` for a unit quaternion (and `| |axis| - 1 |` for a direction)."""

_SERIES_THRESHOLD_RAD = 1e-2
"""Below this angle the coefficient functions use their Taylor series (error < 1e-20)."""


def as_finite_array(value: ArrayLike, shape: tuple[int, ...], *, name: str) -> NDArray[np.float64]:
    """Convert `value` to a float64 array of exactly `shape`, all entries finite.

    Args:
        value: Anything `np.asarray` accepts.
        shape: The required shape, e.g. `(3,)`.
        name: The argument name, used as the error source.

    Returns:
        array: `shape` float64, a new array.

    Raises:
        InputError: Wrong shape or a NaN / infinite entry.
    """
    try:
        array = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(name, f"expected a numeric array of shape {shape}, got {value!r}") from exc
    if array.shape != shape:
        raise InputError(name, f"expected shape {shape}, got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise InputError(name, f"expected finite values, got {array.tolist()}")
    return array


def check_rotation_matrix(R: ArrayLike, *, name: str = "R") -> NDArray[np.float64]:
    """Check that `R` is a proper rotation matrix and return it as float64.

    Args:
        R: (3, 3) orthonormal with determinant +1 (within `ORTHONORMAL_TOL`).
        name: The argument name, used as the error source.

    Returns:
        R: (3, 3) float64, a new array (not re-orthonormalised).

    Raises:
        InputError: Wrong shape, non-finite entries, not orthonormal, or a reflection.
    """
    matrix = as_finite_array(R, (3, 3), name=name)
    error = float(np.max(np.abs(matrix.T @ matrix - np.eye(3))))
    if error > ORTHONORMAL_TOL:
        raise InputError(
            name,
            f"expected a rotation matrix (max |R^T R - I| <= {ORTHONORMAL_TOL:g}), "
            f"got max |R^T R - I| = {error:.3g}",
        )
    det = float(np.linalg.det(matrix))
    if det < 0.0:
        raise InputError(
            name, f"expected a rotation matrix with det +1, got a reflection (det {det:.6g})"
        )
    return matrix


def skew(v: ArrayLike) -> NDArray[np.float64]:
    """Cross-product matrix: `skew(v) @ u == np.cross(v, u)`.

    Args:
        v: (3,).

    Returns:
        S: (3, 3) antisymmetric.
    """
    x, y, z = as_finite_array(v, (3,), name="v")
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def _so3_coefficients(theta: float) -> tuple[float, float, float]:
    """`sin(t)/t`, `(1 - cos t)/t^2`, `(t - sin t)/t^3` at `t = theta >= 0`, series near 0."""
    if theta < _SERIES_THRESHOLD_RAD:
        t2 = theta * theta
        a = 1.0 - t2 / 6.0 * (1.0 - t2 / 20.0 * (1.0 - t2 / 42.0))
        b = 0.5 - t2 / 24.0 * (1.0 - t2 / 30.0 * (1.0 - t2 / 56.0))
        c = 1.0 / 6.0 - t2 / 120.0 * (1.0 - t2 / 42.0 * (1.0 - t2 / 72.0))
        return a, b, c
    half_sin = np.sin(0.5 * theta)
    a = float(np.sin(theta) / theta)
    b = float(2.0 * half_sin * half_sin / (theta * theta))
    c = float((theta - np.sin(theta)) / theta**3)
    return a, b, c


def matrix_from_rotvec(rotvec: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrix of a rotation vector (Rodrigues' formula, the SO(3) exponential).

    Args:
        rotvec: (3,) `angle_rad * unit_axis`; any length (angles beyond pi wrap around).

    Returns:
        R: (3, 3) rotation matrix.
    """
    w = as_finite_array(rotvec, (3,), name="rotvec")
    theta = float(np.linalg.norm(w))
    a, b, _ = _so3_coefficients(theta)
    K = skew(w)
    return np.eye(3) + a * K + b * (K @ K)


def rotvec_from_matrix(R: ArrayLike) -> NDArray[np.float64]:
    """Rotation vector of a rotation matrix (the SO(3) logarithm).

    Args:
        R: (3, 3) rotation matrix.

    Returns:
        rotvec: (3,) with angle `|rotvec|` in [0, pi].
    """
    w, x, y, z = quaternion_wxyz_from_matrix(R)  # w >= 0: angle in [0, pi]
    vector = np.array([x, y, z])
    half_sin = float(np.linalg.norm(vector))
    angle = 2.0 * math.atan2(half_sin, w)
    if angle <= 1e-3:  # angle / sin(angle / 2) by its series (relative error < 1e-19)
        a2 = angle * angle
        scale = 2.0 + a2 / 12.0 + 7.0 * a2 * a2 / 2880.0
    else:
        scale = angle / half_sin
    return scale * vector


def _canonical_quaternion_sign(q_wxyz: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return `q` or `-q`, whichever has `w > 0` (ties: first non-zero component positive)."""
    for component in q_wxyz:
        if component != 0.0:
            return q_wxyz if component > 0.0 else -q_wxyz
    return q_wxyz


def quaternion_wxyz_from_matrix(R: ArrayLike) -> NDArray[np.float64]:
    """Unit quaternion of a rotation matrix, scalar first, with `w >= 0`.

    Args:
        R: (3, 3) rotation matrix.

    Returns:
        q_wxyz: (4,) `(w, x, y, z)`, unit norm, `w >= 0`.
    """
    m = check_rotation_matrix(R, name="R")
    # Shepperd's method: start from the largest of 4w^2, 4x^2, 4y^2, 4z^2 (all from the
    # diagonal), so that the division below is by a number >= 1 and no precision is lost.
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    k = int(np.argmax([trace, m[0, 0], m[1, 1], m[2, 2]]))
    if k == 0:
        q = np.array([1.0 + trace, m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]])
    else:
        i = k - 1
        j, l = (i + 1) % 3, (i + 2) % 3
        q = np.empty(4)
        q[0] = m[l, j] - m[j, l]
        q[1 + i] = 1.0 + 2.0 * m[i, i] - trace
        q[1 + j] = m[j, i] + m[i, j]
        q[1 + l] = m[l, i] + m[i, l]
    return _canonical_quaternion_sign(q / np.linalg.norm(q))


def matrix_from_quaternion_wxyz(q_wxyz: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrix of a unit quaternion `(w, x, y, z)` (either sign).

    Args:
        q_wxyz: (4,) scalar first, norm within `UNIT_NORM_TOL` of 1 (it is re-normalised).

    Returns:
        R: (3, 3) rotation matrix.

    Raises:
        InputError: Wrong shape, non-finite entries or a norm too far from 1.
    """
    q = as_finite_array(q_wxyz, (4,), name="q_wxyz")
    norm = float(np.linalg.norm(q))
    if abs(norm - 1.0) > UNIT_NORM_TOL:
        raise InputError(
            "q_wxyz",
            f"expected a unit quaternion (norm 1 within {UNIT_NORM_TOL:g}), got norm {norm:.6g}",
        )
    w, x, y, z = q / norm
    return np.array(
        [
            [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
            [2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)],
            [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)],
        ]
    )


def left_jacobian_so3(rotvec: ArrayLike) -> NDArray[np.float64]:
    """Left Jacobian of SO(3): `exp(w + d) = exp(J_l(w) d) exp(w)` to first order in `d`.

    `J_l(w) = I + (1 - cos t)/t^2 K + (t - sin t)/t^3 K^2` with `K = skew(w)`, `t = |w|`,
    evaluated with Taylor series for small `t` (so `J_l(0) = I` exactly). Consequently, for a
    fixed vector `v`, `d(exp(w) v)/dw = -skew(exp(w) v) @ J_l(w)`.

    Args:
        rotvec: (3,) the rotation vector `w`.

    Returns:
        J_l: (3, 3).
    """
    w = as_finite_array(rotvec, (3,), name="rotvec")
    theta = float(np.linalg.norm(w))
    _, b, c = _so3_coefficients(theta)
    K = skew(w)
    return np.eye(3) + b * K + c * (K @ K)


def in_normal_frames(
    vectors: NDArray[np.float64], normals: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(N, 3) vectors (N, 3) turned by the minimal rotation taking each unit normal (N, 3)
    to +z (a surface's local frame: z along its normal; dot products kept). Normals
    pointing along -z are not turned (the rotation is not unique there)."""
    w = np.cross(normals, np.array([0.0, 0.0, 1.0]))
    c = normals[:, 2:3]
    wv = np.cross(w, vectors)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(c > -1.0, vectors + wv + np.cross(w, wv) / (1.0 + c), vectors)
