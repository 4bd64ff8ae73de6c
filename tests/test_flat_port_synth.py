"""`lightcal synth --port`: data seen through the camera's flat port, rendered by synth's
own point-sampled imaging (`lightcal.synthetic.port_imaging`), and a calibration on it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lightcal.cli.main import main
from lightcal.core.flat_port import FlatPort
from lightcal.core.medium import Medium
from lightcal.core.port_render import render_image_through_port
from lightcal.core.scene import Rig
from lightcal.io.project import load_project
from lightcal.pipeline import calibrate_project
from lightcal.synthetic.imaging import Imaging
from tests import calib_scenes as cs

PORT_ARGS = ["--port", "20", "10", "1.49", "1.333"]


def test_synths_imaging_through_the_port_agrees_with_the_renderer() -> None:
    """Point-sampled with its own Snell's law against the renderer's footprints through
    the port, in water (c = 0.2 /m), each with its own Fresnel transmittance of the port:
    within 1e-5 on a 320 x 240 camera (measured 5.8e-6; the point sample's error, second
    order in the footprint's size)."""
    port = FlatPort(0.02, 0.01, 1.49, 1.333)
    camera = cs.small_camera()
    rig = Rig.single(cs.symmetric_light())
    imaging = Imaging(camera=camera, rig=rig, attenuation_per_m=0.2, port=port)
    for view in cs.views(3, seed=1):
        ours = imaging.beam(view).filled(np.nan)
        ref = render_image_through_port(
            camera, view, rig, port, medium=Medium(0.2), rid_subsamples=4
        ).filled(np.nan)
        lit = ref > 0.02 * np.nanmax(ref)
        assert np.nanmax(np.abs(ours[lit] / ref[lit] - 1.0)) < 1e-5


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--declare-port"], "--declare-port: expected --port D_MM T_MM NG NW"),
        (["--port", "-1", "10", "1.49", "1.333"], "--port: port: distance_m"),
        ([*PORT_ARGS, "--bow-mm", "3"], "--port: not rendered with a bowed wall"),
        ([*PORT_ARGS, "--wall", "plastic"], "--port: not rendered with a non-Lambertian wall"),
    ],
)
def test_synth_port_errors(tmp_path: Path, capsys, args: list[str], message: str) -> None:
    out = tmp_path / "data"
    small = ["--width", "80", "--height", "60", "--views", "3", "--quiet"]
    assert main(["synth", str(out), *small, *args]) == 2
    assert message in capsys.readouterr().err


def test_the_light_is_recovered_from_synth_data_through_the_port(tmp_path: Path) -> None:
    """`lightcal synth --port 20 10 1.49 1.333 --declare-port` in water of c = 0.2 /m
    estimated (320 x 240, 10 views, synth's noise, poses to 0.5 mm / 0.05 deg), 4000
    pixels an image: the light within 3 mm and 0.2 degrees, c within 1 %; the same data
    without `camera.port` far off (measured 0.74 mm, 0.027 deg, c 0.1993; undeclared
    551 mm; before the port's Fresnel transmittance 0.57 mm, 0.045 deg)."""
    out = tmp_path / "data"
    water = ["--attenuation", "0.2", "--declare-medium", "estimated"]
    argv = ["synth", str(out), "--width", "320", "--height", "240", "--views", "10"]
    assert main([*argv, *PORT_ARGS, "--declare-port", *water, "--seed", "3", "--quiet"]) == 0
    truth = json.loads((out / "truth.json").read_text())
    assert truth["departures"]["port"]["distance_mm"] == 20.0
    doc = json.loads((out / "project.json").read_text())
    assert doc["camera"]["port"]["water_index"] == 1.333
    doc["selection"]["n_per_image"] = 4000
    (out / "project.json").write_text(json.dumps(doc))
    del doc["camera"]["port"]
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
        errors[name] = (position, axis, model.layout.medium_of(x).attenuation_per_m)
    print(f"\n{errors}")
    position, axis, c = errors["project.json"]
    assert position < 3e-3 and axis < 0.2
    assert c == pytest.approx(0.2, rel=0.01)
    assert errors["undeclared.json"][0] > 0.05
