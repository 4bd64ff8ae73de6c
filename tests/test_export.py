"""`lightcal export`: every format read back with its own tools, the pose to 1e-9.

The result comes from `lightcal calibrate` on a small synth dataset with the RID
estimated (cos^m); a 2-D table and a two-light result are written with lightcal's own
result writer. Blender is not installed: its snippet runs against a stand-in `bpy` /
`mathutils` that records the matrix it sets. Mitsuba 3 loads its XML when importable
(single precision there; the XML's numbers are checked to 1e-9 by parsing it).
"""

from __future__ import annotations

import json
import math
import sys
import types
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from lightcal.cli.main import main
from lightcal.core.camera_frames import (
    F_BLENDER,
    F_MITSUBA,
    blender_spot_cone,
    mitsuba_spot_cone,
    opencv_from_blender,
    opencv_from_mitsuba,
)
from lightcal.core.rid import CosPowerRID
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.errors import InputError
from lightcal.io.eulumdat import read_ldt
from lightcal.io.export import export_result
from lightcal.io.export_lights import (
    given_rid_description,
    light_rid,
    light_transform,
    with_given_rids,
)
from lightcal.io.export_mitsuba import TEXTURE_MIN_SIZE, rid_values
from lightcal.io.ies import read_ies
from lightcal.io.photometric_file import read_rid_file
from lightcal.io.result_file import ResultFile, read_result, write_result
from lightcal.synthetic.dataset import SynthConfig, write_dataset
from lightcal.synthetic.scenes import SceneConfig
from tests import calib_scenes as cs

POSE_TOL = 1e-9


@pytest.fixture(scope="module")
def result_path(tmp_path_factory) -> Path:
    """`lightcal calibrate` on 6 synthetic views, the cos^m exponent estimated."""
    folder = tmp_path_factory.mktemp("export")
    config = SynthConfig(camera=cs.small_camera(), scene=SceneConfig(n_views=6), seed=5)
    dataset = write_dataset(folder / "data", config)
    doc = json.loads(dataset.project_path.read_text())
    for light in doc["lights"]:
        light["estimate_rid"] = "cos_power"
    project = dataset.project_path.with_name("project_rid.json")
    project.write_text(json.dumps(doc))
    out = folder / "result.json"
    assert main(["calibrate", str(project), "--out", str(out), "--quiet"]) == 0
    return out


@pytest.fixture(scope="module")
def result(result_path) -> ResultFile:
    loaded = read_result(result_path)
    assert loaded.lights[0].rid is not None
    return loaded


def _two_light_result(result: ResultFile, tmp_path: Path) -> Path:
    """The calibrated result plus a rolled light with a 2-D RID table, as a result file."""
    first = result.lights[0]
    R = matrix_from_rotvec([0.05, -0.08, 0.3]) @ np.array(first.R_camera_light)
    theta_deg = np.linspace(0.0, 60.0, 7)
    phi_deg = np.arange(0.0, 360.0, 45.0)
    values = np.cos(np.radians(theta_deg))[None, :] ** (3.0 + np.cos(np.radians(phi_deg)))[:, None]
    second = first.model_copy(
        update={
            "name": "lopsided",
            "pose_kind": "general",
            "position_m": [-0.07, 0.02, 0.005],
            "R_camera_light": R.tolist(),
            "axis_camera": R[:, 2].tolist(),
            "rid": {
                "model": "table2d",
                "theta_deg": theta_deg.tolist(),
                "phi_deg": phi_deg.tolist(),
                "values": values.tolist(),
            },
        }
    )
    path = tmp_path / "two.json"
    write_result(result.model_copy(update={"lights": [first, second]}), path)
    return path


def _without_rid(result: ResultFile) -> ResultFile:
    """The result with its light's RID dropped (a calibration that did not estimate it)."""
    return result.model_copy(update={"lights": [result.lights[0].model_copy(update={"rid": None})]})


def _export(result_path: Path, fmt: str, out: Path, *extra: str) -> Path:
    assert main(["export", str(result_path), "--format", fmt, "--out", str(out), *extra]) == 0
    return out


# ------------------------------------------------------------------------ conventions


def test_blender_camera_flip_matches_blender_conventions():
    """OpenCV forward/right/down map to Blender camera -Z / +X / -Y; a spot's -Z is the axis."""
    F = F_BLENDER[:3, :3]
    np.testing.assert_array_equal(F @ [0, 0, 1], [0, 0, -1])  # forward: Blender looks down -Z
    np.testing.assert_array_equal(F @ [1, 0, 0], [1, 0, 0])  # right stays +X
    np.testing.assert_array_equal(F @ [0, 1, 0], [0, -1, 0])  # down is -Y (+Y up)
    assert np.linalg.det(F) == 1.0
    T = np.eye(4)
    T[:3, :3] = matrix_from_rotvec([0.1, -0.2, 0.3])
    T[:3, 3] = [0.1, -0.2, 0.5]
    M = opencv_from_blender(np.eye(4))  # identity both ways
    np.testing.assert_array_equal(M, np.eye(4))
    M = F_BLENDER @ T @ F_BLENDER
    spot_dir_blendercam = M[:3, :3] @ [0, 0, -1]
    np.testing.assert_allclose(spot_dir_blendercam, F @ T[:3, 2], atol=1e-15)
    np.testing.assert_allclose(opencv_from_blender(M), T, atol=1e-15)


def test_mitsuba_camera_flip_matches_mitsuba_sensor():
    """Mitsuba's perspective sensor: the top-right of the image is its local (-x, +y, +z)."""
    F = F_MITSUBA[:3, :3]
    np.testing.assert_array_equal(F @ [1, -1, 1], [-1, 1, 1])  # OpenCV top-right, forward
    mi = pytest.importorskip("mitsuba")
    mi.set_variant("scalar_rgb")
    sensor = mi.load_dict({"type": "perspective", "fov": 60.0})
    ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(0.9, 0.1), mi.Point2f(0.5, 0.5))
    d = np.array(ray.d)
    # film (0.9, 0.1) is right of and above the image centre: OpenCV x > 0, y < 0
    d_opencv = F @ d
    assert d_opencv[0] > 0.1 and d_opencv[1] < -0.1 and d_opencv[2] > 0.5


def test_spot_cones_put_the_half_intensity_angle_mid_falloff():
    half = math.radians(25.0)
    size, blend = blender_spot_cone(half)
    assert blend == 1.0
    cos_edge = math.cos(size / 2)
    assert (1.0 + cos_edge) / 2 == pytest.approx(math.cos(half))
    cutoff, beam = mitsuba_spot_cone(half)
    assert (cutoff + beam) / 2 == pytest.approx(25.0)


# ---------------------------------------------------------------------------- formats


def test_opencv_round_trip(result, result_path, tmp_path):
    path = _export(_two_light_result(result, tmp_path), "opencv", tmp_path / "light.yaml")
    two = read_result(tmp_path / "two.json")
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    assert fs.isOpened()
    assert "OpenCV camera frame" in fs.getNode("frame").string()
    lights = fs.getNode("lights")
    assert lights.size() == 2
    for k, light in enumerate(two.lights):
        node = lights.at(k)
        assert node.getNode("name").string() == light.name
        T = node.getNode("T_camera_light").mat()
        np.testing.assert_allclose(T, light_transform(light), rtol=0, atol=POSE_TOL)
        np.testing.assert_allclose(node.getNode("position_m").mat().ravel(), light.position_m)
        np.testing.assert_allclose(
            node.getNode("axis_camera").mat().ravel(), light.axis_camera, rtol=0, atol=POSE_TOL
        )
        np.testing.assert_array_equal(
            node.getNode("sigma_position_m").mat().ravel(), light.sigma.position_m
        )
        assert node.getNode("sigma_scale").real() == light.scale_sigma
        assert light.rid is not None
        if k == 0:
            table = node.getNode("rid_table").mat()
            np.testing.assert_allclose(table[:, 0], np.radians(light.rid["theta_deg"]))
            np.testing.assert_array_equal(table[:, 1], light.rid["values"])
            assert node.getNode("rid_half_angle_rad").real() == pytest.approx(
                math.radians(light.rid["half_angle_deg"])
            )
        else:
            np.testing.assert_array_equal(node.getNode("rid_grid").mat(), light.rid["values"])
            np.testing.assert_allclose(
                node.getNode("rid_phi_rad").mat().ravel(), np.radians(light.rid["phi_deg"])
            )
    fs.release()


class _Matrix:
    """mathutils.Matrix stand-in: rows of floats."""

    def __init__(self, rows: Any) -> None:
        self.rows = np.array(rows, dtype=np.float64)

    @classmethod
    def Identity(cls, n: int) -> _Matrix:
        return cls(np.eye(n))


class _Nodes(list):
    """A light's node collection: its Emission node, and the nodes the snippet adds."""

    def new(self, kind: str) -> types.SimpleNamespace:
        socket = types.SimpleNamespace
        node = socket(
            bl_idname=kind,
            type=kind,
            mode=None,
            ies=None,
            inputs={"Strength": socket(default_value=1.0)},
            outputs={"Fac": socket(name="Fac")},
        )
        self.append(node)
        return node


def _fake_blender(camera: Any) -> tuple[types.ModuleType, types.ModuleType, list[Any]]:
    """`bpy` and `mathutils` stand-ins; the third item collects the created objects."""
    created: list[Any] = []
    socket = types.SimpleNamespace

    def new_light(name: str, type: str) -> types.SimpleNamespace:
        emission = socket(type="EMISSION", inputs={"Strength": socket(default_value=1.0)})
        links: list[tuple[Any, Any]] = []
        new_link = lambda a, b: links.append((a, b))  # noqa: E731
        tree = socket(nodes=_Nodes([emission]), links=socket(new=new_link), made=links)
        return socket(name=name, type=type, node_tree=tree, use_nodes=False)

    def new_text(name: str) -> types.SimpleNamespace:
        text = socket(name=name, body="")
        text.write = lambda more: setattr(text, "body", text.body + more)
        return text

    def new_object(name: str, data: Any) -> types.SimpleNamespace:
        obj = types.SimpleNamespace(name=name, data=data, parent=None)
        created.append(obj)
        return obj

    scene = types.SimpleNamespace(
        camera=camera,
        collection=types.SimpleNamespace(objects=types.SimpleNamespace(link=lambda obj: None)),
    )
    bpy = types.ModuleType("bpy")
    bpy.context = types.SimpleNamespace(scene=scene)  # type: ignore[attr-defined]
    bpy.data = types.SimpleNamespace(  # type: ignore[attr-defined]
        lights=types.SimpleNamespace(new=new_light),
        objects=types.SimpleNamespace(new=new_object),
        texts=types.SimpleNamespace(new=new_text),
    )
    mathutils = types.ModuleType("mathutils")
    mathutils.Matrix = _Matrix  # type: ignore[attr-defined]
    return bpy, mathutils, created


def _ies_node(data: Any) -> Any:
    """The IES Texture node driving a stand-in light's Emission strength (asserted so)."""
    assert data.use_nodes
    (emission, ies) = data.node_tree.nodes
    assert ies.bl_idname == "ShaderNodeTexIES" and ies.mode == "INTERNAL"
    assert data.node_tree.made == [(ies.outputs["Fac"], emission.inputs["Strength"])]
    return ies


def _run_blender_snippet(path: Path, camera: Any, monkeypatch) -> list[Any]:
    """Execute an exported snippet against the stand-ins; the objects it created."""
    bpy, mathutils, created = _fake_blender(camera)
    monkeypatch.setitem(sys.modules, "bpy", bpy)
    monkeypatch.setitem(sys.modules, "mathutils", mathutils)
    exec(compile(path.read_text(), str(path), "exec"), {"__name__": "__main__"})
    return created


@pytest.mark.parametrize("with_camera", [True, False])
def test_blender_snippet_sets_the_pose(result, tmp_path, monkeypatch, with_camera):
    two = read_result(_two_light_result(result, tmp_path))
    path = _export(tmp_path / "two.json", "blender", tmp_path / "lights.py")
    camera = types.SimpleNamespace(name="Camera") if with_camera else None
    created = _run_blender_snippet(path, camera, monkeypatch)
    assert [obj.name for obj in created] == [light.name for light in two.lights]
    for obj, light in zip(created, two.lights, strict=True):
        assert obj.parent is camera
        if with_camera:
            np.testing.assert_array_equal(obj.matrix_parent_inverse.rows, np.eye(4))
        M = obj.matrix_local.rows
        T = opencv_from_blender(M)
        np.testing.assert_allclose(T, light_transform(light), rtol=0, atol=POSE_TOL)
        # the spot shines along its -Z: the light axis in Blender's camera frame
        np.testing.assert_allclose(
            M[:3, :3] @ [0, 0, -1], F_BLENDER[:3, :3] @ light.axis_camera, atol=1e-12
        )
        # a point light driven by its RID through an IES node; power 4 pi scale
        assert obj.data.type == "POINT" and obj.data.shadow_soft_size == 0.0
        assert obj.data.energy == pytest.approx(4.0 * math.pi * light.scale, rel=1e-15)
        ies = _ies_node(obj.data)
        assert ies.inputs["Strength"].default_value == pytest.approx(1.0 / 0.0706650768394)
        ies_path = tmp_path / f"{obj.name}.ies"
        ies_path.write_text(ies.ies.body)
        table = read_ies(ies_path)
        rid = light_rid(light, "r.json")
        assert rid is not None
        # Cycles' horizontal angle C is phi - 90 degrees; on the samples the table is the RID
        column = 45 // 2 if table.candela.shape[0] > 1 else 0  # C = 44 degrees, phi = 134
        phi = math.radians(table.horizontal_deg[column] + 90.0)
        theta = np.radians(table.vertical_deg[::20])
        expected = rid_values(rid, theta, np.full_like(theta, phi))
        np.testing.assert_allclose(table.candela[column, ::20], expected, rtol=1e-6, atol=1e-7)


def _xml_emitters(path: Path) -> dict[str, ET.Element]:
    root = ET.parse(path).getroot()
    assert root.tag == "scene"
    return {e.get("id"): e for e in root.iter("emitter")}  # type: ignore[misc]


def _to_world(element: ET.Element) -> np.ndarray:
    node = element.find("transform[@name='to_world']/matrix")
    assert node is not None
    return np.array([float(v) for v in node.get("value", "").split()]).reshape(4, 4)


def test_mitsuba_fragment_round_trip(result, tmp_path):
    two = read_result(_two_light_result(result, tmp_path))
    path = _export(tmp_path / "two.json", "mitsuba", tmp_path / "lights.xml")
    emitters = _xml_emitters(path)
    assert list(emitters) == [light.name for light in two.lights]
    for index, light in enumerate(two.lights):
        element = emitters[light.name]
        assert element.get("type") == "spot"
        T = opencv_from_mitsuba(_to_world(element))
        np.testing.assert_allclose(T, light_transform(light), rtol=0, atol=POSE_TOL)
        texture = element.find("texture/string[@name='filename']")
        assert texture is not None and texture.get("value") == f"lights_rid_{index}.png"
        image = cv2.imread(str(tmp_path / f"lights_rid_{index}.png"), cv2.IMREAD_UNCHANGED)
        assert image is not None and image.dtype == np.uint16
        assert image.shape[0] == image.shape[1] >= TEXTURE_MIN_SIZE
        cutoff = element.find("float[@name='cutoff_angle']")
        beam = element.find("float[@name='beam_width']")
        assert cutoff is not None and beam is not None
        assert cutoff.get("value") == beam.get("value")  # no falloff: the texture is the RID


def _mitsuba_emitters(path: Path) -> dict[str, Any]:
    """Mitsuba 3's emitters of an exported scene by id (scalar_rgb)."""
    mi = pytest.importorskip("mitsuba")
    mi.set_variant("scalar_rgb")
    scene = mi.load_file(str(path))
    (sensor,) = scene.sensors()
    np.testing.assert_allclose(np.array(mi.traverse(sensor)["to_world"].matrix), np.eye(4), atol=0)
    return {e.id(): e for e in scene.emitters()}


def _mitsuba_intensity(emitter: Any, to_world: np.ndarray, theta: float, phi: float) -> float:
    """Mitsuba's radiant intensity 1 m from the light towards (theta, phi) of its frame,
    relative to its axis (the emitter's intensity is the light's scale)."""
    import mitsuba as mi

    d_light = [math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)]
    it = mi.Interaction3f()
    it.p = mi.Point3f(*(to_world @ [*d_light, 1.0])[:3])
    _, weight = emitter.sample_direction(it, mi.Point2f(0.5, 0.5))
    it.p = mi.Point3f(*(to_world @ [0.0, 0.0, 1.0, 1.0])[:3])
    _, axis = emitter.sample_direction(it, mi.Point2f(0.5, 0.5))
    return float(weight[0]) / float(axis[0])


def test_mitsuba_loads_the_fragment(result, result_path, tmp_path):
    path = _export(result_path, "mitsuba", tmp_path / "light.xml")
    (emitter,) = _mitsuba_emitters(path).values()
    import mitsuba as mi

    to_world = np.array(mi.traverse(emitter)["to_world"].matrix, dtype=np.float64)
    # Mitsuba's scalar variants hold single precision
    T = opencv_from_mitsuba(to_world)
    np.testing.assert_allclose(T, light_transform(result.lights[0]), rtol=0, atol=1e-6)
    # Mitsuba's own texture lookup: half the axis intensity at the RID's half angle
    half = math.radians(result.lights[0].rid["half_angle_deg"])
    for phi in (0.0, 1.0, 2.5, 4.0):
        assert _mitsuba_intensity(emitter, to_world, half, phi) == pytest.approx(0.5, abs=2e-3)


def test_mitsuba_texture_keeps_the_azimuths_of_a_2d_rid(result, tmp_path):
    """f = cos(theta)^(3 + cos(phi)): brighter towards phi = 180 deg than towards phi = 0."""
    two = read_result(_two_light_result(result, tmp_path))
    path = _export(tmp_path / "two.json", "mitsuba", tmp_path / "lights.xml")
    emitter = _mitsuba_emitters(path)["lopsided"]
    to_world = _to_world(_xml_emitters(path)["lopsided"])
    rid = light_rid(two.lights[1], "two.json")
    assert rid is not None
    for theta_deg in (15.0, 35.0, 50.0):
        for phi_deg in (0.0, 60.0, 90.0, 180.0, 250.0, 300.0):
            theta, phi = math.radians(theta_deg), math.radians(phi_deg)
            got = _mitsuba_intensity(emitter, to_world, theta, phi)
            table = float(rid_values(rid, np.array(theta), np.array(phi)))
            assert got == pytest.approx(table, abs=3e-3), (theta_deg, phi_deg)
            assert got == pytest.approx(math.cos(theta) ** (3 + math.cos(phi)), abs=0.03)


@pytest.mark.parametrize("fmt, reader", [("ies", read_ies), ("ldt", read_ldt)])
def test_photometric_round_trip(result, result_path, tmp_path, fmt, reader):
    path = _export(result_path, fmt, tmp_path / f"light.{fmt}")
    rid = result.lights[0].rid
    assert rid is not None
    table = reader(path)
    assert table.symmetry == "axial"
    # the table ends at 90 degrees as LM-63 asks, the RID 0 there
    # (angles without a radian round trip's noise: 3.0, not 3.0000000000000004)
    np.testing.assert_allclose(table.vertical_deg, [*rid["theta_deg"], 90.0], rtol=0, atol=1e-9)
    assert all(len(repr(float(a)).split(".")[-1]) <= 9 for a in table.vertical_deg)
    np.testing.assert_allclose(table.candela[0], [*rid["values"], 0.0], rtol=1e-12, atol=0)
    as_rid = read_rid_file(path)
    theta = np.radians(rid["theta_deg"])
    # The knots exactly (the renderer's grid is within rid_tabulate's accuracy of them).
    exact = as_rid.value_and_derivatives(theta, exact=True)[0]
    np.testing.assert_allclose(exact, rid["values"], rtol=1e-12, atol=1e-15)
    # the estimated exponent's profile, evaluated independently
    expected = CosPowerRID(rid["m"])(theta)
    np.testing.assert_allclose(exact, expected, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("fmt", ["ies", "ldt"])
def test_photometric_2d_table_keeps_the_azimuths(result, tmp_path, fmt):
    two = _two_light_result(result, tmp_path)
    light = read_result(two).lights[1]
    # no half_angle_deg in the table: where the mean over azimuths crosses 1/2
    lopsided = light_rid(light, two)
    assert lopsided is not None
    mean = lopsided.values.mean(axis=0)
    assert np.interp(lopsided.half_angle_rad, lopsided.theta_rad, mean) == pytest.approx(0.5)
    path = _export(two, fmt, tmp_path / f"lopsided.{fmt}", "--light", "lopsided")
    rid = read_rid_file(path)
    assert light.rid is not None
    theta = np.radians(light.rid["theta_deg"])
    for phi_deg, row in zip(light.rid["phi_deg"], light.rid["values"], strict=True):
        phi = np.full(theta.size, math.radians(phi_deg))
        got = rid.value_and_derivatives(theta, phi, exact=True)[0]
        np.testing.assert_allclose(got, row, rtol=1e-12, atol=1e-15)


# ----------------------------------------------------------------------------- errors


def test_cli_formats_match_the_exporter():
    from lightcal.cli.export import FORMATS as CLI_FORMATS
    from lightcal.io.export import FORMATS

    assert CLI_FORMATS == FORMATS


def test_export_help_does_not_import_the_numerical_stack():
    from tests.test_cli_startup import HEAVY, run_lightcal

    out, imported = run_lightcal("export", "--help")
    assert out.startswith("usage: lightcal export")
    assert not imported & set(HEAVY)


def test_export_refuses_to_overwrite_without_force(result_path, tmp_path, capsys):
    out = tmp_path / "light.yaml"
    out.write_text("keep")
    code = main(["export", str(result_path), "--format", "opencv", "--out", str(out)])
    assert code == 2
    assert "--force" in capsys.readouterr().err
    assert out.read_text() == "keep"
    _export(result_path, "opencv", out, "--force")
    assert out.read_text().startswith("%YAML")


def test_photometric_export_needs_an_estimated_rid(result, tmp_path):
    bare = _without_rid(result)
    with pytest.raises(InputError, match="no estimated RID"):
        export_result(bare, "ies", tmp_path / "x.ies", source="r.json")
    assert not (tmp_path / "x.ies").exists()
    # the pose formats still work: a 180 degree cone
    export_result(bare, "mitsuba", tmp_path / "x.xml", source="r.json")
    cutoff = _xml_emitters(tmp_path / "x.xml")[bare.lights[0].name].find(
        "float[@name='cutoff_angle']"
    )
    assert cutoff is not None and float(cutoff.get("value", "")) == 90.0


def test_photometric_export_asks_which_light(result, tmp_path, capsys):
    two = _two_light_result(result, tmp_path)
    code = main(["export", str(two), "--format", "ldt", "--out", str(tmp_path / "a.ldt")])
    assert code == 2
    assert "--light" in capsys.readouterr().err
    code = main(
        ["export", str(two), "--format", "ldt", "--out", str(tmp_path / "a.ldt"), "--light", "x"]
    )
    assert code == 2
    assert "no light named 'x'" in capsys.readouterr().err


# ----------------------------------------------------------------------------- schema


def test_result_schema_describes_every_field_and_the_frame(capsys):
    assert main(["schema", "result"]) == 0
    schema = json.loads(capsys.readouterr().out)
    assert "OpenCV frame: x right, y down, z forward" in schema["description"]
    nodes = [("", schema), *schema["$defs"].items()]
    missing = [
        f"{model}.{name}"
        for model, node in nodes
        for name, prop in node["properties"].items()
        if not prop.get("description")
    ]
    assert missing == []


def test_export_needs_an_existing_folder(result_path, tmp_path, capsys):
    out = tmp_path / "missing" / "light.xml"
    assert main(["export", str(result_path), "--format", "mitsuba", "--out", str(out)]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert not out.parent.exists()


def test_isotropic_light_exports_as_a_point_light(result, tmp_path, monkeypatch):
    light = result.lights[0].model_copy(update={"pose_kind": "isotropic", "rid": None})
    point = result.model_copy(update={"lights": [light]})
    export_result(point, "mitsuba", tmp_path / "p.xml", source="r.json")
    element = _xml_emitters(tmp_path / "p.xml")[light.name]
    assert element.get("type") == "point"
    T = opencv_from_mitsuba(_to_world(element))
    np.testing.assert_allclose(T, light_transform(light), rtol=0, atol=POSE_TOL)
    export_result(point, "blender", tmp_path / "p.py", source="r.json")
    (obj,) = _run_blender_snippet(tmp_path / "p.py", None, monkeypatch)
    assert obj.data.type == "POINT" and obj.parent is None and not obj.data.use_nodes
    np.testing.assert_allclose(
        opencv_from_blender(obj.matrix_local.rows), light_transform(light), rtol=0, atol=POSE_TOL
    )


def test_cli_notes_a_spot_without_a_rid(result, tmp_path, capsys, monkeypatch):
    bare = _without_rid(result)
    write_result(bare, tmp_path / "bare.json")
    _export(tmp_path / "bare.json", "blender", tmp_path / "b.py")
    assert "180 degree spot cone" in capsys.readouterr().err
    (obj,) = _run_blender_snippet(tmp_path / "b.py", None, monkeypatch)
    assert obj.data.type == "SPOT" and not obj.data.use_nodes
    assert obj.data.spot_size == pytest.approx(blender_spot_cone(math.pi / 2)[0])


def test_an_existing_texture_blocks_the_whole_mitsuba_export(result_path, tmp_path, capsys):
    (tmp_path / "light_rid_0.png").write_bytes(b"keep")
    out = tmp_path / "light.xml"
    assert main(["export", str(result_path), "--format", "mitsuba", "--out", str(out)]) == 2
    assert "light_rid_0.png: the file exists" in capsys.readouterr().err
    assert not out.exists()
    _export(result_path, "mitsuba", out, "--force")
    assert (tmp_path / "light_rid_0.png").read_bytes().startswith(b"\x89PNG")


def test_mitsuba_texture_of_a_batwing_keeps_its_off_axis_peak(result, tmp_path):
    """A RID brighter off the axis: the texture is scaled to its peak, the intensity up."""
    theta_deg = [0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0]
    values = [1.0, 1.5, 2.0, 1.5, 0.5, 0.1, 0.0]
    rid = {"model": "curve", "theta_deg": theta_deg, "values": values}
    light = result.lights[0].model_copy(update={"rid": rid})
    write_result(result.model_copy(update={"lights": [light]}), tmp_path / "bat.json")
    path = _export(tmp_path / "bat.json", "mitsuba", tmp_path / "bat.xml")
    emitter = _mitsuba_emitters(path)[light.name]
    to_world = _to_world(_xml_emitters(path)[light.name])
    table = light_rid(light, "bat.json")
    assert table is not None
    for theta in (5.0, 15.0, 25.0, 35.0):  # lightcal's interpolation of the table (PCHIP)
        expected = float(rid_values(table, np.array(math.radians(theta)), np.array(0.7)))
        got = _mitsuba_intensity(emitter, to_world, math.radians(theta), 0.7)
        assert got == pytest.approx(expected, abs=1e-2), theta


def test_project_supplies_the_rid_the_calibration_did_not_estimate(result, tmp_path, capsys):
    from lightcal.io.project import load_project

    assert result.project is not None
    write_result(_without_rid(result), tmp_path / "bare.json")
    out = tmp_path / "given.ies"
    _export(tmp_path / "bare.json", "ies", out, "--project", result.project)
    given = load_project(result.project).lights[0].initial.rid
    theta = np.radians(np.arange(0.0, 90.0, 5.0))  # on the 1 degree samples: exact
    exported = read_rid_file(out).value_and_derivatives(theta, exact=True)[0]
    expected = given.value_and_derivatives(theta, exact=True)[0]
    np.testing.assert_allclose(exported, expected, rtol=1e-12, atol=1e-15)
    between = theta + math.radians(0.5)  # the table's cubic between samples
    np.testing.assert_allclose(read_rid_file(out)(between), given(between), atol=1e-4)
    _export(tmp_path / "bare.json", "blender", tmp_path / "given.py", "--project", result.project)
    assert "180 degree" not in capsys.readouterr().err


def test_a_given_2d_table_exports_its_own_samples(result, tmp_path):
    table = cs.general_rid()
    description = given_rid_description(table)
    assert description is not None
    light = result.lights[0].model_copy(update={"name": "general", "rid": None})
    bare = result.model_copy(update={"lights": [light]})
    export_result(
        with_given_rids(bare, {"general": table}), "ldt", tmp_path / "g.ldt", source="r.json"
    )
    back = read_rid_file(tmp_path / "g.ldt")
    tt, pp = np.meshgrid(table.theta_rad[:-1], table.phi_rad)
    np.testing.assert_allclose(back(tt, pp), table(tt, pp), rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize(
    "rid, expected",
    [
        ({"theta_deg": [0.0, 10.0], "values": [1.0]}, "expected values of shape"),
        ({"theta_deg": [5.0, 10.0], "values": [1.0, 0.5]}, "increasing angles from 0"),
        ({"values": [1.0, 0.5]}, "expected theta_deg and values"),
        (
            {"theta_deg": [0.0, 10.0], "phi_deg": [90.0, 0.0], "values": [[1, 0.5], [1, 0.5]]},
            "phi_deg increasing",
        ),
    ],
)
def test_a_malformed_rid_table_names_the_light(result, rid, expected):
    light = result.lights[0].model_copy(update={"rid": rid})
    bad = result.model_copy(update={"lights": [light]})
    with pytest.raises(InputError, match=expected) as info:
        export_result(bad, "opencv", "unused.yaml", source="r.json")
    assert str(info.value).startswith(f"r.json: lights[{light.name}].rid: ")
