"""Outputs never replace an input, never land outside their folder, are checked first."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from lightcal.cli.main import main
from lightcal.errors import InputError
from lightcal.io.outputs import inside, project_inputs, safe_name, safe_names
from lightcal.io.project import load_project


@pytest.fixture(scope="module")
def dataset(tiny_dataset: Path) -> Path:
    return tiny_dataset


def _hashes(folder: Path) -> dict[str, str]:
    return {
        p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def _error(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    return err.rstrip("\n")


def test_project_inputs_name_every_file_the_project_reads(dataset: Path) -> None:
    project = load_project(dataset / "project.json")
    roles = {p.name: role for p, role in project_inputs(project).items()}
    assert roles["project.json"] == "the project file"
    assert roles[project.image_paths[0].name] == f"image {project.names[0]}"
    assert len(roles) == 1 + len(project.image_paths) + (project.spec.camera.path is not None)


def test_calibrate_refuses_outputs_onto_inputs_before_any_work(
    dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    project = dataset / "project.json"
    before = _hashes(dataset)
    image = load_project(project).image_paths[1]
    base = ["calibrate", str(project), "--quiet"]
    assert _error([*base, "--out", str(project)], capsys) == (
        f"lightcal calibrate: error: {project}: --out: is the project file, an input of the "
        "project; write elsewhere"
    )
    name = load_project(project).names[1]
    assert _error([*base, "--out", str(image)], capsys) == (
        f"lightcal calibrate: error: {image}: --out: is image {name}, an input of the project; "
        "write elsewhere"
    )
    assert _error([*base, "--out", str(tmp_path / "no" / "r.json")], capsys) == (
        f"lightcal calibrate: error: {tmp_path / 'no' / 'r.json'}: --out: the folder "
        f"{tmp_path / 'no'} does not exist; create it first"
    )
    assert _error([*base, "--out", str(tmp_path)], capsys) == (
        f"lightcal calibrate: error: {tmp_path}: --out: is a folder; expected the path of a "
        "file to write"
    )
    long_name = tmp_path / ("r" * 300 + ".json")
    assert _error([*base, "--out", str(long_name)], capsys) == (
        f"lightcal calibrate: error: {long_name}: --out: the file name is longer than 255 bytes"
    )
    out = tmp_path / "r.json"
    assert _error([*base, "--out", str(out), "--report", str(image.parent)], capsys) == (
        f"lightcal calibrate: error: {image.parent}: --report: holds image "
        f"{load_project(project).names[0]}, an input of the project; choose another folder"
    )
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "notes.txt").write_text("mine")
    assert _error([*base, "--out", str(out), "--report", str(tmp_path / "full")], capsys) == (
        f"lightcal calibrate: error: {tmp_path / 'full'}: --report: the folder is not empty; "
        "use --force to write into it"
    )
    assert not out.exists()  # refused before the solve
    assert _hashes(dataset) == before


def test_render_writes_hostile_image_names_inside_its_folder(
    dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = json.loads((dataset / "project.json").read_text())
    hostile = ["../../escaped", "/tmp/absolute", "a/b", ".hidden"]
    for image, name in zip(src["images"], hostile, strict=False):
        image["name"] = name
        image["path"] = str(dataset / image["path"])
    if isinstance(src["camera"], dict) and src["camera"].get("path"):
        src["camera"]["path"] = str(dataset / src["camera"]["path"])
    for light in src["lights"]:
        if light["rid"].get("path"):
            light["rid"]["path"] = str(dataset / light["rid"]["path"])
    work = tmp_path / "work"
    work.mkdir()
    (work / "project.json").write_text(json.dumps(src))
    result = tmp_path / "result.json"
    assert main(["calibrate", str(work / "project.json"), "--out", str(result), "--quiet"]) in (
        0,
        3,
    )
    out = tmp_path / "renders" / "deep"
    (tmp_path / "renders").mkdir()
    render = ["render", str(work / "project.json"), "--result", str(result), "--out", str(out)]
    assert main(render) == 0
    assert (
        main(["render", str(work / "project.json"), "--result", str(result), "--out", str(out)])
        == 2
    )  # not empty now
    capsys.readouterr()
    written = sorted(p.name for p in out.iterdir())
    assert written == sorted(
        f"{safe_name(n)}_{kind}" for n in hostile for kind in ("compare.png", "rendered.tif")
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["renders", "result.json", "work"]
    assert not (tmp_path / "escaped_rendered.tif").exists()


def test_names_from_the_data_become_one_plain_part() -> None:
    assert safe_name("../../x") == "___x"
    assert safe_name("/etc/passwd") == "_etc_passwd"
    assert safe_name("view 01") == "view_01"
    assert safe_name(".hidden") == "hidden"
    assert safe_name("..") == "unnamed"
    assert safe_names(["a b", "a_b", "a/b"]) == ["a_b", "a_b_2", "a_b_3"]


def test_inside_refuses_paths_out_of_the_folder(tmp_path: Path) -> None:
    assert inside(tmp_path, "x.png") == tmp_path / "x.png"
    with pytest.raises(InputError, match="refusing to write outside"):
        inside(tmp_path, "../x.png")
