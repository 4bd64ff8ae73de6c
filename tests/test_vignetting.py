"""Tests of lightcal.core.vignetting and lightcal.io.vignetting_file."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import tifffile
from scipy.optimize import approx_fprime, least_squares

from lightcal.core.vignetting import (
    RadialVignetting,
    _block_samples,
    _FlatFieldProblem,
    _Samples,
    fit_radial_vignetting,
    vignetting_from_map,
)
from lightcal.errors import InputError
from lightcal.io.vignetting_file import (
    load_radial_vignetting,
    load_vignetting,
    load_vignetting_map,
    save_radial_vignetting,
)

# --------------------------------------------------------------------------- model


def test_hand_computed_values() -> None:
    # 4 x 3 image: R = hypot(4, 3) / 2 = 2.5. Pixel (3, 1) is 2 px from the centre
    # (1, 1): r = 0.8, V = 1 - 0.5 * 0.64 + 0.25 * 0.4096 = 0.7824; (1, -1.5) is at
    # r = 1: V = 1 - 0.5 + 0.25.
    model = RadialVignetting(
        center_px=np.array([1.0, 1.0]), coeffs=np.array([-0.5, 0.25]), width=4, height=3
    )
    assert model.norm_radius_px == 2.5
    np.testing.assert_allclose(
        model.evaluate([[1.0, 1.0], [3.0, 1.0], [1.0, -1.5]]), [1.0, 0.7824, 0.75]
    )
    image = model.image(4, 3)
    assert image.shape == (3, 4)
    assert image[1, 3] == pytest.approx(0.7824, abs=1e-15)
    assert image[1, 1] == 1.0
    np.testing.assert_allclose(image.ravel(), model.evaluate(np.argwhere(image > -1)[:, ::-1]))


def test_centered_model_is_symmetric() -> None:
    model = RadialVignetting.centered([-0.3, 0.1, -0.02], width=7, height=4)
    np.testing.assert_array_equal(model.center_px, [3.0, 1.5])
    image = model.image()
    np.testing.assert_allclose(image, image[::-1, ::-1], atol=1e-15)
    # Corners of the sensor ([-0.5, W - 0.5] x [-0.5, H - 0.5]) are at r = 1.
    assert model.evaluate([[-0.5, -0.5]])[0] == pytest.approx(1 - 0.3 + 0.1 - 0.02, abs=1e-15)


def test_image_size_must_match_the_camera() -> None:
    model = RadialVignetting.centered([-0.3], width=640, height=480)
    with pytest.raises(
        InputError,
        match=r"^vignetting: expected a camera of 640 x 480 pixels \(the model's size\), "
        r"got 480 x 640$",
    ):
        model.image(480, 640)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (
            {"center_px": [1.0]},
            r"^center_px: expected a finite \(2,\) \(u, v\) centre, got \[1\.0\]$",
        ),
        ({"coeffs": []}, r"^coeffs: expected a finite \(k,\) vector with k >= 1, got \[\]$"),
        ({"width": 0}, r"^width: expected a positive int, got 0$"),
    ],
)
def test_model_validation(kwargs: dict, message: str) -> None:
    args = {"center_px": [1.0, 1.0], "coeffs": [-0.1], "width": 4, "height": 3, **kwargs}
    with pytest.raises(InputError, match=message):
        RadialVignetting(**args)


# --------------------------------------------------------------------------- fit

TRUE = RadialVignetting(
    center_px=np.array([163.7, 116.2]),
    coeffs=np.array([-0.35, 0.08, -0.03]),
    width=320,
    height=240,
)


def _flat_fields(
    rng: np.random.Generator, model: RadialVignetting, gains: tuple[float, ...], noise: float
) -> list[np.ndarray]:
    falloff = model.image()
    return [g * falloff * (1.0 + noise * rng.standard_normal(falloff.shape)) for g in gains]


def test_fit_recovers_coefficients_and_center_from_noisy_flat_fields() -> None:
    rng = np.random.default_rng(0)
    images = _flat_fields(rng, TRUE, (0.5, 0.8, 0.3), noise=0.002)
    # A few saturated pixels (clipped at 0.9 in the brightest image) and hot pixels.
    hot = rng.choice(images[1].size, 60, replace=False)
    images[1].flat[hot] = 0.9
    images[2].flat[rng.choice(images[2].size, 30, replace=False)] = 0.0

    model, rms = fit_radial_vignetting(images)

    np.testing.assert_allclose(model.coeffs, TRUE.coeffs, atol=1e-3)
    np.testing.assert_allclose(model.center_px, TRUE.center_px, atol=0.3)
    assert (model.width, model.height) == (320, 240)
    # Residual noise is 0.002 V, V in [0.69, 1]: rms in V units a little below 0.002.
    assert 0.0015 < rms < 0.002


def test_the_defects_would_bias_a_plain_least_squares_fit() -> None:
    # The defects of the previous test, fitted by plain least squares (no trimming),
    # move the coefficients by far more than 1e-3: the trimming is what makes it pass.
    rng = np.random.default_rng(0)
    images = _flat_fields(rng, TRUE, (0.5, 0.8, 0.3), noise=0.002)
    images[1].flat[rng.choice(images[1].size, 60, replace=False)] = 0.9
    images[2].flat[rng.choice(images[2].size, 30, replace=False)] = 0.0
    v, u = np.mgrid[0:240, 0:320]
    medians = [np.median(image) for image in images]
    samples = _Samples(
        u=np.tile(u.ravel(), 3).astype(float),
        v=np.tile(v.ravel(), 3).astype(float),
        value=np.concatenate([(im / m).ravel() for im, m in zip(images, medians, strict=True)]),
        weight=np.ones(3 * u.size),
        image=np.repeat(np.arange(3), u.size),
    )
    problem = _FlatFieldProblem(
        samples=samples, n_images=3, n_coeffs=3, center_px=None, radius=200.0
    )
    start = np.array([1.0, 1.0, 1.0, 159.5, 119.5, 0.0, 0.0, 0.0])
    plain = least_squares(problem.residuals, start, jac=problem.jacobian, method="lm").x
    assert np.max(np.abs(plain[5:] - TRUE.coeffs)) > 1e-3


def test_fit_noise_free_with_fixed_center_is_exact() -> None:
    true = RadialVignetting.centered([-0.4, 0.1], width=64, height=48)
    images = [0.7 * true.image(), 0.2 * true.image()]
    model, rms = fit_radial_vignetting(images, fit_center=False, n_coeffs=2)
    np.testing.assert_allclose(model.coeffs, true.coeffs, atol=1e-10)
    np.testing.assert_array_equal(model.center_px, [31.5, 23.5])
    assert rms < 1e-10


def test_fit_ignores_masked_pixels() -> None:
    rng = np.random.default_rng(1)
    images = _flat_fields(rng, TRUE, (0.6, 0.9), noise=0.001)
    masks = [np.ones((240, 320), dtype=bool) for _ in images]
    images[0][:40, :100] = 5.0  # a bright reflection, masked out
    images[1][200:, 250:] = np.nan  # unreadable corner, masked out
    masks[0][:40, :100] = False
    masks[1][200:, 250:] = False
    model, _ = fit_radial_vignetting(images, valid_masks=masks)
    np.testing.assert_allclose(model.coeffs, TRUE.coeffs, atol=1e-3)


def test_fit_with_tile_averaging() -> None:
    # 76800 pixels reduced to ~2000 tile means (7 x 7 tiles): still accurate.
    images = [TRUE.image(), 0.5 * TRUE.image()]
    model, _ = fit_radial_vignetting(images, max_samples_per_image=2000)
    np.testing.assert_allclose(model.coeffs, TRUE.coeffs, atol=1e-4)
    np.testing.assert_allclose(model.center_px, TRUE.center_px, atol=0.01)


def test_block_samples_average_valid_pixels() -> None:
    image = np.arange(12.0).reshape(3, 4)
    valid = np.ones((3, 4), dtype=bool)
    valid[0, 1] = False
    u, v, value, count = _block_samples(image, valid, 2)
    # Tiles: rows 0-1 x cols 0-1 (pixel (1, 0) invalid), rows 0-1 x cols 2-3,
    # row 2 x cols 0-1, row 2 x cols 2-3 (the padding is invalid).
    np.testing.assert_allclose(count, [3, 4, 2, 2])
    np.testing.assert_allclose(value, [(0 + 4 + 5) / 3, (2 + 3 + 6 + 7) / 4, 8.5, 10.5])
    np.testing.assert_allclose(u, [1 / 3, 2.5, 0.5, 2.5])
    np.testing.assert_allclose(v, [2 / 3, 0.5, 2.0, 2.0])


@pytest.mark.parametrize("fit_center", [True, False])
def test_jacobian_matches_finite_differences(fit_center: bool) -> None:
    rng = np.random.default_rng(2)
    m = 40
    samples = _Samples(
        u=rng.uniform(0, 99, m),
        v=rng.uniform(0, 59, m),
        value=rng.uniform(0.5, 1.0, m),
        weight=rng.uniform(1.0, 3.0, m),
        image=rng.integers(0, 2, m),
    )
    problem = _FlatFieldProblem(
        samples=samples,
        n_images=2,
        n_coeffs=3,
        center_px=None if fit_center else np.array([49.5, 29.5]),
        radius=0.5 * np.hypot(100, 60),
    )
    params = np.array([0.8, 1.1, *([47.0, 31.0] if fit_center else []), -0.3, 0.05, -0.02])
    numeric = np.array(
        [approx_fprime(params, lambda p, i=i: problem.residuals(p)[i], 1e-7) for i in range(m)]
    )
    np.testing.assert_allclose(problem.jacobian(params), numeric, atol=1e-6)


@pytest.mark.parametrize(
    ("images", "kwargs", "message"),
    [
        ([], {}, r"^images: expected at least one flat-field image, got none$"),
        (
            [np.ones((4, 5)), np.ones((5, 4))],
            {},
            r"^images\[1\]: expected the shape of images\[0\], \(4, 5\), got \(5, 4\)$",
        ),
        (
            [np.ones((4, 5)), np.full((4, 5), np.nan)],
            {},
            r"^images\[1\]: expected finite values, got 20 NaN or infinite pixels "
            r"\(exclude them with valid_masks\)$",
        ),
        ([-np.ones((4, 5))], {}, r"^images\[0\]: expected a flat field with positive values"),
        ([np.ones(5)], {}, r"^images\[0\]: expected a 2-D \(H, W\) image, got shape \(5,\)$"),
        ([np.ones((4, 5))], {"n_coeffs": 0}, r"^n_coeffs: expected an int from 1 to 6, got 0$"),
        (
            [np.ones((4, 5))],
            {"valid_masks": [np.ones((4, 5))]},
            r"^valid_masks\[0\]: expected a bool array of shape \(4, 5\), got float64 \(4, 5\)$",
        ),
        (
            [np.ones((2, 2))],
            {},
            r"^images: expected at least 12 usable samples for 6 parameters, got 4$",
        ),
    ],
)
def test_fit_errors(images: list, kwargs: dict, message: str) -> None:
    with pytest.raises(InputError, match=message):
        fit_radial_vignetting(images, **kwargs)


# --------------------------------------------------------------------------- maps


def test_map_normalised_by_max_or_center() -> None:
    values = np.array([[1.0, 2.0, 2.0, 1.0], [2.0, 4.0, 6.0, 2.0], [1.0, 2.0, 2.0, 8.0]])
    by_max = vignetting_from_map(values, width=4, height=3)
    np.testing.assert_allclose(by_max, values / 8.0)
    # Centre (1.5, 1): the mean of pixels (1, 1) and (2, 1) = 5.
    by_center = vignetting_from_map(values, width=4, height=3, normalise="center")
    np.testing.assert_allclose(by_center, values / 5.0)


@pytest.mark.parametrize(
    ("values", "message"),
    [
        (
            np.ones((3, 5)),
            r"^flat\.npy: expected a map of the camera's size 4 x 3 \(W x H\), got 5 x 3$",
        ),
        (np.ones((3, 4, 3)), r"^flat\.npy: expected a 2-D \(H, W\) map, got shape \(3, 4, 3\)$"),
        (
            np.where(np.eye(3, 4) > 0, np.inf, 1.0),
            r"^flat\.npy: expected finite values, got 3 NaN or infinite pixels$",
        ),
        (
            np.where(np.eye(3, 4) > 0, -1.0, 1.0),
            r"^flat\.npy: expected positive values, got 3 pixels <= 0 \(minimum -1\)$",
        ),
    ],
)
def test_map_validation(values: np.ndarray, message: str) -> None:
    with pytest.raises(InputError, match=message):
        vignetting_from_map(values, width=4, height=3, source="flat.npy")


def test_map_bad_normalise() -> None:
    with pytest.raises(InputError, match=r"^normalise: expected 'max' or 'center', got 'mean'$"):
        vignetting_from_map(np.ones((3, 4)), width=4, height=3, normalise="mean")  # type: ignore[arg-type]


# --------------------------------------------------------------------------- files


def _smooth_map() -> np.ndarray:
    """(24, 32) a fall-off map with maximum 1 (no pixel sits at the centre itself)."""
    image = RadialVignetting.centered([-0.3, 0.05], width=32, height=24).image()
    return image / image.max()


def test_load_map_from_npy_png_and_tiff(tmp_path: Path) -> None:
    truth = _smooth_map()
    np.save(tmp_path / "flat.npy", 1234.5 * truth)
    cv2.imwrite(str(tmp_path / "flat.png"), np.round(60000 * truth).astype(np.uint16))
    tifffile.imwrite(tmp_path / "flat.tiff", (0.25 * truth).astype(np.float32))

    from_npy = load_vignetting_map(tmp_path / "flat.npy", width=32, height=24)
    from_png = load_vignetting_map(tmp_path / "flat.png", width=32, height=24)
    from_tiff = load_vignetting_map(tmp_path / "flat.tiff", width=32, height=24)

    np.testing.assert_allclose(from_npy, truth, rtol=1e-14)
    np.testing.assert_allclose(from_png, truth, atol=1e-4)  # 16-bit quantisation
    np.testing.assert_allclose(from_tiff, truth, rtol=1e-6)  # float32
    assert from_png.dtype == np.float64 and from_png.max() == 1.0


def test_load_map_errors(tmp_path: Path) -> None:
    cv2.imwrite(str(tmp_path / "colour.png"), np.full((24, 32, 3), 200, dtype=np.uint8))
    with pytest.raises(
        InputError,
        match=r"colour\.png: expected a single-channel \(H, W\) map, got an array of shape "
        r"\(24, 32, 3\)$",
    ):
        load_vignetting_map(tmp_path / "colour.png", width=32, height=24)
    np.save(tmp_path / "small.npy", np.ones((10, 12)))
    with pytest.raises(
        InputError,
        match=r"small\.npy: expected a map of the camera's size 32 x 24 \(W x H\), got 12 x 10$",
    ):
        load_vignetting_map(tmp_path / "small.npy", width=32, height=24)
    with pytest.raises(InputError, match=r"missing\.tif: file not found: expected a fall-off map$"):
        load_vignetting_map(tmp_path / "missing.tif", width=32, height=24)
    with pytest.raises(
        InputError, match=r"flat\.jpg: unsupported suffix '\.jpg': expected one of \.npy, \.png"
    ):
        load_vignetting_map(tmp_path / "flat.jpg", width=32, height=24)
    (tmp_path / "broken.png").write_bytes(b"not a png")
    with pytest.raises(InputError, match=r"broken\.png: not a readable PNG image$"):
        load_vignetting_map(tmp_path / "broken.png", width=32, height=24)


def test_radial_json_round_trip(tmp_path: Path) -> None:
    model = RadialVignetting(
        center_px=np.array([1000.25, 701.0 / 3.0]),
        coeffs=np.array([-0.3, 0.1 / 7.0, -0.01]),
        width=2000,
        height=1400,
    )
    path = tmp_path / "falloff.json"
    path.write_text("old")
    save_radial_vignetting(path, model, fit_rms=0.0021)
    loaded = load_radial_vignetting(path)
    np.testing.assert_array_equal(loaded.center_px, model.center_px)
    np.testing.assert_array_equal(loaded.coeffs, model.coeffs)
    assert (loaded.width, loaded.height) == (2000, 1400)
    content = json.loads(path.read_text())
    assert content["format"] == "lightcal.radial_vignetting"
    assert content["fit_rms"] == 0.0021
    assert sorted(p.name for p in tmp_path.iterdir()) == ["falloff.json"]  # no temp file left
    np.testing.assert_array_equal(
        load_vignetting(path, width=2000, height=1400), model.image(2000, 1400)
    )


def test_radial_json_errors(tmp_path: Path) -> None:
    model = RadialVignetting.centered([-0.3], width=40, height=30)
    path = tmp_path / "falloff.json"
    save_radial_vignetting(path, model)
    with pytest.raises(
        InputError,
        match=r"falloff\.json: expected a camera of 40 x 30 pixels \(the model's size\), "
        r"got 64 x 48$",
    ):
        load_vignetting(path, width=64, height=48)

    content = json.loads(path.read_text())
    content["colour"] = "red"
    path.write_text(json.dumps(content))
    with pytest.raises(InputError, match=r"falloff\.json: field colour: Extra inputs are not"):
        load_radial_vignetting(path)
    del content["colour"]
    content["width"] = "40"
    path.write_text(json.dumps(content))
    with pytest.raises(
        InputError, match=r"falloff\.json: field width: Input should be a valid int"
    ):
        load_radial_vignetting(path)
    content["width"] = -40
    path.write_text(json.dumps(content))
    with pytest.raises(
        InputError, match=r"falloff\.json: field width: expected a positive int, got -40$"
    ):
        load_radial_vignetting(path)
    path.write_text('{\n  "format": \n}')
    with pytest.raises(InputError, match=r"falloff\.json:3: not valid JSON: Expecting value$"):
        load_radial_vignetting(path)
