"""A result records the flat ports it was calibrated through (`ResultFile.ports`), and an
export without the project says that it leaves them out."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from lightcal.cli.main import main
from lightcal.io.result_file import read_result

PORT = {"distance_mm": 20.0, "thickness_mm": 10.0, "glass_index": 1.49, "water_index": 1.333}
LIGHT_PORT = {"distance_mm": 15.0, "thickness_mm": 8.0, "glass_index": 1.52, "water_index": 1.34}


@pytest.fixture(scope="module")
def ported(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A noise-free 160 x 120 synth through the camera's port, its project given the
    light's port too (the fit is then poor: only the record is tested), calibrated."""
    folder = tmp_path_factory.mktemp("ported") / "data"
    args = ["synth", str(folder), "--views", "3", "--width", "160", "--height", "120"]
    assert main([*args, "--no-noise", "--quiet", "--port", "20", "10", "1.49", "1.333"]) == 0
    project = folder / "project.json"
    doc = json.loads(project.read_text())
    doc["camera"]["port"] = PORT
    doc["lights"][0]["port"] = LIGHT_PORT
    project.write_text(json.dumps(doc))
    result = folder / "result.json"
    argv = ["calibrate", str(project), "--out", str(result), "--quiet", "--allow-misfit"]
    assert main(argv) == 0
    return project, result


def test_the_result_records_the_ports(ported: tuple[Path, Path]) -> None:
    _, result = ported
    record = read_result(result).ports
    assert record is not None and record.camera is not None
    assert record.camera.model_dump() == PORT
    name = read_result(result).lights[0].name
    assert {k: v.model_dump() for k, v in record.lights.items()} == {name: LIGHT_PORT}
    assert json.loads(result.read_text())["ports"]["camera"]["distance_mm"] == 20.0


def test_an_export_without_the_project_says_it_leaves_the_ports_out(
    ported: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    project, result = ported
    name = read_result(result).lights[0].name
    out = tmp_path / "lights.yaml"
    assert main(["export", str(result), "--format", "opencv", "--out", str(out)]) == 0
    assert (
        "note: the result was calibrated through flat ports (camera.port, the port of "
        f"{name!r}); without --project the export carries the lights alone, without their "
        "ports"
    ) in capsys.readouterr().err
    assert "camera_port" not in out.read_text()
    with_project = tmp_path / "with.yaml"
    args = ["export", str(result), "--format", "opencv", "--out", str(with_project)]
    assert main([*args, "--project", str(project)]) == 0
    assert "without --project" not in capsys.readouterr().err
    assert "camera_port" in with_project.read_text()


def test_a_result_without_ports_records_none(tiny_dataset: Path, tmp_path: Path) -> None:
    out = tmp_path / "result.json"
    argv = ["calibrate", str(tiny_dataset / "project.json"), "--out", str(out), "--quiet"]
    assert main(argv) in (0, 3)
    assert read_result(out).ports is None
    assert json.loads(out.read_text())["ports"] is None
