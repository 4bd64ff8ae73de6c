"""The Blender export without Blender: the embedded IES table as Cycles reads it, the camera.

Cycles' reading of IES data is modelled in tests/cycles_ies.py from Blender's source; the
renders in tests/test_export_blender_render.py (with `bpy`) confirm the model end to end.
Here: the embedded table, looked up as Cycles does, is lightcal's RID within 1e-4 for a
measured profile (the bundled sample's) and a light without rotational symmetry; the
model itself on hand-checked tables; and the camera numbers and how the snippet sets them
(a stand-in `bpy`).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from types import SimpleNamespace
from unittest import mock

import numpy as np
import pytest

from lightcal.cli.main import main
from lightcal.core.camera import Camera
from lightcal.io.export_blender import (
    CYCLES_WATTS_PER_CANDELA,
    IES_STRENGTH,
    blender_camera_numbers,
    cycles_ies_table,
    cycles_ies_text,
)
from lightcal.io.export_lights import LightRID, given_rid_description, light_rid
from lightcal.io.export_mitsuba import rid_values
from lightcal.io.photometric_table import PhotometricTable
from lightcal.io.project import load_project
from lightcal.resources import sample_project_dir
from tests import calib_scenes as cs
from tests.cycles_ies import WATTS_PER_CANDELA, cycles_lookup
from tests.export_render import result_of_project

RID_TOL = 1e-4


def _table_rid(description: dict | None) -> LightRID:
    rid = light_rid(SimpleNamespace(name="light", rid=description), "r.json")  # type: ignore[arg-type]
    assert rid is not None
    return rid


def _cycles_value(rid: LightRID, theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """The exported light's relative intensity as Cycles computes it (IES node strength
    `IES_STRENGTH`), at light-frame directions (theta, phi)."""
    text = cycles_ies_text(cycles_ies_table(rid, "light"), "test")
    c = np.mod(phi - math.pi / 2, 2 * math.pi)  # Cycles' horizontal angle: phi - 90 degrees
    return cycles_lookup(text, theta, c) * IES_STRENGTH


@pytest.mark.parametrize("which", ["sample", "general"])
def test_cycles_reads_the_embedded_table_as_the_rid(which):
    if which == "sample":
        rid = load_project(sample_project_dir() / "project.json").lights[0].initial.rid
    else:
        rid = cs.general_rid()
    table = _table_rid(given_rid_description(rid))
    rng = np.random.default_rng(3)
    theta = np.radians(rng.uniform(0.0, 85.0, 20000))
    phi = rng.uniform(0.0, 2 * math.pi, theta.size)
    expected = rid_values(table, theta, phi)
    got = _cycles_value(table, theta, phi)
    assert np.max(np.abs(got - expected)) <= RID_TOL
    assert expected.max() > 0.9 and expected.min() < 0.05  # the beam and its edge were seen
    if which == "general":  # the azimuth matters: the mirrored convention (C = -phi) fails
        text = cycles_ies_text(cycles_ies_table(table, "light"), "test")
        mirrored = cycles_lookup(text, theta, np.mod(-phi, 2 * math.pi)) * IES_STRENGTH
        assert np.max(np.abs(mirrored - expected)) > 100 * RID_TOL


def test_the_ies_node_strength_undoes_cycles_candela_factor():
    assert pytest.approx(CYCLES_WATTS_PER_CANDELA, rel=1e-12) == WATTS_PER_CANDELA
    assert pytest.approx(1.0, rel=1e-15) == CYCLES_WATTS_PER_CANDELA * IES_STRENGTH


def _ies(v_deg, h_deg, candela) -> str:
    rows = "\n".join(" ".join(str(c) for c in row) for row in candela)
    return (
        "IESNA:LM-63-2002\n[TEST] x\nTILT=NONE\n"
        f"1 -1 1 {len(v_deg)} {len(h_deg)} 1 2 0 0 0\n1 1 0\n"
        f"{' '.join(map(str, v_deg))}\n{' '.join(map(str, h_deg))}\n{rows}\n"
    )


def test_the_cycles_model_on_hand_checked_tables():
    """A constant table gives the candela factor up to its last interval, where the spline
    takes a zero beyond the table (x^2 (1 - x) more), and zero from the last angle on; on
    a plane's samples the lookup is the sample (Catmull-Rom passes through them)."""
    constant = _ies([0, 45, 90], [0], [[2.0, 2.0, 2.0]])
    v = np.radians([0.0, 10.0, 44.0, 60.0, 89.9, 90.01, 120.0])
    got = cycles_lookup(constant, v, np.full_like(v, 1.0)) / WATTS_PER_CANDELA
    x = (np.degrees(v[3:5]) - 45.0) / 45.0
    np.testing.assert_allclose(got[:5], [2.0, 2.0, 2.0, *(2.0 + x**2 * (1 - x))], rtol=1e-6)
    assert got[5] == got[6] == 0.0
    rows = [[1.0] * 4, [2.0] * 4, [3.0] * 4, [4.0] * 4, [1.0] * 4]
    planes = _ies([0, 30, 60, 90], [0, 90, 180, 270, 360], rows)
    h = np.radians([0.0, 90.0, 180.0, 270.0])
    got = cycles_lookup(planes, np.radians(np.full(4, 30.0)), h) / WATTS_PER_CANDELA
    np.testing.assert_allclose(got, [1, 2, 3, 4], rtol=1e-6)


def test_camera_numbers_of_a_centred_and_an_offset_camera():
    centred = Camera.from_params(fx=500, fy=500, cx=99.5, cy=49.5, width=200, height=100)
    numbers = blender_camera_numbers(centred)
    assert numbers["shift_x"] == 0.0 == numbers["shift_y"]
    assert numbers["lens_mm"] == pytest.approx(500 * 36 / 200)
    assert numbers["pixel_aspect_x"] == 1.0 == numbers["pixel_aspect_y"]
    offset = Camera.from_params(fx=432, fy=420, cx=251.3, cy=150.2, width=480, height=320)
    numbers = blender_camera_numbers(offset)
    assert numbers["shift_x"] == pytest.approx((239.5 - 251.3) / 480)
    assert numbers["shift_y"] == pytest.approx((150.2 - 159.5) * 432 / (420 * 480))
    assert numbers["pixel_aspect_y"] == pytest.approx(432 / 420)
    assert numbers["pixel_aspect_x"] == 1.0


def _run_with_stand_in(snippet: Path) -> mock.MagicMock:
    """Run the snippet against a `bpy` stand-in that records what it sets; the camera."""
    bpy = mock.MagicMock()
    emission = SimpleNamespace(type="EMISSION", inputs={"Strength": mock.MagicMock()})
    bpy.data.lights.new.return_value.node_tree.nodes = mock.MagicMock()
    bpy.data.lights.new.return_value.node_tree.nodes.__iter__.side_effect = lambda: iter([emission])
    with mock.patch.dict(sys.modules, {"bpy": bpy, "mathutils": mock.MagicMock()}):
        exec(compile(snippet.read_text(), str(snippet), "exec"), {"__name__": "__main__"})
    return bpy


def test_the_snippet_gives_the_scene_camera_the_projects_intrinsics(tmp_path):
    args = ["synth", str(tmp_path / "data"), "--views", "2", "--width", "480", "--height", "320"]
    options = ["--cx", "251.3", "--cy", "150.2", "--fy", "420", "--no-noise", "--quiet"]
    assert main([*args, *options]) == 0
    project_path = tmp_path / "data" / "project.json"
    project = load_project(project_path)
    result = result_of_project(project, [2.0], tmp_path / "result.json")
    out = tmp_path / "lights.py"
    export = ["export", str(result), "--format", "blender", "--out", str(out)]
    assert main([*export, "--project", str(project_path)]) == 0
    bpy = _run_with_stand_in(out)
    scene = bpy.context.scene
    expected = blender_camera_numbers(project.camera)
    data = scene.camera.data
    assert data.sensor_fit == "HORIZONTAL" and data.type == "PERSP"
    assert data.lens == expected["lens_mm"] and data.sensor_width == 36.0
    assert (data.shift_x, data.shift_y) == (expected["shift_x"], expected["shift_y"])
    render = scene.render
    assert (render.resolution_x, render.resolution_y) == (480, 320)
    assert render.resolution_percentage == 100
    assert render.pixel_aspect_y == pytest.approx(432 / 420)
    light = bpy.data.lights.new.return_value
    assert light.energy == pytest.approx(4 * math.pi * 2.0) and light.shadow_soft_size == 0.0
    text = out.read_text()
    assert "no lens distortion" in text and "fx 432 px" in text
    # without the project: the scene camera is left alone
    bare = tmp_path / "bare.py"
    assert main(["export", str(result), "--format", "blender", "--out", str(bare)]) == 0
    bpy = _run_with_stand_in(bare)
    assert not isinstance(bpy.context.scene.render.resolution_x, int)
    assert "No project was given" in bare.read_text()


def test_a_rid_beyond_90_degrees_keeps_its_back_half():
    theta_deg = [0.0, 60.0, 120.0, 180.0]
    rid = _table_rid({"theta_deg": theta_deg, "values": [1.0, 0.8, 0.4, 0.2]})
    table = cycles_ies_table(rid, "wide")
    assert isinstance(table, PhotometricTable) and table.vertical_deg[-1] == 180.0
    theta = np.radians([10.0, 100.0, 150.0])
    got = _cycles_value(rid, theta, np.zeros(3))
    np.testing.assert_allclose(got, rid_values(rid, theta, np.zeros(3)), atol=RID_TOL)
