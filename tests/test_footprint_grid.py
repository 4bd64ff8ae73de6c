"""Footprints without kept quads (`GridCorners`): every number as with the quads kept.

A dense selection's `Footprints` hold the camera's corner grid and the view instead of
96 bytes a quad; the flux kernel, the centres and `corners_world` recompute the quads from
there. These tests hold each of them to the kept-quads path bit for bit (renders with and
without gradients, every RID model, binning, sub-sampled RIDs, invalid pixels, pixels out
of order), and the memory the footprints keep.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from lightcal.core.corner_grid import GRID_CACHE
from lightcal.core.footprint import Footprints, pixel_footprints, quad_corner_means
from lightcal.core.kernels.flux import SERIAL_WORK
from lightcal.core.render import shade
from lightcal.core.scene import Light, Rig, View
from lightcal.core.wall import make_wall
from tests.scenes import (
    MILD_DISTORTION,
    RID_NAMES,
    all_pixels,
    horizon_view,
    oblique_view,
    pinhole_camera,
    rid_model,
    rotation_with_z,
)

WIDTH, HEIGHT = 200, 150  # 30,000 pixels: the parallel kernels


@pytest.fixture(autouse=True)
def _fresh_grid_cache() -> Iterator[None]:
    GRID_CACHE.clear()
    yield
    GRID_CACHE.clear()


def _kept(fp: Footprints) -> Footprints:
    """The same footprints with their quads kept (the sparse selections' form)."""
    return Footprints(fp.pixels, fp.corners_world, fp.weights, fp.valid, fp.area_m2)


def _dense(view: View, *, binning: int = 1, shuffle: bool = False) -> Footprints:
    # The field of view of the 64 x 48 scenes (focal length scaled), mild distortion.
    camera = pinhole_camera(width=WIDTH, height=HEIGHT, focal_px=190.0, dist=MILD_DISTORTION)
    pixels = all_pixels(WIDTH // binning, HEIGHT // binning)
    if shuffle:  # any order, repeats: not the rows of a dense selection
        rng = np.random.default_rng(4)
        pixels = np.concatenate([pixels, pixels[:500]])[rng.permutation(len(pixels) + 500)]
    fp = pixel_footprints(camera, view, pixels, binning=binning, sensor="cos4")
    assert fp.stored_corners is None and fp.grid is not None
    return fp


def _light(rid_name: str) -> Light:
    return Light(
        rid_model(rid_name),
        np.array([0.11, -0.04, 0.02]),
        rotation_with_z((-0.12, 0.08, 1.0)),
        scale=2.5,
    )


@pytest.mark.parametrize("rid_name", RID_NAMES)
def test_grid_footprints_render_bit_for_bit_as_kept_quads(rid_name: str) -> None:
    view = oblique_view()
    fp = _dense(view)
    assert len(fp) * fp.weights.shape[1] >= SERIAL_WORK  # the parallel grid kernel
    rig = Rig.single(_light(rid_name))
    for want_grad in (False, True):
        grid = shade(fp, view, rig, want_grad=want_grad)
        kept = shade(_kept(fp), view, rig, want_grad=want_grad)
        assert np.isfinite(grid.values.filled(np.nan)).all()
        assert grid.flux.max() > 0.0
        np.testing.assert_array_equal(grid.values.filled(np.nan), kept.values.filled(np.nan))
        np.testing.assert_array_equal(grid.flux, kept.flux)
        if want_grad:
            np.testing.assert_array_equal(grid.grad_position, kept.grad_position)
            np.testing.assert_array_equal(grid.grad_rotation, kept.grad_rotation)


@pytest.mark.parametrize(
    ("binning", "rid_subsamples", "shuffle"),
    [(2, 1, False), (1, 2, False), (3, 2, True), (1, 1, True)],
)
def test_binning_subsampling_invalid_pixels_and_any_order(
    binning: int, rid_subsamples: int, shuffle: bool
) -> None:
    view = horizon_view()  # its upper rows miss the wall: invalid pixels among valid ones
    fp = _dense(view, binning=binning, shuffle=shuffle)
    assert 0 < fp.valid.sum() < len(fp)
    kept = _kept(fp)
    np.testing.assert_array_equal(np.isnan(kept.corners_world).all(axis=(1, 2, 3)), ~fp.valid)
    rig = Rig.single(_light("table_1d"))
    for want_grad in (False, True):
        grid = shade(fp, view, rig, want_grad=want_grad, rid_subsamples=rid_subsamples)
        ref = shade(kept, view, rig, want_grad=want_grad, rid_subsamples=rid_subsamples)
        np.testing.assert_array_equal(grid.values.mask, ~fp.valid)
        np.testing.assert_array_equal(grid.values.filled(np.nan), ref.values.filled(np.nan))
        np.testing.assert_array_equal(grid.flux, ref.flux)
        if want_grad:
            np.testing.assert_array_equal(grid.grad_position, ref.grad_position)
            np.testing.assert_array_equal(grid.grad_rotation, ref.grad_rotation)


def test_a_few_pixels_take_the_serial_kernel_with_the_same_numbers() -> None:
    view = oblique_view()
    fp = _dense(view).subset(np.arange(0, 30_000, 97))  # 310 pixels: below SERIAL_WORK
    assert fp.grid is not None and len(fp) < SERIAL_WORK
    rig = Rig.single(_light("gaussian"))
    grid = shade(fp, view, rig, want_grad=True)
    ref = shade(_kept(fp), view, rig, want_grad=True)
    np.testing.assert_array_equal(grid.flux, ref.flux)
    np.testing.assert_array_equal(grid.grad_position, ref.grad_position)


def test_centers_and_a_non_lambertian_wall_from_the_grid() -> None:
    view = horizon_view()
    fp = _dense(view, binning=2)
    kept = _kept(fp)
    centers = fp.centers_now()
    np.testing.assert_array_equal(centers, quad_corner_means(kept.corners_world))
    np.testing.assert_array_equal(np.isnan(centers[:, 0]), ~fp.valid)
    assert np.all(centers[fp.valid, 2] == 0.0)  # on the wall
    assert "centers_world" not in fp.__dict__  # centers_now keeps nothing
    wall = make_wall("plastic", {"specular_weight": 0.2, "roughness": 0.3})
    rig = Rig.single(_light("cos_power"))
    grid = shade(fp, view, rig, want_grad=True, wall=wall)
    ref = shade(kept, view, rig, want_grad=True, wall=wall)
    np.testing.assert_array_equal(grid.flux, ref.flux)
    np.testing.assert_array_equal(grid.grad_wall, ref.grad_wall)
    np.testing.assert_array_equal(fp.centers_world, centers)  # now kept


def test_subsets_share_the_grid_and_keep_no_quads() -> None:
    view = oblique_view()
    fp = _dense(view)
    rows = np.arange(100, 20_000, 3)
    sub = fp.subset(rows)
    assert sub.grid is fp.grid and sub.stored_corners is None
    np.testing.assert_array_equal(sub.corners_world, fp.corners_world[rows])
    kept_bytes = sum(getattr(fp, name).nbytes for name in ("pixels", "weights", "valid", "area_m2"))
    assert kept_bytes == len(fp) * 25  # 8 + 8 + 1 + 8 bytes a pixel, no 96-byte quad


def test_footprints_need_exactly_one_source_of_quads() -> None:
    fp = _dense(oblique_view()).subset(np.arange(4))
    with pytest.raises(ValueError, match="either stored corners or a corner grid"):
        Footprints(fp.pixels, None, fp.weights, fp.valid, fp.area_m2)
    with pytest.raises(ValueError, match="either stored corners or a corner grid"):
        Footprints(fp.pixels, fp.corners_world, fp.weights, fp.valid, fp.area_m2, fp.grid)
