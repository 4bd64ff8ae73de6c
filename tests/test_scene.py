"""Tests of lightcal.core.scene: views, lights, rigs and their validation."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from lightcal.core.camera import Camera
from lightcal.core.rid import CosPowerRID, IsotropicRID
from lightcal.core.scene import Light, Rig, View
from tests.scenes import oblique_view, rotation_about, rotation_with_z, straight_down_view

BEHIND = (
    "camera pose: the camera centre is at z = {z} m, on or behind the wall; expected z > 0 "
    "(the wall is z = 0 and cameras look at it from z > 0)"
)


def _exact(message: str) -> str:
    return "^" + re.escape(message) + "$"


# ---------------------------------------------------------------- View


def test_view_center_is_minus_r_transpose_t() -> None:
    R = rotation_about((0.3, -0.2, 1.0), 0.7) @ np.diag([1.0, -1.0, -1.0])
    center = np.array([0.4, -0.3, 2.2])
    view = View(R, -R @ center, exposure=0.25)
    np.testing.assert_allclose(view.center_world, center, rtol=1e-15, atol=1e-15)
    assert view.exposure == 0.25
    assert view.R_camera_world.dtype == np.float64


@pytest.mark.parametrize(("center_z", "shown"), [(-1.0, "-1"), (-0.125, "-0.125"), (0.0, "0")])
def test_view_behind_or_on_the_wall_is_rejected(center_z: float, shown: str) -> None:
    R = np.diag([1.0, -1.0, -1.0])
    center = np.array([0.2, 0.1, center_z])
    with pytest.raises(ValueError, match=_exact(BEHIND.format(z=shown))):
        View(R, -R @ center)


def test_view_rejects_a_reflection_and_a_non_rotation() -> None:
    with pytest.raises(
        ValueError,
        match=_exact(
            "R_camera_world: expected a rotation matrix with det +1, got a reflection (det -1)"
        ),
    ):
        View(np.diag([1.0, 1.0, -1.0]), np.zeros(3))
    with pytest.raises(
        ValueError,
        match=_exact(
            "R_camera_world: expected a rotation matrix (max |R^T R - I| <= 1e-06), "
            "got max |R^T R - I| = 3"
        ),
    ):
        View(2 * np.eye(3), np.zeros(3))
    with pytest.raises(
        ValueError, match=_exact("R_camera_world: expected shape (3, 3), got (2, 2)")
    ):
        View(np.eye(2), np.zeros(3))


def test_view_rejects_bad_translation_and_exposure() -> None:
    R = np.diag([1.0, -1.0, -1.0])
    with pytest.raises(ValueError, match=_exact("t_camera_world: expected shape (3,), got (2,)")):
        View(R, np.zeros(2))
    with pytest.raises(
        ValueError, match=_exact("t_camera_world: expected finite values, got [0.0, nan, 1.0]")
    ):
        View(R, np.array([0.0, math.nan, 1.0]))
    for bad in (0.0, -1.0, math.inf):
        with pytest.raises(
            ValueError, match=_exact(f"exposure: expected a finite value > 0, got {bad}")
        ):
            View(R, np.array([0.0, 0.0, 1.0]), exposure=bad)


def test_looking_at_puts_the_target_on_the_optical_axis() -> None:
    center = np.array([0.3, -0.4, 1.5])
    target = np.array([-0.1, 0.15, 0.0])
    view = View.looking_at(center, target, exposure=2.0)
    np.testing.assert_allclose(view.center_world, center, atol=1e-15)
    target_camera = view.R_camera_world @ target + view.t_camera_world
    np.testing.assert_allclose(target_camera[:2], 0.0, atol=1e-15)
    assert target_camera[2] == pytest.approx(np.linalg.norm(target - center), rel=1e-15)
    assert view.exposure == 2.0
    # Image "down" (camera +y) follows -up_world = +y_world as far as possible.
    y_camera_in_world = view.R_camera_world[1]
    assert y_camera_in_world @ np.array([0.0, 1.0, 0.0]) > 0.9
    assert np.linalg.det(view.R_camera_world) == pytest.approx(1.0, abs=1e-14)


def test_looking_at_projects_the_target_to_the_principal_point() -> None:
    camera = Camera.from_params(fx=500.0, fy=500.0, cx=31.0, cy=23.0, width=64, height=48)
    view = View.looking_at(np.array([1.0, 2.0, 3.0]), np.array([0.5, 0.0, 0.0]))
    target_camera = view.R_camera_world @ np.array([0.5, 0.0, 0.0]) + view.t_camera_world
    pixels, valid = camera.project(target_camera[None])
    assert valid[0]
    np.testing.assert_allclose(pixels[0], [31.0, 23.0], atol=1e-12)


def test_looking_at_validation_messages() -> None:
    c = np.array([0.0, 0.0, 1.0])
    with pytest.raises(
        ValueError, match=_exact("target_world: expected a point different from center_world")
    ):
        View.looking_at(c, c)
    with pytest.raises(
        ValueError,
        match=_exact("up_world: expected a direction not parallel to the optical axis"),
    ):
        View.looking_at(c, np.zeros(3), up_world=(0.0, 0.0, 1.0))
    with pytest.raises(ValueError, match=_exact(BEHIND.format(z="-2"))):
        View.looking_at(np.array([0.0, 0.0, -2.0]), np.zeros(3))


def test_straight_down_view_fixture() -> None:
    view = straight_down_view(height_m=2.0)
    np.testing.assert_array_equal(view.center_world, [0.0, 0.0, 2.0])
    # The optical axis (camera +z) points down the world z axis.
    np.testing.assert_array_equal(view.R_camera_world[2], [0.0, 0.0, -1.0])


# ---------------------------------------------------------------- Light and Rig


def test_light_world_position_and_rotation() -> None:
    view = oblique_view()
    R_cl = rotation_with_z((0.2, -0.1, 1.0))
    t_cl = np.array([0.1, -0.05, 0.02])
    light = Light(CosPowerRID(2.0), t_cl, R_cl, scale=3.0, name="key")
    R = view.R_camera_world
    expected = view.center_world + R.T @ t_cl
    np.testing.assert_allclose(light.position_world(view), expected, rtol=1e-15)
    # Back to the camera frame: X_c = R X_w + t.
    np.testing.assert_allclose(
        R @ light.position_world(view) + view.t_camera_world, t_cl, atol=1e-15
    )
    np.testing.assert_allclose(light.rotation_world(view), R.T @ R_cl, rtol=1e-15)
    np.testing.assert_allclose(light.axis_camera, R_cl[:, 2], rtol=1e-15)
    assert light.scale == 3.0
    assert light.name == "key"


def test_light_defaults_and_replace() -> None:
    light = Light(IsotropicRID(), np.array([0.0, 0.1, 0.0]))
    np.testing.assert_array_equal(light.R_camera_light, np.eye(3))
    assert light.scale == 1.0
    moved = light.replace(t_camera_light=np.array([1.0, 2.0, 3.0]), scale=2.0)
    np.testing.assert_array_equal(moved.t_camera_light, [1.0, 2.0, 3.0])
    assert moved.scale == 2.0
    np.testing.assert_array_equal(light.t_camera_light, [0.0, 0.1, 0.0])  # unchanged
    with pytest.raises(ValueError, match=_exact("light scale: expected a finite value > 0, got 0")):
        light.replace(scale=0)


def test_light_validation_messages() -> None:
    rid = IsotropicRID()
    with pytest.raises(ValueError, match=_exact("t_camera_light: expected shape (3,), got (4,)")):
        Light(rid, np.zeros(4))
    with pytest.raises(ValueError, match=_exact("R_camera_light: expected shape (3, 3), got (3,)")):
        Light(rid, np.zeros(3), np.zeros(3))
    with pytest.raises(
        ValueError, match=_exact("light scale: expected a finite value > 0, got -2.0")
    ):
        Light(rid, np.zeros(3), scale=-2.0)
    with pytest.raises(
        ValueError, match=_exact("light scale: expected a finite value > 0, got nan")
    ):
        Light(rid, np.zeros(3), scale=math.nan)


def test_rig_needs_a_light() -> None:
    with pytest.raises(ValueError, match=_exact("rig: expected at least one light")):
        Rig(())
    light = Light(IsotropicRID(), np.zeros(3))
    rig = Rig([light, light])  # type: ignore[arg-type]
    assert isinstance(rig.lights, tuple)
    assert len(rig.lights) == 2
    assert Rig.single(light).lights == (light,)


def test_fixture_rotations_are_rotations() -> None:
    for R in (
        rotation_about((0.0, 0.0, 1.0), math.pi / 2),
        rotation_with_z((0.3, -0.2, 1.0)),
        rotation_with_z((1.0, 0.0, 0.0)),
    ):
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-15)
        assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_allclose(
        rotation_about((0.0, 0.0, 1.0), math.pi / 2) @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15
    )
    z = np.array([0.3, -0.2, 1.0])
    np.testing.assert_allclose(rotation_with_z(z)[:, 2], z / np.linalg.norm(z), atol=1e-15)
