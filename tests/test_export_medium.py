"""`lightcal export` of a calibration in water: every format's medium read back with the
format's own tools (OpenCV's FileStorage, Mitsuba 3's loader, the Blender snippet against
a `bpy` stand-in), the numbers to 1e-9; an in-air export what it was, to its numbers' 10th digit.

The results are written here (two lights, one with a 2-D RID table), not calibrated:
the export is tested, not a solve. Mitsuba's and Cycles' renders of the water are in
`tests/test_export_mitsuba_render.py`.
"""

from __future__ import annotations

import collections
import hashlib
import json
import math
import re
import sys
import types
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from lightcal.cli.main import main
from lightcal.core.camera import Camera
from lightcal.core.medium import AIR, Medium
from lightcal.core.pose import describe_pose, rotation_from_axis
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.errors import InputError
from lightcal.io import export_lights
from lightcal.io.export import FORMATS, export_result
from lightcal.io.export_medium import export_medium
from lightcal.io.project import load_project
from lightcal.io.result_file import (
    LightResultModel,
    ResultFile,
    write_result,
)
from tests.export_render import placeholder_sigma, result_of_project, stub_result
from tests.test_export import _fake_blender

OUT_NAMES = {
    "opencv": "lights.yaml",
    "blender": "lights.py",
    "mitsuba": "scene.xml",
    "ros": "lights.launch.xml",
    "ies": "spot.ies",
    "ldt": "spot.ldt",
}


def _light(name: str, kind: str, R: np.ndarray, t: list[float], rid: dict[str, Any]) -> Any:
    return LightResultModel(
        name=name,
        pose_kind=kind,
        **describe_pose(R, t),
        scale=2.5,
        scale_sigma=0.01,
        sigma=placeholder_sigma(),
        rid=rid,
    )


def air_result() -> ResultFile:
    """Two lights (a cos^5 table, a general light with a 2-D table), the default medium."""
    theta_deg = np.arange(0.0, 91.0, 5.0)
    spot = _light(
        "spot",
        "symmetric",
        rotation_from_axis(np.array([0.1, -0.05, 1.0]) / math.hypot(0.1, 0.05, 1.0)),
        [0.08, -0.03, 0.01],
        {
            "model": "cos_power",
            "theta_deg": theta_deg.tolist(),
            "values": (np.cos(np.radians(theta_deg)) ** 5).tolist(),
        },
    )
    theta2 = np.linspace(0.0, 60.0, 7)
    phi2 = np.arange(0.0, 360.0, 45.0)
    values2 = np.cos(np.radians(theta2))[None, :] ** (3.0 + np.cos(np.radians(phi2)))[:, None]
    lopsided = _light(
        "lopsided",
        "general",
        matrix_from_rotvec([0.05, -0.08, 0.3]),
        [-0.07, 0.02, 0.005],
        {
            "model": "table2d",
            "theta_deg": theta2.tolist(),
            "phi_deg": phi2.tolist(),
            "values": values2.tolist(),
        },
    )
    return stub_result(
        [spot, lopsided],
        project="project.json",
        image_names=["a.png"],
        message="written by tests/test_export_medium.py",
    )


def camera() -> Camera:
    return Camera.from_params(fx=500.0, fy=505.0, cx=161.3, cy=118.2, width=320, height=240)


_NUMBER = re.compile(rb"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


def canonical(name: str, data: bytes) -> bytes:
    """A written file's bytes with what is not lightcal's taken out: every number to 10
    significant digits (NumPy's SIMD cos and pow, hence the tables' last bits, differ from
    one CPU to another) and OpenCV's `%YAML` directive (`%YAML:1.0` from OpenCV 4,
    `%YAML 1.2` from OpenCV 5). Images are compared as they are (16-bit: no last bits)."""
    if name.endswith(".png"):
        return data
    if data.startswith(b"%YAML"):
        data = data.split(b"\n", 1)[1]
    return _NUMBER.sub(lambda m: b"%.10g" % float(m[0]), data)


def export_digest(result: ResultFile, fmt: str, folder: Path) -> str:
    """sha256 of every file the export writes (`out` first), each `canonical`."""
    from lightcal.io.export import export_files

    files = export_files(
        result,
        fmt,
        folder / OUT_NAMES[fmt],
        source="r.json",
        light_name="spot",
        camera=camera() if fmt in ("mitsuba", "blender") else None,
    )
    return hashlib.sha256(b"".join(canonical(str(p), b) for p, b in files.items())).hexdigest()


# The sha256 of each format's files of `air_result()` written before media were exported
# (lightcal 0.x at commit cc9c08d, the lights' RID origin's version set to "0.0.test"),
# each `canonical`. They change only when a format changes on purpose. (cc9c08d's raw
# bytes were checked equal to this code's on 2026-11-28, OpenCV 5.0.0, NumPy 2.4.6.)
AIR_DIGESTS = {
    "opencv": "d97363c163569b49668acd167f24bee432b3c9de90a28fb478c39bb2c87ea04a",
    "blender": "afa0f7cacda828e80bd9e02dcd84e80439563ccb21c1e96e87bcd2dfe51762a0",
    "mitsuba": "d6ebfa838a4e31ec0e1b4ccdd673fcb52eac0017e2778d0cc972e35d91370726",
    "ros": "d6079e838cf54893bc67621eb66a47f993603f7a48e6efb6167f4e29f55626e7",
    "ies": "fdb51a9c414bcdd76722ceaeeb34d2b5e67ea43599ae433d065e6c772a30c95b",
    "ldt": "0921fcc80ecfb0ce14b6ea6bbe1846178ad14f11c29ccef09cfa06503e5ce6ee",
}

C, BETA, G = 0.3, 0.45, 0.8
RHO = 0.5
SIGMA_C = 0.004
WATER = {
    "attenuation_per_m": C,
    "backscatter_per_m": BETA,
    "phase_g": G,
    "estimated": ["attenuation_per_m", "backscatter_per_m"],
    "sigma": {"attenuation_per_m": SIGMA_C, "backscatter_per_m": 0.02},
}
CLEAR = {"attenuation_per_m": C, "estimated": [], "sigma": {}}  # absorbing only


def in_water(medium: dict[str, Any]) -> ResultFile:
    return air_result().model_copy(update={"medium": medium})


@pytest.fixture
def fixed_version(monkeypatch):
    monkeypatch.setattr(export_lights, "__version__", "0.0.test")


@pytest.mark.parametrize("fmt", FORMATS)
def test_an_export_in_air_is_what_it_was(fmt, tmp_path, fixed_version):
    """The default medium, and the air a calibration writes (c = beta = 0, g 0.9)."""
    assert export_digest(air_result(), fmt, tmp_path) == AIR_DIGESTS[fmt]
    air = {**AIR.describe(), "estimated": [], "sigma": {}}
    assert export_digest(in_water(air), fmt, tmp_path) == AIR_DIGESTS[fmt]
    water = export_digest(in_water(CLEAR), fmt, tmp_path)
    assert (water == AIR_DIGESTS[fmt]) == (fmt in ("ies", "ldt"))  # they cannot hold it


def test_the_scattering_coefficient_is_beta_rho_over_pi():
    medium = export_medium(in_water(WATER), "r.json")
    assert medium is not None and medium.scatters
    assert medium.scattering_per_m(RHO) == BETA * RHO / math.pi
    assert medium.albedo(RHO) == pytest.approx(BETA * RHO / math.pi / C, rel=1e-15)
    with pytest.raises(InputError, match="needs rho: expected --wall-albedo RHO"):
        medium.scattering_per_m(None)
    murky = export_medium(in_water({**WATER, "backscatter_per_m": 4.0}), "r.json")
    assert murky is not None
    with pytest.raises(InputError, match=r"exceeds the attenuation 0\.3 /m"):
        murky.scattering_per_m(RHO)  # sigma_s 0.64 /m > c
    clear = export_medium(in_water(CLEAR), "r.json")
    assert clear is not None and clear.scattering_per_m(None) == 0.0 == clear.albedo(None)
    assert export_medium(air_result(), "r.json") is None
    with pytest.raises(InputError, match="phase_g"):
        export_medium(in_water({**WATER, "phase_g": 1.5}), "r.json")


def test_opencv_reads_the_medium_back(tmp_path):
    export_result(in_water(WATER), "opencv", tmp_path / "w.yaml", source="r.json")
    fs = cv2.FileStorage(str(tmp_path / "w.yaml"), cv2.FILE_STORAGE_READ)
    node = fs.getNode("medium")
    assert node.isMap()
    for name, value in (("attenuation_per_m", C), ("backscatter_per_m", BETA), ("phase_g", G)):
        assert abs(node.getNode(name).real() - value) <= 1e-9
    assert abs(node.getNode("sigma_attenuation_per_m").real() - SIGMA_C) <= 1e-9
    assert abs(node.getNode("sigma_backscatter_per_m").real() - 0.02) <= 1e-9
    assert math.isnan(node.getNode("sigma_phase_g").real())  # given
    estimated = node.getNode("estimated")
    assert [estimated.at(i).string() for i in range(estimated.size())] == WATER["estimated"]
    assert "sigma_s pi / rho" in node.getNode("note").string()
    assert fs.getNode("lights").size() == 2  # the lights as in air
    fs.release()


def _mitsuba_numbers(path: Path) -> dict[str, float]:
    root = ET.parse(path).getroot()
    (medium,) = root.iter("medium")
    assert medium.get("type") == "homogeneous"
    ident = medium.get("id")
    refs = [
        parent.tag
        for parent in root.iter()
        for child in parent
        if child.tag == "ref" and child.get("id") == ident and child.get("name") == "medium"
    ]
    emitters = len(list(root.iter("emitter")))
    assert refs == ["sensor"] + ["emitter"] * emitters  # the camera and every light sit in it
    (integrator,) = root.iter("integrator")
    assert integrator.get("type") == "volpath"
    numbers = {e.get("name", ""): float(e.get("value", "")) for e in medium.iter("float")}
    return numbers


def test_mitsuba_reads_the_medium_back(tmp_path):
    mi = pytest.importorskip("mitsuba")
    path = tmp_path / "w.xml"
    export_result(in_water(WATER), "mitsuba", path, source="r.json", wall_albedo=RHO)
    numbers = _mitsuba_numbers(path)
    sigma_s = BETA * RHO / math.pi
    assert abs(numbers["sigma_t"] - C) <= 1e-9
    assert abs(numbers["albedo"] - sigma_s / C) <= 1e-9
    assert abs(numbers["g"] - G) <= 1e-9
    text = " ".join(path.read_text().split())  # the comment's words, unwrapped
    assert f"sigma_s = beta rho / pi = {sigma_s!r} /m with the wall's albedo rho = 0.5" in text
    mi.set_variant("scalar_rgb")
    scene = mi.load_file(str(path))
    (sensor,) = scene.sensors()
    medium = sensor.get_medium()
    assert medium is not None and all(e.get_medium() is medium for e in scene.emitters())
    params = mi.traverse(scene)
    # Mitsuba's scalar variants hold single precision
    assert params["lightcal_medium.sigma_t.value.value"] == pytest.approx(C, rel=1e-7)
    assert params["lightcal_medium.albedo.value.value"] == pytest.approx(sigma_s / C, rel=1e-7)
    assert params["lightcal_medium.phase_function.g"] == pytest.approx(G, rel=1e-7)
    assert "max_depth = 2," in str(mi.load_file(str(path), max_depth=2).integrator())


def test_an_absorbing_medium_needs_no_wall_albedo(tmp_path):
    mi = pytest.importorskip("mitsuba")
    path = tmp_path / "w.xml"
    export_result(in_water(CLEAR), "mitsuba", path, source="r.json")
    numbers = _mitsuba_numbers(path)
    assert numbers["sigma_t"] == C and numbers["albedo"] == 0.0
    assert "a purely absorbing medium" in " ".join(path.read_text().split())
    mi.set_variant("scalar_rgb")
    assert mi.load_file(str(path)).sensors()[0].get_medium() is not None


@pytest.mark.parametrize("fmt", ["mitsuba", "blender"])
def test_a_scattering_medium_without_the_wall_albedo_is_refused(fmt, tmp_path):
    with pytest.raises(InputError, match="expected --wall-albedo RHO"):
        export_result(in_water(WATER), fmt, tmp_path / OUT_NAMES[fmt], source="r.json")
    assert not list(tmp_path.iterdir())
    with pytest.raises(InputError, match="--wall-albedo: expected the wall's albedo in"):
        export_result(in_water(WATER), fmt, tmp_path / OUT_NAMES[fmt], source="r", wall_albedo=0)


def _world_stand_in(bpy: Any, existing: bool) -> Any:
    """A scene without a world and `bpy.data.worlds` making one (a Background node, which
    the snippet must remove); or the scene's world with a Background and a World Output."""
    socket = types.SimpleNamespace
    links: list[tuple[Any, Any]] = []

    def new_node(kind: str) -> Any:
        node = socket(
            bl_idname=kind,
            type="OUTPUT_WORLD" if kind == "ShaderNodeOutputWorld" else kind,
            inputs=collections.defaultdict(lambda: socket(default_value=None)),
            outputs=collections.defaultdict(lambda: socket()),
        )
        if kind == "ShaderNodeVolumeScatter":
            node.phase = "MIE"  # Blender 4.3+: the snippet sets Henyey-Greenstein
        nodes.append(node)
        return node

    class _Nodes(list):
        def new(self, kind: str) -> Any:
            return new_node(kind)

    nodes = _Nodes()
    tree = socket(nodes=nodes, links=socket(new=lambda a, b: links.append((a, b))), made=links)
    new_node("ShaderNodeBackground")

    def new_world(name: str) -> Any:
        return socket(name=name, node_tree=tree)

    bpy.data.worlds = socket(new=new_world)
    bpy.context.scene.world = None
    if existing:
        new_node("ShaderNodeOutputWorld")
        bpy.context.scene.world = new_world("World")
    return tree


@pytest.mark.parametrize("existing", [False, True])
def test_blender_makes_the_medium_the_worlds_volume(tmp_path, monkeypatch, existing):
    """The scene's world gets the volume, its surface kept; without one, a new black world."""
    path = tmp_path / "w.py"
    export_result(in_water(WATER), "blender", path, source="r.json", wall_albedo=RHO)
    bpy, mathutils, created = _fake_blender(None)
    tree = _world_stand_in(bpy, existing)
    monkeypatch.setitem(sys.modules, "bpy", bpy)
    monkeypatch.setitem(sys.modules, "mathutils", mathutils)
    exec(compile(path.read_text(), str(path), "exec"), {"__name__": "__main__"})
    assert [obj.name for obj in created] == ["spot", "lopsided"]
    world = bpy.context.scene.world
    assert world is not None and world.node_tree is tree
    if existing:
        background, output, absorption, scatter, both = tree.nodes
        assert background.bl_idname == "ShaderNodeBackground"
    else:
        output, absorption, scatter, both = tree.nodes  # the Background removed: black
    assert absorption.bl_idname == "ShaderNodeVolumeAbsorption"
    assert scatter.bl_idname == "ShaderNodeVolumeScatter" and scatter.phase == "HENYEY_GREENSTEIN"
    sigma_s = BETA * RHO / math.pi
    assert abs(absorption.inputs["Density"].default_value - (C - sigma_s)) <= 1e-9
    assert tuple(absorption.inputs["Color"].default_value[:3]) == (0.0, 0.0, 0.0)
    assert abs(scatter.inputs["Density"].default_value - sigma_s) <= 1e-9
    assert tuple(scatter.inputs["Color"].default_value[:3]) == (1.0, 1.0, 1.0)
    assert abs(scatter.inputs["Anisotropy"].default_value - G) <= 1e-9
    assert tree.made == [
        (absorption.outputs["Volume"], both.inputs[0]),
        (scatter.outputs["Volume"], both.inputs[1]),
        (both.outputs["Shader"], output.inputs["Volume"]),
    ]
    assert "sigma_s = beta rho / pi" in " ".join(path.read_text().split())


def test_ros_says_the_calibration_was_in_water(tmp_path):
    files = export_result(in_water(WATER), "ros", tmp_path / "l.launch.xml", source="r.json")
    launch = " ".join(files[0].read_text().split())
    assert "made in a medium: attenuation_per_m 0.3 ± 0.004" in launch
    ET.parse(files[0])  # still XML
    assert "medium" not in files[1].read_text()  # the URDF as in air


def test_cli_notes_that_ies_and_ldt_leave_the_medium_out(tmp_path, capsys):
    write_result(in_water(WATER), tmp_path / "w.json")
    for fmt in ("ies", "ldt"):
        out = tmp_path / OUT_NAMES[fmt]
        args = ["export", str(tmp_path / "w.json"), "--format", fmt, "--out", str(out)]
        assert main([*args, "--light", "spot"]) == 0
        err = capsys.readouterr().err
        assert "note: the result's medium (attenuation_per_m 0.3 ± 0.004" in err
        assert f"has no place in an {fmt.upper()} file" in err


def test_cli_takes_the_wall_albedo(tmp_path, capsys):
    write_result(in_water(WATER), tmp_path / "w.json")
    out = tmp_path / "w.xml"
    args = ["export", str(tmp_path / "w.json"), "--format", "mitsuba", "--out", str(out)]
    assert main(args) == 2
    assert "expected --wall-albedo RHO" in capsys.readouterr().err
    assert main([*args, "--wall-albedo", "0.5"]) == 0
    assert "albedo rho = 0.5 (--wall-albedo)" in capsys.readouterr().err
    assert abs(_mitsuba_numbers(out)["albedo"] - BETA * 0.5 / math.pi / C) <= 1e-9


def test_the_projects_surroundings_give_the_wall_albedo(tmp_path, capsys):
    """`--project` with `surroundings.wall_albedo` 0.7: sigma_s = beta 0.7 / pi; an
    explicit --wall-albedo wins."""
    data = tmp_path / "data"
    args = ["synth", str(data), "--views", "1", "--width", "96", "--height", "64"]
    assert main([*args, "--no-noise", "--quiet"]) == 0
    doc = json.loads((data / "project.json").read_text())
    doc["surroundings"] = {
        "wall_albedo": 0.7,
        "surfaces": [
            {"corner_m": [-2.0, 1.0, 0.0], "edge_u_m": [4.0, 0.0, 0.0], "edge_v_m": [0, 0, 0.5]}
            | {"albedo": 0.5}
        ],
    }
    (data / "project.json").write_text(json.dumps(doc))
    project = load_project(data / "project.json")
    result = result_of_project(project, [1.0], tmp_path / "r.json", Medium(C, BETA, G))
    out = tmp_path / "w.xml"
    args = ["export", str(result), "--format", "mitsuba", "--out", str(out), "--force"]
    assert main([*args, "--project", str(data / "project.json")]) == 0
    assert "rho = 0.7 (surroundings.wall_albedo)" in capsys.readouterr().err
    assert abs(_mitsuba_numbers(out)["albedo"] - BETA * 0.7 / math.pi / C) <= 1e-9
    assert main([*args, "--project", str(data / "project.json"), "--wall-albedo", "0.4"]) == 0
    assert abs(_mitsuba_numbers(out)["albedo"] - BETA * 0.4 / math.pi / C) <= 1e-9


@pytest.mark.parametrize(
    "broken",
    [
        {"attenuation_per_m": "x"},
        {"attenuation_per_m": math.nan},
        {"attenuation_per_m": -0.1},
        {"backscatter_per_m": math.inf},
        {"estimated": 5},
        {"estimated": None},
        {"sigma": [1.0]},
        {"sigma": {"attenuation_per_m": "a"}},
    ],
)
def test_a_broken_medium_is_refused_before_anything_is_written(broken, tmp_path, capsys):
    """Every format, ies included (which cannot hold the medium): one line, no file."""
    doc = json.loads(in_water(WATER).model_dump_json())
    doc["medium"].update(broken)
    (tmp_path / "r.json").write_text(json.dumps(doc, allow_nan=True))
    for fmt in ("opencv", "ies"):
        out = tmp_path / OUT_NAMES[fmt]
        args = ["export", str(tmp_path / "r.json"), "--format", fmt, "--out", str(out)]
        assert main([*args, *(["--light", "spot"] if fmt == "ies" else [])]) == 2
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("lightcal export: error: ")
        assert "medium" in lines[0] and not out.exists()
