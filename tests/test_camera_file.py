"""Tests of lightcal.io.camera_file: OpenCV YAML/XML, JSON, YAML and COLMAP files."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from lightcal.core.camera import Camera
from lightcal.errors import InputError
from lightcal.io.camera_file import read_camera, write_camera

DATA = Path(__file__).parent / "data" / "camera"

CAMERAS = {
    "5 coefficients and skew": Camera.from_params(
        fx=812.3456789012345,
        fy=2400 / 3,
        cx=640.1234567,
        cy=359.5,
        width=1280,
        height=720,
        dist=[-0.1, 0.01, 1e-5, -2e-5, 0.1 / 3],
        skew=0.25,
    ),
    "no distortion": Camera.from_params(fx=800, fy=800, cx=319.5, cy=239.5, width=640, height=480),
    "4 coefficients": Camera.from_params(
        fx=1e3, fy=1e3 + 1e-9, cx=0.1, cy=0.2, width=3, height=2, dist=[1e-300, -2.5, 0.1, 0.7]
    ),
    "8 coefficients": Camera.from_params(
        fx=1400.0, fy=1400.0, cx=960.0, cy=540.0, width=1920, height=1080, dist=np.arange(1, 9) / 97
    ),
}


def _match(path: Path, message: str) -> str:
    return "^" + re.escape(f"{path}: {message}") + "$"


@pytest.mark.parametrize("suffix", [".yaml", ".yml", ".xml", ".json"])
@pytest.mark.parametrize("name", list(CAMERAS))
def test_write_read_round_trip_is_exact(tmp_path: Path, suffix: str, name: str) -> None:
    camera = CAMERAS[name]
    path = tmp_path / f"camera{suffix}"
    write_camera(camera, path)
    back = read_camera(path)
    assert back == camera
    assert back.n_dist == camera.n_dist
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary file left


def test_write_yaml_is_readable_by_opencv(tmp_path: Path) -> None:
    camera = CAMERAS["5 coefficients and skew"]
    path = tmp_path / "camera.yaml"
    write_camera(camera, path)
    assert path.read_text().startswith("%YAML")
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    assert np.array_equal(storage.getNode("camera_matrix").mat(), camera.K)
    assert np.array_equal(storage.getNode("distortion_coefficients").mat().ravel(), camera.dist[:5])
    assert storage.getNode("image_width").real() == 1280
    assert storage.getNode("image_height").real() == 720
    storage.release()


def test_write_json_content(tmp_path: Path) -> None:
    path = tmp_path / "camera.json"
    write_camera(CAMERAS["4 coefficients"], path)
    content = json.loads(path.read_text())
    assert content == {
        "image_width": 3,
        "image_height": 2,
        "camera_matrix": [[1e3, 0.0, 0.1], [0.0, 1e3 + 1e-9, 0.2], [0.0, 0.0, 1.0]],
        "distortion_coefficients": [1e-300, -2.5, 0.1, 0.7],
    }


def test_write_replaces_existing_file(tmp_path: Path) -> None:
    path = tmp_path / "camera.yaml"
    write_camera(CAMERAS["no distortion"], path)
    write_camera(CAMERAS["8 coefficients"], path)
    assert read_camera(path) == CAMERAS["8 coefficients"]


def test_write_errors(tmp_path: Path) -> None:
    camera = CAMERAS["no distortion"]
    bad_suffix = tmp_path / "camera.txt"
    with pytest.raises(
        InputError,
        match=_match(
            bad_suffix, "unsupported file suffix '.txt': expected .yaml, .yml, .xml or .json"
        ),
    ):
        write_camera(camera, bad_suffix)
    missing = tmp_path / "nowhere" / "camera.yaml"
    with pytest.raises(
        InputError,
        match=_match(missing, f"cannot write: folder {str(missing.parent)!r} does not exist"),
    ):
        write_camera(camera, missing)


def test_read_file_written_by_cv2_file_storage(tmp_path: Path) -> None:
    K = np.array([[1000.5, 0.0, 640.25], [0.0, 1001.5, 360.75], [0.0, 0.0, 1.0]])
    dist = np.array([[-0.2], [0.05], [0.001], [-0.002], [0.01], [0.1], [0.02], [0.003]])
    path = tmp_path / "calib.yml"
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    storage.write("cameraMatrix", K)
    storage.write("distCoeffs", dist)
    # What C++ `fs << "image_size" << cv::Size(1280, 720)` writes: a flow sequence.
    storage.startWriteStruct("image_size", cv2.FileNode_SEQ | cv2.FileNode_FLOW)
    storage.write("", 1280)
    storage.write("", 720)
    storage.endWriteStruct()
    storage.write("avg_reprojection_error", 0.21)
    storage.release()
    camera = read_camera(path)
    assert np.array_equal(camera.K, K)
    assert np.array_equal(camera.dist, dist.ravel())
    assert (camera.width, camera.height, camera.n_dist) == (1280, 720, 8)


def test_read_json_written_by_cv2_file_storage(tmp_path: Path) -> None:
    # cv2 writes a 1-D numpy array as an "opencv-nd-matrix" with sizes.
    path = tmp_path / "calib.json"
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    storage.write("K", CAMERAS["5 coefficients and skew"].K)
    storage.write("D", np.array([-0.1, 0.01, 1e-5, -2e-5, 0.1 / 3]))
    storage.write("width", 1280)
    storage.write("height", 720)
    storage.release()
    assert read_camera(path) == CAMERAS["5 coefficients and skew"]


def test_read_opencv4_calibration_sample_file() -> None:
    camera = read_camera(DATA / "opencv4_calibration.yml")
    assert camera.K.tolist() == [
        [1412.8715572357178, 0.0, 963.502685546875],
        [0.0, 1413.1591796875, 540.12158203125],
        [0.0, 0.0, 1.0],
    ]
    assert camera.dist_opencv.tolist() == [
        -1.2345678901234567e-01,
        8.7654321098765432e-02,
        -1e-4,
        2.5000000000000001e-04,
        -1.5e-02,
    ]
    assert (camera.width, camera.height) == (1920, 1080)


def test_read_ros_camera_info_yaml() -> None:
    camera = read_camera(DATA / "ros_camera_info.yaml")
    assert camera == Camera.from_params(
        fx=525.5,
        fy=524.75,
        cx=319.25,
        cy=239.5,
        width=640,
        height=480,
        dist=[0.0213, -0.0512, 0.0003, -0.0007, 0.0118],
    )


@pytest.mark.parametrize(
    "content",
    [
        "K: [[100, 0, 50], [0, 110, 40], [0, 0, 1]]\nD: [0.1, 0.2, 0.0, 0.0]\n"
        "width: 100\nheight: 80\n",
        "K: [100, 0, 50, 0, 110, 40, 0, 0, 1]\ndist_coeffs: [[0.1], [0.2], [0], [0]]\n"
        "image_size: [100, 80]\n",
        "cameraMatrix: {rows: 3, cols: 3, data: [100, 0, 50, 0, 110, 40, 0, 0, 1]}\n"
        "distCoeffs: [[0.1, 0.2, 0, 0]]\nimage_width: 100.0\nimage_height: 80\n",
    ],
)
def test_read_plain_yaml_key_spellings(tmp_path: Path, content: str) -> None:
    path = tmp_path / "camera.yaml"
    path.write_text(content)
    assert read_camera(path) == Camera.from_params(
        fx=100.0, fy=110.0, cx=50.0, cy=40.0, width=100, height=80, dist=[0.1, 0.2, 0.0, 0.0]
    )


def test_read_accepts_zero_thin_prism_terms(tmp_path: Path) -> None:
    path = tmp_path / "camera.json"
    path.write_text(
        json.dumps({"K": np.eye(3).tolist(), "D": [0.1, *[0.0] * 13], "image_size": [4, 3]})
    )
    camera = read_camera(path)
    assert camera.n_dist == 8 and camera.dist[0] == 0.1
    path.write_text(
        json.dumps({"K": np.eye(3).tolist(), "D": [0.1, *[0.0] * 10, 0.5], "image_size": [4, 3]})
    )
    with pytest.raises(
        InputError,
        match=_match(
            path,
            "D: thin-prism and tilt coefficients (s1..s4, tau_x, tau_y) are not supported: "
            "expected them zero, got [0.0, 0.0, 0.0, 0.5]",
        ),
    ):
        read_camera(path)


# --------------------------------------------------------------------------- COLMAP

COLMAP_EXPECTED = {
    1: Camera.from_params(fx=2559.81, fy=2559.81, cx=1535.5, cy=1151.5, width=3072, height=2304),
    2: Camera.from_params(fx=2560.5, fy=2558.25, cx=1536.0, cy=1151.75, width=3072, height=2304),
    3: Camera.from_params(
        fx=1700.5, fy=1700.5, cx=1023.5, cy=767.5, width=2048, height=1536, dist=[-0.0123, 0, 0, 0]
    ),
    4: Camera.from_params(
        fx=1700.5,
        fy=1700.5,
        cx=1024.0,
        cy=768.0,
        width=2048,
        height=1536,
        dist=[-0.0123, 0.0045, 0, 0],
    ),
    5: Camera.from_params(
        fx=1400.25,
        fy=1401.75,
        cx=960.0,
        cy=540.0,
        width=1920,
        height=1080,
        dist=[-0.11, 0.08, 0.0002, -0.0003],
    ),
    7: Camera.from_params(
        fx=1400.25,
        fy=1401.75,
        cx=960.0,
        cy=540.0,
        width=1920,
        height=1080,
        dist=[-0.11, 0.08, 0.0002, -0.0003, 0.01, 0.02, -0.03, 0.004],
    ),
}


@pytest.mark.parametrize("camera_id", list(COLMAP_EXPECTED))
def test_read_colmap_each_model(camera_id: int) -> None:
    # Principal points are shifted by -0.5 (COLMAP's upper-left pixel centre is (0.5, 0.5)).
    camera = read_camera(DATA / "colmap_cameras.txt", camera_id=camera_id)
    assert camera == COLMAP_EXPECTED[camera_id]


def test_colmap_principal_point_convention(tmp_path: Path) -> None:
    # The image centre in COLMAP (w / 2) is the centre in OpenCV ((w - 1) / 2).
    path = tmp_path / "cameras.txt"
    path.write_text("1 PINHOLE 640 480 500 500 320 240\n")
    camera = read_camera(path)
    assert (camera.cx, camera.cy) == ((640 - 1) / 2, (480 - 1) / 2)


def test_colmap_camera_selection_errors(tmp_path: Path) -> None:
    path = DATA / "colmap_cameras.txt"
    with pytest.raises(
        InputError,
        match=_match(path, "found 6 cameras (ids 1, 2, 3, 4, 5, 7): pass camera_id to choose one"),
    ):
        read_camera(path)
    with pytest.raises(
        InputError, match=_match(path, "camera_id 6 not found: the file has ids 1, 2, 3, 4, 5, 7")
    ):
        read_camera(path, camera_id=6)
    empty = tmp_path / "cameras.txt"
    empty.write_text("# nothing\n\n")
    with pytest.raises(
        InputError,
        match=_match(empty, "no camera found: expected lines CAMERA_ID MODEL WIDTH HEIGHT ..."),
    ):
        read_camera(empty)


@pytest.mark.parametrize(
    ("line", "message"),
    [
        (
            "1 OPENCV_FISHEYE 640 480 500 500 320 240 0.1 0.2 0.3 0.4",
            "camera model 'OPENCV_FISHEYE' is not supported: expected one of SIMPLE_PINHOLE, "
            "PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV",
        ),
        ("1 PINHOLE 640 480 500 500 320", "PINHOLE: expected 4 parameters (fx, fy, cx, cy), got 3"),
        ("1 PINHOLE 640", "expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS..., got 3 fields"),
        ("x PINHOLE 640 480 500 500 320 240", "CAMERA_ID: expected an integer, got 'x'"),
        (
            "1 PINHOLE 640 -480 500 500 320 240",
            "HEIGHT: expected a positive integer up to 65535, got '-480'",
        ),
        (
            "1 PINHOLE 640.5 480 500 500 320 240",
            "WIDTH: expected a positive integer up to 65535, got '640.5'",
        ),
        (
            "1 SIMPLE_RADIAL 640 480 500 320 240 abc",
            "SIMPLE_RADIAL k: expected a number, got 'abc'",
        ),
        ("1 PINHOLE 640 480 500 nan 320 240", "PINHOLE fy: expected a finite number, got 'nan'"),
        (
            "1 PINHOLE 640 480 500 -500 320 240",
            "PINHOLE: expected fx > 0 and fy > 0, got fx=500.0, fy=-500.0",
        ),
    ],
)
def test_colmap_line_errors(tmp_path: Path, line: str, message: str) -> None:
    path = tmp_path / "cameras.txt"
    path.write_text(f"# header\n{line}\n")
    with pytest.raises(InputError, match="^" + re.escape(f"{path}:2: {message}") + "$"):
        read_camera(path)


def test_colmap_duplicate_id(tmp_path: Path) -> None:
    path = tmp_path / "cameras.txt"
    path.write_text("1 PINHOLE 640 480 500 500 320 240\n1 PINHOLE 640 480 500 500 320 240\n")
    with pytest.raises(
        InputError,
        match="^"
        + re.escape(f"{path}:2: CAMERA_ID: camera 1 appears twice (first on line 1)")
        + "$",
    ):
        read_camera(path)


def test_camera_id_rejected_for_other_formats() -> None:
    with pytest.raises(
        InputError,
        match=r"^camera_id: applies only to COLMAP cameras\.txt files, "
        r"got camera_id=1 for a \.yaml file$",
    ):
        read_camera(DATA / "ros_camera_info.yaml", camera_id=1)


# --------------------------------------------------------------------------- errors


def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "missing.yaml"
    with pytest.raises(InputError, match=_match(path, "camera file not found")):
        read_camera(path)
    with pytest.raises(InputError, match=_match(tmp_path, "is a folder; expected a camera file")):
        read_camera(tmp_path)


def test_unsupported_suffix(tmp_path: Path) -> None:
    path = tmp_path / "camera.ini"
    path.write_text("fx=1\n")
    with pytest.raises(
        InputError,
        match=_match(
            path,
            "unsupported file suffix '.ini': expected .yaml, .yml, .xml, .json or a COLMAP "
            "cameras .txt",
        ),
    ):
        read_camera(path)


def test_truncated_opencv_yaml(tmp_path: Path) -> None:
    full = tmp_path / "full.yaml"
    write_camera(CAMERAS["8 coefficients"], full)
    text = full.read_text()
    path = tmp_path / "truncated.yaml"
    path.write_text(text[: text.index("data:") + 20])
    with pytest.raises(
        InputError, match=r"truncated\.yaml:\d+: not a valid OpenCV YAML/XML file: "
    ):
        read_camera(path)


def test_opencv_matrix_with_wrong_element_count(tmp_path: Path) -> None:
    path = tmp_path / "camera.yaml"
    path.write_text(
        "%YAML:1.0\n---\nimage_width: 4\nimage_height: 3\ncamera_matrix: !!opencv-matrix\n"
        "   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1., 0., 2. ]\n"
        "distortion_coefficients: !!opencv-matrix\n   rows: 0\n   cols: 1\n   dt: d\n   data: []\n"
    )
    with pytest.raises(
        InputError,
        match=_match(path, "camera_matrix: expected rows x cols = 9 values in data, got 3"),
    ):
        read_camera(path)


def test_corrupt_json_and_yaml(tmp_path: Path) -> None:
    path = tmp_path / "camera.json"
    path.write_text('{"K": [[1, 0, 0],\n  [0, 1, 0]\n')
    with pytest.raises(InputError, match=re.escape(f"{path}:3: not valid JSON: ")):
        read_camera(path)
    path = tmp_path / "camera.yaml"
    path.write_text("K: [[1, 0, 0]\nwidth: 3\n")
    with pytest.raises(InputError, match=re.escape(f"{path}:2: not valid YAML: ")):
        read_camera(path)
    path.write_text("- 1\n- 2\n")
    with pytest.raises(
        InputError, match=_match(path, "expected a mapping of keys at the top level, got list")
    ):
        read_camera(path)
    path.write_bytes(b"K: \x80\x81garbage")
    with pytest.raises(
        InputError,
        match=_match(path, "the camera file is not UTF-8 text (byte 3): save it as UTF-8"),
    ):
        read_camera(path)


GOOD = {
    "camera_matrix": [[100.0, 0.0, 50.0], [0.0, 100.0, 40.0], [0.0, 0.0, 1.0]],
    "distortion_coefficients": [0.1, 0.0, 0.0, 0.0],
    "image_width": 100,
    "image_height": 80,
}


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            {"camera_matrix": None},
            "camera_matrix: missing key: expected one of camera_matrix, K, cameraMatrix",
        ),
        (
            {"distortion_coefficients": None},
            "distortion_coefficients: missing key: expected one of distortion_coefficients, "
            "dist_coeffs, D, distCoeffs",
        ),
        (
            {"image_width": None},
            "image_width: missing key: expected one of image_width, width (or image_size)",
        ),
        (
            {"image_height": None},
            "image_height: missing key: expected one of image_height, height (or image_size)",
        ),
        (
            {"camera_matrix": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]},
            "camera_matrix: expected a 3x3 matrix, got 2x3",
        ),
        (
            {"camera_matrix": [[1.0, 0.0, 0.0], [0.0, 1.0]]},
            "camera_matrix: expected rows of equal length, got [[1.0, 0.0, 0.0], [0.0, 1.0]]",
        ),
        ({"camera_matrix": "eye"}, "camera_matrix: expected a matrix, got 'eye'"),
        (
            {"camera_matrix": [[100.0, 0.0, 50.0], [0.0, 100.0, "40"], [0.0, 0.0, 1.0]]},
            "camera_matrix: expected numbers, got '40'",
        ),
        (
            {"camera_matrix": [[100.0, 0.0, 50.0], [0.0, 100.0, float("nan")], [0.0, 0.0, 1.0]]},
            "camera_matrix: expected finite values, got "
            "[100.0, 0.0, 50.0, 0.0, 100.0, nan, 0.0, 0.0, 1.0]",
        ),
        (
            {"camera_matrix": [[100.0, 0.0, 50.0], [0.0, 100.0, 40.0], [0.0, 0.0, 2.0]]},
            "camera_matrix: expected the form [[fx, s, cx], [0, fy, cy], [0, 0, 1]], got "
            "K[1, 0]=0.0, K[2, 0]=0.0, K[2, 1]=0.0, K[2, 2]=2.0",
        ),
        (
            {"distortion_coefficients": [0.1, 0.2, 0.3]},
            "distortion_coefficients: expected 0, 4, 5 or 8 coefficients, got 3",
        ),
        (
            {"distortion_coefficients": [[0.1, 0.2], [0.3, 0.4]]},
            "distortion_coefficients: expected a 1xn or nx1 vector, got 2x2",
        ),
        (
            {"distortion_coefficients": [0.1, float("inf"), 0.0, 0.0]},
            "distortion_coefficients: expected finite values, got [0.1, inf, 0.0, 0.0]",
        ),
        ({"image_width": -3}, "image_width: expected a positive integer, got -3"),
        ({"image_height": 80.5}, "image_height: expected a positive integer, got 80.5"),
        (
            {"K": [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1]]},
            "camera_matrix: found the keys camera_matrix, K for the same value: expected only one",
        ),
    ],
)
def test_content_errors(tmp_path: Path, change: dict[str, object], message: str) -> None:
    content = {**GOOD, **change}
    content = {key: value for key, value in content.items() if value is not None}
    path = tmp_path / "camera.json"
    path.write_text(json.dumps(content))
    with pytest.raises(InputError, match=_match(path, message)):
        read_camera(path)


def test_content_errors_in_opencv_yaml(tmp_path: Path) -> None:
    path = tmp_path / "camera.yaml"
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    storage.write("camera_matrix", np.eye(3)[:2])
    storage.write("distortion_coefficients", np.zeros((5, 1)))
    storage.write("image_width", 4)
    storage.write("image_height", 3)
    storage.release()
    with pytest.raises(
        InputError, match=_match(path, "camera_matrix: expected a 3x3 matrix, got 2x3")
    ):
        read_camera(path)
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    storage.write("camera_matrix", np.eye(3))
    storage.write("image_width", 4)
    storage.write("image_height", 3)
    storage.release()
    with pytest.raises(
        InputError, match=re.escape(f"{path}: distortion_coefficients: missing key")
    ):
        read_camera(path)


@pytest.mark.parametrize("name", ["camera.yaml", "camera.xml", "camera.json"])
def test_empty_file(tmp_path: Path, name: str) -> None:
    path = tmp_path / name
    path.write_text("\n")
    with pytest.raises(InputError, match=_match(path, "empty file: expected a mapping of keys")):
        read_camera(path)


def _with_covariance(camera: Camera, seed: int = 0) -> Camera:
    p = 4 + camera.n_dist
    a = (
        np.random.default_rng(seed).normal(size=(p, p))
        * np.r_[0.3, 0.3, 0.5, 0.5, [1e-3] * (p - 4)]
    )
    return dataclasses.replace(camera, intrinsics_covariance=a.T @ a / 7.0)


@pytest.mark.parametrize("suffix", [".yaml", ".xml", ".json"])
@pytest.mark.parametrize("name", list(CAMERAS))
def test_intrinsics_covariance_round_trip(tmp_path: Path, suffix: str, name: str) -> None:
    camera = _with_covariance(CAMERAS[name])
    path = tmp_path / f"camera{suffix}"
    write_camera(camera, path)
    back = read_camera(path)
    assert back == camera
    assert back.intrinsics_covariance is not None
    np.testing.assert_array_equal(back.intrinsics_covariance, camera.intrinsics_covariance)
    assert (
        back.intrinsic_names
        == ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")[
            : 4 + camera.n_dist
        ]
    )
    if suffix == ".yaml":  # an OpenCV matrix node that OpenCV reads
        storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
        np.testing.assert_array_equal(
            storage.getNode("intrinsics_covariance").mat(), camera.intrinsics_covariance
        )
        storage.release()


def test_files_without_covariance_load_without_it(tmp_path: Path) -> None:
    path = tmp_path / "camera.yaml"
    write_camera(CAMERAS["4 coefficients"], path)
    assert "intrinsics_covariance" not in path.read_text()
    assert read_camera(path).intrinsics_covariance is None


def test_intrinsics_covariance_errors(tmp_path: Path) -> None:
    path = tmp_path / "camera.json"
    content = {
        "image_width": 640,
        "image_height": 480,
        "camera_matrix": [[800, 0, 320], [0, 800, 240], [0, 0, 1]],
        "distortion_coefficients": [0.1, 0.0, 0.0, 0.0],
        "intrinsics_covariance": np.eye(9).tolist(),
    }
    path.write_text(json.dumps(content))
    with pytest.raises(InputError, match="intrinsics_covariance: expected a 8x8 matrix"):
        read_camera(path)
    content["intrinsics_covariance"] = (-np.eye(8)).tolist()
    path.write_text(json.dumps(content))
    with pytest.raises(InputError, match="intrinsics_covariance: expected a positive semi-def"):
        read_camera(path)
    asym = np.eye(8)
    asym[0, 1] = 0.5
    content["intrinsics_covariance"] = asym.tolist()
    path.write_text(json.dumps(content))
    with pytest.raises(InputError, match="intrinsics_covariance: expected a symmetric matrix"):
        read_camera(path)
