"""Tests of lightcal.core.pose: the axis charts, the three parameterisations and describe_pose."""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable

import numpy as np
import pytest

from lightcal.core.pose import (
    GeneralPose,
    IsotropicPose,
    PoseParameterization,
    SymmetricPose,
    angles_from_axis,
    axis_from_angles,
    axis_from_paper_angles,
    axis_jacobian,
    describe_pose,
    paper_angles_from_axis,
    pose_parameterization,
    rotation_from_axis,
)
from lightcal.core.rotations import matrix_from_rotvec, rotvec_from_matrix
from lightcal.errors import InputError

FD_STEP = 1e-5

# (a, b) points that exercise the chart: the origin, the series region and its threshold
# (|theta| = 1e-2), ordinary tilts and tilts close to the singular antipode (theta = pi).
AB_POINTS = [
    (0.0, 0.0),
    (1e-9, -2e-9),
    (-3e-5, 1e-5),
    (0.6e-2, 0.79999e-2),
    (0.6e-2, 0.80001e-2),
    (0.3, -0.2),
    (-1.0, 0.4),
    (2.0, 1.5),
    (-0.1, -3.0),
]


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    axis = rng.normal(size=3)
    return matrix_from_rotvec(rng.uniform(0.0, np.pi) * axis / np.linalg.norm(axis))


def random_unit_vectors(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def central_differences(f: Callable[[np.ndarray], np.ndarray], x: np.ndarray) -> np.ndarray:
    """d f / d x by central differences: (*f.shape, len(x))."""
    columns = []
    for k in range(len(x)):
        step = np.zeros(len(x))
        step[k] = FD_STEP
        columns.append((f(x + step) - f(x - step)) / (2.0 * FD_STEP))
    return np.stack(columns, axis=-1)


# ------------------------------------------------------------------------ the (a, b) chart


def test_axis_from_angles_hand_cases() -> None:
    np.testing.assert_array_equal(axis_from_angles(0.0, 0.0), [0.0, 0.0, 1.0])
    np.testing.assert_allclose(axis_from_angles(np.pi / 2, 0.0), [1.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(axis_from_angles(0.0, -np.pi / 2), [0.0, -1.0, 0.0], atol=1e-15)
    # theta = 0.5 towards (0.6, 0.8).
    s = math.sin(0.5)
    np.testing.assert_allclose(
        axis_from_angles(0.3, 0.4), [0.6 * s, 0.8 * s, math.cos(0.5)], atol=1e-15
    )
    np.testing.assert_allclose(axis_from_angles(np.pi, 0.0), [0.0, 0.0, -1.0], atol=1e-15)


def test_angles_from_axis_hand_cases() -> None:
    assert angles_from_axis([0.0, 0.0, 1.0]) == (0.0, 0.0)
    np.testing.assert_allclose(angles_from_axis([1.0, 0.0, 0.0]), [np.pi / 2, 0.0], atol=1e-15)
    np.testing.assert_allclose(angles_from_axis([0.0, 1.0, 0.0]), [0.0, np.pi / 2], atol=1e-15)
    # Tiny tilt: the angle equals the tilt, no series needed.
    np.testing.assert_allclose(
        angles_from_axis([1e-12, 0.0, 1.0]), [1e-12, 0.0], rtol=1e-15, atol=0.0
    )


def test_angles_round_trip() -> None:
    rng = np.random.default_rng(10)
    points = [*AB_POINTS]
    for theta in [*rng.uniform(0.0, np.pi - 1e-3, size=50), 1e-15, 1e-7, np.pi - 1e-6]:
        phi = rng.uniform(-np.pi, np.pi)
        points.append((theta * math.cos(phi), theta * math.sin(phi)))
    for a, b in points:
        axis = axis_from_angles(a, b)
        assert abs(np.linalg.norm(axis) - 1.0) < 1e-15
        np.testing.assert_allclose(angles_from_axis(axis), [a, b], rtol=1e-9, atol=1e-15)


def test_axes_round_trip() -> None:
    rng = np.random.default_rng(11)
    for axis in random_unit_vectors(rng, 50):
        np.testing.assert_allclose(axis_from_angles(*angles_from_axis(axis)), axis, atol=1e-14)


@pytest.mark.parametrize(("a", "b"), AB_POINTS)
def test_axis_jacobian_against_finite_differences(a: float, b: float) -> None:
    numeric = central_differences(lambda ab: axis_from_angles(*ab), np.array([a, b]))
    np.testing.assert_allclose(axis_jacobian(a, b), numeric, atol=1e-7)


def test_axis_jacobian_at_origin_and_continuity() -> None:
    np.testing.assert_array_equal(axis_jacobian(0.0, 0.0), [[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]])
    # Crossing a = b = 0 along a line: axis and Jacobian change by O(step) only.
    for direction in [(1.0, 0.0), (0.0, 1.0), (0.6, -0.8)]:
        d = np.array(direction)
        for eps in [1e-12, 1e-8, 1e-4]:
            plus, minus = eps * d, -eps * d
            np.testing.assert_allclose(
                axis_from_angles(*plus), axis_from_angles(*minus), atol=2.0 * eps + 1e-15
            )
            np.testing.assert_allclose(
                axis_jacobian(*plus), axis_jacobian(*minus), atol=2.0 * eps + 1e-15
            )
            np.testing.assert_allclose(
                SymmetricPose().rotation([0, 0, 0, *plus]),
                SymmetricPose().rotation([0, 0, 0, *minus]),
                atol=2.0 * eps + 1e-15,
            )
    # The series and closed-form branches agree at the threshold theta = 1e-2.
    below, above = 1e-2 - 1e-13, 1e-2 + 1e-13
    np.testing.assert_allclose(axis_jacobian(below, 0.0), axis_jacobian(above, 0.0), atol=1e-12)
    np.testing.assert_allclose(
        axis_from_angles(below, 0.0), axis_from_angles(above, 0.0), atol=1e-12
    )


def test_rotation_from_axis_identity_and_minimality() -> None:
    rng = np.random.default_rng(12)
    axes = [*random_unit_vectors(rng, 50), np.array([0.0, 0.0, 1.0])]
    axes += [axis_from_angles(a, b) for a, b in AB_POINTS]
    for axis in axes:
        R = rotation_from_axis(axis)
        a, b = angles_from_axis(axis)
        np.testing.assert_allclose(R, matrix_from_rotvec([-b, a, 0.0]), atol=1e-12)
        np.testing.assert_allclose(R[:, 2], axis, atol=1e-14)
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-14)
        assert abs(np.linalg.det(R) - 1.0) < 1e-14
        # Minimal: the rotation axis lies in the camera xy plane (no twist about z).
        assert abs(rotvec_from_matrix(R)[2]) < 1e-12


def test_rotation_from_axis_near_antipode_is_a_rotation() -> None:
    axis = axis_from_angles(0.0, np.pi - 1e-9)
    R = rotation_from_axis(axis)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(R[:, 2], axis, atol=1e-12)
    np.testing.assert_allclose(R, matrix_from_rotvec([-(np.pi - 1e-9), 0.0, 0.0]), atol=1e-12)


# ------------------------------------------------------------------------- the paper's angles


def test_paper_angles_hand_cases() -> None:
    deg30 = math.radians(30.0)
    np.testing.assert_allclose(
        axis_from_paper_angles(0.0, deg30), [0.5, 0.0, math.sqrt(3) / 2], atol=1e-15
    )
    # Positive roll about camera x tilts the axis towards -y.
    np.testing.assert_allclose(
        axis_from_paper_angles(deg30, 0.0), [0.0, -0.5, math.sqrt(3) / 2], atol=1e-15
    )
    np.testing.assert_array_equal(axis_from_paper_angles(0.0, 0.0), [0.0, 0.0, 1.0])
    assert paper_angles_from_axis([0.0, 0.0, 1.0]) == (0.0, 0.0)
    np.testing.assert_allclose(
        paper_angles_from_axis([0.5, 0.0, math.sqrt(3) / 2]), [0.0, deg30], atol=1e-15
    )
    # Gimbal singularity: roll undefined, reported as 0.
    np.testing.assert_allclose(paper_angles_from_axis([1.0, 0.0, 0.0]), [0.0, np.pi / 2])


def test_paper_angles_round_trip() -> None:
    rng = np.random.default_rng(13)
    for _ in range(50):
        roll, pitch = rng.uniform(-np.pi, np.pi), rng.uniform(-np.pi / 2, np.pi / 2)
        axis = axis_from_paper_angles(roll, pitch)
        np.testing.assert_allclose(paper_angles_from_axis(axis), [roll, pitch], atol=1e-12)
        # The same axis from the definition with explicit matrices.
        Rx = matrix_from_rotvec([roll, 0.0, 0.0])
        Ry = matrix_from_rotvec([0.0, pitch, 0.0])
        np.testing.assert_allclose(axis, Rx @ Ry @ [0.0, 0.0, 1.0], atol=1e-14)


# ---------------------------------------------------------------------- parameterisations


def test_interface_attributes() -> None:
    iso, sym, gen = IsotropicPose(), SymmetricPose(), GeneralPose()
    assert (iso.kind, iso.n_params, iso.n_rot) == ("isotropic", 3, 0)
    assert (sym.kind, sym.n_params, sym.n_rot) == ("symmetric", 5, 2)
    assert (gen.kind, gen.n_params, gen.n_rot) == ("general", 6, 3)
    assert iso.names == ("x_m", "y_m", "z_m")
    assert sym.names == ("x_m", "y_m", "z_m", "a_rad", "b_rad")
    assert gen.names == ("x_m", "y_m", "z_m", "dx_rad", "dy_rad", "dz_rad")
    for chart in (iso, sym, gen):
        assert isinstance(chart, PoseParameterization)
        assert len(chart.names) == chart.n_params
        assert pose_parameterization(chart.kind).kind == chart.kind


def test_isotropic_round_trip() -> None:
    chart = IsotropicPose()
    R, t = chart.to_pose([0.1, -0.2, 0.05])
    np.testing.assert_array_equal(R, np.eye(3))
    np.testing.assert_array_equal(t, [0.1, -0.2, 0.05])
    rng = np.random.default_rng(14)
    np.testing.assert_array_equal(chart.from_pose(random_rotation(rng), t), t)


def test_symmetric_round_trip() -> None:
    chart = SymmetricPose()
    rng = np.random.default_rng(15)
    for a, b in AB_POINTS:
        params = np.array([*rng.uniform(-0.3, 0.3, size=3), a, b])
        R, t = chart.to_pose(params)
        np.testing.assert_allclose(R[:, 2], axis_from_angles(a, b), atol=1e-14)
        np.testing.assert_allclose(R, rotation_from_axis(axis_from_angles(a, b)), atol=1e-12)
        np.testing.assert_allclose(chart.from_pose(R, t), params, rtol=1e-9, atol=1e-15)


def test_symmetric_from_pose_discards_roll() -> None:
    chart = SymmetricPose()
    rng = np.random.default_rng(16)
    t = np.array([0.05, 0.0, -0.01])
    for _ in range(20):
        R = random_rotation(rng)
        twisted = R @ matrix_from_rotvec([0.0, 0.0, rng.uniform(-np.pi, np.pi)])
        params = chart.from_pose(twisted, t)
        np.testing.assert_allclose(params, chart.from_pose(R, t), atol=1e-12)
        R_back, _ = chart.to_pose(params)
        np.testing.assert_allclose(R_back[:, 2], R[:, 2], atol=1e-12)
        np.testing.assert_allclose(R_back, rotation_from_axis(R[:, 2]), atol=1e-12)


def test_general_round_trip_and_recentering() -> None:
    rng = np.random.default_rng(17)
    for _ in range(20):
        chart = GeneralPose(random_rotation(rng))
        delta = rng.normal(size=3)
        delta *= rng.uniform(0.0, np.pi - 0.01) / np.linalg.norm(delta)
        for d in (delta, np.zeros(3), np.array([1e-10, 0.0, -1e-10])):
            params = np.array([*rng.uniform(-0.3, 0.3, size=3), *d])
            R, t = chart.to_pose(params)
            np.testing.assert_allclose(R, matrix_from_rotvec(d) @ chart.R_ref_camera_light)
            np.testing.assert_allclose(chart.from_pose(R, t), params, atol=1e-12)
            new_chart, new_params = chart.recentered(params)
            np.testing.assert_array_equal(new_params[3:], [0.0, 0.0, 0.0])
            np.testing.assert_array_equal(new_params[:3], params[:3])
            R_new, t_new = new_chart.to_pose(new_params)
            np.testing.assert_allclose(R_new, R, atol=1e-14)
            np.testing.assert_array_equal(t_new, t)
    # Default reference is the identity; the reference is read-only.
    chart = GeneralPose()
    np.testing.assert_array_equal(chart.R_ref_camera_light, np.eye(3))
    with pytest.raises(ValueError, match="read-only"):
        chart.R_ref_camera_light[0, 0] = 2.0


def symmetric_params() -> list[np.ndarray]:
    return [np.array([0.1, 0.0, -0.05, a, b]) for a, b in AB_POINTS]


def general_charts_and_params() -> list[tuple[GeneralPose, np.ndarray]]:
    rng = np.random.default_rng(18)
    cases = []
    for delta in ([0.0, 0.0, 0.0], [1e-9, 0.0, 2e-9], [0.0, 0.99e-2, 0.0], [0.3, -1.0, 2.0]):
        cases.append((GeneralPose(random_rotation(rng)), np.array([0.1, 0.2, 0.3, *delta])))
    return cases


def rotated_vector(
    chart: PoseParameterization, position_m: np.ndarray, v_light: np.ndarray
) -> Callable[[np.ndarray], np.ndarray]:
    """The function rotation params -> R_camera_light @ v_light, for finite differences."""

    def rotated(rotation_params: np.ndarray) -> np.ndarray:
        return chart.rotation([*position_m, *rotation_params]) @ v_light

    return rotated


def test_symmetric_jacobian_against_finite_differences() -> None:
    chart = SymmetricPose()
    rng = np.random.default_rng(19)
    v_batch = rng.normal(size=(4, 3))
    for params in symmetric_params():
        analytic = chart.jacobian_direction(params, v_batch)
        assert analytic.shape == (4, 3, 2)
        for v, J in zip(v_batch, analytic, strict=True):
            numeric = central_differences(rotated_vector(chart, params[:3], v), params[3:])
            np.testing.assert_allclose(J, numeric, atol=1e-7)
            np.testing.assert_allclose(chart.jacobian_direction(params, v), J, atol=1e-15)
        # For the light axis itself this is the chart's axis Jacobian.
        np.testing.assert_allclose(
            chart.jacobian_direction(params, [0.0, 0.0, 1.0]),
            axis_jacobian(*params[3:]),
            atol=1e-14,
        )


def test_general_jacobian_against_finite_differences() -> None:
    rng = np.random.default_rng(20)
    v_batch = rng.normal(size=(3, 3))
    for chart, params in general_charts_and_params():
        analytic = chart.jacobian_direction(params, v_batch)
        assert analytic.shape == (3, 3, 3)
        for v, J in zip(v_batch, analytic, strict=True):
            numeric = central_differences(rotated_vector(chart, params[:3], v), params[3:])
            np.testing.assert_allclose(J, numeric, atol=1e-7)
            np.testing.assert_allclose(chart.jacobian_direction(params, v), J, atol=1e-15)


def test_isotropic_jacobian_is_empty() -> None:
    chart = IsotropicPose()
    assert chart.jacobian_direction([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]).shape == (3, 0)
    assert chart.jacobian_direction([0.0, 0.0, 0.0], np.ones((5, 3))).shape == (5, 3, 0)


# ---------------------------------------------------------------------------- describe_pose


def test_describe_pose_hand_case() -> None:
    # Minimal rotation taking +z to (sin 30, 0, cos 30): 30 degrees about +y.
    R = rotation_from_axis(axis_from_paper_angles(0.0, math.radians(30.0)))
    info = describe_pose(R, [0.1, -0.02, 0.0])
    assert set(info) == {
        "position_m",
        "R_camera_light",
        "quaternion_wxyz",
        "axis_camera",
        "roll_deg",
        "pitch_deg",
        "axis_angle_from_optical_axis_deg",
    }
    assert info["position_m"] == [0.1, -0.02, 0.0]
    np.testing.assert_allclose(info["R_camera_light"], R, atol=0.0)
    c15, s15 = math.cos(math.radians(15.0)), math.sin(math.radians(15.0))
    np.testing.assert_allclose(info["quaternion_wxyz"], [c15, 0.0, s15, 0.0], atol=1e-15)
    np.testing.assert_allclose(info["axis_camera"], [0.5, 0.0, math.sqrt(3) / 2], atol=1e-15)
    assert info["roll_deg"] == 0.0
    assert info["pitch_deg"] == pytest.approx(30.0, abs=1e-12)
    assert info["axis_angle_from_optical_axis_deg"] == pytest.approx(30.0, abs=1e-12)
    json.dumps(info)  # plain Python types only


def test_describe_pose_off_axis_angle() -> None:
    # Roll 30 and pitch 40 degrees: cos(off-axis) = cos(30) cos(40).
    axis = axis_from_paper_angles(math.radians(30.0), math.radians(40.0))
    info = describe_pose(rotation_from_axis(axis), [0.0, 0.0, 0.0])
    expected = math.degrees(math.acos(math.cos(math.radians(30.0)) * math.cos(math.radians(40.0))))
    assert info["axis_angle_from_optical_axis_deg"] == pytest.approx(expected, abs=1e-12)
    assert info["roll_deg"] == pytest.approx(30.0, abs=1e-12)
    assert info["pitch_deg"] == pytest.approx(40.0, abs=1e-12)


# ------------------------------------------------------------------------------------ errors


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (
            lambda: angles_from_axis([0.0, 0.0, -1.0]),
            "axis_camera: expected an axis other than -z (where the angles (a, b) are singular),"
            " got (0, 0, -1)",
        ),
        (
            lambda: rotation_from_axis([0.0, 0.0, -1.0]),
            "axis_camera: expected an axis other than -z (where the minimal rotation from +z is"
            " not unique), got (0, 0, -1)",
        ),
        (
            lambda: angles_from_axis([0.0, 0.0, 2.0]),
            "axis_camera: expected a unit vector (norm 1 within 1e-06), got norm 2",
        ),
        (
            lambda: paper_angles_from_axis([1.0, 1.0]),
            "axis_camera: expected shape (3,), got (2,)",
        ),
        (
            lambda: axis_from_angles(float("nan"), 0.0),
            "a_rad: expected a finite real number, got nan",
        ),
        (
            lambda: axis_jacobian(0.0, [1.0, 2.0]),  # type: ignore[arg-type]
            "b_rad: expected a scalar, got an array of shape (2,)",
        ),
        (
            lambda: axis_from_paper_angles(0.0, "x"),  # type: ignore[arg-type]
            "pitch_rad: expected a finite real number, got 'x'",
        ),
        (lambda: SymmetricPose().to_pose([0.0, 0.0, 0.0]), "params: expected shape (5,), got (3,)"),
        (
            lambda: GeneralPose().to_pose([0.0, 0.0, 0.0, 0.0, np.inf, 0.0]),
            "params: expected finite values, got [0.0, 0.0, 0.0, 0.0, inf, 0.0]",
        ),
        (
            lambda: SymmetricPose().from_pose(np.diag([1.0, -1.0, -1.0]), [0.0, 0.0, 0.0]),
            "R_camera_light: expected an axis other than -z (where the angles (a, b) are"
            " singular), got (0, 0, -1)",
        ),
        (
            lambda: IsotropicPose().from_pose(np.diag([1.0, 1.0, -1.0]), [0.0, 0.0, 0.0]),
            "R_camera_light: expected a rotation matrix with det +1, got a reflection (det -1)",
        ),
        (
            lambda: GeneralPose().from_pose(np.eye(3), [0.0, 0.0]),
            "t_camera_light: expected shape (3,), got (2,)",
        ),
        (
            lambda: GeneralPose(np.ones((3, 3))),
            "R_ref_camera_light: expected a rotation matrix (max |R^T R - I| <= 1e-06), got",
        ),
        (
            lambda: SymmetricPose().jacobian_direction(np.zeros(5), np.zeros((2, 2))),
            "v_light: expected shape (3,) or (N, 3), got (2, 2)",
        ),
        (
            lambda: pose_parameterization("spot"),  # type: ignore[arg-type]
            "kind: expected 'isotropic', 'symmetric' or 'general', got 'spot'",
        ),
        (
            lambda: pose_parameterization("symmetric", R_ref_camera_light=np.eye(3)),
            "R_ref_camera_light: expected None for a 'symmetric' light (only 'general' uses it)",
        ),
        (
            lambda: describe_pose(np.eye(3), [0.0, float("nan"), 0.0]),
            "t_camera_light: expected finite values, got [0.0, nan, 0.0]",
        ),
    ],
)
def test_errors(call: Callable[[], object], message: str) -> None:
    with pytest.raises(InputError, match="^" + re.escape(message)):
        call()
