"""Tests of lightcal.capture.apriltag: official tag images and the detected corner order."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from lightcal.capture.apriltag import (
    APRILTAG_DICTIONARIES,
    detected_corner_order,
    dictionary_size,
    drawing_turns,
    marker_modules,
    printed_corners,
)
from lightcal.capture.apriltag_families import FAMILIES
from lightcal.capture.board_layout import aruco_dictionary
from lightcal.errors import InputError

DATA = Path(__file__).parent / "data" / "apriltag"

OFFICIAL_PNGS = [
    ("tag16_05_00000.png", "DICT_APRILTAG_16h5", 0),
    ("tag25_09_00000.png", "DICT_APRILTAG_25h9", 0),
    ("tag36_11_00000.png", "DICT_APRILTAG_36h11", 0),
]


def _with_white_border(modules: np.ndarray) -> np.ndarray:
    return np.pad(modules, 1, constant_values=255)


@pytest.mark.parametrize(("png", "dictionary", "marker_id"), OFFICIAL_PNGS)
def test_drawn_tags_equal_the_official_images_bit_for_bit(png, dictionary, marker_id):
    official = cv2.imread(str(DATA / png), cv2.IMREAD_UNCHANGED)
    assert official is not None and official.ndim == 3 and official.shape[2] == 4  # RGBA
    assert np.all(official[..., 3] == 255) and set(np.unique(official[..., :3])) == {0, 255}
    drawn = _with_white_border(marker_modules(dictionary, marker_id))
    np.testing.assert_array_equal(drawn, official[..., 0])


def test_hand_checked_tag16h5_id_0():
    # Code 0x27c8 = 0010 0111 1100 1000, bit k at (bit_x[k], bit_y[k]), white where 1.
    family = FAMILIES["tag16h5"]
    assert family.codes[0] == 0x27C8
    modules = marker_modules("DICT_APRILTAG_16h5", 0)
    assert modules.shape == (6, 6)
    bits = [(0x27C8 >> (15 - k)) & 1 for k in range(16)]
    for k, bit in enumerate(bits):
        assert modules[family.bit_y[k], family.bit_x[k]] == 255 * bit
    assert np.all(modules[0] == 0) and np.all(modules[:, 0] == 0)  # the black border
    assert np.all(modules[-1] == 0) and np.all(modules[:, -1] == 0)


@pytest.mark.parametrize("dictionary", sorted(APRILTAG_DICTIONARIES))
def test_families_match_opencv_dictionaries(dictionary):
    """The installed OpenCV holds the same codes, turned by one quarter-turn count for every
    id, and `detected_corner_order` agrees with that turn."""
    family = FAMILIES[APRILTAG_DICTIONARIES[dictionary]]
    assert dictionary_size(dictionary) == len(family.codes)
    cv_dictionary = aruco_dictionary(dictionary)
    width = family.width_at_border
    n = len(family.codes)
    turns = set()
    for marker_id in sorted({*range(0, n, max(1, n // 40)), n - 1}):
        drawn = cv_dictionary.generateImageMarker(marker_id, width)
        official = marker_modules(dictionary, marker_id)
        turns |= {k for k in range(4) if np.array_equal(np.rot90(drawn, k), official)}
    assert len(turns) == 1
    (k,) = turns
    assert detected_corner_order(dictionary) == tuple((j + k) % 4 for j in range(4))
    assert drawing_turns(dictionary) == k


@pytest.mark.parametrize("dictionary", [*sorted(APRILTAG_DICTIONARIES), "DICT_5X5_100"])
def test_detected_corners_of_a_printed_marker_follow_the_printed_order(dictionary):
    """Printed markers (official AprilTags), detected by the installed OpenCV in a turned
    and shifted image: `printed_corners` gives top-left, top-right, bottom-right,
    bottom-left of the printed marker, wherever OpenCV starts."""
    detector = cv2.aruco.ArucoDetector(aruco_dictionary(dictionary), cv2.aruco.DetectorParameters())
    for marker_id, quarter_turns in ((1, 0), (4, 1), (9, 3)):
        modules = _with_white_border(marker_modules(dictionary, marker_id))
        image = np.full((400, 400), 255, np.uint8)
        big = np.kron(modules, np.ones((24, 24), np.uint8))
        image[50 : 50 + big.shape[0], 70 : 70 + big.shape[1]] = big
        side = big.shape[0] - 48  # the black square
        lo_u, lo_v = 70 + 24 - 0.5, 50 + 24 - 0.5
        printed = np.array(
            [[lo_u, lo_v], [lo_u + side, lo_v], [lo_u + side, lo_v + side], [lo_u, lo_v + side]]
        )
        # Turn the picture (not the marker's definition): the printed corners turn with it.
        turned = np.rot90(image, quarter_turns)
        for _ in range(quarter_turns):  # a point (u, v) of a 400 x 400 image under rot90
            printed = np.stack([printed[:, 1], 399.0 - printed[:, 0]], axis=1)
        corners, ids, _ = detector.detectMarkers(np.ascontiguousarray(turned))
        assert ids is not None and ids.ravel().tolist() == [marker_id]
        ordered = printed_corners(dictionary, np.asarray(corners, np.float64).reshape(1, 4, 2))
        np.testing.assert_allclose(ordered[0], printed, atol=0.6)


def test_aruco_corner_order_is_opencvs():
    assert detected_corner_order("DICT_4X4_50") == (0, 1, 2, 3)
    np.testing.assert_array_equal(
        marker_modules("DICT_4X4_50", 7), aruco_dictionary("DICT_4X4_50").generateImageMarker(7, 6)
    )


def test_every_official_tag_is_detected_as_its_id():
    for dictionary in sorted(APRILTAG_DICTIONARIES):
        detector = cv2.aruco.ArucoDetector(
            aruco_dictionary(dictionary), cv2.aruco.DetectorParameters()
        )
        n = dictionary_size(dictionary)
        for marker_id in sorted({*range(0, n, max(1, n // 25)), n - 1}):
            modules = _with_white_border(marker_modules(dictionary, marker_id))
            image = np.pad(np.kron(modules, np.ones((10, 10), np.uint8)), 30, constant_values=255)
            _, ids, _ = detector.detectMarkers(image)
            assert ids is not None and ids.ravel().tolist() == [marker_id], (dictionary, marker_id)


def test_bad_ids_and_dictionaries():
    with pytest.raises(InputError) as info:
        marker_modules("DICT_APRILTAG_25h9", 35)
    assert str(info.value) == "id: DICT_APRILTAG_25h9 has ids 0..34, got 35"
    with pytest.raises(InputError, match=r"^dictionary: unknown ArUco dictionary 'tag36h11'"):
        marker_modules("tag36h11", 0)


def test_an_apriltag_grid_is_printed_and_read_as_official_tags():
    """An `aruco_grid` of tag36h11 draws the official images, and its pose from a photo is
    right whatever order the installed OpenCV reports the corners in."""
    from lightcal.capture.boards import ArucoGridBoard
    from lightcal.capture.marker_pose import estimate_pose
    from lightcal.capture.plane_texture import look_at_pose, render_plane_image
    from lightcal.core.camera import Camera

    tag = "DICT_APRILTAG_36h11"
    board = ArucoGridBoard(tag, 3, 2, 0.08, 0.03, first_id=4, origin_world_m=(-0.165, 0.095))
    rendering = board.render(1000.0)  # 10 px a module, a margin of one marker length
    for k, marker_id in enumerate(board.ids):
        row, col = 80 + 110 * (k // 3), 80 + 110 * (k % 3)
        np.testing.assert_array_equal(
            rendering.image[row : row + 80, col : col + 80],
            np.kron(marker_modules(tag, int(marker_id)), np.ones((10, 10), np.uint8)),
        )
    camera = Camera.from_params(fx=900.0, fy=900.0, cx=399.5, cy=299.5, width=800, height=600)
    center = np.array([0.08, -0.05, 0.7])
    R, t = look_at_pose(center, (0.0, 0.0, 0.0), roll_rad=2.0)
    fine = board.render(4000.0)
    albedo = render_plane_image(
        camera, R, t, 0.05 + 0.9 * fine.image / 255.0, fine.px_per_m, fine.top_left_world_m,
        background=0.9,
    )  # fmt: skip
    rows, cols = np.mgrid[0:600, 0:800]
    light = 0.5 + 0.5 * np.exp(-((cols - 300.0) ** 2 + (rows - 200.0) ** 2) / (2 * 400.0**2))
    photo = albedo * light + np.random.default_rng(5).normal(0.0, 0.003, albedo.shape)
    pose = estimate_pose(photo, camera, board, min_markers=6)
    cos = np.clip((np.trace(pose.R_camera_world @ R.T) - 1.0) / 2.0, -1.0, 1.0)
    assert np.degrees(np.arccos(cos)) < 0.05  # the fit's sigma: 0.01 deg a component
    assert np.linalg.norm(pose.camera_center_world - center) < 1e-3
    assert pose.reprojection_rms_px < 0.1
