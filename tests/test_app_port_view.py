"""The flat ports shown in the page: the camera's port (`camera.port`) and a light's
(`lights[i].port`) drawn in the 3D view in their owners' frames, the light's cones
refracted into the water (n_air sin(theta_air) = n_w sin(theta_w)), and the Light tab's
text naming the ports (docs/model.md, "The camera's flat port", "The light's flat port").
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import viser
from lightcal_app.beam_scene import beam_label
from lightcal_app.beam_shapes import ported_beam_rings, rid_angles, ring_lines, ring_mesh
from lightcal_app.panels.light import ports_markdown
from lightcal_app.panels.water import water_text
from lightcal_app.port_scene import camera_port_faces, light_port_faces, slab_mesh
from lightcal_app.scene3d import Scene3D
from lightcal_app.server import LightcalApp, build_app
from lightcal_app.state import LightGuess

from lightcal.cli.main import main
from lightcal.core.flat_port import FlatPort
from lightcal.core.medium import Medium
from lightcal.core.rid import CosPowerRID
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.io.project import load_project
from lightcal.pipeline.port_text import (
    beam_angles_rad,
    light_port_sentence,
    port_sentence,
    water_angle_rad,
)

CAMERA_PORT = FlatPort(0.020, 0.010, 1.49, 1.333)
LIGHT_PORT = FlatPort(0.015, 0.008, 1.49, 1.333)
TILTED = FlatPort(0.015, 0.008, 1.52, 1.34, normal_camera=np.array([0.05, -0.03, 1.0]))


def _angle_deg(v: np.ndarray, axis: np.ndarray) -> np.ndarray:
    v = v / np.linalg.norm(v, axis=-1, keepdims=True)
    return np.degrees(np.arccos(np.clip(v @ (axis / np.linalg.norm(axis)), -1.0, 1.0)))


# -- the beam's angles in the water --------------------------------------------------------


@pytest.mark.parametrize("port", [LIGHT_PORT, FlatPort(0.002, 0.0, 1.52, 1.34)])
def test_water_angle_is_snells_law(port: FlatPort) -> None:
    theta = np.radians(np.linspace(0.0, 89.0, 90))
    water = np.array([water_angle_rad(float(t), port) for t in theta])
    np.testing.assert_allclose(
        port.air_index * np.sin(theta), port.water_index * np.sin(water), atol=1e-15
    )
    # The vector form's water direction (`FlatPort.trace`, both faces) makes that angle.
    rays = np.stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)], axis=1)
    _, w, ok = port.trace(rays)
    assert ok.all()
    np.testing.assert_allclose(np.radians(_angle_deg(w, port.normal_camera)), water, atol=1e-12)
    # Beyond 90 degrees no ray reaches the port: the grazing ray's angle bounds them all.
    limit = math.asin(port.air_index / port.water_index)
    assert water_angle_rad(math.pi, port) == pytest.approx(limit, abs=1e-15)
    assert water_angle_rad(0.5 * math.pi, port) == pytest.approx(limit, abs=1e-15)
    with pytest.raises(ValueError, match="theta_air_rad"):
        water_angle_rad(-0.1, port)


def test_beam_angles_are_the_rids_refracted() -> None:
    rid = CosPowerRID.from_half_angle(math.radians(30.0))
    half, cut = beam_angles_rad(rid, None)
    assert (half, cut) == rid_angles(rid)
    assert math.degrees(half) == pytest.approx(30.0, abs=0.05)
    w_half, w_cut = beam_angles_rad(rid, LIGHT_PORT)
    assert math.sin(half) == pytest.approx(1.333 * math.sin(w_half), abs=1e-15)
    assert math.sin(cut) == pytest.approx(1.333 * math.sin(w_cut), abs=1e-15)
    assert math.degrees(w_half) == pytest.approx(22.03, abs=0.02)


@pytest.mark.parametrize("port", [LIGHT_PORT, TILTED])
def test_the_refracted_cone_runs_through_the_port_at_the_water_angle(port: FlatPort) -> None:
    """The cone's rays: from the emitter to the inner face at the air angle, through the
    glass, then in the water at the water angle (to the port's normal), `length` long."""
    theta = math.radians(30.0)
    rings = ported_beam_rings(theta, 0.3, port, n=24)
    assert rings.shape == (4, 24, 3)
    apex, inner, outer, end = rings
    n = port.normal_camera
    np.testing.assert_array_equal(apex, 0.0)
    np.testing.assert_allclose(_angle_deg(inner, np.array([0.0, 0.0, 1.0])), 30.0, atol=1e-12)
    np.testing.assert_allclose(inner @ n, port.distance_m, atol=1e-15)
    np.testing.assert_allclose(outer @ n, port.distance_m + port.thickness_m, atol=1e-15)
    if port is LIGHT_PORT:  # axial: every ray at the same water angle
        water = math.degrees(water_angle_rad(theta, port))
        np.testing.assert_allclose(_angle_deg(end - outer, n), water, atol=1e-10)
    _, w, _ = port.trace(inner)
    np.testing.assert_allclose(np.cross(end - outer, w), 0.0, atol=1e-15)
    path = np.linalg.norm(inner, axis=1)
    path += np.linalg.norm(outer - inner, axis=1) + np.linalg.norm(end - outer, axis=1)
    np.testing.assert_allclose(path, 0.3, rtol=1e-12)
    lines = ring_lines(rings, n_generators=8)
    assert lines.shape == (24 + 3 * 8, 2, 3)
    vertices, faces = ring_mesh(rings)
    assert vertices.shape == (1 + 3 * 24, 3) and faces.shape == (24 * 5, 3)
    assert faces.max() == len(vertices) - 1


# -- the ports' slabs ------------------------------------------------------------------------


def test_the_camera_ports_faces_span_the_frustums_opening() -> None:
    fov, aspect = math.radians(40.0), 4.0 / 3.0
    inner, outer = camera_port_faces(CAMERA_PORT, fov_y_rad=fov, aspect=aspect)
    half_y = 0.020 * math.tan(fov / 2)
    expected = np.array([[-aspect, -1, 0], [aspect, -1, 0], [aspect, 1, 0], [-aspect, 1, 0]])
    np.testing.assert_allclose(inner, expected * half_y + [0, 0, 0.020], atol=1e-15)
    # The outer face: where the corner rays leave the glass (bent towards the normal).
    corners = expected + np.array([0.0, 0.0, 1.0])
    corners[:, :2] *= math.tan(fov / 2)
    exit_points, _, _ = CAMERA_PORT.trace(corners)
    np.testing.assert_allclose(outer, exit_points, atol=1e-15)
    assert np.all(np.abs(outer[:, :2]) < np.abs(inner[:, :2]) * 1.5)  # narrower than straight
    vertices, faces = slab_mesh(inner, outer)
    assert vertices.shape == (8, 3) and faces.shape == (12, 3)
    # A tilted port: each face in its plane, still around the frustum's corner rays.
    inner, outer = camera_port_faces(TILTED, fov_y_rad=fov, aspect=aspect)
    n = TILTED.normal_camera
    np.testing.assert_allclose(inner @ n, TILTED.distance_m, atol=1e-15)
    np.testing.assert_allclose(outer @ n, TILTED.distance_m + TILTED.thickness_m, atol=1e-15)


def test_a_light_ports_faces_are_where_its_cut_off_cone_crosses_them() -> None:
    cut = math.radians(60.0)
    inner, outer = light_port_faces(LIGHT_PORT, cut, n=32)
    assert inner.shape == outer.shape == (32, 3)
    np.testing.assert_allclose(inner[:, 2], 0.015, atol=1e-15)
    np.testing.assert_allclose(np.hypot(inner[:, 0], inner[:, 1]), 0.015 * math.tan(cut))
    glass = math.asin(math.sin(cut) / 1.49)
    rho = 0.015 * math.tan(cut) + 0.008 * math.tan(glass)
    np.testing.assert_allclose(outer[:, 2], 0.023, atol=1e-15)
    np.testing.assert_allclose(np.hypot(outer[:, 0], outer[:, 1]), rho, rtol=1e-12)


# -- the text --------------------------------------------------------------------------------


def test_the_ports_in_words() -> None:
    assert port_sentence(CAMERA_PORT) == (
        "camera behind a flat port: 20 mm to the glass, 10 mm acrylic (n 1.49) into water (n 1.333)"
    )
    assert port_sentence(FlatPort(0.005, 0.0, 1.52, 1.34), "led") == (
        "led behind a flat port: 5 mm to the glass, a window of thickness 0 into water (n 1.34)"
    )
    assert port_sentence(TILTED).startswith(
        "camera behind a flat port: 15 mm to the glass, 8 mm glass (n 1.52) into water (n 1.34), "
        "tilted 3.34° from the axis"
    )
    rid = CosPowerRID.from_half_angle(math.radians(30.0))
    text = light_port_sentence("led", LIGHT_PORT, rid)
    assert text.startswith(
        "led behind a flat port: 15 mm to the glass, 8 mm acrylic (n 1.49) into water "
        "(n 1.333); its beam in the water: half intensity at 22.0°, cut-off at "
    )
    assert text.endswith("(in air 30.0° and 67.4°)")
    assert beam_label(*rid_angles(rid), LIGHT_PORT).startswith(
        "beam in water: 22.0° half, 43.8° cut-off (in air 30.0°, 67.4°"
    )
    clear = Medium(0.0)
    assert water_text(clear, clear, (), estimate_shown=False, behind_port=True).startswith(
        "**Clear water** behind the flat port"
    )
    assert water_text(clear, clear, (), estimate_shown=False).startswith("**Air**")


# -- in the page -----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def ported(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Synth's light behind a port (d 15 mm, t 8 mm, acrylic into sea water), declared,
    and the camera's port (d 20 mm, t 10 mm) declared beside it (the images are not
    rendered through it: the page only has to show it)."""
    folder = tmp_path_factory.mktemp("port_view") / "data"
    argv = ["synth", str(folder), "--views", "3", "--width", "80", "--height", "60"]
    argv += ["--light-port", "15", "8", "1.49", "1.333", "--declare-light-port"]
    assert main([*argv, "--seed", "4", "--quiet"]) == 0
    path = folder / "project.json"
    data = json.loads(path.read_text())
    data["camera"]["port"] = {"distance_mm": 20, "thickness_mm": 10}
    path.write_text(json.dumps(data))
    return path


@pytest.fixture(scope="module")
def app(ported: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[LightcalApp]:
    a = build_app(ported, port=0, session_path=False, state_dir=tmp_path_factory.mktemp("s"))
    assert a.wait_idle(120.0)
    yield a
    a.close()


def _node(app_or_server: LightcalApp | viser.ViserServer, name: str) -> object:
    server = app_or_server if isinstance(app_or_server, viser.ViserServer) else app_or_server.server
    return server.scene.get_handle_by_name(name)


def test_the_camera_port_is_drawn_in_front_of_every_frustum(app: LightcalApp) -> None:
    project = app.state.project
    port = project.camera_port
    assert port is not None
    cam = project.camera
    inner, outer = camera_port_faces(port, fov_y_rad=cam.fov_y_rad, aspect=cam.aspect)
    np.testing.assert_allclose(inner[:, 2], 0.020)
    np.testing.assert_allclose(np.abs(inner[:, 1]), 0.020 * math.tan(cam.fov_y_rad / 2))
    np.testing.assert_allclose(
        np.abs(inner[:, 0]), 0.020 * math.tan(cam.fov_y_rad / 2) * cam.aspect
    )
    for i in range(len(project.views)):
        node = _node(app, f"/cameras/{i}/port")
        assert node is not None, i
        # Below the frustum node: posed by it (identity in the camera frame).
        np.testing.assert_array_equal(node.position, 0.0)  # type: ignore[attr-defined]
        np.testing.assert_array_equal(node.wxyz, [1.0, 0.0, 0.0, 0.0])  # type: ignore[attr-defined]
        vertices = np.asarray(node.vertices)  # type: ignore[attr-defined]
        np.testing.assert_allclose(vertices, np.vstack([inner, outer]), atol=1e-7)
        assert node.opacity < 1.0  # type: ignore[attr-defined]
        assert _node(app, f"/cameras/{i}/port_edges") is not None


def test_the_light_port_and_its_refracted_cones_are_drawn(app: LightcalApp) -> None:
    project = app.state.project
    light = project.lights[0].initial
    port = light.port
    assert port is not None and port.distance_m == pytest.approx(0.015)
    half, cut = rid_angles(light.rid)
    inner, outer = light_port_faces(port, cut)
    w_cut = math.degrees(water_angle_rad(cut, port))
    length = app.controller.scene.cone_length_m
    for i in range(len(project.views)):
        base = f"/cameras/{i}/light0"
        node = _node(app, f"{base}/port")
        assert node is not None, i
        vertices = np.asarray(node.vertices)  # type: ignore[attr-defined]
        np.testing.assert_allclose(vertices, np.vstack([inner, outer]), atol=1e-7)
        # The cut-off cone's rays in the water (its generators' last segments).
        segments = np.asarray(_node(app, f"{base}/cone_cut").points)  # type: ignore[attr-defined]
        in_water = segments[-8:]
        np.testing.assert_allclose(in_water[:, 0, 2], 0.023, atol=1e-7)
        angles = _angle_deg(in_water[:, 1] - in_water[:, 0], np.array([0.0, 0.0, 1.0]))
        np.testing.assert_allclose(angles, w_cut, atol=1e-3)
        assert w_cut < math.degrees(cut) - 10.0
    ref = app.state.ref_image
    label = _node(app, f"/cameras/{ref}/light0/beam_label")
    assert label is not None
    assert label.text == beam_label(half, cut, port)  # type: ignore[attr-defined]
    np.testing.assert_allclose(label.position, [0.0, 0.0, length])  # type: ignore[attr-defined]


def test_the_light_tab_names_the_ports(app: LightcalApp) -> None:
    project = app.state.project
    text = app.panels.light.light_md.content
    camera = (
        "**camera** behind a flat port: 20 mm to the glass, 10 mm acrylic (n 1.49) into water "
        "(n 1.333)"
    )
    assert camera in text
    light = project.lights[0].initial
    sentence = light_port_sentence(light.name, light.port, light.rid)  # type: ignore[arg-type]
    assert f"**{light.name}**{sentence.removeprefix(light.name)}" in text
    assert ports_markdown(project) in text
    assert app.panels.light.water.text.content.startswith("**Clear water**")


def test_a_plain_project_draws_no_port(ported: Path, tmp_path: Path) -> None:
    data = json.loads(ported.read_text())
    del data["camera"]["port"]
    for light in data["lights"]:
        light.pop("port", None)
    plain = ported.with_name("plain.json")
    plain.write_text(json.dumps(data))
    project = load_project(plain)
    assert project.camera_port is None and project.lights[0].initial.port is None
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        scene = Scene3D(server, on_gizmo=lambda *a: None)
        light = project.lights[0].initial
        guess = [LightGuess(light.t_camera_light, light.R_camera_light)]
        pictures = [np.zeros((6, 8, 3), np.uint8) for _ in project.views]
        scene.build(project, pictures=pictures, guess=guess, ref_image=0, truth=None)
        scene.set_lights(list(guess))
        assert ports_markdown(project) == ""
        for i in range(len(project.views)):
            for name in ("port", "port_edges", "light0/port", "light0/beam_label"):
                assert _node(server, f"/cameras/{i}/{name}") is None, (i, name)
            assert _node(server, f"/cameras/{i}/light0/cone_cut") is not None
        # The same scene with the ports (and a light turned off the camera's axis).
        ported_project = load_project(ported)
        turned = LightGuess(light.t_camera_light, matrix_from_rotvec(np.array([0.1, 0.0, 0.0])))
        scene.build(ported_project, pictures=pictures, guess=[turned], ref_image=0, truth=None)
        scene.set_lights([turned])
        assert _node(server, "/cameras/1/port") is not None
        assert _node(server, "/cameras/1/light0/port") is not None
        frame = _node(server, "/cameras/1/light0")
        np.testing.assert_allclose(frame.position, turned.t_camera_light)  # type: ignore[attr-defined]
    finally:
        server.stop()
