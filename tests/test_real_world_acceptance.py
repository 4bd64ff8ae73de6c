"""Issue 25's acceptance: `lightcal synth --real-world` through the user's commands.

The photos are what a camera writes (8-bit grey sRGB JPEGs with EXIF, a bracket), `init`
refuses them without a response curve (`--assume-linear` does not apply: sRGB codes are
not linear), `lightcal response` fits the curve they were made with, `init --response`
(no other flag) finds every tag, the one the beam overexposes too, and writes a project
whose light starts from its beam (`initial: auto`), whose cos^m exponent and offset are
estimated; `calibrate` lands within 2 mm and 0.1 degrees of truth.json. And the basin:
random starts up to 45 degrees and 0.7 m off all reach the solution.

Measured (2 shared cores, kernels compiled): synth 1.5 s, response 3 s, init 1 s,
calibrate 3 s (every pixel binned 4 x 4: 228,000 super-pixels); the light 0.18 mm and
0.003 degrees from the truth; the basin's 10 starts 3.4 s; the whole file 28 s.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from lightcal.cli.main import main
from lightcal.io.exif import read_exposure
from lightcal.io.project import load_project
from lightcal.io.response import ResponseCurve
from lightcal.io.response_figure import srgb_to_linear
from tests.real_world_basin import prepare, random_start, reach


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("real") / "rw"
    started = time.perf_counter()
    assert main(["synth", str(out), "--real-world", "--quiet"]) == 0
    print(f"synth --real-world: {time.perf_counter() - started:.1f} s")
    return out


def test_the_dataset_is_what_a_camera_writes(dataset: Path) -> None:
    truth = json.loads((dataset / "truth.json").read_text())
    names = sorted(p.name for p in dataset.iterdir())  # no project: the user's path is init
    assert names == ["bracket", "camera.yaml", "images", "markers.yaml", "truth.json"]
    photos = sorted((dataset / "images").glob("*.jpg"))
    assert [p.name for p in photos] == [f"view_{k:02d}.jpg" for k in range(8)]
    for photo, view in zip(photos, truth["views"], strict=True):
        image = np.asarray(cv2.imread(str(photo), cv2.IMREAD_UNCHANGED))
        assert image.shape == (600, 800) and image.dtype == np.uint8  # grey, 8 bits
        exposure = read_exposure(photo)
        assert exposure is not None and exposure.exposure_time_s == pytest.approx(1 / 60)
        # The room-lit wall is far from black; the beam clips.
        assert 30 < np.median(image.astype(np.float64)) < 70
        # (truth counts the codes clipped before the JPEG; its ringing moves a few)
        clipped = np.count_nonzero(image == 255)
        assert view["clipped_pixels"] > 2000 and 0.8 < clipped / view["clipped_pixels"] <= 1.0
    # Every other view has the beam's centre on tag 1, whose white clips.
    on_tag = [v for v in truth["views"] if v["beam_center_tag_distance_m"] < 0.05]
    assert len(on_tag) == 4 and {v["nearest_tag"] for v in on_tag} == {1}
    bracket = [dataset / p for p in truth["bracket"]["paths"]]
    exposures = [read_exposure(p) for p in bracket]
    times = [e.exposure_time_s for e in exposures if e is not None]
    assert times == pytest.approx(truth["bracket"]["exposure_times_s"], rel=1e-6)
    assert times == pytest.approx([2.0**s / 60 for s in range(-4, 5)], rel=1e-6)
    light = truth["lights"][0]
    assert light["rid"]["half_angle_deg"] == 7.0
    np.testing.assert_allclose(light["position_m"], [0.11, -0.03, 0.02])


def test_init_refuses_the_jpegs_without_a_response_curve(dataset: Path, tmp_path: Path, capsys):
    """--assume-linear does not apply: the JPEGs are sRGB-encoded, not linear; without
    it or a curve init stops, naming both flags, and writes nothing."""
    argv = ["init", str(dataset / "images"), "--camera", str(dataset / "camera.yaml")]
    argv += ["--board", str(dataset / "markers.yaml"), "--out", str(tmp_path / "project.json")]
    assert main(argv) == 2
    assert capsys.readouterr().err == (
        f"lightcal init: error: {dataset / 'images' / 'view_00.jpg'}: 8-bit image values are "
        "gamma-encoded by the camera, not proportional to light: give the camera's response "
        "curve with --response FILE (fitted from an exposure bracket by lightcal response), "
        "or --assume-linear if the camera wrote linear values\n"
    )
    assert list(tmp_path.iterdir()) == []


def test_the_users_commands_calibrate_the_light(dataset: Path, tmp_path: Path, capsys):
    bracket = sorted(str(p) for p in (dataset / "bracket").glob("*.jpg"))
    curve_path = tmp_path / "curve.json"
    assert main(["response", *bracket, "--out", str(curve_path)]) == 0
    curve = ResponseCurve.load(curve_path)
    assert curve.n_channels == 1  # grey photos: a curve that reads grey photos
    codes = np.arange(30, 251)
    fitted = curve.values[codes, 0] / curve.values[128, 0]
    truth = srgb_to_linear(codes) / srgb_to_linear(np.array([128]))[0]
    error = np.max(np.abs(np.log(fitted / truth)))
    print(f"response: within {100 * error:.2f} % of sRGB on codes 30-250")
    assert error < 0.02  # measured 0.8 % (a regular grid of 300 locations: 19 %)

    capsys.readouterr()
    argv = ["init", str(dataset / "images"), "--camera", str(dataset / "camera.yaml")]
    argv += ["--board", str(dataset / "markers.yaml"), "--response", str(curve_path)]
    assert main([*argv, "--out", str(tmp_path / "project.json")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split(",")[0] for line in lines[:8]] == [
        f"view_{k:02d}.jpg: 4 markers" for k in range(8)
    ]
    assert lines[-1].startswith("8 of 8 images accepted, 0 rejected")
    project = load_project(tmp_path / "project.json")
    truth_views = json.loads((dataset / "truth.json").read_text())["views"]
    angles, shifts = [], []
    for view, true in zip(project.views, truth_views, strict=True):
        R = np.array(true["T_camera_world"]["R"])
        cos = np.clip((np.trace(view.R_camera_world @ R.T) - 1.0) / 2.0, -1.0, 1.0)
        angles.append(np.degrees(np.arccos(cos)))
        shifts.append(np.linalg.norm(view.center_world - np.array(true["center_world_m"])))
    print(f"init's poses: within {max(angles):.3f} deg and {1e3 * max(shifts):.1f} mm")
    # measured 0.092 deg and 4.3 mm; 0.19 deg and 7.1 mm when the edge refinement kept
    # corners the detector put 1.4-2.1 px off (its limit was 1.5 px, now 3 px)
    assert max(angles) < 0.15 and max(shifts) < 0.005

    # calibrate, as init left the project: initial: auto from the beam.
    spec = json.loads((tmp_path / "project.json").read_text())
    assert spec["lights"][0]["initial"] == "auto"
    assert spec["lights"][0]["estimate_rid"] == "cos_power"  # no light file given
    assert spec["sensor"]["estimate_offset"] is True  # JPEGs: the room light, code 0
    started = time.perf_counter()
    assert (
        main(["calibrate", str(tmp_path / "project.json"), "--out", str(tmp_path / "r.json")]) == 0
    )
    print(f"calibrate: {time.perf_counter() - started:.1f} s")
    said = capsys.readouterr()
    assert "light: initial: auto: from its beam in the images" in said.out + said.err
    light = json.loads((tmp_path / "r.json").read_text())["lights"][0]
    true = json.loads((dataset / "truth.json").read_text())["lights"][0]
    error_mm = 1e3 * np.linalg.norm(np.subtract(light["position_m"], true["position_m"]))
    cos = np.dot(light["axis_camera"], true["axis_camera"])
    error_deg = np.degrees(np.arccos(min(1.0, cos)))
    print(f"the light: {error_mm:.2f} mm and {error_deg:.4f} deg from the truth")
    assert error_mm < 2.0 and error_deg < 0.1  # the bound; measured 0.18 mm, 0.003 deg
    # Tighter, so that the fixes stay: 1.8 mm when codes 243-253 of the JPEGs count as
    # unsaturated (lightcal.io.images.RESPONSE_SATURATION_CODE).
    assert error_mm < 1.0


def test_random_starts_reach_the_solution(tmp_path: Path) -> None:
    """10 starts up to 45 degrees and 0.7 m off, each solved alone (the project's
    multistart 0): all reach the minimum (benchmarks/calibrate.py runs 100)."""
    basin = prepare(tmp_path)
    rng = np.random.default_rng(5)
    started = time.perf_counter()
    reached = [
        reach(basin, random_start(basin, rng, 0.7, 45.0), multistart=0, seed=k) for k in range(10)
    ]
    print(f"basin: 10 starts in {time.perf_counter() - started:.1f} s")
    assert [r[0] for r in reached] == [True] * 10, reached
