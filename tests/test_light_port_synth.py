"""`lightcal synth --light-port`: lights behind flat ports, rendered by synth's own
point-sampled imaging (`lightcal.synthetic.light_port_imaging`), and a calibration on it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lightcal.cli.main import main
from lightcal.core.flat_port import FlatPort
from lightcal.core.medium import Medium
from lightcal.core.render import render_image
from lightcal.core.scene import Rig
from lightcal.io.project import load_project
from lightcal.pipeline import calibrate_project
from lightcal.synthetic.imaging import Imaging
from tests import calib_scenes as cs

LIGHT_PORT_ARGS = ["--light-port", "15", "8", "1.49", "1.333"]


def test_synths_imaging_through_the_lights_port_agrees_with_the_renderer() -> None:
    """Point-sampled with its own path solve, its own dOmega/dA and Fresnel, against the
    renderer's footprints (4 x 4 RID sub-samples) through the light's port, in water
    (c = 0.2 /m): within 1e-4 on a 320 x 240 camera (measured 4.5e-5 at most, median
    4e-6, not shrinking with more RID sub-samples: the point sample's error, second order
    in the footprint's size, and the renderer's footprint edges, great circles of the
    air directions where the true edges bend slightly; 7.5e-6 with the port's indices
    1)."""
    port = FlatPort(0.015, 0.008, 1.49, 1.333)
    camera = cs.small_camera()
    light = cs.symmetric_light()
    imaging = Imaging(camera=camera, rig=Rig.single(light), attenuation_per_m=0.2, light_port=port)
    worst = 0.0
    for view in cs.views(3, seed=1):
        ours = imaging.beam(view).filled(np.nan)
        ref = render_image(
            camera, view, Rig.single(light.replace(port=port)), medium=Medium(0.2),
            rid_subsamples=4,
        ).filled(np.nan)  # fmt: skip
        lit = ref > 0.02 * np.nanmax(ref)
        worst = max(worst, float(np.nanmax(np.abs(ours[lit] / ref[lit] - 1.0))))
    print(f"\nsynth's light port against the renderer: {worst:.2e}")
    assert worst < 1e-4


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--declare-light-port"], "--declare-light-port: expected --light-port D_MM T_MM NG NW"),
        (["--light-port", "0", "8", "1.49", "1.333"], "--light-port: port: distance_m"),
        ([*LIGHT_PORT_ARGS, "--bow-mm", "3"], "--light-port: not rendered with a camera port"),
        ([*LIGHT_PORT_ARGS, "--wall", "plastic"], "--light-port: not rendered with a non-Lamb"),
    ],
)
def test_synth_light_port_errors(tmp_path: Path, capsys, args: list[str], message: str) -> None:
    out = tmp_path / "data"
    small = ["--width", "80", "--height", "60", "--views", "3", "--quiet"]
    assert main(["synth", str(out), *small, *args]) == 2
    assert message in capsys.readouterr().err


def test_the_light_is_recovered_from_synth_data_through_its_port(tmp_path: Path) -> None:
    """`lightcal synth --light-port 15 8 1.49 1.333 --declare-light-port` in water of
    c = 0.2 /m estimated (320 x 240, 10 views, synth's noise, poses to 0.5 mm /
    0.05 deg), 3000 pixels an image: the light within 2 mm and 0.1 degrees, c within 2 %;
    the same data without `lights[0].port` far off."""
    out = tmp_path / "data"
    water = ["--attenuation", "0.2", "--declare-medium", "estimated"]
    argv = ["synth", str(out), "--width", "320", "--height", "240", "--views", "10"]
    assert main([*argv, *LIGHT_PORT_ARGS, "--declare-light-port", *water, "--quiet"]) == 0
    truth = json.loads((out / "truth.json").read_text())
    assert truth["departures"]["light_port"]["thickness_mm"] == 8.0
    doc = json.loads((out / "project.json").read_text())
    assert doc["lights"][0]["port"]["distance_mm"] == 15.0
    doc["selection"]["n_per_image"] = 3000
    (out / "project.json").write_text(json.dumps(doc))
    del doc["lights"][0]["port"]
    (out / "undeclared.json").write_text(json.dumps(doc))
    true_position = np.array(truth["lights"][0]["position_m"])
    true_axis = np.array(truth["lights"][0]["axis_camera"])
    errors = {}
    for name in ("project.json", "undeclared.json"):
        _, model, res = calibrate_project(load_project(out / name))
        x = np.array(res.x)
        est = model.layout.rig(x).lights[0]
        position = float(np.linalg.norm(est.t_camera_light - true_position))
        axis = float(np.degrees(np.arccos(np.clip(est.axis_camera @ true_axis, -1.0, 1.0))))
        errors[name] = (position * 1e3, axis, model.layout.medium_of(x).attenuation_per_m)
    print(
        "\n"
        + "; ".join(f"{k}: {p:.3g} mm, {a:.3g} deg, c {c:.4f}" for k, (p, a, c) in errors.items())
    )
    position_mm, axis, c = errors["project.json"]
    assert position_mm < 2.0 and axis < 0.1
    assert c == pytest.approx(0.2, rel=0.02)
    assert errors["undeclared.json"][0] > 20.0
