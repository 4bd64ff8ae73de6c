"""`lightcal export --project P` of a project whose light shines through a flat port
(`lights[i].port`, `lightcal.io.export_light_port`): Mitsuba gets the port's two
dielectric faces in front of the emitter and the particle tracer, and renders the
exported scene as lightcal renders the light behind its port; Mitsuba in water or with
a camera port, and Blender, are refused naming `lights[0].port`; the opencv and ROS
files, and an ies file's origin text, say that the pose is the emitter's behind its port
and its RID the emitter's in air.

The Mitsuba render (a Lambertian wall added in view 0's pose, as `tests/export_render.py`
adds it) is compared with `render_image` of the same view and light (its port included),
after dividing out albedo / pi: the particle tracer carries flux, so there is no radiance
constant (`tests/mitsuba_light_port.py`). Measured (llvm_ad_rgb, a 160 x 120 synth view,
15444 pixels lit above 5 % of the peak, 2^12 particles a pixel, 27 s): median
-1.1e-4, mean -1.6e-5, per-pixel spread 2.7e-2 (the particles' Poisson noise; a median
of a Poisson count lies (1/3) / lambda below its mean, -2.4e-4 here); without the port's
faces in the scene (the emitter straight in the water) -14 %. The faces are disks of
radius 66 mm here (`light_face_radius_m`: cut to keep them out of the sensor's field;
the RID at the outer rim's 75.8 degrees in air is 1.1e-3 of the axis'). Skipped without Mitsuba.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from lightcal.cli.main import main
from lightcal.core.flat_port import FlatPort
from lightcal.core.medium import AIR, Medium
from lightcal.core.render import render_image
from lightcal.core.scene import Rig
from lightcal.errors import InputError
from lightcal.io.export import export_files
from lightcal.io.export_light_port import (
    BLENDER_LIGHT_REFUSAL,
    LIGHT_PORT_NOTE,
    MITSUBA_CAMERA_PORT_REFUSAL,
    MITSUBA_WATER_REFUSAL,
    light_ports_of,
)
from lightcal.io.project import load_project
from lightcal.io.result_file import read_result
from tests.export_render import ALBEDO, project_lights, result_of_project, undistorted

LIGHT_PORT_ARGS = ["--light-port", "15", "8", "1.49", "1.333", "--declare-light-port"]
SCALE = 2.0


def _project(folder: Path, extra: tuple[str, ...] = ()) -> Path:
    path = folder / "data" / "project.json"
    if not path.exists():
        args = ["synth", str(folder / "data"), "--views", "2", "--width", "160", "--height"]
        assert main([*args, "120", "--no-noise", "--quiet", *LIGHT_PORT_ARGS, *extra]) == 0
    return path


def _export(
    folder: Path, fmt: str, out: str, medium: Medium = AIR, extra: tuple[str, ...] = ()
) -> tuple[int, Path]:
    project_path = _project(folder, extra)
    project = load_project(project_path)
    result = result_of_project(project, [SCALE], folder / "result.json", medium)
    target = folder / out
    args = ["export", str(result), "--format", fmt, "--out", str(target), "--force"]
    return main([*args, "--project", str(project_path)]), target


def _render_with_wall(xml_path: Path, view_T: np.ndarray, spp: int, variant: str) -> np.ndarray:
    """(H, W) Mitsuba's radiance of the exported scene with a Lambertian wall in the
    view's pose, times pi / ALBEDO."""
    import mitsuba as mi

    mi.set_variant(variant)
    tree = ET.parse(xml_path)
    scene = tree.getroot()
    wall = ET.SubElement(scene, "shape", {"type": "rectangle"})
    to_world = np.diag([-1.0, -1.0, 1.0, 1.0]) @ view_T @ np.diag([20.0, 20.0, 1.0, 1.0])
    transform = ET.SubElement(wall, "transform", {"name": "to_world"})
    ET.SubElement(
        transform, "matrix", {"value": " ".join(repr(float(v)) for v in to_world.ravel())}
    )
    bsdf = ET.SubElement(wall, "bsdf", {"type": "diffuse"})
    ET.SubElement(bsdf, "rgb", {"name": "reflectance", "value": repr(ALBEDO)})
    for count in scene.iter("integer"):
        if count.get("name") == "sample_count":
            count.set("value", str(spp))
    with_wall = xml_path.with_name(xml_path.stem + "_with_wall.xml")
    tree.write(with_wall)
    # Depth 12: the glass's inner reflections; the wall lies at depth 3 (inner face,
    # outer face, wall) from the emitter.
    loaded = mi.load_file(str(with_wall), max_depth=12, samples_per_pass=min(spp, 1024))
    image = np.array(mi.render(loaded, seed=1))
    return image[:, :, 0] * math.pi / ALBEDO


@pytest.fixture(scope="module")
def variant() -> str:
    pytest.importorskip("mitsuba", reason="Mitsuba 3 is not installed (pip install .[reference])")
    from tests.mitsuba_datasets import mitsuba_variant

    return mitsuba_variant()


@pytest.mark.slow
def test_mitsuba_renders_the_exported_light_port_as_lightcal_does(tmp_path, variant):
    """The particle tracer's render of the exported scene: the median and mean relative
    differences from lightcal's render within 1e-3; without the port's faces far off."""
    code, xml = _export(tmp_path, "mitsuba", "scene.xml")
    assert code == 0
    text = xml.read_text()
    assert '<integrator type="ptracer">' in text and "lights[0].port" in text
    assert "disks of radius 65.97 mm" in text and "rim is 75.8 degrees off" in " ".join(
        text.split()
    )
    project = load_project(_project(tmp_path))
    port = project.lights[0].initial.port
    assert port is not None
    view = project.views[0]
    light = replace(project_lights(project, [SCALE])[0], port=port)
    camera = undistorted(project.camera)
    ours = render_image(camera, view, Rig.single(light), rid_subsamples=4).filled(np.nan)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = view.R_camera_world, view.t_camera_world
    theirs = _render_with_wall(xml, T, 1 << 12, variant) * view.exposure
    lit = np.isfinite(ours) & (ours > 0.05 * np.nanmax(ours))
    rel = theirs[lit] / ours[lit] - 1.0
    median, mean = float(np.median(rel)), float(np.mean(rel))
    # The same scene without the port's faces: the emitter straight in the water.
    tree = ET.parse(xml)
    for shape in list(tree.getroot().iter("shape")):
        if "_port_" in (shape.get("id") or ""):
            tree.getroot().remove(shape)
    tree.write(tmp_path / "no_port.xml")
    no_port = _render_with_wall(tmp_path / "no_port.xml", T, 1 << 8, variant) * view.exposure
    faceless = float(np.median(no_port[lit] / ours[lit] - 1.0))
    spread = 1.4826 * float(np.median(np.abs(rel - median)))
    print(
        f"\nexported light port: {rel.size} pixels, median {median:+.2e}, mean {mean:+.2e}, "
        f"spread {spread:.2e}; no faces {faceless:+.3f}"
    )
    assert rel.size > 5000
    assert abs(median) < 1e-3 and abs(mean) < 1e-3
    assert abs(faceless) > 0.1


def test_mitsuba_refuses_a_light_port_in_water_or_with_a_camera_port(tmp_path, capsys):
    code, out = _export(tmp_path / "water", "mitsuba", "scene.xml", Medium(0.2))
    assert code == 2 and not out.exists()
    assert f"lights[0].port: {MITSUBA_WATER_REFUSAL}" in capsys.readouterr().err
    assert MITSUBA_WATER_REFUSAL == (
        "the Mitsuba export of a light behind a flat port needs the particle tracer (ptracer: "
        "no path tracer reaches a point light through the port's faces), which has no media; "
        "a result in water cannot be rendered with it: leave out --project for the lights "
        "alone, without their ports"
    )
    # A camera port as well (synth renders none with a light port: the API's export).
    project = load_project(_project(tmp_path / "water"))
    result = read_result(tmp_path / "water" / "result.json")
    ports = light_ports_of([(u.initial.name, u.initial.port) for u in project.lights])
    with pytest.raises(InputError) as caught:
        export_files(
            read_result(result_of_project(project, [SCALE], tmp_path / "air.json")),
            "mitsuba",
            tmp_path / "scene.xml",
            source="air.json",
            port=FlatPort(0.02, 0.01),
            light_ports=ports,
        )
    assert str(caught.value) == f"lights[0].port: {MITSUBA_CAMERA_PORT_REFUSAL}"
    assert result.medium is not None  # the water's result: refused above for its medium
    assert MITSUBA_CAMERA_PORT_REFUSAL == (
        "the Mitsuba export of a light behind a flat port needs the particle tracer, whose "
        "connection to the sensor the camera's own port (camera.port) would block: no "
        "Mitsuba integrator renders both ports; leave out --project for the lights alone"
    )


def test_blender_refuses_a_light_behind_a_port(tmp_path, capsys):
    code, out = _export(tmp_path, "blender", "lights.py")
    assert code == 2 and not out.exists()
    assert f"lights[0].port: {BLENDER_LIGHT_REFUSAL}" in capsys.readouterr().err
    assert BLENDER_LIGHT_REFUSAL == (
        "the Blender export does not carry a light's flat port: its light would shine "
        "straight into the water with the emitter's in-air RID; export --format mitsuba, "
        "which carries the port, or leave out --project for the lights alone"
    )


def test_opencv_ros_and_ies_say_the_pose_and_rid_are_the_emitters(tmp_path, capsys):
    note = (
        "note: lights[0].port: the pose of 'led' is its emitter's, behind its port, and its "
        "RID the emitter's in air (the file says so)"
    )
    code, out = _export(tmp_path, "opencv", "lights.yaml")
    assert code == 0
    assert note.replace("'led'", repr(_name(tmp_path))) in capsys.readouterr().err
    fs = cv2.FileStorage(str(out), cv2.FILE_STORAGE_READ)
    port = fs.getNode("lights").at(0).getNode("port")
    assert port.getNode("key").string() == "lights[0].port"
    assert port.getNode("distance_m").real() == pytest.approx(0.015)
    assert port.getNode("thickness_m").real() == pytest.approx(0.008)
    assert port.getNode("glass_index").real() == pytest.approx(1.49)
    assert port.getNode("water_index").real() == pytest.approx(1.333)
    np.testing.assert_allclose(port.getNode("normal_light").mat().ravel(), [0.0, 0.0, 1.0])
    assert port.getNode("note").string() == LIGHT_PORT_NOTE
    assert fs.getNode("camera_port").empty()
    fs.release()
    code, launch = _export(tmp_path, "ros", "lights.launch.xml")
    assert code == 0
    assert note.replace("'led'", repr(_name(tmp_path))) in capsys.readouterr().err
    text = " ".join(launch.read_text().split())
    assert "port (lights[0].port: distance_mm 15, thickness_mm 8, glass_index 1.49" in text
    assert "its pose is the emitter's, behind the port in the housing's air" in text
    ET.parse(launch)  # still well-formed XML
    code, ies = _export(tmp_path, "ies", "light.ies")
    assert code == 0
    assert "note: lights[0].port: the RID written is the emitter's in air" in (
        capsys.readouterr().err
    )
    assert "the given RID (CosPowerRID); in air, behind lights[0].port" in ies.read_text()
    code, ldt = _export(tmp_path, "ldt", "light.ldt")
    assert code == 0
    assert "note: lights[0].port: the RID written is the emitter's in air" in (
        capsys.readouterr().err
    )
    assert "the given RID (CosPowerRID); in air, behind lights[0].port\n" in ldt.read_text()
    # Without --project the port is unknown: the files are those of a light without one.
    plain = tmp_path / "plain.yaml"
    assert (
        main(["export", str(tmp_path / "result.json"), "--format", "opencv", "--out", str(plain)])
        == 0
    )
    fs = cv2.FileStorage(str(plain), cv2.FILE_STORAGE_READ)
    assert fs.getNode("lights").at(0).getNode("port").empty()
    fs.release()
    assert "lights[0].port" not in capsys.readouterr().err


def _name(folder: Path) -> str:
    return load_project(_project(folder)).lights[0].initial.name


def test_the_api_exports_the_light_port_as_the_cli_does(tmp_path):
    """`lightcal.api.export` with the project: the same files as `lightcal export`."""
    from lightcal import api

    code, cli_yaml = _export(tmp_path, "opencv", "lights.yaml")
    assert code == 0
    out = tmp_path / "api.yaml"
    project = _project(tmp_path)
    api.export(tmp_path / "result.json", "opencv", out, project=project, notify=None)
    assert out.read_bytes() == cli_yaml.read_bytes()
    with pytest.raises(InputError, match=r"lights\[0\]\.port: the Blender export"):
        api.export(tmp_path / "result.json", "blender", tmp_path / "l.py", project=project)
