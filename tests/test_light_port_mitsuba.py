"""lightcal's render of a light behind its flat port against Mitsuba 3's particle
tracer (`tests/mitsuba_light_port.py`: the port as two parallel dielectric faces in
front of the spot, the wall and the camera in the water; skipped without Mitsuba).

Measured (llvm_ad_rgb, 48 x 36, 1057 pixels lit above 30 % of the peak, 2^16 particles
a pixel, 17 s): a median relative difference of +2.9e-4, mean +1.4e-4, per-pixel spread
3.9e-3, the particles' Poisson noise (expected 3.9e-3). No radiance constant: the
particle tracer carries flux, which a refraction does not scale (the module's
docstring). Ignoring the port's Fresnel transmittance gives -4.2 %; ignoring the port
(the emitter straight in the water) +71 % in the median, 6.1 % spread. `ptracer` has no
media: absorption behind the light's port is not checked here.
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
