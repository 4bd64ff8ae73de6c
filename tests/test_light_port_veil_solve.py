"""Calibrating a light behind its flat port in water that scatters: the veil of the
refracted beam (lightcal.core.light_port_veil) in the solver, on noise-free renders and
on `lightcal synth --light-port ... --backscatter ...` data (docs/model.md, "The light's
flat port")."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lightcal.cli.main import main
from lightcal.core.medium import Medium
from lightcal.io.project import load_project
from lightcal.pipeline import calibrate_project
from tests import calib_scenes as cs
from tests.test_light_port_solve import _write

WATER = Medium(0.2, 0.8, 0.6)
LIGHT_PORT_ARGS = ["--light-port", "15", "8", "1.49", "1.333", "--declare-light-port"]


def test_the_light_and_the_water_come_back_from_noise_free_renders() -> None:
    """8 noise-free views (160 x 120: the whole image's veil exact at every pixel) in
    water of c = 0.2 /m, beta = 0.8 /m, g = 0.6; the light started 40 mm and 4 degrees
    off, c and beta estimated from 0.1 and 0.4 /m: the light to 1e-8 m, c and beta to
    1e-7."""
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        doc = {
            "attenuation_per_m": 0.1,
            "backscatter_per_m": 0.4,
            "phase_g": 0.6,
            "estimate": ["attenuation_per_m", "backscatter_per_m"],
        }
        path, light = _write(Path(tmp), port_in_file=True, water=WATER, medium_doc=doc)
        _, model, res = calibrate_project(load_project(path))
    x = np.array(res.x)
    est = model.layout.rig(x).lights[0]
    position, axis = cs.pose_errors(est, light)
    medium = model.layout.medium_of(x)
    print(
        f"\n{position:.2e} m, {axis:.2e} deg, c {medium.attenuation_per_m:.9f}, "
        f"beta {medium.backscatter_per_m:.9f}, {res.iterations} iterations"
    )
    assert res.converged
    assert position < 1e-8 and axis < 1e-6
    assert medium.attenuation_per_m == pytest.approx(WATER.attenuation_per_m, abs=1e-7)
    assert medium.backscatter_per_m == pytest.approx(WATER.backscatter_per_m, abs=1e-7)


def test_the_light_and_the_water_are_recovered_from_synth_data(tmp_path: Path) -> None:
    """`lightcal synth --light-port 15 8 1.49 1.333 --declare-light-port --attenuation 0.3
    --backscatter 0.6 --phase-g 0.8 --declare-medium estimated` (320 x 240, 10 views,
    synth's noise, poses to 0.5 mm / 0.05 deg), 4000 pixels an image, random starts: the
    light within 3 mm and 0.2 degrees, c within 5 %."""
    out = tmp_path / "data"
    water = ["--attenuation", "0.3", "--backscatter", "0.6", "--phase-g", "0.8"]
    water += ["--declare-medium", "estimated"]
    argv = ["synth", str(out), "--width", "320", "--height", "240", "--views", "10"]
    assert main([*argv, *LIGHT_PORT_ARGS, *water, "--seed", "3", "--quiet"]) == 0
    doc = json.loads((out / "project.json").read_text())
    assert doc["medium"]["estimate"] == ["attenuation_per_m", "backscatter_per_m"]
    assert doc["lights"][0]["port"]["distance_mm"] == 15.0
    doc["selection"]["n_per_image"] = 4000
    doc.setdefault("solver", {})["multistart"] = 4  # as tests/test_flat_port_backscatter.py
    (out / "project.json").write_text(json.dumps(doc))
    position, axis, medium = cs.calibrate_synth_folder(out)
    print(
        f"\n{position * 1e3:.2f} mm, {axis:.3f} deg, c {medium.attenuation_per_m:.4f}, "
        f"beta {medium.backscatter_per_m:.4f}"
    )
    assert position < 3e-3 and axis < 0.2
    assert medium.attenuation_per_m == pytest.approx(0.3, rel=0.05)
    assert medium.backscatter_per_m == pytest.approx(0.6, rel=0.1)


def test_lightcal_synth_and_calibrate_run_a_ported_light_in_scattering_water(
    tmp_path: Path,
) -> None:
    """The commands end to end (160 x 120, 6 views): `lightcal synth --light-port ...
    --backscatter ...` writes the data, `lightcal calibrate` solves it and writes its
    report (whole images with the veil)."""
    out = tmp_path / "data"
    water = ["--attenuation", "0.3", "--backscatter", "0.6", "--declare-medium", "estimated"]
    argv = ["synth", str(out), "--width", "160", "--height", "120", "--views", "6"]
    assert main([*argv, *LIGHT_PORT_ARGS, *water, "--quiet"]) == 0
    result, report = tmp_path / "result.json", tmp_path / "report"
    project = str(out / "project.json")
    assert main(["calibrate", project, "--out", str(result), "--report", str(report)]) == 0
    medium = json.loads(result.read_text())["medium"]
    print(f"\n{medium}")
    assert medium["backscatter_per_m"] == pytest.approx(0.6, rel=0.3)
    assert (report / "summary.md").is_file() and len(list(report.glob("*.png"))) > 6
