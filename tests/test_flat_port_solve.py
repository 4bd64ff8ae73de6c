"""Calibrating through the camera's flat port: the project file's `camera.port`, its
refusals, and a solve recovering the light from images rendered through the port."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lightcal.core.flat_port import FlatPort
from lightcal.core.medium import Medium
from lightcal.core.port_render import render_image_through_port
from lightcal.core.scene import Rig
from lightcal.errors import InputError
from lightcal.io.project import load_project
from lightcal.pipeline import calibrate_project
from tests import calib_scenes as cs

PORT_DOC = {"distance_mm": 20.0, "thickness_mm": 10.0, "glass_index": 1.49, "water_index": 1.333}
PORT = FlatPort(0.02, 0.01, 1.49, 1.333)
WATER_C = 0.2


def _write(folder: Path, *, port_in_file: bool, noise_seed: int | None) -> tuple[Path, object]:
    """10 views (160 x 120) rendered through the port in water of c = 0.2 /m, with
    Poisson-Gaussian noise when seeded (gain 0.1 DN / e-, read noise 1 DN: 1 % at the
    peak of 1000 DN)."""
    camera = cs.small_camera(width=160, height=120)
    light = cs.symmetric_light()
    views = cs.views(10, seed=4)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "images").mkdir(exist_ok=True)
    rng = None if noise_seed is None else np.random.default_rng(noise_seed)
    images = []
    for i, view in enumerate(views):
        img = render_image_through_port(
            camera, view, Rig.single(light), PORT, medium=Medium(WATER_C)
        ).filled(0.0)
        if rng is not None:
            img = img + rng.normal(size=img.shape) * np.sqrt(0.1 * img + 1.0)
        np.save(folder / "images" / f"view_{i:02d}.npy", img)
        R, t = view.R_camera_world, view.t_camera_world
        images.append(
            {
                "path": f"images/view_{i:02d}.npy",
                "T_camera_world": {"R": R.tolist(), "t": t.tolist()},
            }
        )
    start = cs.start_near(light)
    K = camera.K
    cam: dict = {
        "fx": float(K[0, 0]), "fy": float(K[1, 1]), "cx": float(K[0, 2]), "cy": float(K[1, 2]),
        "width": camera.width, "height": camera.height, "dist": camera.dist[:5].tolist(),
    }  # fmt: skip
    if port_in_file:
        cam["port"] = PORT_DOC
    doc = {
        "version": 1,
        "camera": cam,
        "images": images,
        "lights": [
            {
                "name": "light",
                "rid": {"type": "half_angle", "half_angle_deg": 30},
                "initial": {
                    "position_m": start.t_camera_light.tolist(),
                    "R_camera_light": start.R_camera_light.tolist(),
                },
            }
        ],
        "medium": {"attenuation_per_m": 0.1, "estimate": ["attenuation_per_m"]},
        "selection": {"n_per_image": 3000, "min_signal": 5.0},
    }
    path = folder / "project.json"
    path.write_text(json.dumps(doc, indent=1))
    return path, light


def test_the_port_key_builds_a_flat_port(tmp_path: Path) -> None:
    path, _ = _write(tmp_path, port_in_file=True, noise_seed=None)
    project = load_project(path)
    assert project.camera_port is not None
    assert project.camera_port.describe()["distance_m"] == pytest.approx(0.02)
    assert project.camera_port.thickness_m == pytest.approx(0.01)
    doc = json.loads(path.read_text())
    del doc["camera"]["port"]
    path.write_text(json.dumps(doc))
    assert load_project(path).camera_port is None


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda d: d["camera"]["port"].update(distance_mm=-1.0), r"camera\.port\.distance_mm"),
        (lambda d: d["camera"]["port"].update(index=1.3), r"camera\.port\.index"),
        (lambda d: d["camera"]["port"].update(water_index=0.9), r"camera\.port\.water_index"),
        (
            lambda d: d.setdefault("wall", {}).update(albedo_map={"spacing_mm": 50}),
            r"camera\.port: .*wall\.albedo_map",
        ),
        (lambda d: d["sensor"].update(model="paper"), r"camera\.port: .*paper"),
        (lambda d: d["lights"][0].update(initial="auto"), r"camera\.port: .*initial: auto"),
    ],
)
def test_bad_ports_are_refused_naming_the_key(tmp_path: Path, edit, match: str) -> None:
    path, _ = _write(tmp_path, port_in_file=True, noise_seed=None)
    doc = json.loads(path.read_text())
    doc.setdefault("sensor", {})
    edit(doc)
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=match):
        load_project(path)


@pytest.mark.parametrize("port_in_file", [True, False])
def test_the_light_is_recovered_through_the_port(tmp_path: Path, port_in_file: bool) -> None:
    """Noisy images through the port, c estimated from 0.1 /m: with the port declared
    the light within 3 mm and 0.2 degrees and c within 2 %; ignoring it, far off."""
    path, light = _write(tmp_path, port_in_file=port_in_file, noise_seed=7)
    _, model, res = calibrate_project(load_project(path))
    est = model.layout.rig(np.array(res.x)).lights[0]
    position, axis = cs.pose_errors(est, light)
    c = model.layout.medium_of(np.array(res.x)).attenuation_per_m
    print(f"\nport declared {port_in_file}: {position * 1e3:.3f} mm, {axis:.4f} deg, c {c:.4f}")
    if port_in_file:
        assert res.converged
        assert position < 3e-3 and axis < 0.2
        assert c == pytest.approx(WATER_C, rel=0.02)
    else:
        assert position > 10e-3 or axis > 1.0


def test_the_report_renders_through_the_port(tmp_path: Path) -> None:
    """`render_views` (the report's renders) goes through the port: at the true light and
    medium it gives the noise-free images back."""
    from lightcal.pipeline.load import load_images
    from lightcal.report import render_views

    path, light = _write(tmp_path, port_in_file=True, noise_seed=None)
    project = load_project(path)
    loaded = load_images(project)
    renders = render_views(project, loaded, Rig.single(light), medium=Medium(WATER_C))
    for i, image in enumerate(renders):
        expected = np.load(tmp_path / "images" / f"view_{i:02d}.npy")
        np.testing.assert_allclose(image.filled(0.0), expected, rtol=1e-12, atol=1e-12)
