"""The albedo map end to end: `lightcal synth --albedo-texture --declare-albedo-map`,
`lightcal calibrate` recovering the light and the wall's texture, its exact gradient, and
the project's refusals."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from lightcal.cli.main import main
from lightcal.errors import InputError
from lightcal.io.project import load_project
from lightcal.io.result_file import read_result
from lightcal.pipeline import calibrate_project
from lightcal.pipeline.load import load_images
from lightcal.pipeline.model import build_model
from lightcal.synthetic.dataset import read_truth
from lightcal.synthetic.departures import read_departures
from lightcal.synthetic.texture import AlbedoTexture
from tests.departure_suite import calibrated, errors, exit_code


def _synth(folder: Path, *extra: str) -> Path:
    argv = ["synth", str(folder), "--width", "480", "--height", "320", "--seed", "5"]
    assert main([*argv, "--quiet", *extra]) == 0
    return folder / "project.json"


@pytest.fixture(scope="module")
def textured(tmp_path_factory) -> Path:
    """12 views (480 x 320, 14-bit noise, poses off by 0.5 mm) of a wall whose albedo
    varies +-10 % in 10-30 cm patches; the project estimates the albedo map."""
    folder = tmp_path_factory.mktemp("albedo") / "textured"
    return _synth(folder, "--albedo-texture", "0.1", "--declare-albedo-map")


def _truth_texture(project: Path) -> AlbedoTexture:
    found = read_departures(read_truth(project.parent / "truth.json"))["albedo_texture"]
    k = 2.0 * math.pi / np.array(found["wavelengths_m"])
    d = np.radians(found["directions_deg"])
    return AlbedoTexture(
        found["amplitude"],
        k[:, None] * np.stack([np.cos(d), np.sin(d)], axis=1),
        np.array(found["phases_rad"]),
        np.array(found["weights"]),
    )


def _variant(project: Path, name: str, change) -> Path:
    doc = json.loads(project.read_text())
    change(doc)
    path = project.with_name(f"{name}.json")
    path.write_text(json.dumps(doc))
    return path


def test_synth_declares_the_map_and_a_dense_selection(textured) -> None:
    doc = json.loads(textured.read_text())
    assert doc["wall"]["albedo_map"] == {"spacing_mm": 25.0, "variation": 0.3, "smoothness": 0.05}
    assert doc["selection"]["strategy"] == "all"
    assert doc["selection"]["binning"] == 4  # 120 x 80 super-pixels: 9600 an image


def test_calibrate_recovers_the_light_and_the_walls_texture(textured, capsys) -> None:
    out = textured.parent / "result.json"
    report = textured.parent / "report"
    code = main(["calibrate", str(textured), "--out", str(out), "--report", str(report)])
    printed = capsys.readouterr().out
    assert code == 0, printed
    assert "wall albedo map: " in printed
    result = read_result(out)
    truth = read_truth(textured.parent / "truth.json")["lights"][0]
    light = result.lights[0]
    position = float(np.linalg.norm(np.array(light.position_m) - truth["position_m"]))
    axis = math.degrees(math.acos(min(1.0, float(np.dot(light.axis_camera, truth["axis_camera"])))))
    assert position < 0.002 and axis < 0.1, (position, axis)
    # The map against the texture that made the data, both over their mean where seen.
    summary = result.albedo_map
    assert summary is not None and (report / "albedo_map.png").is_file()
    values = np.array([[np.nan if v is None else v for v in row] for row in summary["values"]])
    ny, nx = summary["shape"]
    j, i = np.mgrid[0:ny, 0:nx]
    nodes = np.asarray(summary["origin_xy_m"]) + summary["spacing_m"] * np.stack([i, j], -1)
    seen = np.isfinite(values)
    true = _truth_texture(textured).factor(nodes[seen])
    estimated = values[seen]
    true, estimated = true / true.mean(), estimated / estimated.mean()
    assert np.corrcoef(true, estimated)[0, 1] > 0.9
    assert float(np.sqrt(np.mean((estimated - true) ** 2))) < 0.02  # the texture's RMS: 0.05


def test_without_the_map_the_same_photos_are_a_misfit(textured) -> None:
    """The same photos with the map dropped from the project (dense pixels average the
    texture out of the pose, 2 mm / 0.1 deg; not out of the fit test)."""
    even = _variant(textured, "even", lambda d: d["wall"].pop("albedo_map"))
    _, _, result = calibrate_project(load_project(even))
    truth = read_truth(textured.parent / "truth.json")["lights"][0]
    position, position_sigma, _, _ = errors(result, truth)
    # The fit test flags it and names the wall among the causes; the sigma it then
    # widens to covers the error (measured: 2.05 mm, sigma 5.5 mm; 0.10 deg).
    assert exit_code(result) == 3
    assert any("wall" in f for f in result.fit["findings"]), result.fit["findings"]
    assert position < position_sigma


def test_a_clean_wall_with_the_map_has_no_finding(tmp_path) -> None:
    project = _synth(tmp_path / "clean", "--declare-albedo-map")
    _, _, result = calibrate_project(load_project(project))
    truth = read_truth(project.parent / "truth.json")["lights"][0]
    position, position_sigma, axis, axis_sigma = errors(result, truth)
    assert exit_code(result) == 0 and result.fit["findings"] == []
    assert position < 0.002 and axis < 0.1
    assert position < 3 * position_sigma and axis < 3 * axis_sigma
    assert result.albedo_map is not None and result.albedo_map["rms"] < 0.02


@pytest.fixture(scope="module")
def veiled(tmp_path_factory) -> Path:
    """The textured wall of `textured` in water with a backscatter veil (c 0.2 /m, beta
    0.5 /m), both estimated beside the map."""
    folder = tmp_path_factory.mktemp("albedo") / "veiled"
    water = ["--attenuation", "0.2", "--backscatter", "0.5", "--declare-medium", "estimated"]
    return _synth(folder, "--albedo-texture", "0.1", "--declare-albedo-map", *water)


@pytest.mark.parametrize("data", ["textured", "veiled"])
def test_the_reduced_gradient_is_the_costs(data: str, request: pytest.FixtureRequest) -> None:
    """trf's gradient J~^T r~ of the projected problem is the exact gradient of its cost,
    the joint cost minimised over the albedo (the envelope theorem), away from x*; in
    water too, where the map scales the wall's light and not the veil (the medium's
    columns checked with the pose's)."""
    project = load_project(request.getfixturevalue(data))
    model = build_model(project, load_images(project))
    x = model.layout.x0.copy()
    x[:3] += [0.004, -0.003, 0.002]
    water = model.layout.medium
    x[water] = [0.15, 0.3][: water.stop - water.start]  # c and beta, where set
    r, J = model.reduced(x)
    gradient = J.T @ r
    # the position, the axis angles and the water's c and beta
    for k in [*range(5), *range(water.start, water.stop)]:
        h = 1e-6
        costs = []
        for sign in (1.0, -1.0):
            xs = x.copy()
            xs[k] += sign * h
            rs, _ = model.reduced(xs)
            costs.append(0.5 * float(rs @ rs))
        numeric = (costs[0] - costs[1]) / (2 * h)
        assert numeric == pytest.approx(gradient[k], rel=2e-4, abs=1e-6 * np.abs(gradient).max())


@pytest.mark.slow
def test_the_map_beside_the_waters_veil(veiled) -> None:
    """The map scales the wall's light, not the veil: both estimated with the light
    (measured: 1.07 mm / 0.087 deg, sigma 1.6 mm / 0.13 deg; c 0.1990, beta 0.480)."""
    result, (position, position_sigma, axis, axis_sigma) = calibrated(veiled)
    assert exit_code(result) == 0 and result.fit["findings"] == [], result.fit["findings"]
    assert position < 0.003 and axis < 0.2, (position, axis)
    assert position < 3 * position_sigma and axis < 3 * axis_sigma
    assert result.medium["attenuation_per_m"] == pytest.approx(0.2, rel=0.05)
    assert result.medium["backscatter_per_m"] == pytest.approx(0.5, rel=0.1)
    assert result.albedo_map is not None


def test_the_project_refuses_what_the_map_cannot_go_with(textured) -> None:
    robust = _variant(textured, "robust", lambda d: d["solver"].update(loss="huber"))
    with pytest.raises(InputError) as info:
        load_project(robust)
    assert str(info.value).endswith(
        "wall.albedo_map: expected solver.loss linear, got 'huber' (the albedo map is solved "
        "by linear least squares)"
    )
    coarse = _variant(textured, "coarse", lambda d: d["wall"]["albedo_map"].update(spacing_mm=0))
    with pytest.raises(InputError) as info:
        load_project(coarse)
    assert "wall.albedo_map.spacing_mm" in str(info.value)
    assert "greater than or equal to 1" in str(info.value)
