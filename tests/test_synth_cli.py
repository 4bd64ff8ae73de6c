"""Tests of `lightcal synth` end to end through `lightcal.cli.main.main`."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from lightcal.cli.main import main
from lightcal.io.images import read_image
from lightcal.io.project import load_project

SMALL = ["--views", "3", "--width", "80", "--height", "60"]


def files_of(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()
    }


def test_synth_writes_a_loadable_dataset_with_progress(tmp_path: Path, capsys):
    out = tmp_path / "ds"
    assert main(["synth", str(out), *SMALL, "--seed", "3"]) == 0
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert len(lines) == 3
    assert lines[0].startswith("lightcal synth: view_00.png 1/3: distance ")
    assert captured.out.strip() == (
        f"wrote 3 images, {out / 'project.json'} and {out / 'truth.json'}"
    )
    assert sorted(files_of(out)) == [
        "camera.yaml",
        "images/view_00.png",
        "images/view_01.png",
        "images/view_02.png",
        "project.json",
        "truth.json",
    ]
    project = load_project(out / "project.json")
    assert project.camera.width == 80 and project.camera.fx == pytest.approx(72.0)
    assert project.camera.cx == 39.5 and project.camera.cy == 29.5
    truth = json.loads((out / "truth.json").read_text())
    assert truth["seed"] == 3
    assert truth["options"]["pose_noise_mm"] == 0.5
    times = {v["exposure_time_s"] for v in truth["views"]}
    assert times <= {1 / 60, 1 / 50, 1 / 40, 1 / 30}
    for v in truth["views"]:
        assert 0.8 <= v["distance_m"] <= 2.5 and v["tilt_deg"] <= 35.0
    light = truth["lights"][0]
    init = light["initial"]
    assert math.dist(init["position_m"], light["position_m"]) == pytest.approx(0.1)


def test_synth_says_it_builds_the_corners_light_before_the_first_image(tmp_path: Path, capsys):
    """`--corner`'s brute-force bounce takes seconds to set up: a line says so first."""
    out = tmp_path / "corner"
    assert main(["synth", str(out), *SMALL, "--corner", "0.7", "0.5", "0.8"]) == 0
    lines = capsys.readouterr().err.splitlines()
    assert lines[0] == (
        "lightcal synth: the corner's bounce light: building its cells and transfers (seconds)"
    )
    assert lines[1].startswith("lightcal synth: view_00.png 1/3: distance ")


def test_synth_options_reach_the_dataset(tmp_path: Path, capsys):
    out = tmp_path / "ds"
    argv = [
        "synth", str(out), *SMALL, "--fx", "60", "--distortion", "-0.1", "0.02", "0", "0", "0",
        "--light", "table2d", "--half-angle-deg", "25", "--lights", "2", "--bit-depth", "12",
        "--no-noise", "--format", "tiff", "--sensor", "cos4", "--distance", "1.0", "1.5",
        "--tilt-deg", "10", "--pose-noise-mm", "0", "--pose-noise-deg", "0",
        "--init-offset-m", "0.05", "--init-offset-deg", "5", "--quiet", "--seed", "9",
    ]  # fmt: skip
    assert main(argv) == 0
    assert capsys.readouterr().err == ""
    project = load_project(out / "project.json")
    assert project.camera.fx == 60.0 and project.camera.dist[0] == -0.1
    assert project.spec.sensor.model == "cos4"
    assert project.spec.sensor.white_level == 4095.0 and project.spec.sensor.black_level == 128.0
    assert project.spec.sensor.noise is not None and project.spec.sensor.noise.gain == 0.0
    assert [lt.rid.type for lt in project.spec.lights] == ["ies", "ies"]
    assert [lu.kind() for lu in project.lights] == ["general", "general"]
    assert (out / "light.ies").is_file()
    assert project.image_paths[0].name == "view_00.tif"
    truth = json.loads((out / "truth.json").read_text())
    for i, v in enumerate(truth["views"]):
        assert 1.0 <= v["distance_m"] <= 1.5 and v["tilt_deg"] <= 10.0
        # No pose noise: the project states the true poses.
        assert np.allclose(project.views[i].R_camera_world, v["T_camera_world"]["R"], atol=1e-15)
    for light in truth["lights"]:
        assert math.dist(light["initial"]["position_m"], light["position_m"]) == pytest.approx(0.05)
    image = read_image(project.image_paths[0], black_level=128.0, white_level=4095.0)
    assert image.values.max() <= 0.7 * (4095 - 128) + 0.5


def test_synth_map_sensor_from_vignetting_option(tmp_path: Path):
    out = tmp_path / "ds"
    assert main(["synth", str(out), *SMALL, "--vignetting", "-0.2", "--quiet"]) == 0
    project = load_project(out / "project.json")
    assert project.spec.sensor.model == "map"
    assert project.vignetting_path == out / "vignetting.json"
    assert json.loads((out / "vignetting.json").read_text())["coeffs"] == [-0.2]


def test_synth_refuses_a_non_empty_folder_without_force(tmp_path: Path, capsys):
    out = tmp_path / "ds"
    out.mkdir()
    (out / "old.txt").write_text("x")
    assert main(["synth", str(out), *SMALL]) == 2
    assert capsys.readouterr().err == (
        f"lightcal synth: error: {out}: the folder is not empty: expected a new or empty "
        "folder (--force replaces the dataset in it)\n"
    )
    assert sorted(p.name for p in out.iterdir()) == ["old.txt"]
    assert main(["synth", str(out), *SMALL, "--force", "--quiet"]) == 0
    assert (out / "project.json").is_file() and (out / "old.txt").is_file()


def test_synth_is_deterministic(tmp_path: Path):
    argv = [*SMALL, "--quiet", "--light", "ies", "--seed"]
    assert main(["synth", str(tmp_path / "a"), *argv, "4"]) == 0
    assert main(["synth", str(tmp_path / "b"), *argv, "4"]) == 0
    assert main(["synth", str(tmp_path / "c"), *argv, "5"]) == 0
    a, b, c = (files_of(tmp_path / n) for n in "abc")
    assert a == b
    assert a["images/view_00.png"] != c["images/view_00.png"]


ARGUMENT_ERRORS = [
    (["--distance", "2.5", "0.8"], "--distance: expected 0.001 <= min <= max <= 1000, "
     "got (2.5, 0.8)"),
    (["--sensor", "cos4", "--vignetting", "-0.2"], "--vignetting: applies to --sensor map only, "
     "got --sensor cos4"),
    (["--views", "0"], "--views: expected an integer >= 1, got 0"),
    (["--distortion", "0.1", "0.2"], "--distortion: expected 0, 4, 5 or 8 coefficients, got 2"),
    (["--pose-noise-mm", "-1"], "--pose-noise-mm: expected a value >= 0, got -1"),
    (["--half-angle-deg", "95"], "--half-angle-deg: expected a value in (0, 85) degrees, "
     "got 95.0"),
    (["--declare-medium", "given"], "--declare-medium: given: expected --attenuation C > 0 "
     "or --backscatter BETA > 0 (the medium to declare)"),
    (["--backscatter", "0.5", "--sensor", "cos4"], "--backscatter: applies to the radiance "
     "sensor model only, got 'cos4'"),
    (["--phase-g", "1.5"], "--phase-g: expected a value in [-0.99, 0.99], got 1.5"),
]  # fmt: skip


@pytest.mark.parametrize(("args", "message"), ARGUMENT_ERRORS)
def test_synth_argument_errors(tmp_path: Path, capsys, args: list[str], message: str):
    out = tmp_path / "ds"
    assert main(["synth", str(out), *SMALL, *args]) == 2
    assert capsys.readouterr().err == f"lightcal synth: error: {message}\n"
    assert not out.exists()


@pytest.mark.parametrize(
    ("declare", "expected"),
    [
        ([], {"attenuation_per_m": 0.0, "backscatter_per_m": 0.0, "estimate": []}),
        (
            ["--declare-medium", "given"],
            {"attenuation_per_m": 0.25, "backscatter_per_m": 0.5, "estimate": []},
        ),
        (
            ["--declare-medium", "estimated"],
            {
                "attenuation_per_m": 0.0,
                "backscatter_per_m": 0.0,
                "estimate": ["attenuation_per_m", "backscatter_per_m"],
            },
        ),
    ],
)
def test_synth_declares_the_medium_when_asked(tmp_path: Path, declare: list[str], expected):
    """`--attenuation` and `--backscatter` alone are departures (the project says air);
    `--declare-medium` makes the project model the water, given or estimated (g given);
    truth.json records both."""
    out = tmp_path / "ds"
    water = ["--attenuation", "0.25", "--backscatter", "0.5", "--phase-g", "0.7"]
    assert main(["synth", str(out), *SMALL, *water, *declare, "--quiet"]) == 0
    doc = json.loads((out / "project.json").read_text())
    assert {k: doc["medium"][k] for k in expected} == expected
    assert doc["medium"]["phase_g"] == (0.7 if declare else 0.9)
    project = load_project(out / "project.json")
    medium = project.medium.initial
    assert medium.attenuation_per_m == expected["attenuation_per_m"]
    assert medium.backscatter_per_m == expected["backscatter_per_m"]
    assert project.medium.estimate == tuple(expected["estimate"])
    truth = json.loads((out / "truth.json").read_text())
    assert truth["departures"]["attenuation"]["coefficient_per_m"] == 0.25
    assert truth["departures"]["backscatter"]["beta_per_m"] == 0.5
    assert truth["departures"]["backscatter"]["phase_g"] == 0.7
