"""lightcal's render through the camera's flat port against Mitsuba 3's path tracers
(`tests/mitsuba_port.py`: the port as two parallel dielectric faces, the wall and the
spot in the water; skipped without Mitsuba).

Measured (llvm_ad_rgb, 48 x 36, every pixel lit above 30 % of the peak): without
absorption (`path`, 4096 samples) a median relative difference of +1.1e-4, per-pixel
spread 3.3e-4; in water of c = 0.2 /m (`volpath`, 16384 samples) +4.4e-4 (+3.2e-4 at
2^16 samples on 32 x 24), spread 2.6e-3. Mitsuba's radiance carries (n_air / n_w)^2,
divided out (lightcal leaves it to the light's scale). Ignoring the port's Fresnel
transmittance gives -4.1 %; ignoring the port (the test prints the numbers) far more.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mitsuba")

from lightcal.core.camera import Camera
from lightcal.core.medium import AIR, Medium
from lightcal.core.port_render import render_image_through_port
from lightcal.core.render import render_image
from tests.mitsuba_datasets import mitsuba_variant
from tests.mitsuba_port import N_WATER, render_through_port

C = 0.2


def _median(rel: np.ndarray) -> float:
    return float(np.median(rel))


def _spread(rel: np.ndarray) -> float:
    """1.4826 x the median absolute deviation: a robust standard deviation."""
    return 1.4826 * float(np.median(np.abs(rel - np.median(rel))))


@pytest.fixture(scope="module")
def clear() -> tuple:
    return render_through_port(48, 36, 1 << 12, 0.0, mitsuba_variant())


@pytest.fixture(scope="module")
def water() -> tuple:
    return render_through_port(48, 36, 1 << 14, C, mitsuba_variant())


def _without_the_port(scene: tuple, medium: Medium) -> dict[str, np.ndarray]:
    """lightcal's renders of the view without the port: the housing's intrinsics in
    air, and those with fx, fy times n_w (what intrinsics calibrated in water absorb)."""
    camera, view, rig, _ = scene
    K = camera.K
    in_water = Camera.from_params(
        fx=K[0, 0] * N_WATER, fy=K[1, 1] * N_WATER, cx=K[0, 2], cy=K[1, 2],
        width=camera.width, height=camera.height,
    )  # fmt: skip
    return {
        name: render_image(cam, view, rig, medium=medium).filled(np.nan)
        for name, cam in (("in-air K", camera), ("K x n_w", in_water))
    }


def test_the_port_render_matches_mitsubas_path_tracer(clear: tuple) -> None:
    """No absorption (`path`): the median relative difference within 1e-3 (measured
    +1.1e-4: the inner reflections and the port's reflection of the wall onto itself are
    about 1e-4 each), the per-pixel spread Mitsuba's noise, below that of independent
    Fresnel choices. Without the port's Fresnel transmittance, or without the port, the
    comparison fails."""
    images, scene = clear
    rel = images.relative()
    assert rel.size > 1500
    print(f"\nport, no absorption: median {_median(rel):+.2e}, spread {_spread(rel):.2e}")
    assert abs(_median(rel)) < 1e-3
    assert abs(float(np.mean(rel))) < 1e-3
    assert _spread(rel) < float(np.median(images.expected_noise()))
    # Ignoring the port's Fresnel transmittance: -4.1 %, mostly a constant (the light's
    # scale would absorb it), and a radial part that spans 2.7e-3 over this field.
    no_fresnel = images.relative(images.ours / images.fresnel)
    radial = (1.0 + no_fresnel) / (1.0 + _median(no_fresnel)) - 1.0
    print(
        f"ignoring Fresnel: median {_median(no_fresnel):+.2e}, spread {_spread(no_fresnel):.2e}"
        f"; its scale fitted: 1-99 % {np.percentile(radial, 1):+.2e} .. "
        f"{np.percentile(radial, 99):+.2e}"
    )
    assert _median(no_fresnel) < -0.03
    fresnel = images.fresnel[images.lit]
    assert fresnel.max() - fresnel.min() > 2e-3
    for name, plain in _without_the_port(scene, AIR).items():
        r = images.relative(plain)
        print(f"ignoring the port ({name}): median {_median(r):+.3f}, spread {_spread(r):.3f}")
        assert abs(_median(r)) > 0.02 or _spread(r) > 0.02


def test_the_port_render_in_water_matches_mitsubas_volpath(water: tuple) -> None:
    """Water of c = 0.2 /m entered at the port's outer face (`volpath`): the median
    relative difference within 1e-3 over the lit pixels and in each half of their path
    lengths in the water (measured +4.4e-4), the spread below independent sampling's
    (2.6e-3 against 6.6e-3). c 5 % off, or the water or the port dropped, fails."""
    images, scene = water
    rel = images.relative()
    assert rel.size > 1500
    path = images.path_m[images.lit]
    middle = float(np.median(path))
    halves = [_median(rel[h]) for h in (path <= middle, path > middle)]
    print(
        f"\nport, c = {C} /m: median {_median(rel):+.2e} (halves {halves[0]:+.2e}, "
        f"{halves[1]:+.2e}), spread {_spread(rel):.2e}"
    )
    assert abs(_median(rel)) < 1e-3
    assert abs(float(np.mean(rel))) < 1e-3
    assert path.max() - path.min() > 0.3
    assert max(abs(h) for h in halves) < 1e-3
    assert _spread(rel) < float(np.median(images.expected_noise()))
    camera, view, rig, port = scene
    for medium in (Medium(1.05 * C), Medium(0.95 * C), AIR):
        other = render_image_through_port(
            camera, view, rig, port, medium=medium, rid_subsamples=4
        ).filled(np.nan)
        assert abs(_median(images.relative(other))) > 1e-2
    for name, plain in _without_the_port(scene, Medium(C)).items():
        r = images.relative(plain)
        print(f"ignoring the port ({name}): median {_median(r):+.3f}, spread {_spread(r):.3f}")
        assert abs(_median(r)) > 0.02 or _spread(r) > 0.02


def test_the_veil_through_the_port_matches_mitsubas_volpath() -> None:
    """Scattering water behind the port (c = 0.3 /m, sigma_s = 0.24 /m, HG g = 0.5;
    `volpath`, max_depth 4: the two faces, then the wall or one scattering): the
    backscatter integrated along each refracted ray from the port's outer face, with
    the wall's light, within 1e-3 of Mitsuba in the median, where the veil is a large
    share of the signal."""
    images, scene = render_through_port(
        32, 24, 1 << 14, 0.3, mitsuba_variant(), max_depth=4, sigma_s_per_m=0.24, phase_g=0.5
    )
    camera, view, rig, port = scene
    rel = images.relative()
    clear_water = render_image_through_port(
        camera, view, rig, port, medium=Medium(0.3), rid_subsamples=4
    ).filled(np.nan)
    share = 1.0 - clear_water[images.lit] / images.ours[images.lit]
    print(
        f"\nveil through the port: median {_median(rel):+.2e}, spread {_spread(rel):.2e}, "
        f"veil share median {np.median(share):.2f} (max {share.max():.2f})"
    )
    assert rel.size > 300
    assert float(np.median(share)) > 0.1
    assert abs(_median(rel)) < 1e-3
