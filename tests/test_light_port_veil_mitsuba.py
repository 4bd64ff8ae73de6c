"""The veil of a light behind its flat port against Mitsuba 3, by reciprocity
(`tests/mitsuba_light_port_veil.py`: the ported light turned into Mitsuba's sensor
behind the same two dielectric faces, the camera's rays into a spot in the water;
skipped without Mitsuba). Measured (llvm_ad_rgb, 96 x 96 pixels over +-21 degrees, 2^10
samples a pixel, two seeds, 25 s): Mitsuba's f-weighted sum is lightcal's sigma_s I_s
(n_a / n_w)^2 integral of S over the spot's 8 degree cone to -1.4e-4, the two seeds
8.7e-4 apart. The pixels' discretisation (f times a radiance that jumps at the cone's
edge, summed pixel by pixel) costs O(pixel^2): -5e-3 on 24 x 24, -2e-3 to -4e-3 on
48 x 48.
"""

from __future__ import annotations

import pytest

pytest.importorskip("mitsuba")

from tests.mitsuba_datasets import mitsuba_variant
from tests.mitsuba_light_port_veil import compare


def test_the_veil_behind_the_lights_port_agrees_with_mitsuba_turned_round() -> None:
    result = compare(96, 1 << 10, mitsuba_variant())
    rel = result.theirs / result.ours - 1.0
    print(f"\nMitsuba (reciprocal) / lightcal - 1: {rel:+.2e}, seeds {2 * result.noise:.1e} apart")
    assert result.noise < 2e-3
    assert abs(rel) < 2e-3
