"""The backscatter seen through the camera's flat port: the veil integrated along each
pixel's refracted ray in the water, from where it leaves the port to the wall
(docs/model.md, "The camera's flat port")."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad

from lightcal.cli.main import main
from lightcal.core.medium import Medium
from lightcal.core.port_footprints import port_footprints
from lightcal.core.render import shade
from lightcal.core.scene import Light, Rig
from tests.calib_scenes import calibrate_synth_folder
from tests.test_flat_port import PORT, _all_pixels, _camera, _rig, _view

WATER = Medium(0.3, 0.8, 0.6)


def _veil_reference(start: np.ndarray, end: np.ndarray, light: Light, view) -> float:
    """S along the segment start -> end by adaptive quadrature (scipy's QUADPACK), the
    integrand written here: p(mu) f(u) exp(-c (r + t)) / r^2, t from `start`."""
    L = light.position_world(view)
    R = light.rotation_world(view)
    c, g = WATER.attenuation_per_m, WATER.phase_g
    length = float(np.linalg.norm(end - start))
    o = (end - start) / length

    def integrand(t: float) -> float:
        a = start + t * o - L
        r = float(np.linalg.norm(a))
        w = a / r
        mu = -float(w @ o)
        p = (1 - g * g) / (4 * math.pi * (1 + g * g - 2 * g * mu) ** 1.5)
        local = R.T @ w
        f = float(light.rid(np.arccos(np.clip(local[2], -1, 1)), np.arctan2(local[1], local[0])))
        return p * f * math.exp(-c * (r + t)) / (r * r)

    closest = float(np.clip((L - start) @ o, 0.0, length))
    value, _ = quad(integrand, 0.0, length, points=[closest], epsabs=0.0, epsrel=1e-11, limit=500)
    return value


def test_the_veil_through_the_port_is_the_integral_along_the_refracted_ray() -> None:
    camera, view, rig = _camera(), _view(), _rig()
    pixels = _all_pixels(camera)[::37]
    fp = port_footprints(camera, view, pixels, PORT)
    assert fp.port_exits_world is not None
    light = rig.lights[0]
    with_veil = shade(fp, view, rig, medium=WATER).values
    without = shade(fp, view, rig, medium=Medium(WATER.attenuation_per_m)).values
    ours = (with_veil - without) / (light.scale * view.exposure * WATER.backscatter_per_m)
    ref = np.array(
        [
            _veil_reference(s, e, light, view)
            for s, e in zip(fp.port_exits_world, fp.centers_world, strict=True)
        ]
    )
    ok = fp.valid
    assert ok.sum() > 20
    # The veil enters the camera through the port: times its Fresnel transmittance.
    assert fp.port_transmittance is not None
    assert np.all((fp.port_transmittance[ok] > 0.9) & (fp.port_transmittance[ok] < 0.96))
    np.testing.assert_allclose(ours[ok], ref[ok] * fp.port_transmittance[ok], rtol=1e-6)
    assert np.all(np.linalg.norm(fp.port_exits_world[ok] - view.center_world, axis=1) > 0.02)


def test_backscatter_gradients_through_the_port_agree_with_central_differences() -> None:
    """Within 1e-5 of each column's largest difference: the veil's derivatives are the
    quadrature rule applied to the integrand's (`lightcal.core.kernels.backscatter`),
    measured 7e-6 where the light is close to the rays' starts on the port."""
    camera, view, rig = _camera(), _view(), _rig()
    fp = port_footprints(camera, view, _all_pixels(camera)[::7], PORT)
    s = shade(fp, view, rig, want_grad=True, medium=WATER)
    assert s.grad_position is not None and s.grad_rotation is not None
    assert s.grad_medium is not None and s.grad_medium.shape[1] == 3
    light, h = rig.lights[0], 1e-6

    def at(light_: Light, medium: Medium = WATER) -> np.ndarray:
        return shade(fp, view, Rig.single(light_), medium=medium).values.filled(np.nan)

    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        fd = (
            at(light.replace(t_camera_light=light.t_camera_light + e))
            - at(light.replace(t_camera_light=light.t_camera_light - e))
        ) / (2 * h)
        ok = np.isfinite(fd)
        np.testing.assert_allclose(
            s.grad_position[0, ok, k], fd[ok], rtol=1e-5, atol=1e-5 * np.abs(fd[ok]).max()
        )
    names = ("attenuation_per_m", "backscatter_per_m", "phase_g")
    for k, name in enumerate(names):
        values = {n: getattr(WATER, n) for n in names}
        up, dn = dict(values), dict(values)
        up[name] += h
        dn[name] -= h
        fd = (at(light, Medium(**up)) - at(light, Medium(**dn))) / (2 * h)
        ok = np.isfinite(fd)
        np.testing.assert_allclose(
            s.grad_medium[ok, k], fd[ok], rtol=1e-5, atol=1e-7 * np.abs(fd[ok]).max()
        )


def test_the_light_and_the_water_are_recovered_through_the_port_with_backscatter(
    tmp_path: Path,
) -> None:
    """`lightcal synth --port 20 10 1.49 1.333 --declare-port --attenuation 0.3
    --backscatter 0.6 --phase-g 0.8`, c and beta estimated (320 x 240, 10 views, synth's
    noise, poses to 0.5 mm / 0.05 deg): the light within 3 mm and 0.2 degrees, c within
    5 % (the issue's bounds in water with backscatter)."""
    out = tmp_path / "data"
    water = ["--attenuation", "0.3", "--backscatter", "0.6", "--phase-g", "0.8"]
    water += ["--declare-medium", "estimated"]
    argv = ["synth", str(out), "--width", "320", "--height", "240", "--views", "10"]
    argv += ["--port", "20", "10", "1.49", "1.333", "--declare-port", *water]
    assert main([*argv, "--seed", "3", "--quiet"]) == 0
    doc = json.loads((out / "project.json").read_text())
    assert doc["medium"]["estimate"] == ["attenuation_per_m", "backscatter_per_m"]
    doc["selection"]["n_per_image"] = 4000
    # From a rough guess of the water a scattering solve can stop in a wrong minimum
    # (docs/model.md, "Medium": one in six from air; this data at an earlier commit, 20 cm
    # off with c 0.15): the documented remedy, random starts.
    doc.setdefault("solver", {})["multistart"] = 4
    (out / "project.json").write_text(json.dumps(doc))
    position, axis, medium = calibrate_synth_folder(out)
    print(
        f"\n{position * 1e3:.2f} mm, {axis:.3f} deg, c {medium.attenuation_per_m:.4f}, "
        f"beta {medium.backscatter_per_m:.4f}"
    )
    assert position < 3e-3 and axis < 0.2
    assert medium.attenuation_per_m == pytest.approx(0.3, rel=0.05)
    assert medium.backscatter_per_m == pytest.approx(0.6, rel=0.05)
