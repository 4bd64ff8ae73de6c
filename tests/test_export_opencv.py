"""`lightcal export --format opencv`: rvec/tvec and the 6x6 pose covariance, read back
with cv2.FileStorage.

Calibrations of small synthetic datasets (a symmetric cos^m light: solver angles (a, b);
a `table2d` light: a rotation vector about the reference). The covariance, pushed through
cv2.Rodrigues (an independent map), must give back the result's own sigmas of the axis
and of R_camera_light: the mapping of `parameters.covariance` to (rvec, tvec) is right.
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from lightcal.cli.main import main
from lightcal.io.result_file import ResultFile, read_result
from lightcal.synthetic.dataset import SynthConfig, write_dataset
from lightcal.synthetic.rigs import RigConfig
from lightcal.synthetic.scenes import SceneConfig
from tests import calib_scenes as cs


def _calibrated(folder: Path, light: str) -> Path:
    config = SynthConfig(
        camera=cs.small_camera(),
        scene=SceneConfig(n_views=6),
        rig=RigConfig(model=light),  # type: ignore[arg-type]
        seed=7,
    )
    dataset = write_dataset(folder / "data", config)
    out = folder / "result.json"
    assert main(["calibrate", str(dataset.project_path), "--out", str(out), "--quiet"]) == 0
    return out


def _read_back(result_path: Path, tmp_path: Path) -> list[dict[str, np.ndarray]]:
    out = tmp_path / "light.yaml"
    assert main(["export", str(result_path), "--format", "opencv", "--out", str(out)]) == 0
    fs = cv2.FileStorage(str(out), cv2.FILE_STORAGE_READ)
    assert "light -> camera" in fs.getNode("pose_note").string()
    lights = fs.getNode("lights")
    read = []
    for i in range(lights.size()):
        node = lights.at(i)
        read.append({k: node.getNode(k).mat() for k in ("rvec", "tvec", "pose_covariance")})
    fs.release()
    return read


def _rodrigues_jacobian(rvec: np.ndarray) -> np.ndarray:
    """(9, 3) d vec(R) / d rvec by cv2.Rodrigues (row-major R)."""
    _, J = cv2.Rodrigues(rvec.reshape(3, 1))
    # cv2 gives (3, 9): d vec(R) (row-major) / d rvec, transposed
    return J.T


def _check_pose(result: ResultFile, read: dict[str, np.ndarray], index: int) -> np.ndarray:
    light = result.lights[index]
    R, _ = cv2.Rodrigues(read["rvec"])
    np.testing.assert_allclose(R, light.R_camera_light, atol=1e-12)
    np.testing.assert_allclose(read["tvec"].ravel(), light.position_m, atol=0)
    cov = read["pose_covariance"]
    assert cov.shape == (6, 6)
    np.testing.assert_allclose(cov, cov.T, atol=0)
    sigma_t = np.sqrt(np.diag(cov)[3:])
    np.testing.assert_allclose(sigma_t, light.sigma.position_m, rtol=1e-9)  # type: ignore[arg-type]
    return cov


@pytest.fixture(scope="module")
def symmetric(tmp_path_factory) -> Path:
    return _calibrated(tmp_path_factory.mktemp("sym"), "cos_power")


def test_rvec_tvec_and_covariance_of_a_symmetric_light(symmetric, tmp_path):
    result = read_result(symmetric)
    (read,) = _read_back(symmetric, tmp_path)
    cov = _check_pose(result, read, 0)
    # the axis R e_z: its sigma from the rvec covariance through cv2.Rodrigues
    J_axis = _rodrigues_jacobian(read["rvec"])[[2, 5, 8], :]  # column z of R
    sigma_axis = np.sqrt(np.diag(J_axis @ cov[:3, :3] @ J_axis.T))
    light = result.lights[0]
    np.testing.assert_allclose(sigma_axis, light.sigma.axis_camera, rtol=1e-4)  # type: ignore[arg-type]
    # the spin about the axis is not determined: rank 2
    eigen = np.linalg.eigvalsh(cov[:3, :3])
    assert eigen[0] < 1e-9 * eigen[-1]


def test_rvec_tvec_and_covariance_of_a_general_light(tmp_path):
    path = _calibrated(tmp_path, "table2d")
    result = read_result(path)
    assert result.lights[0].pose_kind == "general"
    (read,) = _read_back(path, tmp_path)
    cov = _check_pose(result, read, 0)
    J = _rodrigues_jacobian(read["rvec"])
    sigma_R = np.sqrt(np.diag(J @ cov[:3, :3] @ J.T)).reshape(3, 3)
    expected = np.array(result.lights[0].sigma.R_camera_light, dtype=np.float64)
    np.testing.assert_allclose(sigma_R, expected, rtol=1e-4, atol=1e-9)
    assert np.all(np.linalg.eigvalsh(cov) > 0)


def test_an_isotropic_light_has_no_rotation_covariance(symmetric, tmp_path):
    from lightcal.io.export_opencv import pose_covariance

    result = read_result(symmetric)
    light = result.lights[0].model_copy(update={"pose_kind": "isotropic"})
    cov = pose_covariance(result, light)
    assert np.all(np.isnan(cov[:3])) and np.all(np.isnan(cov[:, :3]))
    np.testing.assert_allclose(np.sqrt(np.diag(cov)[3:]), light.sigma.position_m, rtol=1e-9)  # type: ignore[arg-type]
    assert not math.isnan(cov[5, 5])
