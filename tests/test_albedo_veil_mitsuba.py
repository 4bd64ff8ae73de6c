"""The albedo map beside the water's veil on data lightcal's model did not make: Mitsuba 3
renders a +-10 % textured wall in scattering water (`murky_albedo` of
`tests/mitsuba_datasets.py`: c 0.2 /m, sigma_s 0.16 /m, so beta = sigma_s pi / 0.8 =
0.63 /m, HG g 0.6; the veil is Mitsuba's `volpath`, a third of the signal in most views
and up to three quarters beside the light). The map must scale the wall's light and
leave the veil as it is (docs/model.md, "The albedo map", "In water").

Skipped without Mitsuba (`pip install .[reference]`).
"""

from __future__ import annotations

import json
from dataclasses import replace
from functools import partial
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mitsuba", reason="Mitsuba 3 is not installed: pip install .[reference]")

from lightcal.core.albedo_map import with_albedo
from lightcal.core.camera import Camera
from lightcal.core.medium import Medium
from lightcal.core.render import render_image
from lightcal.core.scene import Rig, View
from lightcal.synthetic.texture import AlbedoTexture
from tests.departure_suite import calibrated, exit_code
from tests.mitsuba_datasets import read_images, session_dataset, truth_scene

#: The water as a user would declare it: g as rendered, c and beta from a rough guess.
GUESSED = {
    "attenuation_per_m": 0.1,
    "backscatter_per_m": 0.3,
    "phase_g": 0.6,
    "estimate": ["attenuation_per_m", "backscatter_per_m"],
}


@pytest.fixture(scope="module")
def murky(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """12 views of 480 x 320, realistic noise (rendered in 83-208 s on 2 loaded cores)."""
    return session_dataset(tmp_path_factory, "murky_albedo", seed=0)


def test_the_map_and_the_water_land_on_the_truth(murky: Path) -> None:
    """The map on, c and beta estimated: the light within the issue's bound in water
    (3 mm, 0.2 deg) and 3 sigma, c within 5 %, beta within 10 % and 3 sigma, no finding,
    and the map is the texture (its range and its correlation with the truth)."""
    doc = json.loads(murky.read_text())
    doc.setdefault("wall", {})["albedo_map"] = {}
    doc["selection"].update(strategy="all", binning=4)  # 120 x 80 super-pixels an image
    doc["medium"] = GUESSED
    mapped = murky.with_name("murky_map.json")
    mapped.write_text(json.dumps(doc))
    result, (position, position_sigma, axis, axis_sigma) = calibrated(mapped)
    scene = truth_scene(murky)
    truth = scene.medium
    # Measured: 1.30 mm (sigma 1.31), 0.101 deg (0.091); c 0.1973 (sigma 0.0017), beta
    # 0.606 (0.154) of 0.628; the map 0.76-1.20, correlation 0.70 with the texture (0.92
    # 40 cm inside the seen wall); 14 iterations, 27-150 s on 2 loaded cores. Mitsuba's
    # veil noise (+-1 % beside the light) makes the images disagree on beta (the
    # jackknife): with 4 times the veil's samples beta's sigma is 0.012 and the map's
    # correlation 0.80, as on lightcal synth's render of the same scene (0.0126, 0.85).
    assert exit_code(result) == 0 and result.fit["findings"] == [], result.fit["findings"]
    assert position < 0.003 and axis < 0.2, (position, axis)
    assert position < 3 * position_sigma and axis < 3 * axis_sigma
    medium = result.medium
    assert medium["attenuation_per_m"] == pytest.approx(truth.attenuation_per_m, rel=0.05)
    assert medium["backscatter_per_m"] == pytest.approx(truth.backscatter_per_m, rel=0.1)
    beta_error = abs(medium["backscatter_per_m"] - truth.backscatter_per_m)
    assert beta_error < 3 * medium["sigma"]["backscatter_per_m"]
    assert result.albedo_map is not None and scene.texture is not None
    low, high = result.albedo_map["range"]
    assert low < 0.93 and high > 1.07  # the bitmap's +-10 %, seen through the noise
    assert _correlation(result.albedo_map, scene.texture) > 0.6


def _correlation(summary: dict, texture: AlbedoTexture) -> float:
    """The correlation of a result's albedo map with the true texture over its seen
    nodes."""
    values = np.array([[np.nan if v is None else v for v in row] for row in summary["values"]])
    j, i = np.mgrid[0 : values.shape[0], 0 : values.shape[1]]
    x0, y0 = summary["origin_xy_m"]
    nodes = np.stack([x0 + summary["spacing_m"] * i, y0 + summary["spacing_m"] * j], axis=-1)
    seen = np.isfinite(values)
    return float(np.corrcoef(texture.factor(nodes)[seen], values[seen])[0, 1])


def _values(camera: Camera, view: View, rig: Rig, medium: Medium) -> np.ndarray:
    """(H, W) lightcal's values of a view (NaN off the wall)."""
    return np.asarray(render_image(camera, view, rig, medium=medium).filled(np.nan))


def _split_fit(murky: Path, views: tuple[int, ...]) -> tuple[dict[str, float], np.ndarray]:
    """Each model's chi^2 / n against the images (the noise model's sigma), pooled over
    `views`, and the split model's residual regressed on (a - 1) x veil and
    (a - 1) x wall light (in sigmas): (how much of the map the veil lacks, how much of
    the map the wall lacks)."""
    scene = truth_scene(murky)
    noise = json.loads((murky.parent / "truth.json").read_text())["sensor"]["noise_model"]
    camera, rig, water = scene.camera, Rig.single(scene.light), scene.medium
    images = read_images(murky)
    chi2 = {"split": 0.0, "veil scaled": 0.0, "no map": 0.0}
    columns, residuals = [], []
    n = 0
    for i in views:
        view = scene.views[i]
        render = partial(_values, camera, view, rig)
        a = scene.albedo_factor(view)
        whole = render(water)
        wall = render(replace(water, backscatter_per_m=0.0))
        split = with_albedo(render, water, a)
        sigma = np.sqrt(noise["gain"] * np.maximum(split, 0.0) + noise["read_variance"])
        lit = np.isfinite(split) & (split > 0.02 * np.nanmax(split))
        for name, model in (("split", split), ("veil scaled", whole * a), ("no map", whole)):
            chi2[name] += float(np.sum(((images[i] - model) / sigma)[lit] ** 2))
        n += int(lit.sum())
        veil = whole - wall
        columns.append(np.stack([((a - 1) * veil / sigma)[lit], ((a - 1) * wall / sigma)[lit]], 1))
        residuals.append(((images[i] - split) / sigma)[lit])
    coef, *_ = np.linalg.lstsq(np.concatenate(columns), np.concatenate(residuals), rcond=None)
    return {name: value / n for name, value in chi2.items()}, coef


def test_lightcal_renders_mitsubas_veil_apart_from_the_map(murky: Path) -> None:
    """At the true poses, lightcal's render with the true texture as its map
    (`with_albedo` at the footprint centres) matches Mitsuba's images within their noise
    on the three views where the veil is about a third of the signal; the same map scaling
    the veil too, or no map, does not. The split model's residual holds none of the
    texture x veil term the other would add (coefficient 0, not -1)."""
    chi2, (veil_lacks, wall_lacks) = _split_fit(murky, (0, 5, 6))
    # Measured: chi^2 / n 1.024 (split), 1.231 (veil scaled), 1.314 (no map); the
    # residual on (a - 1) veil and (a - 1) wall: -0.001 and -0.008 (one view at a time:
    # -0.07 to 0.12 and -0.03 to 0.01). The excess over 1 is mostly Mitsuba's veil noise
    # beside the light (+-1 % of the value there).
    assert chi2["split"] < 1.05, chi2
    assert chi2["veil scaled"] > 1.15 and chi2["no map"] > 1.15, chi2
    assert abs(veil_lacks) < 0.1 and abs(wall_lacks) < 0.05, (veil_lacks, wall_lacks)
