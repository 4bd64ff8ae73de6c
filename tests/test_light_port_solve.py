"""Calibrating a light behind its flat port: the project file's `lights[i].port`, its
refusals, and solves recovering the light from images rendered through the port
(docs/model.md, "The light's flat port")."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lightcal.core.flat_port import FlatPort
from lightcal.core.medium import Medium
from lightcal.core.render import render_image
from lightcal.core.scene import Rig
from lightcal.errors import InputError
from lightcal.io.project import load_project
from lightcal.pipeline import calibrate_project
from tests import calib_scenes as cs

PORT_DOC = {"distance_mm": 15.0, "thickness_mm": 8.0, "glass_index": 1.49, "water_index": 1.333}
PORT = FlatPort(0.015, 0.008, 1.49, 1.333)
WATER_C = 0.2
CLEAR_WATER = Medium(WATER_C)


def _write(
    folder: Path,
    *,
    port_in_file: bool,
    water: Medium = CLEAR_WATER,
    medium_doc: dict | None = None,
) -> tuple[Path, object]:
    """8 noise-free views (160 x 120) of a light behind its port in `water` (c = 0.2 /m);
    the project starts the light 40 mm and 4 degrees off and its `medium` (`medium_doc`)
    estimates c from 0.1 /m."""
    camera = cs.small_camera(width=160, height=120)
    light = cs.symmetric_light().replace(port=PORT)
    views = cs.views(8, seed=4)
    (folder / "images").mkdir(parents=True, exist_ok=True)
    images = []
    for i, view in enumerate(views):
        img = render_image(camera, view, Rig.single(light), medium=water).filled(0.0)
        np.save(folder / "images" / f"view_{i:02d}.npy", img)
        R, t = view.R_camera_world, view.t_camera_world
        images.append(
            {
                "path": f"images/view_{i:02d}.npy",
                "T_camera_world": {"R": R.tolist(), "t": t.tolist()},
            }
        )
    start = cs.start_near(light, position_m=0.04, angle_deg=4.0)
    K = camera.K
    cam: dict = {
        "fx": float(K[0, 0]), "fy": float(K[1, 1]), "cx": float(K[0, 2]), "cy": float(K[1, 2]),
        "width": camera.width, "height": camera.height, "dist": camera.dist[:5].tolist(),
    }  # fmt: skip
    light_doc: dict = {
        "name": "light",
        "rid": {"type": "half_angle", "half_angle_deg": 30},
        "initial": {
            "position_m": start.t_camera_light.tolist(),
            "R_camera_light": start.R_camera_light.tolist(),
        },
    }
    if port_in_file:
        light_doc["port"] = PORT_DOC
    doc = {
        "version": 1,
        "camera": cam,
        "images": images,
        "lights": [light_doc],
        "medium": medium_doc or {"attenuation_per_m": 0.1, "estimate": ["attenuation_per_m"]},
        "selection": {"n_per_image": 1500, "min_signal": 5.0},
    }
    path = folder / "project.json"
    path.write_text(json.dumps(doc, indent=1))
    return path, light


def test_the_port_key_builds_the_lights_port(tmp_path: Path) -> None:
    path, _ = _write(tmp_path, port_in_file=True)
    light = load_project(path).lights[0].initial
    assert light.port is not None
    assert light.port.distance_m == pytest.approx(0.015)
    assert light.port.thickness_m == pytest.approx(0.008)
    assert light.port.glass_index == 1.49 and light.port.water_index == 1.333
    doc = json.loads(path.read_text())
    del doc["lights"][0]["port"]
    path.write_text(json.dumps(doc))
    assert load_project(path).lights[0].initial.port is None


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda d: d["lights"][0]["port"].update(distance_mm=0), r"lights\[0\]\.port\.distance_mm"),
        (lambda d: d["lights"][0]["port"].update(n=1.3), r"lights\[0\]\.port\.n"),
        (lambda d: d["lights"][0]["port"].update(glass_index=0.5), r"lights\[0\]\.port\.glass"),
        (lambda d: d["wall"].update(model="plastic"), r"lights\[0\]\.port: .*wall\.model"),
        (lambda d: d["lights"][0].update(initial="auto"), r"lights\[0\]\.port: .*initial: auto"),
        (
            lambda d: d["lights"][0].update(estimate_rid="cos_power"),
            r"lights\[0\]\.port: .*estimate_rid: cos_power",
        ),
    ],
)
def test_what_the_port_does_not_model_is_refused_naming_the_key(
    tmp_path: Path, edit, match: str
) -> None:
    path, _ = _write(tmp_path, port_in_file=True)
    doc = json.loads(path.read_text())
    doc.setdefault("wall", {})
    edit(doc)
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=match):
        load_project(path)


@pytest.mark.parametrize("port_in_file", [True, False], ids=["declared", "ignored"])
def test_the_light_is_recovered_through_its_port(tmp_path: Path, port_in_file: bool) -> None:
    """Noise-free images, the light started 40 mm and 4 degrees off, c from 0.1 /m: with
    the port declared the light and c come back to round-off; ignoring the port (an
    effective emitter in the water) lands far off."""
    path, light = _write(tmp_path, port_in_file=port_in_file)
    _, model, res = calibrate_project(load_project(path))
    x = np.array(res.x)
    est = model.layout.rig(x).lights[0]
    position, axis = cs.pose_errors(est, light)
    c = model.layout.medium_of(x).attenuation_per_m
    print(
        f"\nlight port declared {port_in_file}: {position * 1e3:.3g} mm, {axis:.3g} deg, "
        f"c {c:.5f}, {res.iterations} iterations"
    )
    if port_in_file:
        assert res.converged
        assert est.port is PORT or est.port is not None
        assert position < 1e-6 and axis < 1e-5
        assert c == pytest.approx(WATER_C, abs=1e-6)
    else:
        assert position > 5e-3 or axis > 0.5
