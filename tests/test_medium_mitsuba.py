"""lightcal's render through water against Mitsuba 3's volumetric path tracer (skipped
without Mitsuba)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("mitsuba")

from lightcal.core.medium import Medium
from lightcal.core.render import render_image
from tests.mitsuba_datasets import mitsuba_variant
from tests.mitsuba_medium import render_in_water
from tests.mitsuba_peer import ALBEDO

C = 0.2


@pytest.fixture(scope="module")
def water() -> tuple:
    return render_in_water(32, 24, 1 << 16, C, mitsuba_variant())


def test_water_render_matches_mitsubas_volpath(water: tuple) -> None:
    """Median relative difference within 1e-3, over the lit pixels and in each half of
    their path lengths (a wrong distance would tilt it); the per-pixel spread is Mitsuba's
    free-flight noise, no more."""
    images, _ = water
    rel = images.relative()
    assert rel.size > 400
    assert abs(float(np.median(rel))) < 1e-3
    assert abs(float(np.mean(rel))) < 1e-3
    path = images.path_m[images.lit]
    middle = float(np.median(path))
    assert path.max() - path.min() > 0.4
    for half in (path <= middle, path > middle):
        assert abs(float(np.median(rel[half]))) < 1e-3
    noise = float(np.median(np.abs(rel))) / (0.6745 * float(np.median(images.expected_noise())))
    assert 0.8 < noise < 1.25


def test_the_comparison_sees_a_five_percent_error_in_c(water: tuple) -> None:
    """The same comparison with lightcal's c 5 % off (or the water left out) fails."""
    images, (camera, view, rig) = water
    for medium in (Medium(1.05 * C), Medium(0.95 * C), Medium(0.0)):
        other = render_image(camera, view, rig, medium=medium).filled(np.nan)
        assert abs(float(np.median(images.relative(other)))) > 3e-3


SCATTERING = {"scattering_albedo": 0.8, "phase_g": 0.5}  # sigma_s = 0.24 /m of c = 0.3 /m


@pytest.fixture(scope="module")
def murky() -> tuple:
    return render_in_water(32, 24, 1 << 16, 0.3, mitsuba_variant(), **SCATTERING)


def test_backscatter_matches_mitsubas_single_scattering(murky: tuple) -> None:
    """Water that scatters (single scattering, Henyey-Greenstein g = 0.5): the backscatter
    is a quarter of the signal (up to 70 % where the beam is dim), and lightcal's render
    agrees with Mitsuba's volpath to 1e-3 in the median, also where it dominates; the
    per-pixel spread is Mitsuba's noise (3e-3 at 2^16 samples). Without the backscatter,
    or with g 0.1 off, the comparison fails."""
    images, (camera, view, rig) = murky
    rel = images.relative()
    assert rel.size > 400
    assert abs(float(np.median(rel))) < 1e-3
    assert abs(float(np.mean(rel))) < 1e-3
    assert float(np.median(np.abs(rel))) < 5e-3
    c = images.attenuation_per_m
    clear = render_image(camera, view, rig, medium=Medium(c)).filled(np.nan)
    share = 1.0 - clear[images.lit] / images.ours[images.lit]
    assert float(np.median(share)) > 0.2
    dominated = share > 0.5
    assert dominated.sum() > 20
    assert abs(float(np.median(rel[dominated]))) < 2e-3
    assert float(np.median(images.relative(clear))) > 0.2
    m = Medium(c, 0.3 * 0.8 * np.pi / ALBEDO, 0.6)
    other = render_image(camera, view, rig, medium=m).filled(np.nan)
    assert abs(float(np.median(images.relative(other)))) > 1e-2
