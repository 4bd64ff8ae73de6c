"""Pixel selection: candidates, regions, strategies, and what a project's images give the solver."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from lightcal.core.camera import Camera
from lightcal.core.footprint import pixel_footprints
from lightcal.core.problem import ImageData
from lightcal.core.scene import View
from lightcal.core.selection import (
    Region,
    SelectionOptions,
    bin_values,
    binned_candidates,
    candidate_mask,
    region_mask,
    select_pixels,
)
from lightcal.core.vignetting import RadialVignetting
from lightcal.io.project import load_project
from lightcal.io.vignetting_file import save_radial_vignetting
from lightcal.pipeline import image_data, load_images, noise_floor, vignetting_for
from lightcal.pipeline.load import _load_vignetting


def _pixels(mask: np.ndarray) -> set[tuple[int, int]]:
    """{(u, v)} of the True entries of an (H, W) mask."""
    v, u = np.nonzero(mask)
    return {(int(a), int(b)) for a, b in zip(u, v, strict=True)}


# ---------------------------------------------------------------------------- candidates


def test_candidate_mask_drops_each_kind_of_bad_pixel():
    values = np.full((3, 4), 10.0)
    values[0, 0] = np.nan  # unreadable
    values[0, 1] = 2.0  # at the noise floor: dropped (values at or below)
    values[0, 2] = 2.0001
    saturated = np.zeros((3, 4), dtype=bool)
    saturated[1, 1] = True
    excluded = np.zeros((3, 4), dtype=bool)
    excluded[2, 3] = True
    ok = candidate_mask(values, saturated=saturated, excluded=excluded, min_signal=2.0)
    expected = np.ones((3, 4), dtype=bool)
    expected[0, 0] = expected[0, 1] = expected[1, 1] = expected[2, 3] = False
    np.testing.assert_array_equal(ok, expected)


def test_rect_region_is_inclusive_and_order_free():
    r = Region("rect", np.array([[3.0, 2.0], [1.0, 1.0]]))
    mask = region_mask([r], 5, 4)
    assert _pixels(mask) == {(u, v) for u in (1, 2, 3) for v in (1, 2)}


def test_polygon_region_exact_pixels():
    # Triangle u >= 0, v >= 0, u + v <= 3.5 (edges between pixel centres).
    tri = Region("polygon", np.array([[-0.5, -0.5], [4.0, -0.5], [-0.5, 4.0]]))
    mask = region_mask([tri], 6, 6)
    assert _pixels(mask) == {(u, v) for u in range(6) for v in range(6) if u + v <= 3}


def test_include_and_exclude_regions():
    include = Region("rect", np.array([[0.0, 0.0], [4.0, 3.0]]))
    hole = Region("rect", np.array([[1.0, 1.0], [2.0, 2.0]]), include=False)
    mask = region_mask([include, hole], 7, 5)
    expected = {(u, v) for u in range(5) for v in range(4)} - {(1, 1), (2, 1), (1, 2), (2, 2)}
    assert _pixels(mask) == expected
    # Exclude regions alone: everything else is allowed.
    only_hole = region_mask([hole], 7, 5)
    assert _pixels(only_hole) == {(u, v) for u in range(7) for v in range(5)} - {
        (1, 1),
        (2, 1),
        (1, 2),
        (2, 2),
    }
    # Two include regions add up.
    other = Region("rect", np.array([[6.0, 4.0], [6.0, 4.0]]))
    assert _pixels(region_mask([include, other], 7, 5)) == _pixels(region_mask([include], 7, 5)) | {
        (6, 4)
    }


def test_candidate_mask_applies_regions():
    values = np.ones((4, 5))
    r = Region("rect", np.array([[1.0, 0.0], [2.0, 3.0]]))
    ok = candidate_mask(values, regions=[r])
    assert _pixels(ok) == {(u, v) for u in (1, 2) for v in range(4)}


def test_binning_of_candidates_and_values():
    cand = np.ones((5, 7), dtype=bool)
    cand[1, 2] = False  # spoils super-pixel (1, 0)
    binned = binned_candidates(cand, 2)
    assert binned.shape == (2, 3)  # the odd last row and column are dropped
    np.testing.assert_array_equal(binned, [[True, False, True], [True, True, True]])
    values = np.arange(35, dtype=float).reshape(5, 7)
    means = bin_values(values, 2)
    np.testing.assert_allclose(means[0, 0], np.mean([0, 1, 7, 8]))
    np.testing.assert_allclose(means[1, 2], np.mean([18, 19, 25, 26]))
    assert means.shape == (2, 3)
    # Larger blocks and images: the same as a mean over the blocks' axes, to rounding.
    rng = np.random.default_rng(6)
    big = rng.uniform(0.0, 4000.0, size=(403, 605))
    cand = rng.uniform(size=big.shape) > 0.002
    for b in (1, 3, 4):
        h, w = big.shape[0] // b * b, big.shape[1] // b * b
        blocks = big[:h, :w].reshape(h // b, b, w // b, b)
        np.testing.assert_allclose(bin_values(big, b), blocks.mean(axis=(1, 3)), rtol=1e-15)
        ok = cand[:h, :w].reshape(h // b, b, w // b, b).all(axis=(1, 3))
        np.testing.assert_array_equal(binned_candidates(cand, b), ok)


# ---------------------------------------------------------------------------- strategies


def test_grid_strategy_exact_pixels():
    cand = np.ones((10, 10), dtype=bool)
    cand[6, 6] = False
    px = select_pixels(cand, SelectionOptions(strategy="grid", grid_step=4))
    assert px.tolist() == [[2, 2], [6, 2], [2, 6]]
    assert px.dtype == np.int64


def test_all_strategy_returns_every_candidate_in_row_order():
    cand = np.zeros((3, 4), dtype=bool)
    cand[2, 0] = cand[0, 3] = cand[1, 1] = True
    px = select_pixels(cand, SelectionOptions(strategy="all"))
    assert px.tolist() == [[3, 0], [1, 1], [0, 2]]
    assert px.dtype == np.int64 and px.flags.c_contiguous


def test_random_strategy_is_deterministic_by_seed():
    cand = np.ones((40, 50), dtype=bool)
    cand[:, :10] = False
    opts = SelectionOptions(strategy="random", n_per_image=30, seed=4)
    a = select_pixels(cand, opts, image_index=2)
    b = select_pixels(cand, opts, image_index=2)
    np.testing.assert_array_equal(a, b)
    assert a.shape == (30, 2)
    assert len({tuple(p) for p in a.tolist()}) == 30  # no repeats
    assert np.all(cand[a[:, 1], a[:, 0]])  # candidates only
    order = np.lexsort((a[:, 0], a[:, 1]))
    np.testing.assert_array_equal(order, np.arange(30))  # sorted by (v, u)
    other_image = select_pixels(cand, opts, image_index=3)
    other_seed = select_pixels(cand, SelectionOptions(n_per_image=30, seed=5), image_index=2)
    assert a.tolist() != other_image.tolist()
    assert a.tolist() != other_seed.tolist()
    assert select_pixels(cand, opts, oversample=1.5).shape == (45, 2)


def test_random_strategy_with_few_candidates_takes_them_all():
    cand = np.zeros((5, 5), dtype=bool)
    cand[1, 2] = cand[3, 4] = True
    px = select_pixels(cand, SelectionOptions(n_per_image=100))
    assert px.tolist() == [[2, 1], [4, 3]]
    none = select_pixels(np.zeros((5, 5), dtype=bool), SelectionOptions(n_per_image=100))
    assert none.shape == (0, 2)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"strategy": "best"}, r"^strategy: expected random, grid or all, got 'best'$"),
        ({"n_per_image": 0}, r"^n_per_image: expected an integer >= 1, got 0$"),
        ({"grid_step": 0}, r"^grid_step: expected an integer >= 1, got 0$"),
        ({"binning": -2}, r"^binning: expected an integer >= 1, got -2$"),
    ],
)
def test_selection_option_errors(options, message):
    with pytest.raises(ValueError, match=message):
        SelectionOptions(**options)


# --------------------------------------------- a project's images -> the solver's pixels

W, H = 40, 30


def _camera() -> Camera:
    return Camera.from_params(fx=36.0, fy=36.0, cx=19.5, cy=14.5, width=W, height=H)


def _grazing_view() -> View:
    """A view whose bottom rows see above the horizon (invalid footprints)."""
    return View.looking_at(np.array([0.0, -1.2, 0.35]), np.array([0.0, 0.0, 0.0]))


def _straight_view() -> View:
    return View.looking_at(np.array([0.05, 0.0, 1.0]), np.array([0.05, 0.0, 0.0]))


def _project(
    folder: Path, view: View, image: np.ndarray, *, mask=None, sensor=None, selection=None
) -> Path:
    """A one-image project with a float .npy image (values are arbitrary: selection only)."""
    np.save(folder / "img.npy", image)
    entry: dict = {
        "path": "img.npy",
        "T_camera_world": {"R": view.R_camera_world.tolist(), "t": view.t_camera_world.tolist()},
    }
    if mask is not None:
        np.save(folder / "mask.npy", mask.astype(np.float64))
        entry["mask"] = "mask.npy"
    doc = {
        "camera": {"fx": 36.0, "fy": 36.0, "cx": 19.5, "cy": 14.5, "width": W, "height": H},
        "sensor": sensor or {},
        "images": [entry],
        "lights": [
            {"rid": {"type": "isotropic"}, "initial": {"position_m": [0.05, 0.0, 0.0], "scale": 1}}
        ],
        "selection": selection or {},
    }
    path = folder / "project.json"
    path.write_text(json.dumps(doc))
    return path


def _selected(path: Path) -> tuple[set[tuple[int, int]], ImageData]:
    project = load_project(path)
    loaded = load_images(project)
    data = image_data(project, loaded, 0)
    return {(int(u), int(v)) for u, v in data.footprints.pixels}, data


def test_project_selection_keeps_valid_pixels_only(tmp_path):
    view = _grazing_view()
    image = np.full((H, W), 100.0)
    image[2:5, 3:9] = 1000.0  # saturated (white level 1000)
    image[10:12, 20:30] = 1.5  # below min_signal
    mask = np.zeros((H, W))
    mask[0:6, 30:40] = 1.0  # excluded by the user's mask
    path = _project(
        tmp_path,
        view,
        image,
        mask=mask,
        sensor={"white_level": 1000.0},
        selection={
            "strategy": "all",
            "min_signal": 2.0,
            "regions": [
                {"kind": "rect", "points": [[0, 0], [35, 29]]},
                {
                    "kind": "polygon",
                    "include": False,
                    "points": [[9.5, 14.5], [15.0, 14.5], [9.5, 20.0]],
                },
            ],
        },
    )
    got, data = _selected(path)
    all_px = np.stack(np.meshgrid(np.arange(W), np.arange(H)), axis=-1).reshape(-1, 2)
    fp = pixel_footprints(_camera(), view, all_px)
    expected = set()
    for (u, v), ok in zip(all_px.tolist(), fp.valid.tolist(), strict=True):
        if not ok or u > 35:
            continue
        if 2 <= v < 5 and 3 <= u < 9:
            continue
        if 10 <= v < 12 and 20 <= u < 30:
            continue
        if v < 6 and u >= 30:
            continue
        if u >= 10 and v >= 15 and (u - 10) + (v - 15) <= 4:  # the excluded triangle
            continue
        expected.add((u, v))
    assert 0 < fp.valid.sum() < W * H  # the view really has invalid pixels
    assert got == expected
    np.testing.assert_array_equal(
        data.observed, image[data.footprints.pixels[:, 1], data.footprints.pixels[:, 0]]
    )
    np.testing.assert_array_equal(data.sigma, 1.0)


def test_project_selection_all_with_binning(tmp_path):
    view = _straight_view()
    image = np.arange(W * H, dtype=float).reshape(H, W) + 10.0
    image[4, 7] = 0.0  # spoils super-pixel (3, 2) at b = 2
    path = _project(
        tmp_path,
        view,
        image,
        selection={"strategy": "all", "binning": 2, "min_signal": 1.0},
        sensor={"noise": {"gain": 2.0, "read_variance": 4.0}},
    )
    got, data = _selected(path)
    assert got == {(u, v) for u in range(W // 2) for v in range(H // 2)} - {(3, 2)}
    u, v = data.footprints.pixels[0]
    block = image[2 * v : 2 * v + 2, 2 * u : 2 * u + 2]
    assert data.observed[0] == pytest.approx(block.mean())
    # Poisson-Gaussian sigma of a mean of b^2 pixels.
    assert data.sigma[0] == pytest.approx(np.sqrt((2.0 * block.mean() + 4.0) / 4.0))
    assert data.footprints.corners_world.shape[1] == 4  # 2 x 2 quads per super-pixel


def test_project_selection_grid(tmp_path):
    path = _project(
        tmp_path,
        _straight_view(),
        np.full((H, W), 50.0),
        selection={"strategy": "grid", "grid_step": 8},
    )
    got, _ = _selected(path)
    assert got == {(u, v) for u in (4, 12, 20, 28, 36) for v in (4, 12, 20, 28)}


def test_random_selection_of_a_project_is_reproducible(tmp_path):
    path = _project(
        tmp_path, _straight_view(), np.full((H, W), 50.0), selection={"n_per_image": 60, "seed": 3}
    )
    a, _ = _selected(path)
    b, _ = _selected(path)
    assert a == b and len(a) == 60


def test_random_selection_covers_the_whole_image(tmp_path):
    path = _project(
        tmp_path, _straight_view(), np.full((H, W), 50.0), selection={"n_per_image": 100}
    )
    got, _ = _selected(path)
    rows = np.array([v for _, v in got])
    assert len(got) == 100
    assert rows.max() >= H - 4
    assert rows.mean() == pytest.approx((H - 1) / 2, abs=3.0)


def test_noise_floor_rules(tmp_path):
    image = np.linspace(0.0, 200.0, W * H).reshape(H, W)
    path = _project(tmp_path, _straight_view(), image, selection={"min_signal": 7.5})
    project = load_project(path)
    img = load_images(project).images[0]
    assert noise_floor(project, img) == 7.5
    path = _project(
        tmp_path,
        _straight_view(),
        image,
        sensor={"offset": 3.0, "noise": {"gain": 1.0, "read_variance": 16.0}},
    )
    project = load_project(path)
    assert noise_floor(project, img) == 3.0 + 5 * 4.0
    path = _project(tmp_path, _straight_view(), image)
    project = load_project(path)
    assert noise_floor(project, img) == pytest.approx(0.01 * np.percentile(image, 99))


def test_the_99th_percentile_of_a_large_image_reads_a_regular_subsample():
    from lightcal.io.linear_image import PERCENTILE_SAMPLES, LinearImage

    rng = np.random.default_rng(5)
    h, w = 2000, 3000  # 6 M values: about one in six read
    yy, xx = np.mgrid[0:h, 0:w]
    values = 4000.0 * np.exp(-((xx - 1400.0) ** 2 + (yy - 900.0) ** 2) / (2 * 900.0**2))
    values += rng.normal(size=values.shape) * 20.0
    values[::7, ::5] = np.nan
    image = LinearImage(
        values=values,
        saturated=np.zeros((h, w), dtype=bool),
        white_level=1e4,
        black_level=0.0,
        exposure=None,
        source="test",
        bit_depth=None,
    )
    exact = np.percentile(values[np.isfinite(values)], 99)
    assert values.size > 5 * PERCENTILE_SAMPLES
    assert image.percentile_99 == pytest.approx(exact, rel=2e-3)
    assert image.percentile_99 != exact  # a subsample was read
    small = LinearImage(
        values=values[:500, :500],
        saturated=np.zeros((500, 500), dtype=bool),
        white_level=1e4,
        black_level=0.0,
        exposure=None,
        source="test",
        bit_depth=None,
    )
    patch = values[:500, :500]
    assert small.percentile_99 == np.percentile(patch[np.isfinite(patch)], 99)  # all read


def test_project_noise_model_reaches_the_solver_per_super_pixel(tmp_path):
    image = 50.0 + np.arange(H * W, dtype=np.float64).reshape(H, W) % 17.0
    path = _project(
        tmp_path,
        _straight_view(),
        image,
        sensor={"offset": 10.0, "noise": {"gain": 2.0, "read_variance": 8.0}},
        selection={"strategy": "all", "binning": 2, "min_signal": 1.0},
    )
    _, data = _selected(path)
    # A 2 x 2 super-pixel is the mean of 4 pixels: a quarter of their variance.
    assert data.noise == (0.5, 2.0)
    np.testing.assert_allclose(data.sigma, np.sqrt(0.5 * (data.observed - 10.0) + 2.0), rtol=1e-14)
    without = _project(tmp_path, _straight_view(), image, selection={"strategy": "all"})
    _, plain = _selected(without)
    assert plain.noise is None and np.all(plain.sigma == 1.0)


def test_extra_pixels_join_the_selection_when_they_are_candidates(tmp_path):
    image = np.full((H, W), 100.0)
    image[3, 4] = 1000.0  # saturated (white level 1000)
    path = _project(
        tmp_path,
        _straight_view(),
        image,
        sensor={"white_level": 1000.0},
        selection={"strategy": "random", "n_per_image": 5, "seed": 1},
    )
    project = load_project(path)
    loaded = load_images(project)
    plain = image_data(project, loaded, 0)
    chosen = {(int(u), int(v)) for u, v in plain.footprints.pixels}
    assert len(chosen) == 5
    clicked = np.array([[1, 1], [2, 7], [4, 3], [-1, 0], [W, 0], [2, 7]])
    data = image_data(project, loaded, 0, extra_pixels=clicked)
    got = {(int(u), int(v)) for u, v in data.footprints.pixels}
    # The two valid clicks are kept on top of N random pixels; the saturated and the
    # outside ones are ignored; a click repeated counts once.
    assert {(1, 1), (2, 7)} <= got
    assert (4, 3) not in got
    assert len(got) == 5 + 2  # N random ones besides the clicks
    assert len(data.observed) == len(got)


def test_vignetting_for_reads_a_map_once_and_keeps_few(tmp_path: Path):
    model = RadialVignetting(np.array([19.5, 14.5]), np.array([-0.3]), 40, 30)
    camera = SimpleNamespace(width=40, height=30)  # all vignetting_for looks at

    def project(sensor: str, name: str = "falloff.json"):
        path = tmp_path / name
        if not path.exists():
            save_radial_vignetting(path, model)
        sensor_spec = SimpleNamespace(model=sensor)
        return SimpleNamespace(spec=SimpleNamespace(sensor=sensor_spec), vignetting_path=path)

    vmap = vignetting_for(project("map"), camera)
    assert vmap is not None
    np.testing.assert_array_equal(vmap, model.image(40, 30))
    assert vignetting_for(project("map"), camera) is vmap  # read once
    assert vignetting_for(project("cos4"), camera) is None
    # The cache is bounded: many map files do not pile up in memory.
    for k in range(6):
        assert vignetting_for(project("map", f"falloff_{k}.json"), camera) is not None
    info = _load_vignetting.cache_info()
    assert info.maxsize == 4 and info.currsize <= 4
