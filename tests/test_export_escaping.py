"""Hostile strings in a result reach every exported file only escaped (issue 28).

Each format's file is read back with its real parser (Python's `ast` for the Blender
snippet, ElementTree for Mitsuba, lightcal's IES/EULUMDAT readers, cv2.FileStorage) and
compared with the export of the same result under benign names: same structure, same
numbers, the hostile text present only as data.
"""

from __future__ import annotations

import ast
import xml.etree.ElementTree as ET
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lightcal.io.escaping import (
    markdown_prose,
    markdown_text,
    plain_line,
    xml_attribute,
    xml_comment,
)
from lightcal.io.eulumdat import read_ldt
from lightcal.io.export import export_files
from lightcal.io.ies import read_ies
from lightcal.io.result_file import (
    ImageResult,
    LightResultModel,
    Parameters,
    ResultFile,
)
from tests.export_render import placeholder_sigma

HOSTILE = [
    '"""; import os; os.system(\'x\') #',
    "'''; __import__('os').system('x') #",
    '</light><shape type="sphere"/>',
    "--><shape type='sphere'/><!--",
    "\nTILT=INCLUDE\n",
    "a\r\nTILT=INCLUDE\r\n1 2 3",
    "\x00nul\x1b[31m\x7f",
    "x" * 20_000,
    "ünïcødé ☃ 光 \u2028 \u0085 e\u0301",
    "%YAML 1.0\n---\nname: x",
    "| a | b |\n# heading [link](http://x) ![img](http://x/i.png) <script>x</script>",
    "{version} {lights} %s",
    '"',
    '"a" , evil: "b"',  # cv2 writes a string in matching quotes as is
    "'a\\' x: 'b'",
    "null",  # cv2 writes a YAML keyword bare and reads it back as empty
    "True",
]

BENIGN = "light"


def _light(name: str, *, kind: str = "general", rid: bool = True) -> LightResultModel:
    theta = np.linspace(0.0, 90.0, 10)
    return LightResultModel(
        name=name,
        pose_kind=kind,
        position_m=[0.1, -0.05, 0.02],
        R_camera_light=np.eye(3).tolist(),
        quaternion_wxyz=[1.0, 0.0, 0.0, 0.0],
        axis_camera=[0.0, 0.0, 1.0],
        roll_deg=0.0,
        pitch_deg=0.0,
        axis_angle_from_optical_axis_deg=0.0,
        scale=1.0,
        scale_sigma=0.01,
        sigma=placeholder_sigma(),
        rid={
            "model": "cos_power",
            "theta_deg": theta.tolist(),
            "values": (np.cos(np.radians(theta)) ** 3).clip(0.0).tolist(),
        }
        if rid
        else None,
    )


def _result(name: str, version: str = "0.1.0", text: str = "ok") -> ResultFile:
    return ResultFile(
        lightcal_version=version,
        project=text,
        lights=[_light(name), _light(name + "2", kind="isotropic", rid=False)],
        offset=0.0,
        offset_sigma=None,
        images=[ImageResult(name=text, rms=0.1, pixels=10, gain=1.0)],
        iterations=1,
        nfev=1,
        status=1,
        message=text,
        converged=True,
        cost=1.0,
        time_s=0.1,
        warnings=[text],
        parameters=Parameters(names=[text], x=[0.0], covariance=[[1.0]]),
    )


def _export(result: ResultFile, fmt: str, tmp_path: Path) -> bytes:
    files = export_files(
        result,
        fmt,
        tmp_path / f"out.{fmt}",
        source="result.json",
        light_name=None if fmt not in ("ies", "ldt") else result.lights[0].name,
    )
    return files[tmp_path / f"out.{fmt}"]


# ---------------------------------------------------------------------------- blender


def _code_shape(source: bytes) -> str:
    """The snippet's AST with every string constant blanked: its code, not its data."""
    tree = ast.parse(source)
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            node.value = ""
    return ast.dump(tree)


def _assigned(source: bytes, name: str):
    for node in ast.parse(source).body:
        if isinstance(node, ast.Assign) and ast.unparse(node.targets[0]) == name:
            return ast.literal_eval(node.value)
    raise AssertionError(f"no {name} in the snippet")


@pytest.mark.parametrize("hostile", HOSTILE)
def test_blender_snippet_holds_hostile_strings_as_literals_only(hostile, tmp_path):
    benign = _export(_result(BENIGN), "blender", tmp_path)
    snippet = _export(_result(hostile, version=hostile), "blender", tmp_path)
    assert _code_shape(snippet) == _code_shape(benign)  # no call, import or name added
    imports = [
        n for n in ast.walk(ast.parse(snippet)) if isinstance(n, ast.Import | ast.ImportFrom)
    ]
    assert [ast.unparse(n) for n in imports] == ["import bpy", "from mathutils import Matrix"]
    lights = _assigned(snippet, "LIGHTS")
    assert [light["name"] for light in lights] == [hostile, hostile + "2"]
    assert _assigned(snippet, "LIGHTCAL_VERSION") == plain_line(hostile)
    docstring = ast.get_docstring(ast.parse(snippet))
    assert docstring is not None and "import os" not in docstring and "TILT" not in docstring


# ---------------------------------------------------------------------------- mitsuba


def _xml_with_comments(data: bytes) -> ET.Element:
    parser = ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))
    parser.feed(data)
    return parser.close()


@pytest.mark.parametrize("hostile", HOSTILE)
def test_mitsuba_xml_holds_hostile_strings_as_attribute_text(hostile, tmp_path):
    benign = _xml_with_comments(_export(_result(BENIGN), "mitsuba", tmp_path))
    data = _export(_result(hostile, version=hostile), "mitsuba", tmp_path)
    root = _xml_with_comments(data)
    assert [e.tag for e in root.iter()] == [e.tag for e in benign.iter()]
    assert [e.attrib.keys() for e in root.iter()] == [e.attrib.keys() for e in benign.iter()]
    assert ET.fromstring(data).find("shape") is None
    ids = [e.get("id") for e in root.iter("emitter")]
    assert ids == [plain_line(hostile), plain_line(hostile + "2")]
    assert len(data.decode("utf-8").splitlines()) == len(
        _export(_result(BENIGN), "mitsuba", tmp_path).decode().splitlines()
    )


# ------------------------------------------------------------------------ photometric


@pytest.mark.parametrize("hostile", HOSTILE)
@pytest.mark.parametrize("fmt", ["ies", "ldt"])
def test_photometric_headers_keep_hostile_names_on_their_line(hostile, fmt, tmp_path):
    read = read_ies if fmt == "ies" else read_ldt
    benign_data = _export(_result(BENIGN), fmt, tmp_path)
    data = _export(_result(hostile), fmt, tmp_path)
    (tmp_path / f"benign.{fmt}").write_bytes(benign_data)
    (tmp_path / f"hostile.{fmt}").write_bytes(data)
    benign, table = read(tmp_path / f"benign.{fmt}"), read(tmp_path / f"hostile.{fmt}")
    np.testing.assert_array_equal(table.vertical_deg, benign.vertical_deg)
    np.testing.assert_array_equal(table.horizontal_deg, benign.horizontal_deg)
    np.testing.assert_array_equal(table.candela, benign.candela)
    text = data.decode("utf-8")
    lines = text.split("\r\n")
    benign_lines = benign_data.decode("utf-8").split("\r\n")
    # a value's line breaks continue on [MORE] lines (LM-63), never start a line of their own
    assert len([line for line in lines if not line.startswith("[MORE]")]) == len(benign_lines)
    assert not any(c in text.replace("\r\n", "") for c in "\x00\r\n\x1b\x7f\u2028\x85")
    if fmt == "ies":
        assert all(len(line) <= 256 for line in lines)
        assert [line for line in lines if line.replace(" ", "").startswith("TILT=")] == [
            "TILT=NONE"
        ]
        assert "INCLUDE" not in table.luminaire or "TILT=INCLUDE" in hostile
    else:
        assert all(len(line) <= 78 for line in lines)
        assert table.luminaire == plain_line(hostile, max_chars=78)


# ---------------------------------------------------------------------------- opencv


@pytest.mark.parametrize("hostile", HOSTILE)
def test_opencv_yaml_reads_back_the_written_strings(hostile, tmp_path):
    data = _export(_result(hostile, version=hostile), "opencv", tmp_path)
    fs = cv2.FileStorage(data.decode("utf-8"), cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
    assert fs.getNode("lightcal_version").string() == plain_line(hostile)
    assert int(fs.getNode("lights_count").real()) == 2
    lights = fs.getNode("lights")
    assert lights.size() == 2
    assert lights.at(0).getNode("name").string() == plain_line(hostile)
    assert lights.at(1).getNode("name").string() == plain_line(hostile + "2")
    np.testing.assert_array_equal(
        lights.at(0).getNode("position_m").mat().ravel(), [0.1, -0.05, 0.02]
    )
    fs.release()


# --------------------------------------------------------------------------- markdown


@pytest.mark.parametrize("hostile", HOSTILE)
def test_markdown_helpers_leave_no_markup(hostile):
    for text in (markdown_text(hostile), markdown_prose(hostile)):
        assert "\n" not in text and "<" not in text and "](" not in text.replace("\\](", "")
    name = markdown_text(hostile)
    assert "|" not in name.replace("\\|", "")
    assert not name.startswith("#")


def test_xml_helpers_give_well_formed_xml():
    for hostile in HOSTILE:
        element = ET.fromstring(
            f"<a b={xml_attribute(hostile)}><!-- {xml_comment(hostile)} --></a>"
        )
        assert element.get("b") == plain_line(hostile)


# ------------------------------------------------------------------------------- fuzz


@settings(max_examples=50, deadline=None)
@given(name=st.text(min_size=1, max_size=300), version=st.text(max_size=300))
def test_fuzz_every_format_escapes_random_names_and_versions(name, version, tmp_path_factory):
    tmp_path = tmp_path_factory.mktemp("fuzz")
    result = _result(name, version=version)
    benign_shape = _code_shape(_export(_result(BENIGN), "blender", tmp_path))
    snippet = _export(result, "blender", tmp_path)
    assert _code_shape(snippet) == benign_shape
    assert [light["name"] for light in _assigned(snippet, "LIGHTS")] == [name, name + "2"]
    root = ET.fromstring(_export(result, "mitsuba", tmp_path))
    assert [e.get("id") for e in root.iter("emitter")] == [plain_line(name), plain_line(name + "2")]
    fs = cv2.FileStorage(
        _export(result, "opencv", tmp_path).decode("utf-8"),
        cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY,
    )
    assert fs.getNode("lights").at(0).getNode("name").string() == plain_line(name)
    assert fs.getNode("lightcal_version").string() == plain_line(version)
    for fmt, read in (("ies", read_ies), ("ldt", read_ldt)):
        path = tmp_path / f"fuzz.{fmt}"
        path.write_bytes(_export(result, fmt, tmp_path))
        assert read(path).candela.shape[-1] >= 10


def _summary(name: str):
    """The report's Markdown summary of a one-light, one-image result named `name`."""
    from types import SimpleNamespace as NS

    from lightcal.report import _summary_markdown

    light = NS(
        name=name,
        pose_kind="general",
        pose=NS(
            t_camera_light=[0.1, 0.0, 0.5],
            axis_camera=[0.0, 0.0, 1.0],
            roll_deg=1.0,
            pitch_deg=2.0,
            axis_angle_from_optical_axis_deg=2.2,
        ),
        sigma=NS(
            t_camera_light=[1e-3] * 3,
            roll_deg=0.1,
            pitch_deg=0.1,
            axis_angle_from_optical_axis_deg=0.1,
        ),
        scale=1.0,
        scale_sigma=0.01,
    )
    result = NS(
        converged=True,
        iterations=3,
        status=2,
        message=name,
        pixels_used=[10],
        time_s=0.1,
        lights=[light],
        warnings=[f"light {name!r} is dim"],
        image_names=[name],
        per_image_rms=[0.1],
        wall={"model": name},
        fit=None,
        uncertainty_terms=[name],
        start=name,
        start_costs=[],
        medium={},  # air
        fall_off=None,
        ambient=None,
        ambient_sigma=None,
        albedo_map=None,
    )
    project = NS(path=Path(name.replace("/", "_") or "p"))
    return _summary_markdown(project, result, [(name, 0.1)])  # type: ignore[arg-type]


@pytest.mark.parametrize("hostile", HOSTILE)
def test_report_summary_shows_hostile_names_as_text(hostile):
    benign = _summary(BENIGN).splitlines()
    lines = _summary(hostile).splitlines()
    assert len(lines) == len(benign)  # no name adds a line, heading or list item
    assert [line[:2] for line in lines] == [line[:2] for line in benign]
    table = [line for line in lines if line.startswith("| ")]
    assert all(line.replace("\\|", "").count("|") == 5 for line in table)
    text = "\n".join(lines)
    assert "<" not in text and "](http" not in text.replace("\\](http", "")
