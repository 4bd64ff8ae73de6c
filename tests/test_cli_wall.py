"""Glossy walls end to end: `lightcal synth --wall`, `lightcal calibrate` with its fit test,
exit code 3, `--allow-misfit`, `wall: auto` and the mirror exclusion."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from lightcal.cli.main import main
from lightcal.io.result_file import read_result
from lightcal.synthetic.dataset import read_truth


@pytest.fixture(scope="module")
def glossy(tmp_path_factory) -> Path:
    """12 views (480 x 360, 14-bit noise, poses off by 0.5 mm) of a satin wall."""
    folder = tmp_path_factory.mktemp("wall") / "satin"
    argv = ["synth", str(folder), "--wall", "plastic", "--roughness", "0.2", "--quiet"]
    assert main([*argv, "--width", "480", "--height", "360", "--seed", "4"]) == 0
    return folder


@pytest.fixture(scope="module")
def matte(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("wall") / "matte"
    assert main(["synth", str(folder), "--width", "480", "--height", "360", "--quiet"]) == 0
    return folder


def _variant(folder: Path, name: str, **changes: dict) -> Path:
    doc = json.loads((folder / "project.json").read_text())
    for key, value in changes.items():
        doc.setdefault(key, {}).update(value)
    path = folder / f"{name}.json"
    path.write_text(json.dumps(doc))
    return path


def _errors(result_path: Path, folder: Path) -> tuple[float, float]:
    light = read_result(result_path).lights[0]
    truth = read_truth(folder / "truth.json")["lights"][0]
    position = float(np.linalg.norm(np.array(light.position_m) - truth["position_m"]))
    cos = float(np.clip(np.dot(light.axis_camera, truth["axis_camera"]), -1, 1))
    return position, math.degrees(math.acos(cos))


def test_truth_records_the_wall(glossy) -> None:
    wall = read_truth(glossy / "truth.json")["wall"]
    assert wall["model"] == "plastic"
    assert wall["roughness"] == 0.2
    assert (
        json.loads((glossy / "project.json").read_text()).get("wall", {}).get("model", "lambertian")
        == "lambertian"
    )


def test_glossy_wall_as_lambertian_exits_3(glossy, tmp_path, capsys) -> None:
    out = tmp_path / "r.json"
    assert main(["calibrate", str(glossy / "project.json"), "--out", str(out)]) == 3
    captured = capsys.readouterr()
    text = " ".join((captured.out + captured.err).split())
    assert "it looks glossy (a correction of" in text
    assert "; try `wall: {model: plastic}` (or `auto`)" in text
    assert "exit code 3 (--allow-misfit: 0)" in text
    assert "the sigmas include: pixel noise (the sensor's noise model)" in text
    assert "systematic: the shift the gloss cause accounts for" in text
    result = read_result(out)
    assert result.converged
    assert result.fit is not None and result.fit["adequate"] is False
    assert result.fit["mirror"]["significant"] is True
    args = ["calibrate", str(glossy / "project.json"), "--out", str(out), "--allow-misfit"]
    assert main([*args, "--quiet"]) == 0


def test_auto_chooses_plastic_and_finds_the_light(glossy, tmp_path, capsys) -> None:
    project = _variant(glossy, "auto", wall={"model": "auto"}, selection={"n_per_image": 2000})
    out = tmp_path / "r.json"
    assert main(["calibrate", str(project), "--out", str(out), "--quiet"]) == 0
    result = read_result(out)
    assert result.wall["model"] == "plastic"
    assert result.wall["roughness"] == pytest.approx(0.2, abs=0.02)
    assert any(w.startswith("wall: auto chose plastic (BIC ") for w in result.warnings)
    position, axis = _errors(out, glossy)
    assert position < 2e-3
    assert axis < 0.1
    assert result.fit is not None and result.fit["adequate"] is True
    assert any(
        t.startswith("camera poses (12 images' marker-fit covariances): ")
        for t in result.uncertainty
    )


def test_auto_on_a_lambertian_wall_is_lambertian(matte, tmp_path) -> None:
    plain, auto = tmp_path / "plain.json", tmp_path / "auto.json"
    assert main(["calibrate", str(matte / "project.json"), "--out", str(plain), "--quiet"]) == 0
    project = _variant(matte, "auto", wall={"model": "auto"})
    assert main(["calibrate", str(project), "--out", str(auto), "--quiet"]) == 0
    a, b = read_result(plain), read_result(auto)
    assert b.wall["model"] == "lambertian"
    np.testing.assert_allclose(a.lights[0].position_m, b.lights[0].position_m, rtol=0, atol=1e-9)
    assert b.warnings[-1] == (
        "wall: auto kept lambertian: no misfit moves the pose beyond its sigma"
    )


def test_mirror_exclusion_drops_pixels(glossy, tmp_path) -> None:
    project = _variant(glossy, "mirror", selection={"exclude_mirror_deg": 10.0})
    out = tmp_path / "r.json"
    main(["calibrate", str(project), "--out", str(out), "--quiet", "--allow-misfit"])
    result = read_result(out)
    note = next(w for w in result.warnings if w.startswith("selection: "))
    dropped = int(note.split()[1])
    assert dropped > 0
    assert sum(im.pixels for im in result.images) + dropped == 12 * 100


def test_wall_errors_name_the_field(matte, tmp_path, capsys) -> None:
    project = _variant(matte, "bad", wall={"model": "oren_nayar", "parameters": {"sigma": 20}})
    code = main(["calibrate", str(project), "--out", str(tmp_path / "r.json")])
    assert code == 2
    err = capsys.readouterr().err
    assert (
        "wall.parameters: the oren_nayar wall has no parameter 'sigma'; expected sigma_deg" in err
    )
