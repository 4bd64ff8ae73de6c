"""lightcal's renderer against Mitsuba 3 on the same scene (skipped without Mitsuba)."""

from __future__ import annotations

import math

import pytest

pytest.importorskip("mitsuba")

from tests.mitsuba_peer import ALBEDO, compare


def test_full_frame_matches_mitsuba_up_to_the_lambertian_constant() -> None:
    r = compare(160, 120, spp=32)
    # Mitsuba's film records radiance: lightcal's radiance-model image times albedo / pi.
    assert r.scale == pytest.approx(ALBEDO / math.pi, rel=1e-3)
    assert r.lit > 10_000
    assert r.median_rel < 1e-3  # Mitsuba's pixel sampling noise at 32 samples
    assert r.p99_rel < 1e-2  # the spot's kinks at 25 and 40 degrees
