"""Tests of `lightcal camera calibrate` and `lightcal camera import` through the CLI."""

from __future__ import annotations

import functools
import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from lightcal.capture.boards import ArucoGridBoard, Chessboard
from lightcal.capture.plane_texture import look_at_pose, render_plane_image
from lightcal.cli.main import main
from lightcal.core.camera import Camera
from lightcal.io.board_file import write_board
from lightcal.io.camera_file import read_camera, write_camera

WIDTH, HEIGHT = 640, 480
CAMERA = Camera.from_params(
    fx=560.0,
    fy=561.0,
    cx=322.4,
    cy=238.1,
    width=WIDTH,
    height=HEIGHT,
    dist=(-0.12, 0.05, 3e-4, -2e-4, 0.0),
)
CHESSBOARD = Chessboard(9, 6, 0.03)


@functools.cache
def chessboard_views(n_views: int = 10) -> tuple[np.ndarray, ...]:
    """uint8 views of the chessboard from all around, tilted 20 - 40 degrees."""
    rng = np.random.default_rng(11)
    rendering = CHESSBOARD.render(2000)
    texture = 0.05 + 0.85 * rendering.image / 255.0
    s = CHESSBOARD.square_length_m
    center = np.array([(CHESSBOARD.inner_x - 1) * s / 2, -(CHESSBOARD.inner_y - 1) * s / 2, 0.0])
    images = []
    for k in range(n_views):
        azimuth = 2 * np.pi * k / n_views + rng.uniform(-0.2, 0.2)
        tilt = np.radians(rng.uniform(20.0, 40.0))
        distance = rng.uniform(0.38, 0.5)
        direction = [np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)]
        target = center + np.r_[rng.uniform(-0.04, 0.04, 2), 0.0]
        R, t = look_at_pose(
            center + distance * np.array(direction), target, roll_rad=rng.uniform(-0.5, 0.5)
        )
        image = render_plane_image(
            CAMERA, R, t, texture, rendering.px_per_m, rendering.top_left_world_m
        )
        image += rng.normal(0.0, 0.005, image.shape)
        images.append(np.clip(np.rint(image * 255.0), 0, 255).astype(np.uint8))
    return tuple(images)


@pytest.fixture
def chessboard_folder(tmp_path: Path) -> Path:
    folder = tmp_path / "chess"
    folder.mkdir()
    for i, image in enumerate(chessboard_views()):
        cv2.imwrite(str(folder / f"chess_{i:02d}.png"), image)
    write_board(CHESSBOARD, tmp_path / "chessboard.yaml")
    return folder


def test_calibrate_writes_the_camera_and_reports_every_view(
    tmp_path: Path, chessboard_folder: Path, capsys
):
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((HEIGHT, WIDTH), 128, np.uint8))
    corrupt = tmp_path / "corrupt.png"
    corrupt.write_bytes(b"\x89PNG\r\n\x1a\n this is not a PNG")
    out = tmp_path / "camera.yaml"
    argv = ["camera", "calibrate", str(chessboard_folder), str(blank), str(corrupt)]
    code = main([*argv, "--board", str(tmp_path / "chessboard.yaml"), "--out", str(out)])
    assert code == 0
    lines = capsys.readouterr().out.splitlines()
    for i, line in enumerate(lines[:10]):
        assert line.startswith(f"chess_{i:02d}.png: reprojection RMS 0.")
        assert float(line.split()[-2]) < 0.2
    assert lines[10] == "blank.png: rejected: no chessboard with 9x6 inner corners found"
    assert lines[11] == "corrupt.png: rejected: not a readable PNG image"
    assert re.fullmatch(
        r"fx 5\d\d\.\d{3} px, fy 5\d\d\.\d{3} px, cx 32\d\.\d{3} px, cy 2\d\d\.\d{3} px, "
        r"640x480, distortion \[([-+]\d\.\d{5}, ){4}[-+]\d\.\d{5}\]",
        lines[12],
    ), lines[12]
    assert re.fullmatch(
        r"1-sigma: fx 0\.\d{3} px, fy 0\.\d{3} px, cx 0\.\d{3} px, cy 0\.\d{3} px, "
        r"distortion \[(\d\.\d{5}, ){4}\d\.\d{5}\] \(the full covariance is in the file\)",
        lines[13],
    ), lines[13]
    assert lines[14].startswith("10 views used, 2 rejected, reprojection RMS 0.")
    assert lines[14].endswith(f"camera written to {out}")
    assert len(lines) == 15

    camera = read_camera(out)
    assert out.read_text().startswith("%YAML")  # OpenCV FileStorage
    assert abs(camera.fx / CAMERA.fx - 1.0) < 2e-3
    assert abs(camera.fy / CAMERA.fy - 1.0) < 2e-3
    assert abs(camera.cx - CAMERA.cx) < 1.0 and abs(camera.cy - CAMERA.cy) < 1.0
    assert (camera.width, camera.height, camera.n_dist) == (WIDTH, HEIGHT, 5)
    np.testing.assert_allclose(camera.dist[:2], CAMERA.dist[:2], atol=0.03)
    assert camera.intrinsics_covariance is not None
    assert camera.intrinsics_covariance.shape == (9, 9)
    assert abs(camera.fx - CAMERA.fx) < 5 * np.sqrt(camera.intrinsics_covariance[0, 0])


def test_calibrate_json_and_four_coefficients(tmp_path: Path, chessboard_folder: Path, capsys):
    out = tmp_path / "camera.json"
    images = sorted(str(p) for p in chessboard_folder.iterdir())[:6]
    code = main(
        [
            "camera",
            "calibrate",
            *images,
            "--board",
            str(tmp_path / "chessboard.yaml"),
            "--out",
            str(out),
            "--n-dist",
            "4",
        ]
    )
    assert code == 0
    assert "6 views used, 0 rejected" in capsys.readouterr().out
    camera = read_camera(out)
    assert out.read_text().startswith("{")
    assert camera.n_dist == 4
    assert abs(camera.fx / CAMERA.fx - 1.0) < 5e-3
    assert camera.intrinsics_covariance is not None
    assert camera.intrinsics_covariance.shape == (8, 8)


def test_calibrate_errors(tmp_path: Path, chessboard_folder: Path, capsys):
    grid = tmp_path / "grid.yaml"
    write_board(ArucoGridBoard("DICT_4X4_50", 4, 3, 0.05, 0.01), grid)
    out = tmp_path / "camera.yaml"
    assert (
        main(
            ["camera", "calibrate", str(chessboard_folder), "--board", str(grid), "--out", str(out)]
        )
        == 2
    )
    assert capsys.readouterr().err == (
        f"lightcal camera: error: {grid}: an ArUco grid gives too few points per view for "
        "intrinsics: expected a chessboard or charuco board\n"
    )
    layout = tmp_path / "layout.yaml"
    layout.write_text(
        "type: markers\ndictionary: DICT_APRILTAG_36h11\nmarkers:\n"
        "- {id: 0, center_world_m: [0, 0], size_m: 0.1}\n"
    )
    argv = ["camera", "calibrate", str(chessboard_folder), "--board", str(layout)]
    assert main([*argv, "--out", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"lightcal camera: error: {layout}: a markers board gives too few points per view for "
        "intrinsics: expected a chessboard or charuco board\n"
    )
    board = tmp_path / "chessboard.yaml"
    missing = tmp_path / "nothing.png"
    assert (
        main(["camera", "calibrate", str(missing), "--board", str(board), "--out", str(out)]) == 2
    )
    assert capsys.readouterr().err == f"lightcal camera: error: {missing}: image file not found\n"
    corrupt_board = tmp_path / "corrupt.yaml"
    corrupt_board.write_text("type: chessboard\ninner_x: [9\n")
    assert (
        main(
            [
                "camera",
                "calibrate",
                str(chessboard_folder),
                "--board",
                str(corrupt_board),
                "--out",
                str(out),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert err.startswith(f"lightcal camera: error: {corrupt_board}:") and "not valid YAML" in err
    assert err.count("\n") == 1
    two = sorted(str(p) for p in chessboard_folder.iterdir())[:2]
    assert main(["camera", "calibrate", *two, "--board", str(board), "--out", str(out)]) == 2
    assert capsys.readouterr().err == (
        "lightcal camera: error: images: 2 usable views of the board, need at least 3\n"
    )
    assert not out.exists()


def test_import_colmap_and_opencv(tmp_path: Path, capsys):
    colmap = tmp_path / "cameras.txt"
    colmap.write_text(
        "# Camera list\n1 OPENCV 640 480 560 561 322.9 238.6 -0.12 0.05 0.0003 -0.0002\n"
    )
    out = tmp_path / "camera.yaml"
    assert main(["camera", "import", str(colmap), "--out", str(out)]) == 0
    assert capsys.readouterr().out.splitlines() == [
        "fx 560.000 px, fy 561.000 px, cx 322.400 px, cy 238.100 px, 640x480, "
        "distortion [-0.12000, +0.05000, +0.00030, -0.00020]",
        f"camera written to {out}",
    ]
    camera = read_camera(out)
    assert (camera.cx, camera.cy) == (322.4, 238.1)  # COLMAP's pixel centres at +1/2
    np.testing.assert_array_equal(camera.dist[:4], [-0.12, 0.05, 0.0003, -0.0002])
    as_json = tmp_path / "camera.json"
    assert main(["camera", "import", str(out), "--out", str(as_json)]) == 0
    assert read_camera(as_json) == camera


def test_import_corrupt_input(tmp_path: Path, capsys):
    corrupt = tmp_path / "camera.yaml"
    corrupt.write_bytes(b"%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols")
    out = tmp_path / "out.json"
    assert main(["camera", "import", str(corrupt), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"lightcal camera: error: {corrupt}")
    assert err.count("\n") == 1
    assert not out.exists()
    good = tmp_path / "good.json"
    write_camera(CAMERA, good)
    assert main(["camera", "import", str(good), "--out", str(tmp_path / "camera.txt")]) == 2
    assert capsys.readouterr().err == (
        f"lightcal camera: error: {tmp_path / 'camera.txt'}: unsupported file suffix '.txt': "
        "expected .yaml, .yml, .xml or .json\n"
    )
