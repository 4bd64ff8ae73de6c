"""The result file: every field from a calibration, round trip, read errors, schema."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from lightcal import __version__
from lightcal.core.problem import LightUnknown
from lightcal.core.rid import CosPowerRID
from lightcal.core.solver import run_least_squares
from lightcal.errors import InputError
from lightcal.io.result_file import (
    RESULT_VERSION,
    ResultFile,
    read_result,
    result_schema,
    result_to_file,
    write_result,
)
from lightcal.pipeline import summarise
from tests import calib_scenes as cs
from tests.test_project import _check_refs


@pytest.fixture(scope="module")
def result():
    """Two lights, one with its cos^m exponent estimated, free gains and offset."""
    rig = cs.two_light_rig()
    images = cs.observe(
        cs.small_camera(),
        cs.views(6, seed=3),
        rig,
        n_per_image=60,
        rng=np.random.default_rng(0),
        noise=(0.5, 4.0),
    )
    left, right = rig.lights
    unknowns = [
        LightUnknown(cs.start_near(left).replace(rid=CosPowerRID(3.0)), estimate_rid="cos_power"),
        LightUnknown(cs.start_near(right)),
    ]
    model = cs.model_of(images, unknowns, estimate_gains=True, estimate_offset=True)
    return summarise(model, run_least_squares(model))


def test_every_field_is_written(result):
    rf = result_to_file(result, project="/data/project.json")
    assert rf.version == RESULT_VERSION == 1
    assert rf.lightcal_version == __version__
    assert rf.project == "/data/project.json"
    assert len(rf.lights) == 2
    for lm, lr in zip(rf.lights, result.lights, strict=True):
        assert lm.name == lr.name
        assert lm.pose_kind == lr.pose_kind == "symmetric"
        for key in (
            "position_m",
            "R_camera_light",
            "quaternion_wxyz",
            "axis_camera",
            "roll_deg",
            "pitch_deg",
            "axis_angle_from_optical_axis_deg",
        ):
            assert getattr(lm, key) == lr.pose.to_dict()[key], key
            assert getattr(lm.sigma, key) == lr.sigma.to_dict()[key], key
        assert lm.scale == lr.scale and lm.scale_sigma == lr.scale_sigma
        assert lm.rid == lr.rid
    assert rf.lights[0].rid is not None and rf.lights[0].rid["model"] == "cos_power"
    assert rf.lights[1].rid is None
    assert rf.lights[0].quaternion_wxyz[0] >= 0.0
    assert rf.offset == result.offset and rf.offset_sigma == result.offset_sigma
    assert rf.offset_sigma is not None
    assert [im.name for im in rf.images] == result.image_names
    assert [im.rms for im in rf.images] == result.per_image_rms
    assert [im.pixels for im in rf.images] == result.pixels_used
    assert [im.gain for im in rf.images] == result.gains
    assert rf.images[0].gain == 1.0
    for key in ("iterations", "nfev", "status", "message", "converged", "cost", "time_s"):
        assert getattr(rf, key) == getattr(result, key), key
    assert rf.warnings == result.warnings
    assert rf.parameters.names == result.parameter_names
    assert rf.parameters.x == result.x
    assert rf.parameters.covariance == result.covariance
    assert result_to_file(result).project is None


def test_where_the_iterations_began_is_written(result, tmp_path):
    assert result_to_file(result).start == ""  # the initial guess
    began = "the estimate of a first solve on one pixel in 37 (256459 of 9488747 pixels)"
    rf = result_to_file(dataclasses.replace(result, start=began))
    write_result(rf, tmp_path / "r.json")
    assert read_result(tmp_path / "r.json").start == began
    assert json.loads((tmp_path / "r.json").read_text())["start"] == began


def test_write_read_round_trip(result, tmp_path):
    rf = result_to_file(result, project=tmp_path / "p.json")
    path = tmp_path / "out" / "result.json"
    path.parent.mkdir()
    write_result(rf, path)
    assert read_result(path) == rf
    data = json.loads(path.read_text())
    assert data["lights"][0]["sigma"]["position_m"] == rf.lights[0].sigma.position_m
    assert data["parameters"]["names"][0] == "left.x_m"
    assert path.read_text().endswith("}\n")
    assert list(tmp_path.joinpath("out").iterdir()) == [path]  # no temporary files left


def test_read_errors(result, tmp_path):
    missing = tmp_path / "none.json"
    with pytest.raises(InputError) as info:
        read_result(missing)
    assert str(info.value) == f"{missing}: result file not found"
    bad = tmp_path / "bad.json"
    bad.write_text('{"version": 1,\n "lights": [}\n')
    with pytest.raises(InputError) as info:
        read_result(bad)
    assert str(info.value) == f"{bad}:2: not valid JSON: Expecting value"
    data = result_to_file(result).model_dump(mode="json")
    del data["lights"][1]["scale"]
    incomplete = tmp_path / "incomplete.json"
    incomplete.write_text(json.dumps(data))
    with pytest.raises(InputError) as info:
        read_result(incomplete)
    assert str(info.value) == f"{incomplete}: lights.1.scale: Field required"
    data = result_to_file(result).model_dump(mode="json")
    data["images"][0]["colour"] = "red"
    extra = tmp_path / "extra.json"
    extra.write_text(json.dumps(data))
    with pytest.raises(InputError) as info:
        read_result(extra)
    assert str(info.value) == f"{extra}: images.0.colour: Extra inputs are not permitted"


def test_result_schema(result):
    schema = result_schema()
    assert schema["title"] == "lightcal result (version 1)"
    assert schema["type"] == "object"
    assert json.loads(json.dumps(schema)) == schema
    assert {"lights", "images", "parameters", "converged", "warnings"} <= set(schema["properties"])
    assert set(schema["$defs"]["LightResultModel"]["properties"]) >= {
        "position_m",
        "axis_camera",
        "sigma",
        "scale",
        "rid",
    }
    _check_refs(schema, schema)
    # What is written validates against the model the schema describes.
    data = json.loads(result_to_file(result).model_dump_json())
    assert ResultFile.model_validate(data) == result_to_file(result)
