"""Tests of lightcal.capture.boards: geometry in the world frame, rendering, validation."""

from __future__ import annotations

import re

import numpy as np
import pytest

from lightcal.capture.boards import (
    R_WORLD_BOARD,
    ArucoGridBoard,
    CharucoBoard,
    Chessboard,
    aruco_dictionary,
    aruco_dictionary_names,
)
from lightcal.capture.plane_texture import look_at_pose, render_plane_image
from lightcal.core.camera import Camera
from lightcal.errors import InputError


def _opencv_points_in_world(points_board, origin):
    """OpenCV's float32 board-frame points mapped by the documented board -> world rule."""
    points = np.asarray(points_board, dtype=np.float64) @ R_WORLD_BOARD.T
    return points + np.array([origin[0], origin[1], 0.0])


def test_world_frame_is_a_proper_rotation_of_the_board_frame():
    assert np.allclose(R_WORLD_BOARD @ R_WORLD_BOARD.T, np.eye(3))
    assert np.linalg.det(R_WORLD_BOARD) == pytest.approx(1.0)
    # Board y runs down the page, world y up; board z into the wall, world z out of it.
    assert np.array_equal(R_WORLD_BOARD @ [0.0, 1.0, 0.0], [0.0, -1.0, 0.0])
    assert np.array_equal(R_WORLD_BOARD @ [0.0, 0.0, 1.0], [0.0, 0.0, -1.0])


def test_grid_corners_hand_computed():
    board = ArucoGridBoard("DICT_5X5_100", 3, 2, 0.08, 0.02, first_id=10, origin_world_m=(1.0, 2.0))
    # Marker 14 is the 5th marker: column 1, row 1, top-left at board (0.1, 0.1).
    corners = board.corners_world([14])
    expected = [[1.1, 1.9, 0.0], [1.18, 1.9, 0.0], [1.18, 1.82, 0.0], [1.1, 1.82, 0.0]]
    assert corners.shape == (1, 4, 3)
    np.testing.assert_allclose(corners[0], expected, atol=1e-15)
    assert board.size_m == pytest.approx((0.28, 0.18))
    np.testing.assert_array_equal(board.ids, [10, 11, 12, 13, 14, 15])


def test_grid_corners_match_opencv_board():
    board = ArucoGridBoard("DICT_4X4_50", 4, 3, 0.05, 0.01, first_id=7, origin_world_m=(-0.3, 0.2))
    cv_board = board.cv_board()
    np.testing.assert_array_equal(cv_board.getIds().ravel(), board.ids)
    expected = _opencv_points_in_world(np.array(cv_board.getObjPoints()), board.origin_world_m)
    np.testing.assert_allclose(board.corners_world(board.ids), expected, atol=1e-7)
    # Any subset, in the order asked for.
    np.testing.assert_allclose(board.corners_world([9, 7]), expected[[2, 0]], atol=1e-7)


@pytest.mark.parametrize(("squares_x", "squares_y"), [(5, 4), (6, 5), (7, 7)])
def test_charuco_corners_match_opencv_board(squares_x, squares_y):
    board = CharucoBoard("DICT_5X5_100", squares_x, squares_y, 0.06, 0.045, (0.5, -0.1))
    cv_board = board.cv_board()
    np.testing.assert_array_equal(cv_board.getIds().ravel(), board.marker_ids)
    chessboard = _opencv_points_in_world(cv_board.getChessboardCorners(), board.origin_world_m)
    np.testing.assert_allclose(board.corners_world(board.corner_ids), chessboard, atol=1e-7)
    markers = _opencv_points_in_world(np.array(cv_board.getObjPoints()), board.origin_world_m)
    np.testing.assert_allclose(board.marker_corners_world(board.marker_ids), markers, atol=1e-7)


def test_charuco_corner_ids_hand_computed():
    board = CharucoBoard("DICT_5X5_100", 5, 4, 0.1, 0.07)
    # 4 inner corners per row; corner 5 is column 1, row 1: board (0.2, 0.2).
    np.testing.assert_allclose(board.corners_world([5]), [[0.2, -0.2, 0.0]], atol=1e-15)
    assert board.n_markers == 10
    assert board.corner_ids.size == 12


def test_charuco_outline_whole_board_and_around_corners():
    board = CharucoBoard("DICT_5X5_100", 5, 4, 0.1, 0.07, origin_world_m=(1.0, 1.0))
    whole = board.outline_world()
    np.testing.assert_allclose(
        whole, [[[1.0, 1.0, 0.0], [1.5, 1.0, 0.0], [1.5, 0.6, 0.0], [1.0, 0.6, 0.0]]]
    )
    # Corner 0 (board (0.1, 0.1)) touches the four squares of the top-left 2 x 2 block.
    around = board.outline_world([0])
    assert around.shape == (4, 4, 3)
    np.testing.assert_allclose(around[:, :, :2].min(axis=(0, 1)), [1.0, 0.8])
    np.testing.assert_allclose(around[:, :, :2].max(axis=(0, 1)), [1.2, 1.0])


def test_grid_render_matches_opencv_generate_image():
    board = ArucoGridBoard("DICT_5X5_100", 3, 2, 0.08, 0.02, first_id=10)
    rendering = board.render(1000, margin_m=0.01)
    height, width = rendering.image.shape
    assert (width, height) == (280 + 20, 180 + 20)
    reference = board.cv_board().generateImage((width, height), marginSize=10)
    np.testing.assert_array_equal(rendering.image, reference)


@pytest.mark.parametrize(("squares_x", "squares_y"), [(5, 4), (6, 5)])
def test_charuco_render_matches_opencv_generate_image(squares_x, squares_y):
    board = CharucoBoard("DICT_5X5_100", squares_x, squares_y, 0.06, 0.04)
    rendering = board.render(1000, margin_m=0.02)
    height, width = rendering.image.shape
    assert (width, height) == (squares_x * 60 + 40, squares_y * 60 + 40)
    reference = board.cv_board().generateImage((width, height), marginSize=20)
    np.testing.assert_array_equal(rendering.image, reference)


def test_render_affine_puts_marker_corners_on_pixel_corners():
    board = ArucoGridBoard("DICT_4X4_50", 2, 2, 0.05, 0.02, origin_world_m=(0.3, -0.4))
    rendering = board.render(2000)  # default margin: one marker length
    A = rendering.A_pixel_world
    corners = board.corners_world(board.ids)  # (4, 4, 3)
    uv = corners[..., :2] @ A[:, :2].T + A[:, 2]
    # Corners of markers fall on pixel corners (half-integers).
    np.testing.assert_allclose(uv - np.floor(uv), 0.5, atol=1e-9)
    image = rendering.image
    for quad in uv:
        # Top-left and bottom-right corners, as the pixel indices around them.
        (u0, v0), (u1, v1) = np.rint(quad[0] + 0.5).astype(int), np.rint(quad[2] + 0.5).astype(int)
        inside_tl, outside_tl = image[v0, u0], image[v0 - 1, u0 - 1]
        inside_br, outside_br = image[v1 - 1, u1 - 1], image[v1, u1]
        assert (inside_tl, inside_br, outside_tl, outside_br) == (0, 0, 255, 255)
    # The top-left corner of the image is one margin (a marker length) up and left.
    np.testing.assert_allclose(rendering.top_left_world_m, [0.25, -0.35])
    np.testing.assert_allclose(A @ [0.25, -0.35, 1.0], [-0.5, -0.5])


def test_chessboard_render_and_corners_hand_computed():
    board = Chessboard(2, 2, 0.01)
    rendering = board.render(100, margin_m=0.01)  # 1 px squares, 1 px margin
    w, b = 255, 0
    expected = [
        [w, w, w, w, w],
        [w, b, w, b, w],
        [w, w, b, w, w],
        [w, b, w, b, w],
        [w, w, w, w, w],
    ]
    np.testing.assert_array_equal(rendering.image, expected)
    np.testing.assert_allclose(rendering.top_left_world_m, [-0.02, 0.02])
    corners = np.array([[0, 0, 0], [0.01, 0, 0], [0, -0.01, 0], [0.01, -0.01, 0]])
    np.testing.assert_allclose(board.corners_world(), corners)
    # The first inner corner (world origin) is the corner between pixels 1 and 2.
    np.testing.assert_allclose(rendering.A_pixel_world @ [0.0, 0.0, 1.0], [1.5, 1.5])
    np.testing.assert_allclose(
        board.outline_world(),
        [[[-0.01, 0.01, 0], [0.02, 0.01, 0], [0.02, -0.02, 0], [-0.01, -0.02, 0]]],
    )


def test_dictionary_lookup():
    assert "DICT_5X5_100" in aruco_dictionary_names()
    assert aruco_dictionary("DICT_6X6_250").bytesList.shape[0] == 250


@pytest.mark.parametrize(
    ("make", "source", "message"),
    [
        (
            lambda: ArucoGridBoard("DICT_5X5_99", 2, 2, 0.05, 0.01),
            "dictionary",
            "unknown ArUco dictionary 'DICT_5X5_99': expected a cv2.aruco name such as "
            "DICT_4X4_50, DICT_5X5_100, DICT_6X6_250, DICT_7X7_1000 or DICT_APRILTAG_36h11",
        ),
        (
            lambda: ArucoGridBoard("DICT_5X5_100", 2, 2, 0.0, 0.01),
            "marker_length_m",
            "expected a positive length in metres, got 0.0",
        ),
        (
            lambda: ArucoGridBoard("DICT_5X5_100", 2, 2, 0.05, -0.01),
            "separation_m",
            "expected a positive length in metres, got -0.01",
        ),
        (
            lambda: ArucoGridBoard("DICT_5X5_100", 0, 2, 0.05, 0.01),
            "markers_x",
            "expected an int >= 1, got 0",
        ),
        (
            lambda: ArucoGridBoard("DICT_5X5_100", 10, 10, 0.05, 0.01, first_id=1),
            "first_id",
            "the board needs marker ids 1..100 but DICT_5X5_100 has ids 0..99",
        ),
        (
            lambda: ArucoGridBoard("DICT_5X5_100", 2, 2, 0.05, 0.01, origin_world_m=(0.0,)),  # type: ignore[arg-type]
            "origin_world_m",
            "expected two finite coordinates (x, y) in metres, got (0.0,)",
        ),
        (
            lambda: CharucoBoard("DICT_5X5_100", 5, 4, 0.05, 0.05),
            "marker_length_m",
            "expected a marker smaller than the square (0.05 m), got 0.05 m",
        ),
        (
            lambda: CharucoBoard("DICT_4X4_50", 11, 10, 0.05, 0.03),
            "dictionary",
            "the board needs 55 markers but DICT_4X4_50 has 50",
        ),
        (
            lambda: CharucoBoard("DICT_5X5_100", 1, 4, 0.05, 0.03),
            "squares_x",
            "expected an int >= 2, got 1",
        ),
        (
            lambda: Chessboard(9, 6, float("nan")),
            "square_length_m",
            "expected a positive length in metres, got nan",
        ),
    ],
)
def test_invalid_boards(make, source, message):
    with pytest.raises(InputError, match=re.escape(f"{source}: {message}")) as info:
        make()
    assert info.value.source == source
    assert str(info.value) == f"{source}: {message}"


def test_unknown_ids():
    board = ArucoGridBoard("DICT_5X5_100", 2, 2, 0.05, 0.01, first_id=4)
    with pytest.raises(
        InputError, match=re.escape("ids: marker id 3 is not on the board: expected ids 4..7")
    ):
        board.corners_world([4, 3])
    charuco = CharucoBoard("DICT_5X5_100", 3, 3, 0.05, 0.03)
    with pytest.raises(
        InputError,
        match=re.escape("ids: ChArUco corner id 4 is not on the board: expected ids 0..3"),
    ):
        charuco.corners_world([4])


def test_render_requires_whole_pixels():
    board = ArucoGridBoard("DICT_5X5_100", 2, 2, 0.05, 0.01)
    message = (
        "px_per_m: expected the board's lengths to be whole numbers of pixels at "
        "11811.0 px/m, got marker_length_m -> 590.55 px, separation_m -> 118.11 px, "
        "margin_m -> 590.55 px"
    )
    with pytest.raises(InputError, match=re.escape(message)):
        board.render(11811.0)
    with pytest.raises(InputError, match=re.escape("px_per_m: expected a positive number")):
        board.render(-1.0)
    with pytest.raises(InputError, match=re.escape("margin_m: expected a length >= 0 in metres")):
        board.render(1000.0, margin_m=-0.01)


def test_look_at_pose_faces_the_wall():
    R, t = look_at_pose([0.2, -0.1, 1.5], [0.2, -0.1, 0.0])
    np.testing.assert_allclose(R, np.diag([1.0, -1.0, -1.0]), atol=1e-15)
    np.testing.assert_allclose(-R.T @ t, [0.2, -0.1, 1.5])
    R, _ = look_at_pose([0.0, 0.0, 1.0], [0.0, 0.0, 0.0], roll_rad=np.pi / 2)
    np.testing.assert_allclose(R @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)


def test_render_plane_image_places_an_edge_where_the_camera_sees_it():
    camera = Camera.from_params(fx=500.0, fy=500.0, cx=50.3, cy=40.0, width=101, height=81)
    R, t = look_at_pose([0.0, 0.0, 1.0], [0.0, 0.0, 0.0])  # 1 m from the wall, facing it
    texture = np.zeros((400, 400))
    texture[:, 200:] = 1.0  # dark left half, light right half: edge at texture column 200
    edge_x_m = 0.00123
    origin = (edge_x_m - 0.2, 0.2)
    image = render_plane_image(camera, R, t, texture, 1000.0, origin, background=0.25)
    # A box-filtered edge: the light area of a row is (100.5 - u_edge) pixels.
    u_edge = camera.cx + camera.fx * edge_x_m  # 50.915
    np.testing.assert_allclose(image.sum(axis=1), 100.5 - u_edge, atol=0.03)
    assert image.min() == 0.0 and image.max() == 1.0
    # Outside the texture, and where the rays miss the wall, the background is seen.
    small = render_plane_image(camera, R, t, texture[:20, :20], 1000.0, (-0.01, 0.01))
    assert small[0, 0] == 0.5 and small[40, 50] == 0.0
    R_away, t_away = look_at_pose([0.0, 0.0, 1.0], [0.0, 0.0, 2.0])
    away = render_plane_image(camera, R_away, t_away, texture, 1000.0, origin, background=0.25)
    assert np.all(away == 0.25)
