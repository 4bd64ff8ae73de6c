"""The compiled `pixel_footprints` against the NumPy formulation it replaced.

`_reference_footprints` is the former NumPy implementation of
`lightcal.core.footprint.pixel_footprints`, kept verbatim (with its `corners_to_wall`) as
the ground truth of the kernel in `lightcal.core.footprint_kernels`. It undistorts the
corners with `Camera.pixels_to_normalized`, as the kernel's direct path does; the grid
path reads them from the camera's corner grid, which agrees with it to round-off (not bit
for bit: tests/test_corner_grid.py), so that path is held to the reference fed the grid's
corners, and to the direct path within what the grid's 1e-12 allows.
"""

from __future__ import annotations

import math
import tracemalloc
from collections.abc import Iterator
from fractions import Fraction
from typing import Any, Literal

import numpy as np
import pytest

from lightcal.core import footprint
from lightcal.core import footprint_kernels as fk
from lightcal.core.camera import Camera
from lightcal.core.corner_grid import GRID_CACHE, CornerGrid, corner_grid
from lightcal.core.footprint import (
    SENSOR_MODELS,
    Footprints,
    SensorModel,
    check_pixels,
    check_vignetting,
)
from lightcal.core.scene import View
from tests.scenes import (
    MILD_DISTORTION,
    all_pixels,
    distorted_camera,
    oblique_view,
    pinhole_camera,
)

_CORNER_OFFSETS = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]])


def _reference_corners_to_wall(
    xy: np.ndarray, ok: np.ndarray, view: View
) -> tuple[np.ndarray, np.ndarray]:
    rays_camera = np.concatenate([xy, np.ones((xy.shape[0], 1))], axis=1)
    d = rays_camera @ view.R_camera_world  # rows: R^T ray
    c = view.center_world
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = -c[2] / d[:, 2]
    hit = ok & (d[:, 2] < 0.0) & (lam > 0.0)
    points = c + lam[:, None] * d
    points[:, 2] = 0.0
    points[~hit] = np.nan
    return points, hit


def _reference_footprints(
    camera: Camera,
    view: View,
    pixels: np.ndarray,
    *,
    sensor: SensorModel = "radiance",
    vignetting: np.ndarray | None = None,
    binning: int = 1,
    grid: CornerGrid | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(pixels, corners_world, weights, valid, area_m2) as the NumPy implementation had them.

    The corners are undistorted by `Camera.pixels_to_normalized`, or read from `grid`
    (the camera's `corner_grid`: corner (u, v) of pixel coordinates at index
    (v + 1/2, u + 1/2)) when it is given.
    """
    b = int(binning)
    p = check_pixels(pixels, camera.width // b, camera.height // b)
    if sensor == "map":
        vignetting = check_vignetting(vignetting, camera)
    n = p.shape[0]
    k = b * b
    jj, ii = np.meshgrid(np.arange(b), np.arange(b), indexing="ij")
    member = (p[:, None, :] * b + np.stack([ii.ravel(), jj.ravel()], axis=1)[None]).reshape(
        n * k, 2
    )
    corner_px = (member[:, None, :] + _CORNER_OFFSETS[None]).reshape(-1, 2)
    if grid is None:
        xy, ok = camera.pixels_to_normalized(corner_px)
    else:
        ii, jj = (corner_px + 0.5).astype(np.int64).T
        ok = grid[1][jj, ii]
        xy = np.where(ok[:, None], grid[0][jj, ii], np.nan)
    points, hit = _reference_corners_to_wall(xy, ok, view)
    corners = points.reshape(n, k, 4, 3)
    valid: np.ndarray = np.all(hit.reshape(n, k * 4), axis=1)

    d1 = corners[:, :, 2, :2] - corners[:, :, 0, :2]
    d2 = corners[:, :, 3, :2] - corners[:, :, 1, :2]
    quad_area = 0.5 * np.abs(d1[..., 0] * d2[..., 1] - d1[..., 1] * d2[..., 0])  # (n, k)
    area = quad_area.sum(axis=1)

    if sensor == "paper":
        centroid = corners.mean(axis=2)  # (n, k, 3)
        offset = view.center_world - centroid
        d2sum = np.einsum("nkd,nkd->nk", offset, offset)
        weights = (view.center_world[2] / np.sqrt(d2sum)) / d2sum / k
    else:
        if sensor == "cos4":
            xy_mean = xy.reshape(n, k, 4, 2).mean(axis=2)
            cos2 = 1.0 / (1.0 + np.einsum("nkd,nkd->nk", xy_mean, xy_mean))
            v_mean = (cos2 * cos2).mean(axis=1)
        elif sensor == "map":
            assert vignetting is not None
            v_mean = vignetting[member[:, 1], member[:, 0]].reshape(n, k).mean(axis=1)
        else:
            v_mean = np.ones(n)
        with np.errstate(divide="ignore", invalid="ignore"):
            weights = np.repeat((v_mean / area)[:, None], k, axis=1)
    weights = np.where(valid[:, None], weights, 0.0)
    corners[~valid] = np.nan
    area = np.where(valid, area, np.nan)
    s = footprint.quads_per_side(b)
    if s < b:
        corners, weights = _merged(corners, weights, b, s)
    return p, corners, weights, valid, area


def _merged(
    corners: np.ndarray, weights: np.ndarray, b: int, s: int
) -> tuple[np.ndarray, np.ndarray]:
    """Members' quads (n, b^2, 4, 3) and weights (n, b^2) merged into s x s groups of
    g x g members (g = b / s): each group's quad the outer corners of its corner members'
    quads, its weight the mean of its members'."""
    n = corners.shape[0]
    g = b // s
    c = corners.reshape(n, s, g, s, g, 4, 3)
    merged = np.stack(
        [c[:, :, 0, :, 0, 0], c[:, :, 0, :, -1, 1], c[:, :, -1, :, -1, 2], c[:, :, -1, :, 0, 3]],
        axis=3,
    ).reshape(n, s * s, 4, 3)
    w = weights.reshape(n, s, g, s, g).transpose(0, 1, 3, 2, 4).reshape(n, s * s, g * g)
    return merged, w.sum(axis=2) / (g * g)


# ---------------------------------------------------------------- scenes


def _strong_barrel_camera() -> Camera:
    """Skewed, strongly distorted: the outer corners fall outside the model's valid region."""
    return Camera.from_params(
        fx=30.0,
        fy=31.0,
        cx=32.3,
        cy=23.6,
        width=64,
        height=48,
        dist=(-0.6, 0.1, 0.001, -0.002),
        skew=0.4,
    )


def _vignetting(camera: Camera) -> np.ndarray:
    rng = np.random.default_rng(7)
    return rng.uniform(0.4, 1.0, (camera.height, camera.width))


def _rolled_horizon_view() -> View:
    """`horizon_view` turned and rolled: no rotation entry is 0, the horizon is slanted."""
    return View.looking_at(
        np.array([0.0, -2.0, 0.5]), np.array([0.4, 3.0, 0.0]), up_world=(0.15, 0.0, 1.0)
    )


def _rolled_down_view() -> View:
    """Nearly straight down, turned about every axis."""
    return View.looking_at(
        np.array([0.1, -0.2, 1.2]), np.array([0.05, -0.1, 0.0]), up_world=(0.3, -1.0, 0.1)
    )


#: name: (camera, view); "horizon": some corner rays miss the wall; "strong": some
#: corners do not undistort.
SCENES = {
    "oblique": (distorted_camera, oblique_view),
    "horizon": (distorted_camera, _rolled_horizon_view),
    "strong_distortion": (_strong_barrel_camera, _rolled_down_view),
    "strong_distortion_horizon": (_strong_barrel_camera, _rolled_horizon_view),
}


def _matmul_rounds_like_fma() -> bool:
    """Whether `(N, 3) @ (3, 3)` here rounds as fl(fl(fma(y, R1, fl(x R0))) + R2).

    The kernel reproduces OpenBLAS's FMA kernels (x86-64 since Haswell, ARM64); with any
    other BLAS the reference's ray directions differ from the kernel's by an ulp.
    """
    rng = np.random.default_rng(3)
    xy = rng.normal(size=(64, 2))
    R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    d = np.concatenate([xy, np.ones((64, 1))], axis=1) @ R
    for (x, y), row in zip(xy, d, strict=True):
        for k in range(3):
            inner = float(Fraction(y) * Fraction(R[1, k]) + Fraction(x * R[0, k]))
            if float(Fraction(inner) + Fraction(R[2, k])) != row[k]:
                return False
    return True


MATMUL_ROUNDS_LIKE_FMA = _matmul_rounds_like_fma()


@pytest.fixture(autouse=True)
def _fresh_grid_cache() -> Iterator[None]:
    GRID_CACHE.clear()
    yield
    GRID_CACHE.clear()


def _footprints(
    camera: Camera,
    view: View,
    pixels: np.ndarray,
    path: Literal["grid", "direct"],
    monkeypatch: pytest.MonkeyPatch,
    **options: Any,
) -> Footprints:
    """`pixel_footprints` forced onto one corner source."""
    GRID_CACHE.clear()
    monkeypatch.setattr(footprint, "GRID_MIN_CORNER_SHARE", 0.0 if path == "grid" else math.inf)
    fp = footprint.pixel_footprints(camera, view, pixels, **options)
    assert (GRID_CACHE.lookup(camera) is not None) == (path == "grid")
    return fp


def _assert_same_as_reference(fp: Footprints, reference: tuple[np.ndarray, ...]) -> None:
    pixels, corners, weights, valid, area = reference
    np.testing.assert_array_equal(fp.pixels, pixels)
    np.testing.assert_array_equal(fp.valid, valid)
    if MATMUL_ROUNDS_LIKE_FMA:
        np.testing.assert_array_equal(fp.corners_world, corners)
    else:  # an ulp in a ray's direction, amplified near the horizon
        np.testing.assert_allclose(fp.corners_world, corners, rtol=1e-9)
    np.testing.assert_allclose(fp.weights, weights, rtol=1e-14, atol=0.0)
    np.testing.assert_allclose(fp.area_m2, area, rtol=1e-14, atol=0.0)
    assert fp.corners_world.shape == corners.shape and fp.weights.shape == weights.shape


# ---------------------------------------------------------------- the kernel vs NumPy


@pytest.mark.parametrize("path", ["grid", "direct"])
@pytest.mark.parametrize("binning", [1, 3])
@pytest.mark.parametrize("scene", list(SCENES))
def test_every_sensor_matches_the_numpy_reference(
    scene: str, binning: int, path: Literal["grid", "direct"], monkeypatch: pytest.MonkeyPatch
) -> None:
    make_camera, make_view = SCENES[scene]
    camera, view = make_camera(), make_view()
    vignetting = _vignetting(camera)
    pixels = all_pixels(camera.width // binning, camera.height // binning)
    for sensor in SENSOR_MODELS:
        options: dict[str, Any] = {"sensor": sensor, "vignetting": vignetting, "binning": binning}
        grid = corner_grid(camera) if path == "grid" else None
        reference = _reference_footprints(camera, view, pixels, grid=grid, **options)
        fp = _footprints(camera, view, pixels, path, monkeypatch, **options)
        _assert_same_as_reference(fp, reference)
    # The scene exercises what it is named for: misses, undistortion failures, both kinds.
    valid = reference[3]
    assert valid.any()
    if scene != "oblique":
        assert not valid.all()
    corner_px = np.stack(np.meshgrid(np.arange(65) - 0.5, np.arange(49) - 0.5), -1)
    _, undistorted = camera.pixels_to_normalized(corner_px.reshape(-1, 2))
    assert undistorted.all() == (not scene.startswith("strong"))


@pytest.mark.parametrize("binning", [2, 4, 12])
def test_odd_binnings_match_the_numpy_reference(
    binning: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    # b^2 = 4 (sequential sums), 16 (NumPy's 8-way pairwise sum), 144 (its split halves).
    camera = _strong_barrel_camera()
    view = oblique_view()
    vignetting = _vignetting(camera)
    pixels = all_pixels(camera.width // binning, camera.height // binning)
    for sensor in ("cos4", "map", "paper"):
        options: dict[str, Any] = {"sensor": sensor, "vignetting": vignetting, "binning": binning}
        for path in ("grid", "direct"):
            grid = corner_grid(camera) if path == "grid" else None
            reference = _reference_footprints(camera, view, pixels, grid=grid, **options)
            fp = _footprints(camera, view, pixels, path, monkeypatch, **options)
            _assert_same_as_reference(fp, reference)


@pytest.mark.parametrize("sensor", SENSOR_MODELS)
def test_grid_and_direct_paths_agree(sensor: SensorModel, monkeypatch: pytest.MonkeyPatch) -> None:
    # The same pixels valid; the numbers as close as the grid's corners are to
    # `pixels_to_normalized`'s (1e-12 in normalised coordinates, ~1e-15 in fact): a
    # super-pixel here spans ~0.1 in normalised coordinates and the rolled horizon view
    # meets the wall at a grazing angle, so 1e-10 relative (found: ~1e-13).
    camera = _strong_barrel_camera()
    view = _rolled_horizon_view()
    rng = np.random.default_rng(11)
    pixels = rng.integers(0, [21, 16], size=(300, 2))  # repeats, any order
    options: dict[str, Any] = {"sensor": sensor, "vignetting": _vignetting(camera), "binning": 3}
    grid = _footprints(camera, view, pixels, "grid", monkeypatch, **options)
    direct = _footprints(camera, view, pixels, "direct", monkeypatch, **options)
    assert 0 < grid.valid.sum() < len(pixels)
    np.testing.assert_array_equal(grid.pixels, direct.pixels)
    np.testing.assert_array_equal(grid.valid, direct.valid)
    for name in ("corners_world", "weights", "area_m2"):
        np.testing.assert_allclose(getattr(grid, name), getattr(direct, name), rtol=1e-10)


@pytest.mark.parametrize("path", ["grid", "direct"])
def test_serial_and_parallel_kernels_agree_bit_for_bit(
    path: Literal["grid", "direct"], monkeypatch: pytest.MonkeyPatch
) -> None:
    # Selections of up to one work item run on the calling thread; both read the corners
    # from the same source (the cached grid, or each its own undistortion).
    camera = pinhole_camera(width=160, height=120, dist=MILD_DISTORTION)
    view = oblique_view()
    pixels = all_pixels(160, 120)
    assert len(pixels) > fk.CHUNK_CORNERS  # several parallel work items
    whole = _footprints(camera, view, pixels, path, monkeypatch, sensor="cos4")
    parts = [
        footprint.pixel_footprints(camera, view, pixels[i : i + 100], sensor="cos4")
        for i in range(0, len(pixels), 100)
    ]
    assert (GRID_CACHE.lookup(camera) is not None) == (path == "grid")
    for name in ("corners_world", "weights", "valid", "area_m2"):
        np.testing.assert_array_equal(
            getattr(whole, name), np.concatenate([getattr(fp, name) for fp in parts])
        )


def test_empty_selection() -> None:
    camera = distorted_camera()
    fp = footprint.pixel_footprints(camera, oblique_view(), np.zeros((0, 2), int), binning=2)
    assert fp.corners_world.shape == (0, 4, 4, 3)
    assert fp.weights.shape == (0, 4) and fp.valid.shape == (0,) and fp.area_m2.shape == (0,)


# ---------------------------------------------------------------- which corner source


def test_a_sparse_selection_on_a_large_sensor_builds_no_grid() -> None:
    camera = Camera.from_params(
        fx=5640.0,
        fy=5640.0,
        cx=3000.2,
        cy=1999.1,
        width=6000,
        height=4000,
        dist=(-0.05, 0.01, 0.0, 0.0),
    )
    view = oblique_view()
    rng = np.random.default_rng(5)
    pixels = np.stack([rng.integers(0, 6000, 100), rng.integers(0, 4000, 100)], axis=1)
    fp = footprint.pixel_footprints(camera, view, pixels)
    assert GRID_CACHE.lookup(camera) is None
    reference = _reference_footprints(camera, view, pixels)
    _assert_same_as_reference(fp, reference)
    assert fp.valid.all()


def test_a_dense_selection_builds_the_grid_and_later_calls_read_it() -> None:
    camera = distorted_camera()
    view = oblique_view()
    n_grid = (camera.height + 1) * (camera.width + 1)
    n_dense = math.ceil(footprint.GRID_MIN_CORNER_SHARE * n_grid / 4)  # 4 corners a pixel
    pixels = all_pixels(camera.width, camera.height)
    footprint.pixel_footprints(camera, view, pixels[: n_dense - 1])
    assert GRID_CACHE.lookup(camera) is None
    footprint.pixel_footprints(camera, view, pixels[:n_dense])
    grid = GRID_CACHE.lookup(camera)
    assert grid is not None
    # A later single pixel reads the cached grid: mark one corner of pixel (5, 7) failed.
    assert footprint.pixel_footprints(camera, view, np.array([[5, 7]])).valid[0]
    grid[1][8, 6] = False  # corner (j, i) = (8, 6): P3 of pixel (5, 7)
    assert not footprint.pixel_footprints(camera, view, np.array([[5, 7], [3, 3]])).valid[0]


def test_no_temporaries_beyond_the_outputs() -> None:
    camera = pinhole_camera(width=200, height=150, dist=MILD_DISTORTION)
    view = oblique_view()
    pixels = all_pixels(200, 150)
    footprint.pixel_footprints(camera, view, pixels, sensor="cos4")  # builds the grid
    tracemalloc.start()
    try:
        fp = footprint.pixel_footprints(camera, view, pixels, sensor="cos4")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    # A dense selection does not keep its quads (96 bytes each): only these outputs.
    assert fp.stored_corners is None and fp.grid is not None
    outputs = sum(getattr(fp, name).nbytes for name in ("pixels", "weights", "valid", "area_m2"))
    assert outputs == len(pixels) * (8 + 8 + 1 + 8)
    assert outputs < peak < outputs + 100_000


# ---------------------------------------------------------------- kernel pieces


def test_pairwise_sum_is_numpys_row_sum() -> None:
    rng = np.random.default_rng(2)
    for n in [*range(0, 20), 31, 64, 127, 128, 129, 144, 255, 256, 400, 1031]:
        row = rng.uniform(-1.0, 1.0, n) * 10.0 ** rng.integers(-12, 12, n)
        padded = np.concatenate([[1e300], row])
        assert fk.pairwise_sum(padded, 1, n) == np.add.reduce(row[None], axis=1)[0], n
