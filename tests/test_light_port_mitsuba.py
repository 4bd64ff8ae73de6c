"""lightcal's render of a light behind its flat port against Mitsuba 3's particle
tracer (`tests/mitsuba_light_port.py`: the port as two parallel dielectric faces in
front of the spot, the wall and the camera in the water; skipped without Mitsuba).

Measured (llvm_ad_rgb, 48 x 36, 1057 pixels lit above 30 % of the peak, 2^16 particles
a pixel, 17 s): a median relative difference of +2.9e-4, mean +1.4e-4, per-pixel spread
3.9e-3, the particles' Poisson noise (expected 3.9e-3). No radiance constant: the
particle tracer carries flux, which a refraction does not scale (the module's
docstring). Ignoring the port's Fresnel transmittance gives -4.2 %; ignoring the port
(the emitter straight in the water) +71 % in the median, 6.1 % spread. `ptracer` has no
media: absorption behind the light's port is checked through its path length in the
water, Mitsuba's rays along lightcal's air directions refracted by its `dielectric`
faces reaching lightcal's wall points within 2.9e-7 m, their water segments within
4.1e-7 relative (exp(-c L) within 3e-7 at c = 0.5 /m).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("mitsuba")

from lightcal.core.render import render_image
from lightcal.core.scene import Rig
from tests.mitsuba_datasets import mitsuba_variant
from tests.mitsuba_light_port import render_light_port


def _median(rel: np.ndarray) -> float:
    return float(np.median(rel))


def _spread(rel: np.ndarray) -> float:
    """1.4826 x the median absolute deviation: a robust standard deviation."""
    return 1.4826 * float(np.median(np.abs(rel - np.median(rel))))


@pytest.fixture(scope="module")
def clear() -> tuple:
    return render_light_port(48, 36, 1 << 16, mitsuba_variant())


def test_the_light_port_render_matches_mitsubas_particle_tracer(clear: tuple) -> None:
    """No absorption (`ptracer`): the median and mean relative differences within 1e-3,
    the per-pixel spread the particles' Poisson noise (within 15 %), with no radiance
    constant (the path tracer's (n_air / n_w)^2 would be a factor 1.78 off). Without the
    port's Fresnel transmittance, or without the port, the comparison fails."""
    images, scene = clear
    rel = images.relative()
    assert rel.size > 900
    expected = float(np.median(images.expected_noise()))
    print(
        f"\nlight port, no absorption: median {_median(rel):+.2e}, mean "
        f"{float(np.mean(rel)):+.2e}, spread {_spread(rel):.2e} (Poisson {expected:.2e})"
    )
    assert abs(_median(rel)) < 1e-3
    assert abs(float(np.mean(rel))) < 1e-3
    assert _spread(rel) < 1.15 * expected
    # Ignoring the port's Fresnel transmittance (that of each footprint centre's air
    # angle): -4.2 %, mostly a constant the light's scale would absorb.
    no_fresnel = images.relative(images.ours / images.fresnel)
    print(f"ignoring Fresnel: median {_median(no_fresnel):+.2e}")
    assert _median(no_fresnel) < -0.03
    camera, view, rig, _ = scene
    plain = Rig.single(replace(rig.lights[0], port=None))
    r = images.relative(render_image(camera, view, plain, rid_subsamples=4).filled(np.nan))
    print(f"ignoring the port: median {_median(r):+.3f}, spread {_spread(r):.3f}")
    assert abs(_median(r)) > 0.3 and _spread(r) > 0.03


def test_the_water_path_through_the_port_is_mitsubas(clear: tuple) -> None:
    """`ptracer` has no media, so the light's absorption behind its port is checked
    through the one thing it depends on, the path length in the water |P - E|: Mitsuba's
    rays leaving the emitter along lightcal's air directions, refracted by its
    `dielectric` faces (float32), reach lightcal's wall points within 2e-6 m and their
    water segments agree within 2e-6 relative (measured 2.9e-7 m and 4.1e-7 over 1.2-1.6 m),
    so exp(-c |P - E|) agrees within 1e-6 at c = 0.5 /m."""
    from lightcal.core.footprint import pixel_footprints
    from tests.mitsuba_light_port import trace_light_paths

    images, scene = clear
    camera, view, _, _ = scene
    pixels = np.argwhere(images.lit)[::5, ::-1]  # (u, v) of every 5th lit pixel
    points = pixel_footprints(camera, view, pixels).centers_world
    traced = trace_light_paths(points, scene)
    miss = np.linalg.norm(traced.arrivals_world - points, axis=1)
    rel = traced.their_water_m / traced.water_m - 1.0
    print(
        f"\n{len(points)} paths: arrivals within {miss.max():.1e} m, water lengths "
        f"{np.abs(rel).max():.1e} relative ({traced.water_m.min():.2f}-"
        f"{traced.water_m.max():.2f} m); absorption at c = 0.5 /m "
        f"{np.abs(np.expm1(-0.5 * (traced.their_water_m - traced.water_m))).max():.1e}"
    )
    assert len(points) > 150
    assert miss.max() < 2e-6
    assert np.abs(rel).max() < 2e-6
    assert traced.water_m.max() - traced.water_m.min() > 0.2
    # The straight path from the emitter (no port) is far longer than lightcal's and
    # Mitsuba's water path: the check can tell the port's geometry apart.
    light = scene[2].lights[0]
    straight = np.linalg.norm(points - light.position_world(view), axis=1)
    assert np.min(straight - traced.their_water_m) > 0.01
