"""The camera's corner grid against `Camera.pixels_to_normalized`, corner by corner.

`corner_grid` seeds each corner's Newton iteration from its solved neighbours (issue 12);
`pixels_to_normalized` runs `undistort_normalized` from the distorted point, the grid's
arithmetic before. Stated accuracy: every valid corner maps back to its pixel within
1e-9 px and lies within 1e-12 of `pixels_to_normalized`'s root in normalised coordinates;
the validity flags are `pixels_to_normalized`'s exactly, failures included.
"""

from __future__ import annotations

from pathlib import Path

import numba
import numpy as np
import pytest

from lightcal.core import corner_grid as cg
from lightcal.core.camera import Camera
from lightcal.core.corner_grid import corner_grid
from lightcal.io.camera_file import read_camera
from tests.scenes import MILD_DISTORTION

REPO = Path(__file__).resolve().parents[1]

ROUND_TRIP_PX = 1e-9
NORMALISED_TOL = 1e-12


def _corner_pixels(camera: Camera, rows: np.ndarray | None = None) -> np.ndarray:
    """(n, 2) pixel coordinates (i - 1/2, j - 1/2) of the corners of `rows` (all), row-major."""
    j = np.arange(camera.height + 1) if rows is None else rows
    vv, uu = np.meshgrid(j - 0.5, np.arange(camera.width + 1) - 0.5, indexing="ij")
    return np.stack([uu.ravel(), vv.ravel()], axis=1)


def _assert_grid_matches(camera: Camera, rows: np.ndarray | None = None) -> int:
    """Check the grid's corners of `rows` (all) against `pixels_to_normalized` and their
    round trip; return how many fail."""
    grid_xy, grid_ok = corner_grid(camera)
    assert grid_xy.shape == (camera.height + 1, camera.width + 1, 2)
    assert grid_ok.shape == (camera.height + 1, camera.width + 1)
    j = np.arange(camera.height + 1) if rows is None else rows
    pixels = _corner_pixels(camera, j)
    xy = grid_xy[j].reshape(-1, 2)
    ok = grid_ok[j].ravel()
    expected, expected_ok = camera.pixels_to_normalized(pixels)
    np.testing.assert_array_equal(ok, expected_ok)  # failures where they were, no others
    assert np.all(xy[~ok] == 0.0)
    np.testing.assert_allclose(xy[ok], expected[ok], rtol=0.0, atol=NORMALISED_TOL)
    back = camera.normalized_to_pixels(xy[ok])
    assert np.abs(back - pixels[ok]).max(initial=0.0) <= ROUND_TRIP_PX
    return int(np.count_nonzero(~ok))


STRONG_CAMERAS = {
    # Skewed, strong barrel: the outer corners lie past the fold (k1 -0.6, k2 0.1).
    "barrel": Camera.from_params(
        fx=30.0, fy=31.0, cx=20.3, cy=14.6, width=40, height=30,
        dist=(-0.6, 0.1, 0.0, 0.0), skew=0.4,
    ),
    # The same with tangential terms (tests/test_footprint_kernels.py's scenes).
    "barrel_tangential": Camera.from_params(
        fx=30.0, fy=31.0, cx=32.3, cy=23.6, width=64, height=48,
        dist=(-0.6, 0.1, 0.001, -0.002), skew=0.4,
    ),
    # k1 alone folds at r = 0.98 (rho 0.65): the image's corners do not undistort.
    "folded": Camera.from_params(
        fx=280.0, fy=280.0, cx=179.5, cy=119.5, width=360, height=240,
        dist=(-0.35, 0.0, 0.0012, -0.0008),
    ),
    # Rational model, pincushion.
    "rational": Camera.from_params(
        fx=60.0, fy=58.0, cx=41.0, cy=29.0, width=80, height=60,
        dist=(0.4, -0.05, -0.004, 0.003, 0.01, 0.2, -0.1, 0.02),
    ),
}  # fmt: skip


@pytest.mark.parametrize("name", list(STRONG_CAMERAS))
def test_every_corner_of_a_strong_distortion_round_trips_and_fails_where_it_did(
    name: str,
) -> None:
    n_failed = _assert_grid_matches(STRONG_CAMERAS[name])
    camera = STRONG_CAMERAS[name]
    n_corners = (camera.width + 1) * (camera.height + 1)
    if name == "rational":
        assert n_failed == 0
    else:
        assert 0 < n_failed < n_corners / 2


def test_random_strong_cameras_agree_with_pixels_to_normalized() -> None:
    # Where a neighbour-seeded root is kept (`SAFE_SLOPE`, `SAFE_MARGIN`) was chosen on
    # 10,500 such cameras (no validity flag differed; without the margin some did, where
    # the distorted point lay at the disc's edge); these 150 keep an eye on it.
    rng = np.random.default_rng(2026)
    n_failed = 0
    for k in range(150):
        w, h = (int(n) for n in rng.integers(8, 120, 2))
        f = rng.uniform(0.15, 1.5) * w
        sc = rng.choice([0.1, 0.4, 1.0])
        dist = [*rng.normal(0, [0.4 * sc, 0.2 * sc, 0.03 * sc, 0.03 * sc, 0.1 * sc])]
        if k % 3 == 0:
            dist += [*rng.normal(0, 0.3 * sc, 3)]
        camera = Camera.from_params(
            fx=f, fy=f * rng.uniform(0.8, 1.2), cx=w / 2 + rng.normal(0, 5),
            cy=h / 2 + rng.normal(0, 5), width=w, height=h, dist=dist, skew=rng.normal(0, 0.5),
        )  # fmt: skip
        n_failed += _assert_grid_matches(camera)
    assert n_failed > 10_000  # many corners past a fold among them


def test_a_large_sensor_with_the_sample_distortion() -> None:
    # The sample camera at 2400 x 1600: every corner valid, every 37th row compared.
    sample = read_camera(REPO / "sample_data" / "camera.yaml")
    K = sample.K.copy()
    K[:2] *= 2.0
    K[0, 2] += 0.5
    K[1, 2] += 0.5
    camera = Camera(K=K, dist=sample.dist_opencv, width=2400, height=1600)
    assert _assert_grid_matches(camera, np.arange(0, 1601, 37)) == 0
    grid_xy, grid_ok = corner_grid(camera)
    assert grid_ok.all()
    back = camera.normalized_to_pixels(grid_xy.reshape(-1, 2))
    assert np.abs(back - _corner_pixels(camera)).max() <= ROUND_TRIP_PX


def test_the_grid_is_the_same_on_any_number_of_threads() -> None:
    # Blocks of rows are fixed by ROWS_PER_BLOCK, not by the threads: the same seeds.
    camera = Camera.from_params(
        fx=150.0, fy=150.0, cx=99.5, cy=74.5, width=200, height=150, dist=MILD_DISTORTION
    )
    assert camera.height + 1 > 2 * cg.ROWS_PER_BLOCK
    many = corner_grid(camera)
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        one = corner_grid(camera)
    finally:
        numba.set_num_threads(threads)
    np.testing.assert_array_equal(many[0], one[0])
    np.testing.assert_array_equal(many[1], one[1])


def test_without_distortion_the_corners_are_k_inverse() -> None:
    # To round-off: a seed is kept once its residual is (1e-15 relative), not only when 0.
    camera = Camera.from_params(fx=40.0, fy=44.0, cx=15.2, cy=11.7, width=30, height=24, skew=0.3)
    grid_xy, grid_ok = corner_grid(camera)
    assert grid_ok.all()
    pixels = _corner_pixels(camera)
    yd = (pixels[:, 1] - camera.cy) / camera.fy
    xd = (pixels[:, 0] - camera.cx - camera.skew * yd) / camera.fx
    expected = np.stack([xd, yd], axis=1)
    np.testing.assert_allclose(grid_xy.reshape(-1, 2), expected, rtol=0.0, atol=2e-15)
