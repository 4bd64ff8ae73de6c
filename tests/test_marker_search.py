"""Tests of lightcal.capture.marker_search: markers found on several stretches of a photo
with a bright beam, merged, checked for consistency and refined (issue 25)."""

from __future__ import annotations

import functools
import math

import cv2
import numpy as np
import pytest

from lightcal.capture import marker_search
from lightcal.capture.board_layout import aruco_dictionary
from lightcal.capture.marker_detection import detection_images, find_board_markers
from lightcal.capture.marker_pose import estimate_pose, pose_report
from lightcal.capture.marker_search import (
    STRETCHES,
    MarkerRefusal,
    detection_stretches,
    detector_parameters,
    find_markers,
)
from lightcal.errors import InputError
from tests.test_marker_pose import CAMERA, GRID, scene

# A beam centred left of the board (its saturated core, 2 % of the image, misses the
# markers), 300 times the room light at its peak, over the board's left markers.
BEAM_CENTER_PX = (250.0, 600.0)
BEAM_SIGMA_PX = 120.0
BEAM_PEAK = 300.0
SATURATION = 100.0


def _beam_photo() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(linear photo (H, W), R_camera_world, t_camera_world) of the 1.5 m grid under a beam."""
    _, image, R, t = scene("grid_1.5m_tilt30")
    rows, cols = np.mgrid[0 : CAMERA.height, 0 : CAMERA.width]
    u0, v0 = BEAM_CENTER_PX
    beam = 1.0 + BEAM_PEAK * np.exp(-((cols - u0) ** 2 + (rows - v0) ** 2) / (2 * BEAM_SIGMA_PX**2))
    return np.minimum(np.array(image) * beam, SATURATION), R, t


def _true_corners(ids: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    pixels, valid = CAMERA.project(GRID.corners_world(ids).reshape(-1, 3) @ R.T + t)
    assert np.all(valid)
    return pixels.reshape(-1, 4, 2)


def test_the_beam_hides_markers_from_the_percentile_stretch_but_not_from_the_search():
    photo, R, t = _beam_photo()
    assert 0.01 < np.mean(photo >= SATURATION) < 0.03  # partly saturated
    image_u8, _ = detection_images(photo, CAMERA, "beam")
    detector = cv2.aruco.ArucoDetector(aruco_dictionary(GRID.dictionary), detector_parameters())
    _, ids_percentile, _ = detector.detectMarkers(image_u8)
    assert len(ids_percentile) <= 5  # of 48: the percentile stretch alone loses them

    search = find_markers(
        image_u8, detection_images(photo, CAMERA, "beam")[1], CAMERA, {GRID.dictionary: GRID.ids}
    )
    assert search.refused == ()
    np.testing.assert_array_equal(search.ids(GRID.dictionary), GRID.ids)
    errors = np.linalg.norm(
        search.corners_px(GRID.dictionary) - _true_corners(GRID.ids, R, t), axis=-1
    )
    print(f"corner errors: max {errors.max():.3f} px, median {np.median(errors):.3f} px")
    assert errors.max() < 0.1
    assert all(np.all(m.refined) for m in search.found)
    only_stretched = [m for m in search.found if "percentile" not in m.stretches]
    assert len(only_stretched) >= 40
    # Every marker found after two stretches: the log and CLAHE ones are not made.
    assert all(m.stretches == ("gamma",) for m in only_stretched)

    # The pose from every marker (estimate_pose goes through the same search).
    pose = estimate_pose(photo, CAMERA, GRID, source="beam")
    assert pose.n_markers == 48
    assert pose.reprojection_rms_px < 0.05


def test_find_board_markers_reports_what_it_found():
    photo, _, _ = _beam_photo()
    search = find_board_markers(photo, CAMERA, GRID, source="beam.png")
    ids = ", ".join(str(i) for i in GRID.ids)
    assert search.report() == f"beam.png: 48 markers found ({GRID.dictionary} {ids})"


def _quad(u: float, v: float, side: float = 40.0) -> np.ndarray:
    return np.array([[u, v], [u + side, v], [u + side, v + side], [u, v + side]])


def _forge(monkeypatch: pytest.MonkeyPatch, seen: dict[int, list[tuple[str, np.ndarray]]]):
    monkeypatch.setattr(marker_search, "_detect", lambda images, dictionary, wanted: seen)


def test_a_marker_found_at_two_places_is_refused_with_the_reason(monkeypatch):
    _, image, R, t = scene("grid_1.5m_tilt30")
    true = _true_corners(np.array([3, 5]), R, t)
    forged = true[1] + np.array([12.0, 0.0])
    # Half a module of the 5 x 5 marker (7 modules a side with its border), or 3 px.
    side_px = np.mean(np.linalg.norm(np.roll(true[1], -1, axis=0) - true[1], axis=-1))
    tolerance = max(3.0, 0.5 * side_px / 7)
    assert 4.0 < tolerance < 6.0
    _forge(
        monkeypatch,
        {
            3: [("percentile", true[0] + 0.3), ("log", true[0] - 0.2)],
            5: [("percentile", true[1]), ("gamma", forged), ("clahe", true[1])],
        },
    )
    image_u8, image_f = detection_images(image, CAMERA, "forged.png")
    search = find_markers(image_u8, image_f, CAMERA, {GRID.dictionary: GRID.ids}, source="forged")
    u, v = true[1].mean(axis=0)
    reason = (
        f"found by the percentile and gamma stretches at places 12.0 px apart (centres "
        f"({u:.1f}, {v:.1f}) and ({u + 12:.1f}, {v:.1f})); expected the same corners within "
        f"{tolerance:.1f} px"
    )
    assert search.refused == (MarkerRefusal(GRID.dictionary, 5, reason),)
    assert str(search.refused[0]) == f"marker 5 ({GRID.dictionary}) refused: {reason}"
    assert search.report() == (
        f"forged: 1 marker found ({GRID.dictionary} 3); marker 5 ({GRID.dictionary}) "
        f"refused: {reason}"
    )
    # The consistent one: refined on the edges from its first stretch's detection.
    (found,) = search.found
    assert found.marker_id == 3 and found.stretches == ("percentile", "log")
    assert np.all(found.refined)
    assert np.max(np.linalg.norm(found.corners_px - true[0], axis=-1)) < 0.1


def test_the_pose_and_its_report_name_the_refused_markers(monkeypatch):
    """What `lightcal init` prints per photo: the markers found, and each one refused with
    why; a photo rejected for too few markers says which were seen and refused."""
    _, image, R, t = scene("grid_1.5m_tilt30")
    true = _true_corners(GRID.ids, R, t)
    seen = {int(i): [("percentile", true[k])] for k, i in enumerate(GRID.ids)}
    seen[5] = [("percentile", true[5]), ("gamma", true[5] + np.array([12.0, 0.0]))]
    _forge(monkeypatch, seen)
    pose = estimate_pose(image, CAMERA, GRID, source="view.png")
    (refusal,) = pose.refused
    assert refusal.startswith(f"marker 5 ({GRID.dictionary}) refused: found by the percentile")
    assert pose.n_markers == GRID.n_markers - 1
    line = pose_report([pose])
    assert line.startswith(f"view.png: {GRID.n_markers - 1} markers, rms ")
    assert line.endswith(f" m; {refusal}")
    _forge(monkeypatch, {5: seen[5], 3: [("percentile", true[3])]})
    with pytest.raises(InputError) as info:
        estimate_pose(image, CAMERA, GRID, source="view.png")
    assert str(info.value) == f"view.png: found 1 markers, need at least 4; {refusal}"


def test_twice_in_one_stretch_and_non_finite_corners_are_refused(monkeypatch):
    quad = _quad(600.0, 400.0)
    nan_quad = quad.copy()
    nan_quad[2, 0] = math.nan
    inf_quad = quad.copy()
    inf_quad[0, 1] = math.inf
    _forge(
        monkeypatch,
        {
            7: [("log", quad), ("log", quad + np.array([0.0, 5.0]))],
            8: [("percentile", nan_quad)],
            9: [("gamma", quad), ("clahe", inf_quad)],
        },
    )
    _, image, _, _ = scene("grid_1.5m_tilt30")
    image_u8, image_f = detection_images(image, CAMERA, "x")
    search = find_markers(image_u8, image_f, CAMERA, {GRID.dictionary: GRID.ids})
    assert search.found == ()
    assert [str(r) for r in search.refused] == [
        f"marker 7 ({GRID.dictionary}) refused: found twice by the log stretch at places "
        "5.0 px apart (centres (620.0, 420.0) and (620.0, 425.0)); expected the same corners "
        "within 3.0 px",
        f"marker 8 ({GRID.dictionary}) refused: the percentile stretch's detection has "
        "non-finite corners",
        f"marker 9 ({GRID.dictionary}) refused: the clahe stretch's detection has "
        "non-finite corners",
    ]


def test_the_stretches_by_hand():
    image_f = np.array([[0.0, 1.0, 10.0, 100.0], [-5.0, 50.0, 100.0, math.nan]])
    image_u8 = np.rint(np.clip(np.nan_to_num(image_f) * 2.55, 0, 255)).astype(np.uint8)
    stretched = detection_stretches(image_u8, image_f)
    assert list(stretched) == list(STRETCHES)
    assert stretched["percentile"] is image_u8
    x = np.clip(np.nan_to_num(image_f), 0.0, None) / 100.0
    gamma = 255.0 * x ** (1 / 2.2)
    log = 255.0 * np.log1p(x / 1e-3) / np.log1p(1e3)
    # (16-bit quantisation of x, then rounding)
    assert np.max(np.abs(stretched["gamma"] - gamma)) <= 1.0
    assert np.max(np.abs(stretched["log"] - log)) <= 1.0
    assert stretched["gamma"][0, 1] == 31 and stretched["log"][0, 1] == 88
    assert stretched["clahe"].dtype == np.uint8 and stretched["clahe"].shape == (2, 4)
    dark = detection_stretches(image_u8, np.zeros((2, 4)))
    assert not np.any(dark["gamma"]) and not np.any(dark["clahe"])


def test_find_markers_checks_the_image_sizes():
    from lightcal.errors import InputError

    with pytest.raises(InputError) as error:
        find_markers(
            np.zeros((10, 20), np.uint8), np.zeros((10, 20)), CAMERA, {}, source="small.png"
        )
    assert str(error.value) == (
        "small.png: expected images of the camera's size 1600x1200 px, got 20x10 and 20x10 px"
    )


@functools.cache
def _tag_wall() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Issue 25's wall: four tag36h11 at the corners of a 1.2 x 0.7 m rectangle, seen from
    1.6 m, a 14-degree beam (7 degrees half angle) from beside the camera between them.

    Returns:
        albedo: (H, W) the wall's albedo in the image.
        beam: (H, W) the beam's irradiance, 1 at its peak.
        R_camera_world: (3, 3).
        t_camera_world: (3,).
    """
    from lightcal.capture.plane_texture import look_at_pose, render_plane_image
    from lightcal.core.pose import rotation_from_axis
    from lightcal.core.render import render_image
    from lightcal.core.rid import CosPowerRID
    from lightcal.core.scene import Light, Rig, View
    from tests.test_marker_layout import CAMERA as TAG_CAMERA
    from tests.test_marker_layout import RECTANGLE

    R, t = look_at_pose(np.array([0.15, -0.1, 1.6]), np.array([0.05, 0.0, 0.0]), roll_rad=0.2)
    rendering = RECTANGLE.render(2000.0)
    albedo = render_plane_image(
        TAG_CAMERA,
        R,
        t,
        0.05 + 0.9 * rendering.image / 255.0,
        rendering.px_per_m,
        rendering.top_left_world_m,
        background=0.95,
        supersample=3,
    )
    view = View(R, t, 1.0)
    p_light_camera = np.array([0.1, 0.0, 0.0])
    axis_camera = R @ (np.array([0.1, 0.05, 0.0]) - view.center_world) - p_light_camera
    light = Light(
        CosPowerRID.from_half_angle(math.radians(7.0)),
        p_light_camera,
        rotation_from_axis(axis_camera / np.linalg.norm(axis_camera)),
    )
    beam = np.ma.getdata(render_image(TAG_CAMERA, view, Rig.single(light)))
    return albedo, beam / beam.max(), R, t


@pytest.mark.parametrize(
    ("room_light", "stretch", "max_error_px"),
    [(1e-2, "gamma", 0.1), (1e-3, "log", 0.5), (3e-4, "clahe", 0.5)],
)
def test_the_issues_four_apriltags_beside_a_narrow_beam_are_all_found(
    room_light, stretch, max_error_px
):
    """The beam saturated at its centre, the room light a fraction of its peak: the
    percentile stretch finds no tag, the search all four, on the stretch that the room
    light's level needs. (Under a room light of 1e-3 of the beam's peak or less, the
    beam's tail, about 5e-4 of its peak at the tags and falling steeply across each, is as
    bright as the room light: the corners are 0.4 px off, where the gamma stretch finds no
    tag at all.)"""
    from lightcal.capture.apriltag import printed_corners
    from tests.test_marker_layout import CAMERA as TAG_CAMERA
    from tests.test_marker_layout import RECTANGLE, TAG

    albedo, beam, R, t = _tag_wall()
    photo = 1000.0 * np.minimum(albedo * (beam + room_light), 0.6)
    photo += np.random.default_rng(0).normal(0.0, 0.02, photo.shape)
    assert 0.01 < np.mean(photo >= 599.0) < 0.03  # the beam's centre saturates

    image_u8, image_f = detection_images(photo, TAG_CAMERA, "tags")
    detector = cv2.aruco.ArucoDetector(aruco_dictionary(TAG), detector_parameters())
    assert detector.detectMarkers(image_u8)[1] is None  # the percentile stretch: none
    search = find_markers(image_u8, image_f, TAG_CAMERA, {TAG: RECTANGLE.ids_of(TAG)})
    assert search.refused == ()
    np.testing.assert_array_equal(search.ids(TAG), [0, 1, 2, 3])
    first = [STRETCHES.index(m.stretches[0]) for m in search.found]
    assert min(first) <= STRETCHES.index(stretch) == max(first)  # that stretch was needed
    true, _ = TAG_CAMERA.project(
        RECTANGLE.marker_corners_world(RECTANGLE.indices_of(TAG, [0, 1, 2, 3])).reshape(-1, 3) @ R.T
        + t
    )
    found = printed_corners(TAG, search.corners_px(TAG)).reshape(-1, 2)
    errors = np.linalg.norm(found - true, axis=-1)
    print(f"room light {room_light:g}: tag corners within {errors.max():.3f} px")
    assert errors.max() < max_error_px


def test_a_charuco_board_beside_a_beam_gives_every_corner():
    """The 1.6 m ChArUco scene under the beam of `_beam_photo`, left of the board."""
    from lightcal.capture.marker_detection import detect_charuco
    from tests.test_marker_pose import CHARUCO

    _, image, R, t = scene("charuco_1.6m_tilt30")
    rows, cols = np.mgrid[0 : CAMERA.height, 0 : CAMERA.width]
    beam = 1.0 + BEAM_PEAK * np.exp(-((cols - 300.0) ** 2 + (rows - 580.0) ** 2) / (2 * 120.0**2))
    photo = np.minimum(np.array(image) * beam, SATURATION)
    image_u8, image_f = detection_images(photo, CAMERA, "charuco")
    parameters = cv2.aruco.CharucoParameters()
    parameters.cameraMatrix = np.array(CAMERA.K)
    parameters.distCoeffs = np.array(CAMERA.dist)
    detector = cv2.aruco.CharucoDetector(CHARUCO.cv_board(), parameters, detector_parameters())
    _, percentile_ids, _, _ = detector.detectBoard(image_u8)
    assert len(percentile_ids) <= 10  # of 70 corners: the percentile stretch alone
    markers, corner_ids, corners_world, corners_px = detect_charuco(
        image_u8, image_f, CHARUCO, CAMERA, "charuco"
    )
    assert markers.size == 44
    np.testing.assert_array_equal(corner_ids, np.arange(70))
    true, _ = CAMERA.project(corners_world @ R.T + t)
    errors = np.linalg.norm(corners_px - true, axis=-1)
    print(f"ChArUco corners: max error {errors.max():.3f} px")
    assert errors.max() < 0.1


def test_large_blurred_markers_are_not_refused_for_their_detectors_spread(monkeypatch):
    """Markers of 140 px (0.8 m) blurred by 2 px: on the four stretches the detector's
    corners of one marker differ by more than `CONSISTENT_PX` (as on a 24 MP photo); half
    a module (10 px) is the tolerance, and every marker is kept and refined."""
    monkeypatch.setattr(marker_search, "MIN_STRETCHES", len(STRETCHES))  # all four
    _, image, R, t = scene("grid_0.8m_frontal")
    image_u8, image_f = detection_images(
        cv2.GaussianBlur(np.array(image), (0, 0), 2.0), CAMERA, "blurred"
    )
    seen = marker_search._detect(
        detection_stretches(image_u8, image_f), GRID.dictionary, np.asarray(GRID.ids)
    )
    spread = max(
        np.max(np.linalg.norm(a - b, axis=-1))
        for quads in seen.values()
        for _, a in quads
        for _, b in quads
    )
    assert spread > marker_search.CONSISTENT_PX
    search = find_markers(image_u8, image_f, CAMERA, {GRID.dictionary: GRID.ids})
    assert search.refused == ()
    np.testing.assert_array_equal(search.ids(GRID.dictionary), GRID.ids)
    errors = np.linalg.norm(
        search.corners_px(GRID.dictionary) - _true_corners(GRID.ids, R, t), axis=-1
    )
    print(f"spread {spread:.1f} px, corners within {errors.max():.3f} px")
    assert errors.max() < 0.1
