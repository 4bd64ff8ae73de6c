"""A project key lightcal would not use is an error naming it (issue 29: `camera.dist`
beside `camera.path` was silently ignored, the renders bit-identical)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from lightcal.errors import InputError
from lightcal.io.project import load_project
from lightcal.io.project_keys import ignored_keys
from lightcal.io.project_spec import parse_project
from lightcal.resources import sample_project_dir


def _sample() -> dict[str, Any]:
    return json.loads((sample_project_dir() / "project.json").read_text())


def _write(tmp_path: Path, doc: dict[str, Any]) -> Path:
    """The document beside copies of the sample's files it names (camera, light)."""
    sample = sample_project_dir()
    for name in ("camera.yaml", "light.ies"):
        (tmp_path / name).write_bytes((sample / name).read_bytes())
    for image in doc["images"]:
        image["path"] = str(sample / image["path"])
        if image.get("mask"):
            image["mask"] = str(sample / image["mask"])
    path = tmp_path / "project.json"
    path.write_text(json.dumps(doc))
    return path


def test_the_sample_gives_no_ignored_key():
    """Its `dist: []` and `skew: 0` beside `path` are the defaults: nothing said."""
    assert ignored_keys(parse_project(_sample(), "sample")) == []


@pytest.mark.parametrize(
    "edit, key",
    [
        (lambda d: d["camera"].update(dist=[-0.1, 0.02, 0, 0]), "camera.dist"),
        (lambda d: d["camera"].update(skew=0.5), "camera.skew"),
        (lambda d: d["sensor"].update(vignetting="v.tif"), "sensor.vignetting"),
        (lambda d: d["lights"][0]["rid"].update(m=3.0), "lights[0].rid.m"),
        (lambda d: d["lights"][0]["rid"].update(profile="gaussian"), "lights[0].rid.profile"),
        (lambda d: d["lights"][0].update(curve_knots=9), "lights[0].curve_knots"),
        (lambda d: d["lights"][0].update(curve_max_angle_deg=60), "lights[0].curve_max_angle_deg"),
    ],
)
def test_an_ignored_key_is_named(tmp_path, edit, key):
    doc = _sample()
    edit(doc)
    with pytest.raises(InputError) as info:
        load_project(_write(tmp_path, doc))
    message = str(info.value)
    assert f"{key}: given but not used" in message and "remove it" in message


def test_camera_id_without_a_camera_file(tmp_path):
    doc = _sample()
    doc["camera"] = {"fx": 900, "fy": 900, "cx": 599.5, "cy": 399.5, "width": 1200,
                     "height": 800, "camera_id": 2}  # fmt: skip
    with pytest.raises(InputError, match=r"camera\.camera_id: given but not used without"):
        load_project(_write(tmp_path, doc))


def test_used_keys_are_accepted(tmp_path):
    """Inline intrinsics with their distortion; a curve's knots when a curve is estimated."""
    doc = _sample()
    doc["camera"] = {"fx": 933.4, "fy": 933.4, "cx": 602.5, "cy": 397.7, "width": 1200,
                     "height": 800, "dist": [-0.08, 0.02, 0, 0, 0]}  # fmt: skip
    doc["lights"][0].update(estimate_rid="curve", curve_knots=9, curve_max_angle_deg=60)
    project = load_project(_write(tmp_path, doc))
    assert project.camera.dist[0] == -0.08
    assert project.lights[0].curve_knots == 9


def test_several_ignored_keys_are_counted(tmp_path):
    doc = _sample()
    doc["camera"].update(dist=[0.1, 0, 0, 0], skew=1.0)
    doc["lights"][0].update(curve_knots=4)
    with pytest.raises(InputError, match=r"camera\.dist: .* \(and 2 more such keys\)"):
        load_project(_write(tmp_path, doc))
