"""`PlasticWall` against an independent implementation: Mitsuba 3's `roughplastic`.

Mitsuba is an optional test extra (`pip install .[reference]`); without it these tests
are skipped. Its BRDF times cos(theta_o) is `bsdf.eval`; `lightcal` writes B = f_r / k_d
with k_d = rho_d T(1)^2 / (pi eta^2 (1 - F_dr)) for `PlasticWall.from_albedo`.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from lightcal.core.wall import PlasticWall, internal_reflectance, rough_transmittance

mi = pytest.importorskip("mitsuba")


@pytest.fixture(scope="module", autouse=True)
def _variant() -> None:
    mi.set_variant("scalar_rgb")


def _directions() -> list[tuple[np.ndarray, np.ndarray]]:
    out = []
    for th_i in np.radians([0.0, 10.0, 30.0, 50.0, 70.0, 85.0]):
        for th_o in np.radians([0.0, 5.0, 20.0, 45.0, 60.0, 80.0]):
            for dphi in np.radians([0.0, 30.0, 90.0, 180.0]):
                wi = np.array([math.sin(th_i), 0.0, math.cos(th_i)])
                wo = np.array(
                    [
                        math.sin(th_o) * math.cos(dphi),
                        math.sin(th_o) * math.sin(dphi),
                        math.cos(th_o),
                    ]
                )
                out.append((wi, wo))
    return out


@pytest.mark.parametrize("ior", [1.3, 1.5, 1.8])
@pytest.mark.parametrize("roughness", [0.05, 0.1, 0.2, 0.3, 0.5, 0.8])
def test_plastic_matches_mitsuba_roughplastic(roughness: float, ior: float) -> None:
    albedo = 0.8
    bsdf = mi.load_dict(
        {
            "type": "roughplastic",
            "distribution": "ggx",
            "alpha": roughness,
            "int_ior": ior,
            "ext_ior": 1.0,
            "diffuse_reflectance": {"type": "rgb", "value": [albedo] * 3},
        }
    )
    wall = PlasticWall.from_albedo(roughness, ior, albedo)
    t1 = rough_transmittance(roughness, ior)[0][-1]
    k_d = albedo * t1**2 / (math.pi * ior**2 * (1.0 - internal_reflectance(roughness, ior)))
    ctx = mi.BSDFContext()
    worst = 0.0
    for wi, wo in _directions():
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*wi)
        si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
        reference = bsdf.eval(ctx, si, mi.Vector3f(*wo))[0] / wo[2]
        ours = k_d * wall.factor(wi[None], wo[None])[0][0]
        worst = max(worst, abs(ours - reference) / reference)
    assert worst < 1e-3
