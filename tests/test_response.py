"""Camera response curve: Debevec fit on a synthetic gamma-2.2 bracket, save/load, linearize."""

from __future__ import annotations

import json
import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from lightcal.errors import InputError
from lightcal.io.images import read_image
from lightcal.io.response import ResponseCurve, fit_response_debevec

GAMMA = 2.2
TIMES_S = np.array([1 / 16, 1 / 8, 1 / 4, 1 / 2, 1.0, 2.0])


def _bracket(seed: int = 0) -> tuple[np.ndarray, list[np.ndarray]]:
    """Radiance map (log-uniform over 3 decades) and its 8-bit images, code = 255 (E t)^(1/2.2)."""
    rng = np.random.default_rng(seed)
    radiance = np.exp(rng.uniform(np.log(2e-3), np.log(2.0), (48, 48, 3)))
    images = [
        np.clip(np.round(255.0 * np.clip(radiance * t, 0, 1) ** (1 / GAMMA)), 0, 255).astype(
            np.uint8
        )
        for t in TIMES_S
    ]
    return radiance, images


@pytest.fixture(scope="module")
def fitted() -> tuple[ResponseCurve, list[np.ndarray]]:
    _, images = _bracket()
    return fit_response_debevec(images, TIMES_S), images


def test_fitted_curve_is_the_inverse_gamma(fitted: tuple[ResponseCurve, list[np.ndarray]]) -> None:
    curve, _ = fitted
    assert curve.values.shape == (256, 3)
    codes = np.arange(40, 241)
    for c in range(3):
        relative = curve.values[codes, c] / curve.values[128, c]
        np.testing.assert_allclose(relative, (codes / 128.0) ** GAMMA, rtol=0.03)


def test_linearized_bracket_is_proportional_to_exposure(
    fitted: tuple[ResponseCurve, list[np.ndarray]],
) -> None:
    curve, images = fitted
    reference = 3
    linear_ref = curve.linearize(images[reference])
    for k, image in enumerate(images):
        if k == reference:
            continue
        linear = curve.linearize(image)
        usable = (
            (image >= 40) & (image <= 240) & (images[reference] >= 40) & (images[reference] <= 240)
        )
        assert usable.sum() > 500
        ratio = linear[usable] / linear_ref[usable]
        expected = TIMES_S[k] / TIMES_S[reference]
        assert np.median(ratio) == pytest.approx(expected, rel=0.01)
        assert np.percentile(np.abs(ratio / expected - 1), 95) < 0.04
        # linear in the radiance: correlation of log values across pixels
        assert np.corrcoef(np.log(linear[usable]), np.log(linear_ref[usable]))[0, 1] > 0.999


def test_uncorrected_codes_are_not_proportional(
    fitted: tuple[ResponseCurve, list[np.ndarray]],
) -> None:
    """Control for the test above: the raw codes of a gamma bracket fail the same check."""
    _, images = fitted
    usable = (images[2] >= 40) & (images[2] <= 240) & (images[3] >= 40) & (images[3] <= 240)
    ratio = images[2][usable].astype(float) / images[3][usable]
    assert abs(np.median(ratio) - 0.5) > 0.1


def test_read_image_with_fitted_curve(
    tmp_path: Path, fitted: tuple[ResponseCurve, list[np.ndarray]]
) -> None:
    curve, images = fitted
    paths = []
    for k in (2, 3):
        paths.append(tmp_path / f"bracket_{k}.png")
        assert cv2.imwrite(str(paths[-1]), images[k])  # the fit's channel order = the file's
    dim, bright = (read_image(p, response=curve, channel="G") for p in paths)
    usable = ~dim.saturated & ~bright.saturated & (images[2][..., 1] >= 40)
    assert np.median(dim.values[usable] / bright.values[usable]) == pytest.approx(0.5, rel=0.02)


def test_save_load_round_trip(
    tmp_path: Path, fitted: tuple[ResponseCurve, list[np.ndarray]]
) -> None:
    curve, _ = fitted
    for name in ("curve.npy", "curve.json"):
        curve.save(tmp_path / name)
        loaded = ResponseCurve.load(tmp_path / name)
        np.testing.assert_array_equal(loaded.values, curve.values)
    document = json.loads((tmp_path / "curve.json").read_text())
    assert document["format"] == "lightcal.response_curve"
    assert document["version"] == 1


def test_save_load_errors(tmp_path: Path) -> None:
    curve = ResponseCurve(np.linspace(0.01, 1, 256))
    with pytest.raises(
        InputError,
        match=re.escape(
            f"{tmp_path / 'c.txt'}: unknown response curve extension; expected .npy or .json"
        ),
    ):
        curve.save(tmp_path / "c.txt")
    with pytest.raises(InputError, match=re.escape(f"{tmp_path / 'gone.npy'}: file not found")):
        ResponseCurve.load(tmp_path / "gone.npy")
    (tmp_path / "other.json").write_text('{"format": "something else"}')
    with pytest.raises(
        InputError,
        match=re.escape(
            f"{tmp_path / 'other.json'}: "
            'expected a JSON object with "format": "lightcal.response_curve"'
        ),
    ):
        ResponseCurve.load(tmp_path / "other.json")
    np.save(tmp_path / "short.npy", np.ones((10, 3)))
    with pytest.raises(
        InputError,
        match=re.escape(
            f"{tmp_path / 'short.npy'}: "
            "expected a response curve of shape (256, 1) or (256, 3), got (10, 3)"
        ),
    ):
        ResponseCurve.load(tmp_path / "short.npy")


def test_curve_validation() -> None:
    decreasing = np.linspace(1, 0.1, 256)
    with pytest.raises(
        InputError,
        match=re.escape("values: expected a response that does not decrease from code 0 to 255"),
    ):
        ResponseCurve(decreasing)
    with pytest.raises(InputError, match=re.escape("values: expected finite response values > 0")):
        ResponseCurve(np.zeros(256))


def test_linearize_hand_case() -> None:
    curve = ResponseCurve(np.arange(1, 257, dtype=float))  # code z -> z + 1
    image = np.array([[0, 1], [254, 255]], dtype=np.uint8)
    np.testing.assert_array_equal(curve.linearize(image), [[1, 2], [255, 256]])
    np.testing.assert_array_equal(
        curve.linearize(np.stack([image] * 3, -1))[..., 2], [[1, 2], [255, 256]]
    )
    three = ResponseCurve(
        np.stack([np.arange(1, 257), 2 * np.arange(1, 257), 3 * np.arange(1, 257)], 1)
    )
    np.testing.assert_array_equal(
        three.linearize(np.full((1, 1, 3), 9, np.uint8)), [[[10, 20, 30]]]
    )
    with pytest.raises(
        InputError, match=re.escape("image: expected 8-bit (uint8) pixel values, got uint16")
    ):
        curve.linearize(image.astype(np.uint16))
    with pytest.raises(
        InputError,
        match=re.escape(
            "image: single-channel image but the response curve has 3 channels; "
            "fit a curve on single-channel images or read the image in colour"
        ),
    ):
        three.linearize(image)


def test_fit_input_errors() -> None:
    _, images = _bracket()
    with pytest.raises(
        InputError,
        match=re.escape("images: expected at least 2 images of an exposure bracket, got 1"),
    ):
        fit_response_debevec(images[:1], TIMES_S[:1])
    with pytest.raises(
        InputError,
        match=re.escape("exposure_times_s: expected 6 exposure times, one per image, got 5"),
    ):
        fit_response_debevec(images, TIMES_S[:5])
    with pytest.raises(
        InputError,
        match=re.escape(
            "images[1]: expected an (H, W, 3) uint8 image, got shape (48, 48) of uint8"
        ),
    ):
        fit_response_debevec([images[0], images[1][..., 0]], TIMES_S[:2])
