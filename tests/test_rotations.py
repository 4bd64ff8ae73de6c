"""Tests of lightcal.core.rotations: hand cases, round trips, scipy agreement, Jacobians, errors."""

from __future__ import annotations

import re
from collections.abc import Callable

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from lightcal.core.rotations import (
    check_rotation_matrix,
    left_jacobian_so3,
    matrix_from_quaternion_wxyz,
    matrix_from_rotvec,
    quaternion_wxyz_from_matrix,
    rotvec_from_matrix,
    skew,
)
from lightcal.errors import InputError

FD_STEP = 1e-5


def random_rotvecs(rng: np.random.Generator, n: int, max_angle: float) -> np.ndarray:
    """(n, 3) rotation vectors with uniform random axes and angles in [0, max_angle)."""
    axes = rng.normal(size=(n, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    return axes * rng.uniform(0.0, max_angle, size=(n, 1))


def test_skew_hand_case_and_cross_product() -> None:
    expected = np.array([[0.0, -3.0, 2.0], [3.0, 0.0, -1.0], [-2.0, 1.0, 0.0]])
    np.testing.assert_array_equal(skew([1.0, 2.0, 3.0]), expected)
    rng = np.random.default_rng(0)
    v, u = rng.normal(size=(2, 3))
    np.testing.assert_allclose(skew(v) @ u, np.cross(v, u), atol=1e-15)


def test_matrix_from_rotvec_hand_cases() -> None:
    np.testing.assert_array_equal(matrix_from_rotvec([0.0, 0.0, 0.0]), np.eye(3))
    quarter_turn_z = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(
        matrix_from_rotvec([0.0, 0.0, np.pi / 2]), quarter_turn_z, atol=1e-15
    )
    half_turn_x = np.diag([1.0, -1.0, -1.0])
    np.testing.assert_allclose(matrix_from_rotvec([np.pi, 0.0, 0.0]), half_turn_x, atol=1e-15)


@pytest.mark.parametrize("angle", [0.0, 1e-12, 1e-6, 0.9999e-2, 1.0001e-2, 0.5, 2.0, 3.1])
def test_matrix_from_rotvec_matches_scipy(angle: float) -> None:
    rng = np.random.default_rng(1)
    axis = rng.normal(size=3)
    rotvec = angle * axis / np.linalg.norm(axis)
    expected = Rotation.from_rotvec(rotvec).as_matrix()
    np.testing.assert_allclose(matrix_from_rotvec(rotvec), expected, atol=1e-15)


def test_rotvec_round_trip() -> None:
    rng = np.random.default_rng(2)
    rotvecs = random_rotvecs(rng, 100, np.pi - 1e-6)
    rotvecs[:3] = [[0.0, 0.0, 0.0], [1e-10, 0.0, -2e-10], [0.0, 1e-4, 0.0]]
    for rotvec in rotvecs:
        np.testing.assert_allclose(
            rotvec_from_matrix(matrix_from_rotvec(rotvec)), rotvec, atol=1e-12
        )


def test_rotvec_from_matrix_at_half_turn() -> None:
    rotvec = rotvec_from_matrix(np.diag([1.0, -1.0, -1.0]))
    np.testing.assert_allclose(np.abs(rotvec), [np.pi, 0.0, 0.0], atol=1e-12)


def test_quaternion_hand_cases_and_sign_convention() -> None:
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    # +90 degrees about z.
    q = quaternion_wxyz_from_matrix(matrix_from_rotvec([0.0, 0.0, np.pi / 2]))
    np.testing.assert_allclose(q, [c, 0.0, 0.0, s], atol=1e-15)
    # 270 degrees about z is -90 degrees: w >= 0 picks (c, 0, 0, -s), not (-c, 0, 0, s).
    q = quaternion_wxyz_from_matrix(matrix_from_rotvec([0.0, 0.0, 1.5 * np.pi]))
    np.testing.assert_allclose(q, [c, 0.0, 0.0, -s], atol=1e-15)
    # w == 0 (half turn): the first non-zero component is made positive.
    q = quaternion_wxyz_from_matrix(np.diag([1.0, -1.0, -1.0]))
    np.testing.assert_array_equal(q, [0.0, 1.0, 0.0, 0.0])
    np.testing.assert_array_equal(quaternion_wxyz_from_matrix(np.eye(3)), [1.0, 0.0, 0.0, 0.0])


def test_quaternion_round_trip_and_scipy_agreement() -> None:
    rng = np.random.default_rng(3)
    for rotvec in random_rotvecs(rng, 100, 2.0 * np.pi):
        R = matrix_from_rotvec(rotvec)
        q = quaternion_wxyz_from_matrix(R)
        assert q[0] >= 0.0
        assert abs(np.linalg.norm(q) - 1.0) < 1e-14
        np.testing.assert_allclose(matrix_from_quaternion_wxyz(q), R, atol=1e-14)
        np.testing.assert_allclose(matrix_from_quaternion_wxyz(-q), R, atol=1e-14)
        x, y, z, w = Rotation.from_matrix(R).as_quat()
        np.testing.assert_allclose(q, np.sign(w) * np.array([w, x, y, z]), atol=1e-14)


def test_matrix_from_quaternion_renormalises_within_tolerance() -> None:
    q = np.array([0.5, 0.5, 0.5, 0.5]) * (1.0 + 5e-7)
    R = matrix_from_quaternion_wxyz(q)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-15)
    # (0.5, 0.5, 0.5, 0.5) is +120 degrees about (1, 1, 1): x -> y -> z -> x.
    np.testing.assert_allclose(R @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)


def direction_jacobian_fd(rotvec: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Central differences of exp(w) v with respect to w: (3, 3)."""
    columns = []
    for k in range(3):
        step = np.zeros(3)
        step[k] = FD_STEP
        plus = matrix_from_rotvec(rotvec + step) @ v
        minus = matrix_from_rotvec(rotvec - step) @ v
        columns.append((plus - minus) / (2.0 * FD_STEP))
    return np.stack(columns, axis=1)


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-4, 0.9999e-2, 1.0001e-2, 0.3, 1.5, 3.0])
def test_left_jacobian_against_finite_differences(angle: float) -> None:
    rng = np.random.default_rng(4)
    axis = rng.normal(size=3)
    rotvec = angle * axis / np.linalg.norm(axis)
    v = rng.normal(size=3)
    analytic = -skew(matrix_from_rotvec(rotvec) @ v) @ left_jacobian_so3(rotvec)
    np.testing.assert_allclose(analytic, direction_jacobian_fd(rotvec, v), atol=1e-7)


def test_left_jacobian_identities() -> None:
    np.testing.assert_array_equal(left_jacobian_so3([0.0, 0.0, 0.0]), np.eye(3))
    rng = np.random.default_rng(5)
    for rotvec in random_rotvecs(rng, 20, 3.0):
        J_l = left_jacobian_so3(rotvec)
        # J_l(w) w = w, and J_l(w) = exp(w) J_r(w) with J_r(w) = J_l(-w).
        np.testing.assert_allclose(J_l @ rotvec, rotvec, atol=1e-14)
        np.testing.assert_allclose(
            J_l, matrix_from_rotvec(rotvec) @ left_jacobian_so3(-rotvec), atol=1e-14
        )


def test_left_jacobian_continuous_at_series_threshold() -> None:
    axis = np.array([0.6, -0.8, 0.0])
    below = left_jacobian_so3(axis * (1e-2 - 1e-12))
    above = left_jacobian_so3(axis * (1e-2 + 1e-12))
    np.testing.assert_allclose(below, above, atol=1e-13)


def test_check_rotation_matrix_accepts_rotation() -> None:
    R = matrix_from_rotvec([0.1, 0.2, 0.3])
    np.testing.assert_array_equal(check_rotation_matrix(R), R)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: skew([1.0, 2.0]), "v: expected shape (3,), got (2,)"),
        (lambda: matrix_from_rotvec([0.0, np.nan, 0.0]), "rotvec: expected finite values, got"),
        (lambda: left_jacobian_so3(np.zeros((3, 1))), "rotvec: expected shape (3,), got (3, 1)"),
        (lambda: rotvec_from_matrix(np.eye(4)), "R: expected shape (3, 3), got (4, 4)"),
        (
            lambda: rotvec_from_matrix(2.0 * np.eye(3)),
            "R: expected a rotation matrix (max |R^T R - I| <= 1e-06), got max |R^T R - I| = 3",
        ),
        (
            lambda: quaternion_wxyz_from_matrix(np.diag([1.0, 1.0, -1.0])),
            "R: expected a rotation matrix with det +1, got a reflection (det -1)",
        ),
        (
            lambda: matrix_from_quaternion_wxyz([1.5, 0.0, 0.0, 0.0]),
            "q_wxyz: expected a unit quaternion (norm 1 within 1e-06), got norm 1.5",
        ),
        (
            lambda: matrix_from_quaternion_wxyz([1.0, 0.0, 0.0]),
            "q_wxyz: expected shape (4,), got (3,)",
        ),
        (
            lambda: matrix_from_quaternion_wxyz(["w", "x", "y", "z"]),
            "q_wxyz: expected a numeric array of shape (4,), got",
        ),
    ],
)
def test_errors(call: Callable[[], object], message: str) -> None:
    with pytest.raises(InputError, match="^" + re.escape(message)):
        call()


@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("angle", [1e-9, 1e-3, 0.5, 2.0, np.pi - 1e-9, np.pi])
def test_rotvec_and_quaternion_in_every_branch_agree_with_scipy(axis: int, angle: float) -> None:
    """Our Shepperd quaternion and SO(3) logarithm (no SciPy import at start-up) against
    SciPy's, about each axis (each branch of the largest-diagonal choice) and a tilted one,
    from near identity to the half turn."""
    rng = np.random.default_rng(axis)
    for direction in (np.eye(3)[axis], np.eye(3)[axis] + 0.1 * rng.normal(size=3)):
        rotvec = angle * direction / np.linalg.norm(direction)
        R = matrix_from_rotvec(rotvec)
        expected = Rotation.from_matrix(R).as_rotvec()
        got = rotvec_from_matrix(R)
        if angle < np.pi - 1e-6:
            np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-15)
        else:  # at the half turn +axis and -axis are one rotation
            np.testing.assert_allclose(matrix_from_rotvec(got), R, atol=1e-14)
            assert abs(np.linalg.norm(got) - angle) < 1e-12
        x, y, z, w = Rotation.from_matrix(R).as_quat()
        q = quaternion_wxyz_from_matrix(R)
        np.testing.assert_allclose(np.abs(q), np.abs([w, x, y, z]), atol=2e-16 + 1e-15)
        np.testing.assert_allclose(matrix_from_quaternion_wxyz(q), R, atol=1e-15)
