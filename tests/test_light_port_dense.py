"""A dense selection lit through a light's flat port (`lightcal.core.light_port_dense`):
the straight twin's flux times the port's ratio, exact on a node grid and cubic between,
with the gradients of that model, against every pixel's exact path
(`light_port_flux.port_light_flux`); where it applies; and a noise-free dense solve."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import lightcal.core.light_port_dense as dense
from lightcal.core.footprint import pixel_footprints
from lightcal.core.medium import Medium
from lightcal.core.render import light_flux
from lightcal.core.scene import Light, View
from lightcal.io.project import load_project
from lightcal.pipeline import calibrate_project
from tests import calib_scenes as cs
from tests.test_light_port_frame import LIGHT_PORT, VIEW, _camera, _lopsided
from tests.test_light_port_solve import WATER_C, _write
from tests.test_port_fused import _rotation


@pytest.fixture
def small_dense(monkeypatch: pytest.MonkeyPatch) -> None:
    """The ratio path from 1,000 pixels on (the tests' images are small)."""
    monkeypatch.setattr(dense, "DENSE_PIXELS", 1_000)


def _light(rid: str = "cos") -> Light:
    from lightcal.core.rid import CosPowerRID

    return Light(
        CosPowerRID(3.0) if rid == "cos" else _lopsided(),
        np.array([0.12, -0.05, 0.03]),
        _rotation((0.1, -0.05, 1.0)),
        2.0,
        port=LIGHT_PORT,
    )


def _flux(footprints, view: View, light: Light, medium: Medium) -> tuple:
    n = len(footprints)
    grad, d_c = np.zeros((n, 6)), np.zeros((n, 1))
    flux, _ = light_flux(
        footprints, view, light, want_grad=True, grad_out=grad, medium=medium,
        medium_grad_out=d_c,
    )  # fmt: skip
    return flux, grad, d_c


@pytest.mark.parametrize("rid", ["cos", "table"])
def test_the_flux_and_its_gradients_are_the_exact_paths(
    rid: str, small_dense: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    camera = _camera(240, 180, f=220.0)
    v, u = np.mgrid[0:180, 0:240]
    fp = pixel_footprints(camera, VIEW, np.stack([u.ravel(), v.ravel()], axis=1))
    assert fp.grid is not None
    water = Medium(0.3)
    assert dense.dense_applies(fp, water, np.zeros((len(fp), 1)))
    fast = _flux(fp, VIEW, _light(rid), water)
    monkeypatch.setattr(dense, "DENSE_PIXELS", 10**9)
    exact = _flux(fp, VIEW, _light(rid), water)
    lit = exact[0] > 0.0
    assert lit.mean() > 0.9
    np.testing.assert_array_equal(fast[0] > 0.0, lit)
    # Measured (600 x 400, cos^3): flux 1.7e-8, gradient columns 7e-8, d/dc 7e-9.
    np.testing.assert_allclose(fast[0][lit], exact[0][lit], rtol=3e-6, atol=0.0)
    for j in range(6):
        scale = np.abs(exact[1][:, j]).max()
        np.testing.assert_allclose(fast[1][:, j], exact[1][:, j], rtol=0.0, atol=1e-5 * scale)
    np.testing.assert_allclose(fast[2], exact[2], rtol=0.0, atol=1e-6 * np.abs(exact[2]).max())


def test_where_the_ratio_path_applies(small_dense: None) -> None:
    camera = _camera(240, 180, f=220.0)
    v, u = np.mgrid[0:180, 0:240]
    every = np.stack([u.ravel(), v.ravel()], axis=1)
    fp = pixel_footprints(camera, VIEW, every)
    assert dense.dense_applies(fp, Medium(0.3), None)
    assert not dense.dense_applies(fp, Medium(0.3, 0.5, 0.8), None)  # the veil: exact
    assert not dense.dense_applies(fp, Medium(0.3), np.zeros((len(fp), 2)))  # d/d beta
    sparse = pixel_footprints(camera, VIEW, every[::97])
    assert len(sparse) < 1_000 and not dense.dense_applies(sparse, Medium(0.3), None)
    b = np.mgrid[0:90, 0:120]
    binned = pixel_footprints(camera, VIEW, np.stack([b[1].ravel(), b[0].ravel()], 1), binning=2)
    assert binned.grid is not None and not dense.dense_applies(binned, Medium(0.3), None)


def test_a_ported_light_behind_the_wall_lights_nothing(small_dense: None) -> None:
    camera = _camera(240, 180, f=220.0)
    v, u = np.mgrid[0:180, 0:240]
    fp = pixel_footprints(camera, VIEW, np.stack([u.ravel(), v.ravel()], axis=1))
    from lightcal.core.rid import CosPowerRID

    behind = Light(CosPowerRID(2.0), np.array([0.0, 0.3, 3.0]), np.eye(3), 0.3, port=LIGHT_PORT)
    assert behind.position_world(VIEW)[2] < 0.0
    flux, grad, d_c = _flux(fp, VIEW, behind, Medium(0.3))
    assert not flux.any() and not grad.any() and not d_c.any()


def test_a_noise_free_dense_solve_through_the_port(
    tmp_path: Path, small_dense: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every pixel of 8 noise-free views (160 x 120) rendered exactly through the port,
    the light started 40 mm and 4 degrees off and c at 0.1 /m: the ratio path brings the
    light back to a micrometre (the cubics' 1e-8) and c to 1e-6."""
    path, light = _write(tmp_path, port_in_file=True)
    doc = json.loads(path.read_text())
    doc["selection"] = {"strategy": "all", "min_signal": 5.0}
    path.write_text(json.dumps(doc))
    calls = []
    real = dense.dense_port_flux

    def counted(*args, **kwargs):
        calls.append(len(args[0]))
        return real(*args, **kwargs)

    import lightcal.core.render as render

    monkeypatch.setattr(render, "dense_port_flux", counted)
    _, model, res = calibrate_project(load_project(path))
    assert calls and min(calls) >= 1_000
    x = np.array(res.x)
    est = model.layout.rig(x).lights[0]
    position, axis = cs.pose_errors(est, light)
    c = model.layout.medium_of(x).attenuation_per_m
    print(f"\ndense through the port: {position * 1e6:.3g} um, {axis:.3g} deg, c {c:.7f}")
    assert res.converged
    assert position < 1e-5 and axis < math.degrees(1e-5)
    assert c == pytest.approx(WATER_C, abs=1e-6)
