"""Degenerate capture sets (issue 28): one photo given twice is refused; copies of one
camera pose are warned about in the result (they shrink the sigmas without information)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from lightcal.errors import InputError
from lightcal.io.project import load_project
from lightcal.pipeline import calibrate_project


def _copy(dataset: Path, folder: Path) -> tuple[Path, dict]:
    copy = folder / "data"
    shutil.copytree(dataset, copy)
    return copy, json.loads((copy / "project.json").read_text())


def test_one_photo_given_twice_is_refused(tiny_dataset: Path, tmp_path: Path) -> None:
    copy, data = _copy(tiny_dataset, tmp_path)
    again = dict(data["images"][1], name="again")
    data["images"].append(again)
    (copy / "project.json").write_text(json.dumps(data))
    with pytest.raises(InputError) as refused:
        load_project(copy / "project.json")
    assert str(refused.value) == (
        f"{copy / 'project.json'}: images[4].path: the same file as images[1] (view_01.png): "
        "a copy adds no information and would count its noise twice; expected each photo once"
    )


def test_copies_of_one_pose_are_warned_about(tiny_dataset: Path, tmp_path: Path) -> None:
    copy, data = _copy(tiny_dataset, tmp_path)
    shutil.copyfile(copy / "images" / "view_01.png", copy / "images" / "copy.png")
    data["images"].append(dict(data["images"][1], name="copy", path="images/copy.png"))
    (copy / "project.json").write_text(json.dumps(data))
    _, _, result = calibrate_project(load_project(copy / "project.json"))
    same = [w for w in result.warnings if "taken from one camera pose" in w]
    assert same == [
        "images view_01, copy were taken from one camera pose (within 2 mm and 0.2 deg): a "
        "repeated view adds no information about the light but counts its noise again, so "
        "the sigmas are too small; keep one of them, or move the camera between shots"
    ]
    _, _, clean = calibrate_project(load_project(tiny_dataset / "project.json"))
    assert not [w for w in clean.warnings if "camera pose" in w]
