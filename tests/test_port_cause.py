"""The fit test's `port` cause: an undeclared camera port is named as the misfit's cause."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from lightcal.cli.main import main
from lightcal.core.port_bend import port_bend_pattern
from lightcal.core.rid import IsotropicRID
from lightcal.core.scene import Light, View
from lightcal.io.project import load_project
from lightcal.pipeline import calibrate_project


def test_the_pattern_of_a_light_at_the_camera_looking_down_is_3_tan2() -> None:
    """An isotropic light at the centre of a camera 1.3 m above the wall, looking straight
    down: E = h / d^3 and the bend moves r = D tan(theta) by -D tan(theta) sec^2(theta)
    per unit eps, so d ln E / d eps = 3 tan^2(theta) (to the central difference's 1e-7)."""
    height = 1.3
    R = np.diag([1.0, -1.0, -1.0])
    view = View(R, -R @ np.array([0.0, 0.0, height]))
    light = Light(IsotropicRID(), np.zeros(3), np.eye(3))
    r = np.linspace(0.0, 1.5, 16)
    phi = np.linspace(0.0, 5.0, 16)
    centres = np.column_stack([r * np.cos(phi), r * np.sin(phi), np.zeros(16)])
    q = port_bend_pattern(centres, view, (light,), np.zeros(16, dtype=int))
    np.testing.assert_allclose(q, 3.0 * (r / height) ** 2, rtol=1e-7, atol=1e-9)


def test_an_undeclared_port_is_named_as_the_cause(tmp_path: Path) -> None:
    """`lightcal synth --port 20 10 1.49 1.333` (clear water) calibrated without
    `camera.port`: the fit test's first finding is the port (before it, "the images
    disagree"); with the port declared the fit passes and the port is no finding
    (measured: the port's correction 8.6 % of the signal, 330 mm)."""
    out = tmp_path / "data"
    argv = ["synth", str(out), "--width", "320", "--height", "240", "--views", "10"]
    assert main([*argv, "--port", "20", "10", "1.49", "1.333", "--seed", "3", "--quiet"]) == 0
    doc = json.loads((out / "project.json").read_text())
    doc["selection"]["n_per_image"] = 2000
    (out / "undeclared.json").write_text(json.dumps(doc))
    doc["camera"]["port"] = {
        "distance_mm": 20.0,
        "thickness_mm": 10.0,
        "glass_index": 1.49,
        "water_index": 1.333,
    }
    (out / "declared.json").write_text(json.dumps(doc))
    _, _, undeclared = calibrate_project(load_project(out / "undeclared.json"))
    assert not undeclared.fit_adequate
    assert undeclared.fit["causes"][0]["cause"] == "port"
    assert undeclared.fit["findings"][0].startswith(
        "the wall is seen as if through a flat window in water"
    )
    assert "declare the camera's port (`camera.port: {distance_mm," in undeclared.fit["findings"][0]
    _, _, declared = calibrate_project(load_project(out / "declared.json"))
    assert declared.fit_adequate, declared.fit["findings"]
    port = next(c for c in declared.fit["causes"] if c["cause"] == "port")
    assert not port["material"]
    truth = json.loads((out / "truth.json").read_text())
    true_position = np.array(truth["lights"][0]["position_m"])
    error = np.linalg.norm(declared.lights[0].pose.t_camera_light - true_position)
    assert math.isfinite(error) and error < 3e-3


def test_an_undeclared_light_port_is_named_by_the_profile_cause(tmp_path: Path) -> None:
    """`lightcal synth --light-port 15 8 1.49 1.333` calibrated without `lights[0].port`:
    a window at the emitter changes the beam's profile in the water (the first order of
    an interface of index 1 + eps at the emitter is a function of the angle from the
    axis alone), so the `profile` cause is first and its advice names the light's port
    (measured: 9.7 % of the signal, 200 mm)."""
    out = tmp_path / "data"
    argv = ["synth", str(out), "--width", "320", "--height", "240", "--views", "10"]
    assert main([*argv, "--light-port", "15", "8", "1.49", "1.333", "--seed", "3", "--quiet"]) == 0
    doc = json.loads((out / "project.json").read_text())
    doc["selection"]["n_per_image"] = 2000
    (out / "project.json").write_text(json.dumps(doc))
    _, _, result = calibrate_project(load_project(out / "project.json"))
    assert not result.fit_adequate
    assert result.fit["causes"][0]["cause"] == "profile"
    assert "declare the light's port in water (`lights[i].port`)" in result.fit["findings"][0]
