"""Tests of lightcal.capture.marker_layout (markers placed one by one) and its board file."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from lightcal.capture.apriltag import marker_modules
from lightcal.capture.boards import LayoutMarker, MarkerLayout
from lightcal.capture.marker_pose import estimate_pose
from lightcal.capture.plane_texture import look_at_pose, render_plane_image
from lightcal.core.camera import Camera
from lightcal.errors import InputError
from lightcal.io.board_file import board_from_spec, parse_board, read_board, write_board

TAG = "DICT_APRILTAG_36h11"

RECTANGLE = MarkerLayout(
    tuple(
        LayoutMarker(TAG, k, center, 0.16)
        for k, center in enumerate([(-0.6, 0.35), (0.6, 0.35), (0.6, -0.35), (-0.6, -0.35)])
    )
)
"""Four tag36h11 at the corners of a 1.2 m x 0.7 m rectangle (the issue's wall)."""

MIXED = MarkerLayout(
    (
        LayoutMarker(TAG, 3, (-0.3, 0.2), 0.12, rotation_deg=90.0),
        LayoutMarker(TAG, 5, (0.25, 0.22), 0.12, rotation_deg=-30.0),
        LayoutMarker("DICT_4X4_50", 3, (0.3, -0.2), 0.1),
        LayoutMarker("DICT_APRILTAG_16h5", 7, (-0.25, -0.2), 0.1, rotation_deg=180.0),
        LayoutMarker("DICT_4X4_50", 9, (0.0, 0.0), 0.08, rotation_deg=12.5),
    )
)

LAYOUT_YAML = """\
type: markers
dictionary: DICT_APRILTAG_36h11
markers:
  - {id: 0, center_world_m: [-0.6, 0.35], size_m: 0.16}
  - {id: 1, center_world_m: [0.6, 0.35], size_m: 0.16, rotation_deg: 90}
  - {dictionary: DICT_4X4_50, id: 0, center_world_m: [0.0, -0.35], size_m: 0.1}
"""


def test_corners_hand_computed_upright_and_turned():
    upright = LayoutMarker(TAG, 0, (1.0, 2.0), 0.2)
    np.testing.assert_allclose(
        upright.square_world(),
        [[0.9, 2.1, 0.0], [1.1, 2.1, 0.0], [1.1, 1.9, 0.0], [0.9, 1.9, 0.0]],
        atol=1e-15,
    )
    # A quarter turn counterclockwise: the printed top-left corner goes to the bottom-left.
    turned = LayoutMarker(TAG, 0, (1.0, 2.0), 0.2, rotation_deg=90.0)
    np.testing.assert_allclose(
        turned.square_world(),
        [[0.9, 1.9, 0.0], [0.9, 2.1, 0.0], [1.1, 2.1, 0.0], [1.1, 1.9, 0.0]],
        atol=1e-15,
    )
    # 30 degrees: the top edge runs along (cos 30, sin 30), the corners stay s / sqrt 2 out.
    tilted = LayoutMarker(TAG, 0, (0.0, 0.0), 0.2, rotation_deg=30.0).square_world()
    edge = tilted[1, :2] - tilted[0, :2]
    np.testing.assert_allclose(edge, 0.2 * np.array([math.cos(math.pi / 6), 0.5]), atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(tilted[:, :2], axis=1), 0.1 * math.sqrt(2))
    # The layout's corners by id and dictionary, and by position.
    np.testing.assert_allclose(RECTANGLE.corners_world([2])[0, 0], [0.52, -0.27, 0.0])
    np.testing.assert_array_equal(
        MIXED.corners_world([3], "DICT_4X4_50"), MIXED.marker_corners_world([2])
    )
    np.testing.assert_array_equal(MIXED.outline_world(), MIXED.marker_corners_world(range(5)))


def test_render_draws_each_marker_as_printed():
    rendering = RECTANGLE.render(1000.0)  # 16 cm tags of 8 modules: 20 px a module
    A = rendering.A_pixel_world
    for k, marker in enumerate(RECTANGLE.markers):
        u, v = np.rint(marker.square_world()[0, :2] @ A[:, :2].T + A[:, 2] + 0.5).astype(int)
        patch = rendering.image[v : v + 160, u : u + 160]
        expected = np.kron(marker_modules(TAG, k), np.ones((20, 20), np.uint8))
        np.testing.assert_array_equal(patch, expected)
        # The official white border (one module) around the black square.
        ring = rendering.image[v - 20 : v + 180, u - 20 : u + 180].copy()
        ring[20:180, 20:180] = 255
        assert np.all(ring == 255)
    assert rendering.image.mean() > 240  # white paper elsewhere
    # A marker turned by 90 degrees counterclockwise is the upright drawing turned.
    upright = MarkerLayout((LayoutMarker(TAG, 4, (0.0, 0.0), 0.08),)).render(1000.0)
    turned = MarkerLayout((LayoutMarker(TAG, 4, (0.0, 0.0), 0.08, 90.0),)).render(1000.0)
    np.testing.assert_array_equal(turned.image, np.rot90(upright.image))
    np.testing.assert_allclose(upright.top_left_world_m, [-0.13, 0.13])


@pytest.mark.parametrize(
    ("make", "source", "message"),
    [
        (
            lambda: MarkerLayout(
                (LayoutMarker(TAG, 2, (0, 0), 0.1), LayoutMarker(TAG, 2, (1, 0), 0.1))
            ),
            "markers[1]",
            "DICT_APRILTAG_36h11 id 2 is also markers[0]: expected each (dictionary, id) once",
        ),
        (
            lambda: MarkerLayout(
                (LayoutMarker(TAG, 0, (0, 0), 0.1), LayoutMarker(TAG, 1, (0.12, 0), 0.1))
            ),
            "markers[1]",
            "DICT_APRILTAG_36h11 id 1 overlaps markers[0] (DICT_APRILTAG_36h11 id 0): expected "
            "each marker and its white border of one module clear of the others",
        ),
        (
            lambda: LayoutMarker("DICT_APRILTAG_16h5", 30, (0, 0), 0.1),
            "id",
            "DICT_APRILTAG_16h5 has ids 0..29, got 30",
        ),
        (
            lambda: LayoutMarker(TAG, 0, (0, 0), 0.0),
            "size_m",
            "expected a positive length in metres, got 0.0",
        ),
        (
            lambda: LayoutMarker(TAG, 0, (0, 0), 0.1, rotation_deg=math.nan),
            "rotation_deg",
            "expected a finite angle in degrees, got nan",
        ),
        (lambda: MarkerLayout(()), "markers", "expected at least one marker"),
        (
            lambda: MIXED.corners_world([3]),
            "dictionary",
            "the board has markers of DICT_4X4_50, DICT_APRILTAG_16h5, DICT_APRILTAG_36h11: "
            "say which",
        ),
        (
            lambda: RECTANGLE.corners_world([4]),
            "ids",
            "DICT_APRILTAG_36h11 id 4 is not on the board: expected one of [0, 1, 2, 3]",
        ),
    ],
)
def test_invalid_layouts(make, source, message):
    with pytest.raises(InputError) as info:
        make()
    assert (info.value.source, info.value.detail) == (source, message)


def test_markers_one_module_apart_are_accepted():
    # 8 modules of 1 cm: the white borders of the two tags touch, nothing overlaps.
    layout = MarkerLayout(
        (LayoutMarker(TAG, 0, (0, 0), 0.08), LayoutMarker(TAG, 1, (0.1, 0), 0.08))
    )
    assert layout.n_markers == 2
    # Two diamonds (45 degrees) whose bounding boxes meet but whose squares do not: the
    # white-bordered squares reach 0.0625 m along (1, 1) / sqrt(2) from each centre.
    apart = MarkerLayout(
        (LayoutMarker(TAG, 0, (0, 0), 0.1, 45.0), LayoutMarker(TAG, 1, (0.15, 0.15), 0.1, 45.0))
    )
    assert apart.n_markers == 2
    with pytest.raises(InputError, match=r"^markers\[1\]: DICT_APRILTAG_36h11 id 1 overlaps"):
        MarkerLayout(
            (LayoutMarker(TAG, 0, (0, 0), 0.1, 45.0), LayoutMarker(TAG, 1, (0.08, 0.08), 0.1, 45.0))
        )


@pytest.mark.parametrize("suffix", [".json", ".yaml"])
@pytest.mark.parametrize("layout", [RECTANGLE, MIXED], ids=["rectangle", "mixed"])
def test_board_file_round_trip(tmp_path: Path, layout, suffix):
    path = tmp_path / f"wall{suffix}"
    write_board(layout, path)
    assert read_board(path) == layout


def test_hand_written_board_file_with_a_default_dictionary(tmp_path: Path):
    path = tmp_path / "wall.yaml"
    path.write_text(LAYOUT_YAML)
    layout = read_board(path)
    assert layout == MarkerLayout(
        (
            LayoutMarker(TAG, 0, (-0.6, 0.35), 0.16),
            LayoutMarker(TAG, 1, (0.6, 0.35), 0.16, 90.0),
            LayoutMarker("DICT_4X4_50", 0, (0.0, -0.35), 0.1),
        )
    )
    write_board(RECTANGLE, path)
    assert path.read_text().startswith(
        "version: 1\ntype: markers\ndictionary: DICT_APRILTAG_36h11\nmarkers:\n- id: 0\n"
    )


def _marker(**change):
    return {"id": 0, "center_world_m": [0.0, 0.0], "size_m": 0.1, **change}


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (
            {"markers": [_marker()]},
            "markers[0].dictionary: expected the marker's dictionary, or a 'dictionary' for "
            "every marker at the top of the file",
        ),
        (
            {"dictionary": "DICT_APRILTAG_36h9", "markers": [_marker()]},
            "dictionary: unknown ArUco dictionary 'DICT_APRILTAG_36h9': expected a cv2.aruco "
            "name such as DICT_4X4_50, DICT_5X5_100, DICT_6X6_250, DICT_7X7_1000 or "
            "DICT_APRILTAG_36h11",
        ),
        (
            {"dictionary": TAG, "markers": [_marker(), _marker(dictionary="tag36h11", id=1)]},
            "markers[1].dictionary: unknown ArUco dictionary 'tag36h11': expected a cv2.aruco "
            "name such as DICT_4X4_50, DICT_5X5_100, DICT_6X6_250, DICT_7X7_1000 or "
            "DICT_APRILTAG_36h11",
        ),
        (
            {"dictionary": TAG, "markers": [_marker(id=587)]},
            "markers[0].id: DICT_APRILTAG_36h11 has ids 0..586, got 587",
        ),
        (
            {"dictionary": TAG, "markers": [_marker(), _marker(center_world_m=[1, 0])]},
            "markers[1]: DICT_APRILTAG_36h11 id 0 is also markers[0]: expected each "
            "(dictionary, id) once",
        ),
        (
            {"dictionary": TAG, "markers": [_marker(), _marker(id=1, center_world_m=[0.1, 0])]},
            "markers[1]: DICT_APRILTAG_36h11 id 1 overlaps markers[0] (DICT_APRILTAG_36h11 id "
            "0): expected each marker and its white border of one module clear of the others",
        ),
        (
            {"dictionary": TAG, "markers": []},
            "markers: List should have at least 1 item after validation, not 0",
        ),
        (
            {"dictionary": TAG, "markers": [_marker(size_m=-0.1)]},
            "markers[0].size_m: Input should be greater than 0",
        ),
        (
            {"dictionary": TAG, "markers": [_marker(centre_m=[0, 0])]},
            "markers[0].centre_m: Extra inputs are not permitted",
        ),
        (
            {"dictionary": TAG, "markers": [_marker(rotation_deg=True)]},
            "markers[0].rotation_deg: expected a number, got True",
        ),
    ],
)
def test_invalid_board_files(data, message):
    with pytest.raises(InputError, match=f"^{re.escape(f'wall.yaml: {message}')}$"):
        board_from_spec(parse_board({"type": "markers", **data}, "wall.yaml"), "wall.yaml")


CAMERA = Camera.from_params(
    fx=1150.0, fy=1150.0, cx=801.3, cy=598.6, width=1600, height=1200, dist=(-0.08, 0.02, 0, 0)
)


def _angle_deg(R_a: np.ndarray, R_b: np.ndarray) -> float:
    return math.degrees(math.acos(np.clip((np.trace(R_a @ R_b.T) - 1.0) / 2.0, -1.0, 1.0)))


@pytest.mark.parametrize(
    ("layout", "center", "target", "roll"),
    [
        (RECTANGLE, (0.15, -0.1, 1.6), (0.05, 0.0, 0.0), 0.2),
        (RECTANGLE, (-0.45, 0.25, 1.5), (0.0, 0.0, 0.0), -2.8),
        (MIXED, (0.1, 0.05, 0.9), (0.0, 0.0, 0.0), 0.4),
    ],
    ids=["rectangle", "rectangle_oblique_upside_down", "mixed"],
)
def test_pose_from_a_synthetic_image_of_the_layout(layout, center, target, roll):
    R, t = look_at_pose(center, target, roll_rad=roll)
    rendering = layout.render(2000.0)
    albedo = render_plane_image(
        CAMERA,
        R,
        t,
        0.05 + 0.9 * rendering.image / 255.0,
        rendering.px_per_m,
        rendering.top_left_world_m,
        background=0.95,
    )
    # A light spot off the centre and a little noise, as on a photo.
    rows, cols = np.mgrid[0 : CAMERA.height, 0 : CAMERA.width]
    spot = 0.4 + np.exp(-((cols - 700.0) ** 2 + (rows - 650.0) ** 2) / (2 * 600.0**2))
    noise = np.random.default_rng(3).normal(0.0, 0.004, albedo.shape)
    pose = estimate_pose(albedo * spot + noise, CAMERA, layout, min_markers=layout.n_markers)
    assert pose.n_markers == layout.n_markers
    assert sorted(pose.ids.tolist()) == sorted(m.id for m in layout.markers)
    assert _angle_deg(pose.R_camera_world, R) < 0.01
    assert np.linalg.norm(pose.camera_center_world - np.asarray(center)) < 3e-4
    assert pose.reprojection_rms_px < 0.1
