"""YAML/JSON documents are bounded in aliases, size and depth, in linear time (issue 28:
an alias bomb hung `calibrate` for over 300 s)."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
import yaml

from lightcal.cli.main import main
from lightcal.errors import InputError
from lightcal.io.document import (
    MAX_ALIAS_VALUES,
    MAX_DEPTH,
    measure_document,
    read_document,
)
from lightcal.io.project import load_project

BOMB_MESSAGE = (
    "the project file has too many YAML aliases (they repeat over 100,000 values): "
    "expected a plain project file"
)


def _bomb(levels: int, refs: int) -> str:
    """`l0: &l0 [x, x, ...]`, `l1: &l1 [*l0, *l0, ...]`, ...: refs**levels values."""
    lines = [f"l0: &l0 [{', '.join(['x'] * refs)}]"]
    for i in range(1, levels):
        lines.append(f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * refs)}]")
    return "\n".join(lines) + "\n"


def test_alias_bomb_is_refused_quickly_by_calibrate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "project.yaml"
    path.write_text(_bomb(9, 9))
    out = tmp_path / "r.json"
    start = time.perf_counter()
    code = main(["calibrate", str(path), "--out", str(out), "--quiet"])
    seconds = time.perf_counter() - start
    assert code == 2
    assert capsys.readouterr().err == f"lightcal calibrate: error: {path}: {BOMB_MESSAGE}\n"
    assert seconds < 5.0  # a sanity bound (shared machines); the step count is the real test
    assert not out.exists()


def test_alias_bomb_is_measured_visiting_each_shared_list_once() -> None:
    data = yaml.safe_load(_bomb(9, 9))
    measure = measure_document(data)
    assert measure.steps == 10  # the 9 anchored lists and the root mapping, once each
    assert measure.written == 1 + 9 + 9 * 9  # the values as written: root, keys' values, refs
    # expanded: l_i holds sum_{k=1..i+1} 9**k values below it, plus itself
    expanded_levels = sum(sum(9**k for k in range(1, i + 2)) + 1 for i in range(9))
    assert measure.expanded == 1 + expanded_levels
    assert measure.depth == 10
    assert not measure.cyclic


def test_deeper_bomb_saturates_instead_of_growing() -> None:
    measure = measure_document(yaml.safe_load(_bomb(40, 9)))
    assert measure.steps == 41
    assert measure.expanded == 2**62
    assert measure.repeated > MAX_ALIAS_VALUES


def test_read_document_refuses_a_bomb_with_the_file_named(tmp_path: Path) -> None:
    path = tmp_path / "board.yaml"
    path.write_text(_bomb(9, 9))
    with pytest.raises(InputError) as info:
        read_document(path, what="board file", as_json=False)
    assert str(info.value) == (
        f"{path}: the board file has too many YAML aliases (they repeat over 100,000 "
        "values): expected a plain board file"
    )


def _repeats(count: int) -> str:
    """A list of 100 values written once and repeated through `count` aliases: each
    alias copies the list and its values (101) in place of itself (1), repeating 100."""
    return "a: &a [" + ", ".join(["1"] * 100) + "]\nb: [" + ", ".join(["*a"] * count) + "]\n"


def test_alias_limit_is_on_repeated_values(tmp_path: Path) -> None:
    at_limit = MAX_ALIAS_VALUES // 100
    path = tmp_path / "doc.yaml"
    path.write_text(_repeats(at_limit))
    data = read_document(path, what="project file", as_json=False)
    assert measure_document(data).repeated == MAX_ALIAS_VALUES
    assert len(data["b"]) == at_limit
    path.write_text(_repeats(at_limit + 1))
    with pytest.raises(InputError, match="too many YAML aliases"):
        read_document(path, what="project file", as_json=False)


def test_repeated_counts_values_an_alias_copies() -> None:
    measure = measure_document(yaml.safe_load("a: &a [1, 2]\nb: *a\nc: *a\n"))
    assert measure.repeated == 2 * 2  # each alias copies the list's 2 values
    assert measure_document(json.loads('{"a": [1, 2], "b": [1, 2]}')).repeated == 0


def test_an_alias_inside_its_anchor_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "project.yaml"
    path.write_text("a: &a [1, *a]\n")
    with pytest.raises(InputError) as info:
        read_document(path, what="project file", as_json=False)
    assert str(info.value) == (
        f"{path}: the project file contains itself through a YAML alias: "
        "expected a plain project file"
    )


@pytest.mark.parametrize("as_json", [True, False], ids=["json", "yaml"])
def test_depth_limit_still_holds(tmp_path: Path, as_json: bool) -> None:
    path = tmp_path / ("doc.json" if as_json else "doc.yaml")
    path.write_text("[" * MAX_DEPTH + "]" * MAX_DEPTH)
    read_document(path, what="project file", as_json=as_json)  # exactly the limit: read
    path.write_text("[" * (MAX_DEPTH + 1) + "]" * (MAX_DEPTH + 1))
    with pytest.raises(InputError) as info:
        read_document(path, what="project file", as_json=as_json)
    assert str(info.value) == f"{path}: the project file is nested more than 64 levels deep"


def test_depth_through_aliases_is_the_expanded_depth(tmp_path: Path) -> None:
    # 33 levels of lists, referenced from inside a 33-deep list: 66 deep once expanded
    deep = "[" * 33 + "]" * 33
    path = tmp_path / "doc.yaml"
    path.write_text(f"a: &a {deep}\nb: {'[' * 32}*a{']' * 32}\n")
    with pytest.raises(InputError, match="nested more than 64 levels deep"):
        read_document(path, what="project file", as_json=False)


def test_project_with_a_few_anchors_still_loads(tiny_dataset: Path) -> None:
    project = json.loads((tiny_dataset / "project.json").read_text())
    shared = project["images"][0]["T_camera_world"]["covariance"]
    for image in project["images"]:
        image["T_camera_world"]["covariance"] = shared  # safe_dump writes &id001 / *id001
    text = yaml.safe_dump(project)
    assert "&id001" in text and "*id001" in text
    path = tiny_dataset / "anchors.yaml"
    path.write_text(text)
    try:
        loaded = load_project(path)
    finally:
        path.unlink()
    assert len(loaded.views) == len(project["images"])


def test_a_camera_file_bomb_is_refused_with_the_file_named(tmp_path) -> None:
    from lightcal.io.camera_file import read_camera

    lines = ["a0: &a0 [1, 1, 1, 1, 1, 1, 1, 1, 1]"]
    lines += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 9) + "]" for i in range(1, 10)]
    path = tmp_path / "camera.yaml"
    path.write_text("\n".join(lines) + "\ncamera_matrix: *a9\n")
    with pytest.raises(InputError) as info:
        read_camera(path)
    assert str(info.value) == (
        f"{path}: the camera file has too many YAML aliases (they repeat over 100,000 "
        "values): expected a plain camera file"
    )
