"""A result is bound to its project (issue 28): `project_id` is written by calibrate and
checked by plan, render and export --project; a result file is validated as a whole
(version, shapes, rotations, sizes) with messages naming its fields."""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from lightcal.cli.main import main
from lightcal.io.project import load_project
from lightcal.io.project_identity import project_identity
from lightcal.io.result_file import read_result
from tests.test_bad_inputs import _hashes, _set


@pytest.fixture(scope="module")
def result_file(tiny_dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("result") / "result.json"
    argv = ["calibrate", str(tiny_dataset / "project.json"), "--out", str(out), "--quiet"]
    assert main(argv) in (0, 3)
    return out


def _edited_project(dataset: Path, folder: Path, edit: Callable[[dict[str, Any]], None]) -> Path:
    """A copy of the dataset in `folder` with its project edited."""
    copy = folder / "copy"
    shutil.copytree(dataset, copy)
    data = json.loads((copy / "project.json").read_text())
    edit(data)
    (copy / "project.json").write_text(json.dumps(data))
    return copy / "project.json"


def test_calibrate_writes_the_projects_identity(tiny_dataset: Path, result_file: Path) -> None:
    identity = project_identity(load_project(tiny_dataset / "project.json"))
    assert identity.startswith("sha256:") and len(identity) == len("sha256:") + 16
    assert read_result(result_file).project_id == identity


def _move_start(data: dict[str, Any]) -> None:
    data["lights"][0]["initial"]["position_m"] = [0.3, -0.2, 0.1]


def _solver_and_wall(data: dict[str, Any]) -> None:
    data["solver"] = {"max_iterations": 7}
    data["wall"] = {"model": "plastic"}


def _move_image(data: dict[str, Any]) -> None:
    data["images"][2]["T_camera_world"]["t"][2] += 0.001


def _rename_light(data: dict[str, Any]) -> None:
    data["lights"][0]["name"] = "torch"


PORT = {"distance_mm": 20.0, "thickness_mm": 10.0, "glass_index": 1.49, "water_index": 1.333}


def _camera_port(data: dict[str, Any]) -> None:
    data["camera"]["port"] = PORT


def _light_port(data: dict[str, Any]) -> None:
    data["lights"][0]["port"] = PORT


def _change_focal_length(data: dict[str, Any]) -> None:
    """The camera inline, as in the camera file but fx 1 % longer."""
    data["camera"] = {"fx": 1.01, "fy": 1.0, "cx": 0.0, "cy": 0.0}  # scaled in the test


@pytest.mark.parametrize(
    ("edit", "same"),
    [
        (_move_start, True),
        (_solver_and_wall, True),
        (_move_image, False),
        (_rename_light, False),
        (_change_focal_length, False),
        (_camera_port, False),
        (_light_port, False),
    ],
    ids=[
        "initial guess",
        "solver and wall",
        "an image's pose",
        "a light's name",
        "fx",
        "camera.port",
        "lights[0].port",
    ],
)
def test_the_identity_covers_geometry_and_lights_not_the_start(
    tiny_dataset: Path, tmp_path: Path, edit: Callable[[dict[str, Any]], None], same: bool
) -> None:
    camera = load_project(tiny_dataset / "project.json").camera
    original = project_identity(load_project(tiny_dataset / "project.json"))
    if edit is _change_focal_length:
        (fx, _, cx), (_, fy, cy) = camera.K[:2]
        inline = {"fx": fx, "fy": fy, "cx": cx, "cy": cy, "width": camera.width}
        inline["height"] = camera.height
        as_file = project_identity(
            load_project(_edited_project(tiny_dataset, tmp_path / "a", _set("camera", inline)))
        )
        assert as_file == original  # the same camera inline: the same identity
        edit = _set("camera", {**inline, "fx": 1.01 * fx})
    edited = project_identity(load_project(_edited_project(tiny_dataset, tmp_path, edit)))
    assert (edited == original) is same


def test_a_moved_project_folder_keeps_its_identity(tiny_dataset: Path, tmp_path: Path) -> None:
    moved = tmp_path / "elsewhere" / "deeper"
    shutil.copytree(tiny_dataset, moved)
    assert project_identity(load_project(moved / "project.json")) == project_identity(
        load_project(tiny_dataset / "project.json")
    )


def test_a_photometric_file_counts_by_content(tiny_dataset: Path, tmp_path: Path) -> None:
    ies = Path(__file__).parent / "data" / "photometry" / "bilateral_0_180_2019.ies"

    def with_ies(data: dict[str, Any]) -> None:
        data["lights"][0]["rid"] = {"type": "ies", "path": "light.ies"}

    project = _edited_project(tiny_dataset, tmp_path, with_ies)
    shutil.copyfile(ies, project.parent / "light.ies")
    before = project_identity(load_project(project))
    shutil.copyfile(ies, project.parent / "renamed.ies")
    data = json.loads(project.read_text())
    data["lights"][0]["rid"]["path"] = "renamed.ies"
    project.write_text(json.dumps(data))
    assert project_identity(load_project(project)) == before  # same content, other name
    (project.parent / "renamed.ies").write_text(ies.read_text() + "\n")  # other bytes
    assert project_identity(load_project(project)) != before


COMMANDS = [
    ("plan", "plan {p} --result {r} --n 1"),
    ("render", "render {p} --result {r} --out {t}/renders"),
    ("export", "export {r} --format mitsuba --out {t}/scene.xml --project {p}"),
]


@pytest.mark.parametrize(("command", "argv"), COMMANDS, ids=[c[0] for c in COMMANDS])
def test_a_result_of_another_project_is_refused_by_name(
    tiny_dataset: Path,
    result_file: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    command: str,
    argv: str,
) -> None:
    """Another project whose light has the same name: refused before any work."""
    other = _edited_project(tiny_dataset, tmp_path, _move_image)
    own = project_identity(load_project(other))
    theirs = read_result(result_file).project_id
    before = _hashes(other.parent)
    capsys.readouterr()
    fill = {"p": other, "r": result_file, "t": tmp_path}
    assert main(argv.format(**fill).split()) == 2
    assert capsys.readouterr().err == (
        f"lightcal {command}: error: {result_file}: the result is of another project "
        f"(project_id {theirs}; {other} is {own}: its camera, image poses or lights "
        "differ); calibrate this project, or give the project the result was calibrated on\n"
    )
    assert _hashes(other.parent) == before
    assert not (tmp_path / "renders").exists() and not (tmp_path / "scene.xml").exists()


def test_a_result_without_identity_is_still_read(
    tiny_dataset: Path, result_file: Path, tmp_path: Path
) -> None:
    """Results written before project_id existed (or by hand): nothing to check against."""
    data = json.loads(result_file.read_text())
    del data["project_id"]
    old = tmp_path / "old.json"
    old.write_text(json.dumps(data))
    argv = ["export", str(old), "--format", "mitsuba", "--out", str(tmp_path / "s.xml")]
    assert main([*argv, "--project", str(tiny_dataset / "project.json")]) == 0
    assert (tmp_path / "s.xml").is_file()


RESULT_CASES: list[tuple[str, Callable[[dict[str, Any]], None], str]] = [
    (
        "a newer version",
        _set("version", 99),
        "version: expected 1 (lightcal 0.1.0 reads result files of version 1), got 99",
    ),
    (
        "no lights",
        _set("lights", []),
        "lights: List should have at least 1 item after validation, not 0",
    ),
    (
        "a 2-vector position",
        _set("lights.0.position_m", [0.0, 0.1]),
        "lights.0.position_m: expected 3 numbers (x, y, z in the camera frame), got 2",
    ),
    (
        "a 2 x 2 rotation",
        _set("lights.0.R_camera_light", [[1.0, 0.0], [0.0, 1.0]]),
        "lights.0.R_camera_light: expected a 3 x 3 rotation matrix (light -> camera), got 2 x 2",
    ),
    (
        "ragged rotation",
        _set("lights.0.R_camera_light", [[1.0, 0.0, 0.0], [0.0, 1.0], [0.0, 0.0, 1.0]]),
        "lights.0.R_camera_light: expected a 3 x 3 rotation matrix (light -> camera), "
        "got rows of unequal length",
    ),
    (
        "a reflection",
        _set("lights.0.R_camera_light", [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]]),
        "lights.0.R_camera_light: expected a rotation matrix (light -> camera: max "
        "|R^T R - I| <= 1e-06, det +1), got max |R^T R - I| = 0, det -1",
    ),
    (
        "a 3-number quaternion",
        _set("lights.0.quaternion_wxyz", [1.0, 0.0, 0.0]),
        "lights.0.quaternion_wxyz: expected 4 numbers (w, x, y, z), got 3",
    ),
    ("a zero scale", _set("lights.0.scale", 0.0), "lights.0.scale: Input should be greater than 0"),
    (
        "a negative gain",
        _set("images.0.gain", -1.0),
        "images.0.gain: Input should be greater than 0",
    ),
    (
        "parameters of another size",
        _set("parameters.x", [1.0]),
        "parameters: x: expected 6 values, one per name, got 1",
    ),
    (
        "a covariance of another size",
        _set("parameters.covariance", [[1.0]]),
        "parameters: covariance: expected 6 x 6 (one row per name), got 1 x 1",
    ),
    (
        "one light twice",
        lambda d: d["lights"].append(dict(d["lights"][0])),
        "lights: each light once by name, got light twice",
    ),
]


@pytest.mark.parametrize(
    ("case", "edit", "expected"), RESULT_CASES, ids=[c[0] for c in RESULT_CASES]
)
def test_a_broken_result_is_named_by_its_field(
    result_file: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    case: str,
    edit: Callable[[dict[str, Any]], None],
    expected: str,
) -> None:
    data = json.loads(result_file.read_text())
    assert len(data["parameters"]["names"]) == 6  # the messages count on it
    edit(data)
    broken = tmp_path / "broken.json"
    broken.write_text(json.dumps(data))
    capsys.readouterr()
    argv = ["export", str(broken), "--format", "opencv", "--out", str(tmp_path / "x.yaml")]
    assert main(argv) == 2
    assert capsys.readouterr().err == f"lightcal export: error: {broken}: {expected}\n"
    assert not (tmp_path / "x.yaml").exists()


def test_an_undetermined_result_round_trips_through_json() -> None:
    """Null sigmas and covariance entries (undetermined) are read back, not refused."""
    from lightcal.io.result_file import ResultFile

    data = {
        "lights": [
            {
                "name": "light",
                "pose_kind": "symmetric",
                "position_m": [0.1, 0.0, 0.0],
                "R_camera_light": np.eye(3).tolist(),
                "quaternion_wxyz": [1.0, 0.0, 0.0, 0.0],
                "axis_camera": [0.0, 0.0, 1.0],
                "roll_deg": 0.0,
                "pitch_deg": 0.0,
                "axis_angle_from_optical_axis_deg": 0.0,
                "scale": 2.0,
                "scale_sigma": None,
                "sigma": {
                    "position_m": [None] * 3,
                    "R_camera_light": [[None] * 3] * 3,
                    "quaternion_wxyz": [None] * 4,
                    "axis_camera": [None] * 3,
                    "roll_deg": None,
                    "pitch_deg": None,
                    "axis_angle_from_optical_axis_deg": None,
                },
            }
        ],
        "offset": 0.0,
        "offset_sigma": None,
        "images": [{"name": "a", "rms": None, "pixels": 0, "gain": 1.0}],
        "iterations": 1,
        "nfev": 1,
        "status": 2,
        "message": "m",
        "converged": False,
        "cost": 1.0,
        "time_s": 0.1,
        "warnings": [],
        "parameters": {"names": ["a", "b"], "x": [1.0, 2.0], "covariance": [[math.nan] * 2] * 2},
        "undetermined": ["the data do not determine a, b"],
    }
    text = ResultFile.model_validate(data).model_dump_json()
    back = ResultFile.model_validate_json(text)
    assert back.parameters.covariance == [[None, None], [None, None]]
    assert back.images[0].rms is None


@pytest.mark.parametrize("value", ["-3", "0", "nan", "inf"])
def test_plan_checks_the_wall_size_before_any_work(
    tiny_dataset: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    value: str,
) -> None:
    import lightcal.pipeline

    def no_work(*args: object, **kwargs: object) -> None:
        raise AssertionError("images loaded before the arguments were checked")

    monkeypatch.setattr(lightcal.pipeline, "load_images", no_work)
    capsys.readouterr()
    assert main(["plan", str(tiny_dataset / "project.json"), "--wall-size", value]) == 2
    assert capsys.readouterr().err == (
        f"lightcal plan: error: --wall-size: expected the wall's width in m (> 0), "
        f"got {float(value)}\n"
    )
