"""The bundled sample set (sample_data/): it loads, its pipeline outputs match the truth,
the end-to-end calibration recovers the light, and its generator is deterministic."""

from __future__ import annotations

import importlib.util
import json
import math
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from lightcal.capture.boards import ArucoGridBoard
from lightcal.capture.marker_pose import estimate_pose
from lightcal.capture.project_init import POSE_FLOOR_DEG, POSE_FLOOR_M, with_pose_floor
from lightcal.cli.main import main
from lightcal.core.camera import Camera
from lightcal.io.board_file import read_board
from lightcal.io.camera_file import read_camera
from lightcal.io.images import read_image
from lightcal.io.project import load_project
from lightcal.io.result_file import read_result

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data"

MAX_POSE_POSITION_M = 1e-3
MAX_POSE_ANGLE_DEG = 0.05
MAX_FOCAL_ERROR = 1e-3
MAX_LIGHT_POSITION_M = 3e-3
MAX_LIGHT_ANGLE_DEG = 0.2


def _truth() -> dict:
    return json.loads((SAMPLE / "truth.json").read_text())


def _true_camera(truth: dict) -> Camera:
    c = truth["camera"]
    return Camera.from_params(
        fx=c["fx"],
        fy=c["fy"],
        cx=c["cx"],
        cy=c["cy"],
        width=c["width"],
        height=c["height"],
        dist=c["dist"],
    )


def _rotation_angle_deg(R_a: np.ndarray, R_b: np.ndarray) -> float:
    cos = (float(np.trace(R_a @ R_b.T)) - 1.0) / 2.0
    return math.degrees(math.acos(min(1.0, max(-1.0, cos))))


def test_sample_data_loads_and_fits_in_30_mb():
    project = load_project(SAMPLE / "project.json")
    truth = _truth()
    assert truth["format"] == "lightcal.sample_truth"
    assert project.names == [f"view_{i:02d}" for i in range(12)]
    assert project.camera.width == 1200 and project.camera.height == 800
    assert project.spec.sensor.black_level == 512.0
    assert project.spec.lights[0].rid.type == "ies"
    for i, view in enumerate(truth["views"]):
        assert project.views[i].exposure == pytest.approx(view["exposure"], rel=1e-12)
        assert 0.8 <= view["distance_m"] <= 2.5 and view["tilt_deg"] <= 30.0
        assert view["saturated_pixels"] == 0
        mask_path = project.mask_paths[i]
        assert mask_path is not None and mask_path.is_file()
    image = read_image(project.image_paths[0], black_level=512.0, white_level=16383.0)
    assert image.shape == (800, 1200) and image.exposure is not None
    assert not image.saturated.any()
    assert len(list((SAMPLE / "chessboard").glob("chess_*.png"))) == 16
    size = sum(p.stat().st_size for p in SAMPLE.rglob("*") if p.is_file())
    assert size < 30e6


def test_intrinsics_within_a_tenth_of_a_percent():
    truth = _truth()
    true_camera = _true_camera(truth)
    camera = read_camera(SAMPLE / "camera.yaml")
    assert abs(camera.fx / true_camera.fx - 1.0) < MAX_FOCAL_ERROR
    assert abs(camera.fy / true_camera.fy - 1.0) < MAX_FOCAL_ERROR
    assert abs(camera.cx - true_camera.cx) < 0.5 and abs(camera.cy - true_camera.cy) < 0.5
    # The estimated and the true camera agree over the whole frame, corners included.
    us, vs = np.meshgrid(np.linspace(0, 1199, 13), np.linspace(0, 799, 9))
    pixels = np.column_stack([us.ravel(), vs.ravel()])
    rays, _ = true_camera.rays_camera(pixels)
    projected, _ = camera.project(rays)
    assert np.max(np.abs(projected - pixels)) < 0.3


POSE_REPEAT = 1e-6
"""How closely a marker pose estimated now repeats the committed project's (rad, m)."""


@pytest.mark.slow
def test_marker_poses_of_the_committed_images():
    truth = _truth()
    board = read_board(SAMPLE / "board.yaml")
    assert isinstance(board, ArucoGridBoard)
    project = load_project(SAMPLE / "project.json")
    cameras = {"estimated": project.camera, "true": _true_camera(truth)}
    for i, view in enumerate(truth["views"]):
        image = read_image(SAMPLE / view["path"], black_level=512.0)
        R = np.array(view["T_camera_world"]["R"])
        center = np.array(view["center_world_m"])
        for kind, camera in cameras.items():
            pose = estimate_pose(image.values, camera, board, source=view["name"])
            position_error = float(np.linalg.norm(pose.camera_center_world - center))
            angle_error = _rotation_angle_deg(pose.R_camera_world, R)
            assert position_error < MAX_POSE_POSITION_M, (view["name"], kind, position_error)
            assert angle_error < MAX_POSE_ANGLE_DEG, (view["name"], kind, angle_error)
            if kind == "estimated":  # what `lightcal init` wrote
                # To 1e-6 (rad, m): OpenCV 5's marker corner refinement moves the poses by
                # up to 3e-8 from those OpenCV 4 wrote, against pose sigmas of ~1e-5.
                np.testing.assert_allclose(
                    pose.R_camera_world, project.views[i].R_camera_world, atol=POSE_REPEAT
                )
                np.testing.assert_allclose(
                    pose.t_camera_world, project.views[i].t_camera_world, atol=POSE_REPEAT
                )
                written = project.pose_covariances[i]
                assert written is not None
                expected = with_pose_floor(pose.covariance, POSE_FLOOR_M, POSE_FLOOR_DEG)
                np.testing.assert_allclose(
                    expected, written, rtol=0, atol=1e-6 * np.abs(written).max()
                )


@pytest.mark.slow
def test_end_to_end_calibration_recovers_the_light(tmp_path: Path):
    out = tmp_path / "result.json"
    assert main(["calibrate", str(SAMPLE / "project.json"), "--out", str(out), "--quiet"]) == 0
    result = read_result(out)
    light = result.lights[0]
    true_light = _truth()["light"]
    position_error = math.dist(light.position_m, true_light["position_m"])
    axis = np.array(light.axis_camera)
    cos = float(axis @ np.array(true_light["axis_camera"]))
    angle_error = math.degrees(math.acos(min(1.0, cos)))
    assert result.converged
    assert position_error < MAX_LIGHT_POSITION_M, position_error
    assert angle_error < MAX_LIGHT_ANGLE_DEG, angle_error
    # The initial guess was well off: the solver did the work.
    initial = _truth()["light"]["initial_guess"]["position_m"]
    assert math.dist(initial, true_light["position_m"]) > 0.02


@pytest.mark.slow
@pytest.mark.parametrize("selection", ["random", "all"])
def test_the_truth_lies_within_3_sigma(tmp_path: Path, selection: str):
    """The sigmas are honest on the sample data: with 100 px per image, and with every lit
    pixel (binned 2 x 2), where the pixel noise alone would claim a few micrometres and
    the camera poses' errors (0.3-0.55 mm) dominate."""
    doc = json.loads((SAMPLE / "project.json").read_text())
    if selection == "all":
        doc["selection"].update(strategy="all", binning=2)
    # Beside the files it names, linked into tmp_path: a file written into sample_data
    # would show in the listing tests/test_sample_command.py takes in another worker.
    folder = tmp_path / "sample"
    folder.mkdir()
    for entry in SAMPLE.iterdir():
        (folder / entry.name).symlink_to(entry)
    project = folder / "variant.json"
    project.write_text(json.dumps(doc))
    out = tmp_path / "result.json"
    assert main(["calibrate", str(project), "--out", str(out), "--quiet"]) == 0
    result = read_result(out)
    assert result.fit is not None and result.fit["adequate"]
    assert any(t.startswith("camera poses (12 images") for t in result.uncertainty)
    # camera.yaml carries the intrinsics' covariance, project.json how each pose moves with
    # them: the intrinsics term is in.
    assert any(
        t.startswith("camera intrinsics (9 parameters' calibration covariance, 12 of 12")
        for t in result.uncertainty
    )
    light, truth = result.lights[0], _truth()["light"]
    z = (np.array(light.position_m) - truth["position_m"]) / np.array(light.sigma.position_m)
    assert np.all(np.abs(z) < 3.0), z
    for angle in ("roll_deg", "pitch_deg"):
        error = getattr(light, angle) - truth[angle]
        assert abs(error) < 3.0 * getattr(light.sigma, angle), (angle, error)


def _generator() -> ModuleType:
    name = "lightcal_sample_data_generator"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, SAMPLE / "make_sample_data.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def _files(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()
    }


@pytest.mark.slow
def test_generator_is_deterministic_in_quick_mode(tmp_path: Path, capsys):
    generator = _generator()
    for run in ("a", "b"):
        assert generator.main(["--quick", "--skip-calibration", "--out", str(tmp_path / run)]) == 0
    first, second = _files(tmp_path / "a"), _files(tmp_path / "b")
    assert sorted(first) == sorted(second)
    assert {"camera.yaml", "project.json", "truth.json", "light.ies", "board.yaml"} <= set(first)
    assert any(name.startswith("masks/") for name in first)
    for name, content in first.items():
        assert content == second[name], name
    assert "lightcal init" in capsys.readouterr().out
