"""Merged footprint quads of binned pixels (`footprint.quads_per_side`, issue 12).

A super-pixel of b x b pixels beyond `MAX_QUADS_PER_SIDE` a side is integrated over
s x s quads of g x g pixels (b = s g) instead of its b^2 pixels' quads. Solid angle is
additive, so only the RID's and the sensor weights' variation inside a group is
approximated: the values, gradients and solver estimates must stay as close to the exact
footprints' as measured here.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from lightcal.core import footprint
from lightcal.core.corner_grid import GRID_CACHE
from lightcal.core.footprint import MAX_QUADS_PER_SIDE, pixel_footprints, quads_per_side
from lightcal.core.problem import ImageData
from lightcal.core.render import shade
from lightcal.core.rid import RID, CosPowerRID
from lightcal.core.scene import Light, Rig
from lightcal.core.solver import run_least_squares
from lightcal.pipeline import summarise
from tests import calib_scenes as cs
from tests.scenes import (
    MILD_DISTORTION,
    oblique_view,
    pinhole_camera,
    rotation_with_z,
    symmetric_table_rid,
)

#: Bound on |merged / exact - 1| of a binning-4 super-pixel's value on the 1200 x 800
#: camera below (pixels ~0.9 mrad, 4 x 4 super-pixels merged into 2 x 2 quads), over both
#: RIDs, both sensor models and both corner sources. Measured: 1.3e-6 (cos^3.7), 8.2e-7
#: (table).
VALUE_BOUND = 3e-6
#: ... and of each pixel's position and rotation gradients (relative, as vectors).
#: Measured: position 1.7e-6 (cos^m), 9.1e-5 (table: its piecewise cubic derivative
#: varies fastest); rotation 2.1e-5 (cos^m), 5.6e-4 (table; small near the axis).
GRAD_BOUNDS = (2e-4, 1e-3)


def test_quads_per_side() -> None:
    assert MAX_QUADS_PER_SIDE == 2
    assert [quads_per_side(b) for b in (1, 2, 3, 4, 5, 6, 8, 12)] == [1, 2, 3, 2, 5, 2, 2, 2]
    assert quads_per_side(8, 4) == 4 and quads_per_side(6, 4) == 6
    assert quads_per_side(8, None) == 8


def _camera() -> Any:
    return pinhole_camera(width=1200, height=800, focal_px=0.94 * 1200, dist=MILD_DISTORTION)


def _vignetting(camera: Any) -> np.ndarray:
    """A smooth radial fall-off with a faint ripple (so groups' members differ)."""
    v, u = np.mgrid[0 : camera.height, 0 : camera.width].astype(float)
    r2 = ((u - camera.width / 2) ** 2 + (v - camera.height / 2) ** 2) / camera.width**2
    return 1.0 - 0.6 * r2 + 0.01 * np.sin(u / 3.0) * np.cos(v / 5.0)


def _rig(rid: RID) -> Rig:
    light = Light(rid, np.array([0.1, -0.03, 0.01]), rotation_with_z((0.05, -0.08, 1.0)))
    return Rig.single(light)


@pytest.mark.parametrize("path", ["stored", "grid"])
@pytest.mark.parametrize("rid_name", ["cos_power", "table"])
def test_values_and_gradients_of_merged_quads_match_the_exact_ones(
    rid_name: str, path: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    camera = _camera()
    view = oblique_view()
    b = 4
    rid = CosPowerRID(3.7) if rid_name == "cos_power" else symmetric_table_rid()
    rig = _rig(rid)
    rng = np.random.default_rng(4)
    pixels = np.stack(
        [rng.integers(0, camera.width // b, 3000), rng.integers(0, camera.height // b, 3000)], 1
    )
    GRID_CACHE.clear()
    monkeypatch.setattr(footprint, "GRID_MIN_CORNER_SHARE", 0.0 if path == "grid" else math.inf)
    vignetting = _vignetting(camera)
    for sensor in ("radiance", "map"):
        options: dict[str, Any] = {"sensor": sensor, "vignetting": vignetting, "binning": b}
        exact = pixel_footprints(camera, view, pixels, max_quads_per_side=None, **options)
        merged = pixel_footprints(camera, view, pixels, **options)
        assert (merged.grid is not None) == (path == "grid")
        assert merged.weights.shape == (len(pixels), 4) and exact.weights.shape[1] == 16
        np.testing.assert_array_equal(merged.valid, exact.valid)
        np.testing.assert_array_equal(merged.area_m2, exact.area_m2)
        assert merged.valid.sum() > 0.9 * len(pixels)
        # The centres: the mean of the groups' corners, not the members' (the wall's B is
        # evaluated there): a small fraction of a super-pixel's footprint apart.
        size = np.sqrt(exact.area_m2)
        shift = np.linalg.norm(merged.centers_now() - exact.centers_now(), axis=1) / size
        assert np.nanmax(shift) < 0.02
        a = shade(exact, view, rig, want_grad=True)
        m = shade(merged, view, rig, want_grad=True)
        ok = exact.valid
        rel = np.abs(m.values[ok] / a.values[ok] - 1.0)
        assert rel.max() < VALUE_BOUND, (sensor, rel.max())
        print(f"{rid_name} {path} {sensor}: values {rel.max():.2e}", end="")
        pairs = ((a.grad_position, m.grad_position), (a.grad_rotation, m.grad_rotation))
        for (ga, gm), bound in zip(pairs, GRAD_BOUNDS, strict=True):
            assert ga is not None and gm is not None
            # Each pixel's gradient against its own size (a component may vanish: the
            # roll of a symmetric light).
            size = np.linalg.norm(ga[0, ok], axis=1)
            grel = np.linalg.norm(gm[0, ok] - ga[0, ok], axis=1) / size
            print(f", gradient {grel.max():.2e}", end="")
            assert grel.max() < bound
        print()


def test_stored_and_grid_paths_of_merged_quads_agree(monkeypatch: pytest.MonkeyPatch) -> None:
    camera = _camera()
    view = oblique_view()
    pixels = np.stack(np.meshgrid(np.arange(0, 300, 7), np.arange(0, 200, 5)), -1).reshape(-1, 2)
    out = {}
    for path in ("stored", "grid"):
        GRID_CACHE.clear()
        monkeypatch.setattr(footprint, "GRID_MIN_CORNER_SHARE", 0.0 if path == "grid" else math.inf)
        fp = pixel_footprints(camera, view, pixels, sensor="cos4", binning=4)
        out[path] = (fp, shade(fp, view, _rig(CosPowerRID(3.7)), want_grad=True))
    (fs, ss), (fg, sg) = out["stored"], out["grid"]
    assert fs.grid is None and fg.grid is not None
    # The grid's corners and the direct undistortion's agree to round-off (metres).
    np.testing.assert_allclose(fg.corners_world, fs.corners_world, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(fg.centers_now(), fs.centers_now(), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(sg.values, ss.values, rtol=1e-11)
    np.testing.assert_allclose(sg.grad_position, ss.grad_position, rtol=1e-9, atol=1e-300)


def test_solver_estimate_moves_by_under_one_percent_of_its_sigma() -> None:
    # Noisy data rendered with the exact footprints; solved once with exact and once with
    # merged footprints of the same super-pixels: binning 4 of the 3000 x 2000 camera of
    # benchmarks/fullres.py (green-binned 6000 x 4000), 3000 random super-pixels a view.
    camera = cs.small_camera(width=3000, height=2000)
    truth = cs.symmetric_light()
    rig = Rig.single(truth)
    b = 4
    rng = np.random.default_rng(12)
    images: dict[str, list[ImageData]] = {"exact": [], "merged": []}
    for i, view in enumerate(cs.views(6)):
        pixels = np.unique(
            np.stack([rng.integers(0, 750, 3000), rng.integers(0, 500, 3000)], 1), axis=0
        )
        exact = pixel_footprints(camera, view, pixels, binning=b, max_quads_per_side=None)
        values = shade(exact, view, rig).values.filled(np.nan)
        keep = exact.valid & (values > 0.05 * np.nanmax(values))
        signal = values[keep]
        variance = (0.5 * signal + 4.0) / (b * b)
        observed = signal + rng.normal(size=signal.shape) * np.sqrt(variance)
        sigma = np.sqrt(variance)
        merged = pixel_footprints(camera, view, pixels[keep], binning=b)
        images["exact"].append(ImageData(f"v{i}", view, exact.subset(keep), observed, sigma))
        images["merged"].append(ImageData(f"v{i}", view, merged, observed, sigma))
    results = {}
    for name, data in images.items():
        model = cs.model_of(data, [cs.start_near(truth)])
        results[name] = summarise(model, run_least_squares(model)).lights[0]
    e, m = results["exact"], results["merged"]
    shift = np.abs(m.pose.t_camera_light - e.pose.t_camera_light) / e.sigma.t_camera_light
    print(f"position shift / sigma {shift}", end="")
    assert shift.max() < 0.01, shift
    for angle in ("roll_deg", "pitch_deg"):
        d = abs(getattr(m.pose, angle) - getattr(e.pose, angle)) / getattr(e.sigma, angle)
        print(f", {angle} {d:.2e}", end="")
        assert d < 0.01, (angle, d)
