"""The project file: validation errors naming the field, paths, YAML/JSON, image formats."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest
import tifffile
import yaml

from lightcal.core.pose import axis_from_paper_angles
from lightcal.core.rid import CosPowerRID, GaussianRID, IsotropicRID
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.core.scene import View
from lightcal.errors import InputError
from lightcal.io.camera_file import write_camera
from lightcal.io.project import (
    ProjectFile,
    load_project,
    parse_project,
    project_schema,
    save_project,
)
from lightcal.pipeline import load_images
from tests import calib_scenes as cs

W, H = 40, 30


def _views() -> list[View]:
    return [
        View.looking_at(np.array([0.1, 0.0, 1.0]), np.array([0.1, 0.0, 0.0])),
        View.looking_at(np.array([0.4, -0.2, 1.5]), np.array([0.0, 0.1, 0.0])),
        View.looking_at(np.array([-0.3, 0.3, 0.8]), np.array([0.0, 0.0, 0.0])),
    ]


def _pose(view: View) -> dict:
    return {"R": view.R_camera_world.tolist(), "t": view.t_camera_world.tolist()}


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    """A project folder: camera.yaml, images/a.npy, b.npy, c.npy (W x H floats)."""
    write_camera(cs.small_camera(width=W, height=H), tmp_path / "camera.yaml")
    (tmp_path / "images").mkdir()
    for k, name in enumerate("abc"):
        np.save(tmp_path / "images" / f"{name}.npy", np.full((H, W), 10.0 + k))
    return tmp_path


def _doc() -> dict:
    return {
        "version": 1,
        "camera": {"path": "camera.yaml"},
        "images": [
            {"path": f"images/{name}.npy", "T_camera_world": _pose(v)}
            for name, v in zip("abc", _views(), strict=True)
        ],
        "lights": [
            {
                "name": "led",
                "rid": {"type": "half_angle", "half_angle_deg": 30},
                "initial": {"position_m": [0.1, 0.0, 0.0]},
            }
        ],
    }


def _write(folder: Path, doc: dict, name: str = "project.json") -> Path:
    path = folder / name
    if name.endswith(".json"):
        path.write_text(json.dumps(doc, indent=1))
    else:
        path.write_text(yaml.safe_dump(doc))
    return path


def _error(folder: Path, doc: dict, name: str = "project.json") -> str:
    path = _write(folder, doc, name)
    with pytest.raises(InputError) as info:
        load_project(path)
    return str(info.value)


# -------------------------------------------------------------------------------- errors


def test_unknown_field(folder):
    doc = _doc()
    doc["images"][2]["exposure_time"] = 0.01
    msg = _error(folder, doc)
    assert (
        msg == f"{folder / 'project.json'}: images[2].exposure_time: Extra inputs are not permitted"
    )
    doc = _doc()
    doc["colour"] = "red"
    assert _error(folder, doc).endswith(": colour: Extra inputs are not permitted")


def test_several_problems_are_counted(folder):
    doc = _doc()
    doc["images"][0]["foo"] = 1
    doc["images"][1]["bar"] = 2
    assert _error(folder, doc).endswith(
        ": images[0].foo: Extra inputs are not permitted (and 1 more problems)"
    )


def test_missing_image_file(folder):
    doc = _doc()
    doc["images"][1]["path"] = "images/missing.png"
    assert _error(folder, doc) == (
        f"{folder / 'project.json'}: images[1].path: image file not found: "
        f"{folder / 'images' / 'missing.png'}"
    )


def test_missing_camera_and_mask_files(folder):
    doc = _doc()
    doc["camera"]["path"] = "nope.yaml"
    assert _error(folder, doc).endswith(
        f": camera.path: camera file not found: {folder / 'nope.yaml'}"
    )
    doc = _doc()
    doc["images"][0]["mask"] = "mask.png"
    assert _error(folder, doc).endswith(
        f": images[0].mask: mask file not found: {folder / 'mask.png'}"
    )


def test_missing_project_file(tmp_path):
    with pytest.raises(InputError, match=r"project.json: project file not found$"):
        load_project(tmp_path / "project.json")


@pytest.mark.parametrize("name", ["project.json", "project.yaml"])
def test_nan_is_refused(folder, name):
    doc = _doc()
    doc["images"][1]["T_camera_world"]["t"][1] = math.nan
    assert _error(folder, doc, name) == (
        f"{folder / name}: images[1].T_camera_world.t[1]: Input should be a finite number"
    )


def test_camera_behind_the_wall(folder):
    doc = _doc()
    doc["images"][2]["T_camera_world"] = {"R": np.eye(3).tolist(), "t": [0.0, 0.0, 1.0]}
    assert _error(folder, doc) == (
        f"{folder / 'project.json'}: images[2].T_camera_world: camera pose: the camera centre "
        "is at z = -1 m, on or behind the wall; expected z > 0 (the wall is z = 0 and cameras "
        "look at it from z > 0)"
    )


def test_initial_light_behind_the_wall(folder):
    doc = _doc()
    doc["lights"][0]["initial"]["position_m"] = [0.0, 0.0, 1.2]
    # Image b (the second) stands 1.5 m from the wall, a: 1.0 m: a is the first offender.
    v = _views()[0]
    z = float((v.center_world + v.R_camera_world.T @ np.array([0.0, 0.0, 1.2]))[2])
    assert z < 0
    assert _error(folder, doc) == (
        f"{folder / 'project.json'}: lights[0].initial.position_m: the light is on or behind "
        f"the wall in image 'a' (world z = {z:.3g} m); expected it in front (z > 0)"
    )


def test_a_rotation_that_is_not_one(folder):
    doc = _doc()
    doc["images"][0]["T_camera_world"]["R"] = [[1, 0, 0], [0, 1, 0], [0, 0, 2]]
    assert _error(folder, doc).endswith(
        ": images[0].T_camera_world: R_camera_world: expected a rotation matrix "
        "(max |R^T R - I| <= 1e-06), got max |R^T R - I| = 3"
    )


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            lambda d: d["images"][0]["T_camera_world"].update(rvec=[0, 0, 0]),
            "images[0].T_camera_world: give exactly one of R or rvec",
        ),
        (lambda d: d.update(version=2), "version: this lightcal reads project version 1, got 2"),
        (
            lambda d: d["lights"][0]["rid"].update(type="cos_power"),
            "lights[0].rid: RID type 'cos_power' needs m",
        ),
        (
            lambda d: d["lights"][0]["initial"].update(axis_camera=[0, 0, 1], roll_deg=3),
            "lights[0].initial: give at most one of axis_camera, roll_deg/pitch_deg, "
            "R_camera_light",
        ),
        (
            lambda d: d["lights"][0]["initial"].update(axis_camera=[0, 0, 0]),
            "lights[0].initial: axis_camera: expected a non-zero vector",
        ),
        (
            lambda d: d["camera"].update(fx=100.0),
            "camera: give either path or inline intrinsics, not both",
        ),
        (
            lambda d: d.update(selection={"regions": [{"kind": "rect", "points": [[0, 0]] * 3}]}),
            "selection.regions[0]: a rect needs exactly 2 points (opposite corners)",
        ),
        (
            lambda d: d.update(sensor={"model": "map"}),
            "sensor: the 'map' sensor model needs a vignetting file",
        ),
        (
            lambda d: d.update(solver={"max_iterations": 0}),
            "solver.max_iterations: Input should be greater than or equal to 1",
        ),
        (
            lambda d: d.update(images=[]),
            "images: List should have at least 1 item after validation, not 0",
        ),
        (
            lambda d: d["images"][1].update(name="a"),
            "images: two images are named 'a'; names must be unique",
        ),
        (
            lambda d: d["lights"].append(copy.deepcopy(d["lights"][0])),
            "lights: light names must be unique",
        ),
        (
            lambda d: d["images"][0]["T_camera_world"].update(d_pose_d_intrinsics=[[0.0] * 9] * 5),
            "images[0].T_camera_world.d_pose_d_intrinsics: List should have at least 6 items "
            "after validation, not 5",
        ),
        (
            lambda d: d["images"][0]["T_camera_world"].update(
                d_pose_d_intrinsics=[[0.0] * 9] * 5 + [[0.0] * 8]
            ),
            "images[0].T_camera_world: d_pose_d_intrinsics: expected 6 rows of 4, 8, 9 or 12 "
            "values (one per intrinsic parameter: fx, fy, cx, cy, distortion)",
        ),
        (
            lambda d: d["images"][1]["T_camera_world"].update(d_pose_d_intrinsics=[[0.0] * 8] * 6),
            "images[1].T_camera_world.d_pose_d_intrinsics: expected 6 x 9 (the camera's fx, "
            "fy, cx, cy and 5 distortion coefficients), got 6 x 8",
        ),
    ],
)
def test_field_errors(folder, change, message):
    doc = _doc()
    change(doc)
    assert _error(folder, doc) == f"{folder / 'project.json'}: {message}"


def test_pose_intrinsics_jacobians(folder):
    doc = _doc()
    D = np.arange(54.0).reshape(6, 9) / 7
    doc["images"][2]["T_camera_world"]["d_pose_d_intrinsics"] = D.tolist()
    project = load_project(_write(folder, doc))
    assert project.pose_intrinsics_jacobians[:2] == [None, None]
    np.testing.assert_array_equal(project.pose_intrinsics_jacobians[2], D)


def test_syntax_errors_name_the_line(folder):
    bad_json = folder / "project.json"
    bad_json.write_text('{\n "version": 1,\n "camera": \n}\n')
    with pytest.raises(InputError) as info:
        load_project(bad_json)
    assert str(info.value) == f"{bad_json}:4: not valid JSON: Expecting value"
    assert info.value.line == 4
    bad_yaml = folder / "project.yaml"
    bad_yaml.write_text("version: 1\ncamera: [1, 2\nimages: 3\n")
    with pytest.raises(InputError) as info:
        load_project(bad_yaml)
    assert str(info.value).startswith(f"{bad_yaml}:")
    assert "not valid YAML" in str(info.value)
    top = folder / "list.json"
    top.write_text("[1, 2]")
    with pytest.raises(InputError) as info:
        load_project(top)
    assert str(info.value) == f"{top}: expected a mapping (JSON object) at the top level"


def test_image_size_must_match_the_intrinsics(folder):
    np.save(folder / "images" / "b.npy", np.zeros((H, W + 1)))
    project = load_project(_write(folder, _doc()))
    with pytest.raises(InputError) as info:
        load_images(project)
    assert str(info.value) == (
        f"{folder / 'images' / 'b.npy'}: image is {W + 1}x{H} pixels but the camera intrinsics "
        f"are for {W}x{H}; expected the same size"
    )


# ---------------------------------------------------------------- paths, YAML and JSON


def test_relative_paths_resolve_against_the_project_folder(folder, tmp_path_factory, monkeypatch):
    path = _write(folder, _doc())
    monkeypatch.chdir(tmp_path_factory.mktemp("elsewhere"))
    project = load_project(path)
    assert project.path == path.resolve()
    assert project.folder == folder.resolve()
    assert project.image_paths == [folder.resolve() / "images" / f"{n}.npy" for n in "abc"]
    assert project.names == ["a", "b", "c"]
    assert project.mask_paths == [None, None, None]
    # A project file in a sub-folder, referring back up, and an absolute path.
    sub = folder / "sub"
    sub.mkdir()
    doc = _doc()
    doc["camera"]["path"] = "../camera.yaml"
    doc["images"][0]["path"] = str(folder / "images" / "a.npy")
    doc["images"][1]["path"] = "../images/b.npy"
    doc["images"][2]["path"] = "../images/c.npy"
    project = load_project(_write(sub, doc))
    assert project.image_paths[0] == folder / "images" / "a.npy"
    assert project.image_paths[1].resolve() == folder.resolve() / "images" / "b.npy"
    assert project.camera.width == W


def test_yaml_and_json_give_the_same_project(folder):
    doc = _doc()
    a = load_project(_write(folder, doc, "project.json"))
    b = load_project(_write(folder, doc, "project.yml"))
    assert a.spec == b.spec
    assert a.camera == b.camera
    for va, vb in zip(a.views, b.views, strict=True):
        np.testing.assert_array_equal(va.R_camera_world, vb.R_camera_world)


def test_save_project_round_trips(folder):
    spec = load_project(_write(folder, _doc())).spec
    for name in ("again.json", "again.yaml"):
        save_project(spec, folder / name)
        assert load_project(folder / name).spec == spec


def test_parse_project_defaults():
    spec = parse_project(_doc(), "memory")
    assert isinstance(spec, ProjectFile)
    assert spec.selection.strategy == "random" and spec.selection.n_per_image == 100
    assert spec.solver.loss == "linear" and spec.solver.max_iterations == 100
    assert spec.sensor.model == "radiance"


# --------------------------------------------------------------------- what is built


def test_views_lights_and_options(folder):
    doc = _doc()
    doc["images"][0]["T_camera_world"] = {
        "rvec": [math.pi, 0.0, 0.0],
        "t": [0.0, 0.0, 1.0],
    }
    doc["images"][1]["exposure"] = 2.5
    doc["lights"][0]["initial"].update(axis_camera=[0.0, 0.6, 0.8], scale=5.0)
    doc["lights"].append(
        {
            "name": "second",
            "rid": {"type": "half_angle", "half_angle_deg": 20, "profile": "gaussian"},
            "pose": "general",
            "initial": {"position_m": [-0.1, 0, 0], "roll_deg": 10, "pitch_deg": -5},
            "estimate_rid": "none",
        }
    )
    doc["lights"].append(
        {"name": "third", "rid": {"type": "isotropic"}, "pose": "isotropic",
         "initial": {"position_m": [0, 0.1, 0]}},
    )  # fmt: skip
    doc["solver"] = {"loss": "huber", "f_scale": 2.0, "max_iterations": 7, "estimate_gains": True}
    doc["sensor"] = {"offset": 1.5, "estimate_offset": True}
    doc["selection"] = {"strategy": "grid", "grid_step": 5, "seed": 9}
    p = load_project(_write(folder, doc))
    np.testing.assert_allclose(p.views[0].R_camera_world, matrix_from_rotvec([math.pi, 0, 0]))
    np.testing.assert_allclose(p.views[0].center_world, [0, 0, 1.0], atol=1e-15)
    assert [v.exposure for v in p.views] == [1.0, 2.5, 1.0]
    first, second, third = p.lights
    assert first.initial.name == "led" and first.initial.scale == 5.0
    assert isinstance(first.initial.rid, CosPowerRID)
    assert math.degrees(first.initial.rid.half_angle_rad) == pytest.approx(30.0)
    np.testing.assert_allclose(first.initial.axis_camera, [0.0, 0.6, 0.8], atol=1e-15)
    assert first.pose_kind is None and first.kind() == "symmetric"
    assert isinstance(second.initial.rid, GaussianRID)
    assert second.kind() == "general"
    np.testing.assert_allclose(
        second.initial.axis_camera,
        axis_from_paper_angles(math.radians(10), math.radians(-5)),
        atol=1e-15,
    )
    assert second.initial.scale == 1.0  # null: fitted linearly later
    assert isinstance(third.initial.rid, IsotropicRID) and third.kind() == "isotropic"
    assert p.solver.loss == "huber" and p.solver.f_scale == 2.0
    assert p.solver.max_iterations == 7 and p.solver.estimate_gains
    assert p.solver.estimate_offset and p.solver.offset == 1.5
    assert p.selection.strategy == "grid" and p.selection.grid_step == 5
    assert p.selection.seed == 9


def test_exposure_settings_are_relative_to_the_first_image(folder):
    doc = _doc()
    doc["images"][0]["exposure"] = {"exposure_time_s": 0.02, "iso": 200}
    doc["images"][1]["exposure"] = {"exposure_time_s": 0.01, "iso": 100, "f_number": 2.0}
    doc["images"][2]["exposure"] = 0.5  # an explicit factor is taken as given
    p = load_project(_write(folder, doc))
    assert p.views[0].exposure == pytest.approx(1.0)
    assert p.views[1].exposure == pytest.approx((0.01 * 100 / 4) / (0.02 * 200))
    assert p.views[2].exposure == 0.5
    # Settings for some images and none for another (a .npy has no EXIF): an error.
    del doc["images"][2]["exposure"]
    assert _error(folder, doc) == (
        f"{folder / 'project.json'}: images[2].exposure: not given and c.npy has no EXIF "
        "exposure time, while other images' exposures come from settings; give the exposure "
        "of every image"
    )


# ----------------------------------------------------------------------- image formats


def _image_project(folder: Path, file_name: str, sensor: dict) -> Path:
    doc = _doc()
    doc["images"] = [{"path": file_name, "T_camera_world": _pose(_views()[0])}]
    doc["sensor"] = sensor
    return _write(folder, doc)


@pytest.mark.parametrize(
    ("file_name", "dtype", "sensor"),
    [
        ("img16.png", np.uint16, {}),
        ("img16.tif", np.uint16, {}),
        ("img8.png", np.uint8, {"assume_linear": True}),
        ("img8.tif", np.uint8, {"assume_linear": True}),
        ("imgf.tif", np.float32, {}),
        ("imgf.npy", np.float64, {}),
    ],
)
def test_image_formats(folder, file_name, dtype, sensor):
    rng = np.random.default_rng(0)
    top = 200 if dtype == np.uint8 else 60000
    data = rng.integers(5, top, size=(H, W)).astype(dtype)
    if file_name.endswith(".png"):
        assert cv2.imwrite(str(folder / file_name), data)
    elif file_name.endswith(".tif"):
        tifffile.imwrite(folder / file_name, data)
    else:
        np.save(folder / file_name, data)
    project = load_project(_image_project(folder, file_name, {**sensor, "black_level": 3.0}))
    img = load_images(project).images[0]
    np.testing.assert_array_equal(img.values, data.astype(np.float64) - 3.0)
    assert not img.saturated.any()


def test_eight_bit_images_need_linear_data(folder):
    cv2.imwrite(str(folder / "img8.png"), np.full((H, W), 100, dtype=np.uint8))
    project = load_project(_image_project(folder, "img8.png", {}))
    with pytest.raises(InputError, match=r"img8\.png: 8-bit image values are gamma-encoded"):
        load_images(project)


def test_sixteen_bit_saturation(folder):
    data = np.full((H, W), 1000, dtype=np.uint16)
    data[3, 4] = 4095
    cv2.imwrite(str(folder / "sat.png"), data)
    project = load_project(_image_project(folder, "sat.png", {"white_level": 4095}))
    img = load_images(project).images[0]
    assert {tuple(p) for p in np.argwhere(img.saturated).tolist()} == {(3, 4)}


# ------------------------------------------------------------------------------ schema


def test_project_schema_is_a_json_schema():
    schema = project_schema()
    text = json.dumps(schema)
    assert json.loads(text) == schema
    assert schema["type"] == "object"
    assert schema["title"] == "lightcal project (version 1)"
    assert set(schema["required"]) == {"camera", "images", "lights"}
    assert schema["additionalProperties"] is False
    assert {"version", "camera", "sensor", "images", "lights", "selection", "solver"} <= set(
        schema["properties"]
    )
    _check_refs(schema, schema)


def _check_refs(node, root) -> None:
    """Every $ref points into $defs, every 'required' names a property, types are valid."""
    types = {"object", "array", "string", "number", "integer", "boolean", "null"}
    if isinstance(node, dict):
        ref = node.get("$ref")
        if ref is not None:
            assert ref.startswith("#/$defs/"), ref
            assert ref.removeprefix("#/$defs/") in root["$defs"], ref
        if "required" in node:
            assert set(node["required"]) <= set(node.get("properties", {})), node
        if isinstance(node.get("type"), str):
            assert node["type"] in types, node["type"]
        for value in node.values():
            _check_refs(value, root)
    elif isinstance(node, list):
        for value in node:
            _check_refs(value, root)
