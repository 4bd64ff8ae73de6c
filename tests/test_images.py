"""read_image on PNG, TIFF, .npy and EXR: exact values, levels, saturation, errors."""

from __future__ import annotations

import math
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
import tifffile

from lightcal.errors import InputError
from lightcal.io.images import read_image, read_mask
from lightcal.io.linear_image import LinearImage
from lightcal.io.response import ResponseCurve

LUMA = (0.2126, 0.7152, 0.0722)
# 16-bit saturation threshold: 65535 - 0.005 * 65535 = 65207.325.


def _grey16(seed: int = 0) -> np.ndarray:
    data = np.random.default_rng(seed).integers(0, 60000, (5, 7)).astype(np.uint16)
    data[0, 0] = 65535
    data[1, 2] = 65208  # saturated (within the margin)
    data[3, 4] = 65207  # not saturated
    return data


def test_png16_grey_round_trip(tmp_path: Path) -> None:
    data = _grey16()
    path = tmp_path / "grey.png"
    assert cv2.imwrite(str(path), data)
    image = read_image(path)
    np.testing.assert_array_equal(image.values, data.astype(np.float64))
    expected_mask = np.zeros(data.shape, dtype=bool)
    expected_mask[0, 0] = expected_mask[1, 2] = True
    np.testing.assert_array_equal(image.saturated, expected_mask)
    assert image.white_level == 65535
    assert image.black_level == 0
    assert image.bit_depth == 16
    assert image.binning == 1
    assert image.channel == "luminance"
    assert image.exposure is None
    assert image.source == str(path)


def test_png16_colour_luminance_and_channels(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    rgb = rng.integers(0, 60000, (4, 6, 3)).astype(np.uint16)
    rgb[2, 3, 2] = 65535  # only blue clipped
    path = tmp_path / "colour.png"
    assert cv2.imwrite(str(path), rgb[..., ::-1])  # OpenCV writes B, G, R
    r, g, b = (rgb[..., c].astype(np.float64) for c in range(3))
    image = read_image(path)
    np.testing.assert_allclose(image.values, LUMA[0] * r + LUMA[1] * g + LUMA[2] * b, rtol=1e-15)
    assert image.saturated[2, 3] and image.saturated.sum() == 1
    for name, plane in (("R", r), ("G", g), ("B", b)):
        single = read_image(path, channel=name)  # type: ignore[arg-type]
        np.testing.assert_array_equal(single.values, plane)
        assert single.saturated.sum() == (1 if name == "B" else 0)


def test_png16_with_alpha_drops_alpha(tmp_path: Path) -> None:
    bgra = np.random.default_rng(2).integers(0, 60000, (4, 5, 4)).astype(np.uint16)
    bgra[..., 3] = 65535  # opaque alpha must not count as saturation
    path = tmp_path / "alpha.png"
    assert cv2.imwrite(str(path), bgra)
    image = read_image(path, channel="R")
    np.testing.assert_array_equal(image.values, bgra[..., 2].astype(np.float64))
    assert not image.saturated.any()


def test_tiff16_round_trip_with_levels(tmp_path: Path) -> None:
    data = _grey16(3)
    path = tmp_path / "grey.tif"
    tifffile.imwrite(path, data)
    image = read_image(path)
    np.testing.assert_array_equal(image.values, data.astype(np.float64))
    assert image.bit_depth == 16
    assert image.white_level == 65535
    levelled = read_image(path, black_level=1000, white_level=50000)
    np.testing.assert_array_equal(levelled.values, data.astype(np.float64) - 1000)
    assert levelled.white_level == 49000
    assert levelled.black_level == 1000
    # threshold 50000 - 0.005 * 49000 = 49755
    np.testing.assert_array_equal(levelled.saturated, data >= 49755)


def test_tiff16_colour_is_rgb(tmp_path: Path) -> None:
    rgb = np.random.default_rng(4).integers(0, 60000, (4, 6, 3)).astype(np.uint16)
    path = tmp_path / "colour.tif"
    tifffile.imwrite(path, rgb, photometric="rgb")
    r, g, b = (rgb[..., c].astype(np.float64) for c in range(3))
    np.testing.assert_array_equal(read_image(path, channel="R").values, r)
    np.testing.assert_array_equal(read_image(path, channel="B").values, b)
    np.testing.assert_allclose(
        read_image(path).values, LUMA[0] * r + LUMA[1] * g + LUMA[2] * b, rtol=1e-15
    )


def test_tiff_planar_colour(tmp_path: Path) -> None:
    rgb = np.random.default_rng(5).integers(0, 60000, (3, 4, 6)).astype(np.uint16)
    path = tmp_path / "planar.tif"
    tifffile.imwrite(path, rgb, photometric="rgb", planarconfig="separate")
    np.testing.assert_array_equal(read_image(path, channel="G").values, rgb[1].astype(np.float64))


def test_float_tiff(tmp_path: Path) -> None:
    data = np.random.default_rng(6).random((5, 7)).astype(np.float32) * 3
    path = tmp_path / "float.tif"
    tifffile.imwrite(path, data)
    image = read_image(path)
    np.testing.assert_array_equal(image.values, data.astype(np.float64))
    assert image.white_level == math.inf
    assert not image.saturated.any()
    assert image.bit_depth is None
    given = read_image(path, white_level=2.0, black_level=0.5)
    np.testing.assert_array_equal(given.values, data.astype(np.float64) - 0.5)
    assert given.white_level == 1.5
    np.testing.assert_array_equal(given.saturated, data >= 2.0 - 0.005 * 1.5)


def test_float_tiff_with_nan_and_inf(tmp_path: Path) -> None:
    data = np.ones((4, 4), dtype=np.float32)
    data[1, 1] = np.nan
    data[2, 3] = np.inf
    path = tmp_path / "bad.tif"
    tifffile.imwrite(path, data)
    with pytest.raises(
        InputError,
        match=re.escape(
            f"{path}: 2 pixel values are NaN or infinite; expected finite linear values"
        ),
    ):
        read_image(path)


def test_npy_float_and_integer(tmp_path: Path) -> None:
    floats = np.random.default_rng(7).normal(size=(3, 4))
    np.save(tmp_path / "f.npy", floats)
    image = read_image(tmp_path / "f.npy")
    np.testing.assert_array_equal(image.values, floats)
    assert image.exposure is None
    integers = np.arange(12, dtype=np.uint16).reshape(3, 4) * 5000
    integers[2, 3] = 65535
    np.save(tmp_path / "i.npy", integers)
    image = read_image(tmp_path / "i.npy")
    np.testing.assert_array_equal(image.values, integers.astype(np.float64))
    assert image.white_level == 65535
    np.testing.assert_array_equal(image.saturated, integers >= 65207.325)
    assert image.saturated.sum() == 1


def test_npy_rejects_pickles_and_wrong_shapes(tmp_path: Path) -> None:
    objects = np.empty((2, 2), dtype=object)
    np.save(tmp_path / "o.npy", objects, allow_pickle=True)
    with pytest.raises(
        InputError,
        match=re.escape(
            f"{tmp_path / 'o.npy'}: contains Python objects (pickle), which are not read; "
            "expected a numeric (H, W) array"
        ),
    ):
        read_image(tmp_path / "o.npy")
    np.save(tmp_path / "c.npy", np.zeros((2, 3, 3)))
    with pytest.raises(
        InputError,
        match=re.escape(f"{tmp_path / 'c.npy'}: expected an (H, W) array, got shape (2, 3, 3)"),
    ):
        read_image(tmp_path / "c.npy")
    np.save(tmp_path / "s.npy", np.zeros((2, 3), dtype=np.int16))
    with pytest.raises(
        InputError,
        match=re.escape(
            f"{tmp_path / 's.npy'}: unsupported pixel type int16; "
            "expected unsigned integers or floats"
        ),
    ):
        read_image(tmp_path / "s.npy")


def test_npy_nan(tmp_path: Path) -> None:
    data = np.zeros((3, 3))
    data[0, 0] = np.nan
    np.save(tmp_path / "n.npy", data)
    with pytest.raises(InputError, match=re.escape("1 pixel values are NaN or infinite")):
        read_image(tmp_path / "n.npy")


EIGHT_BIT_MESSAGE = (
    "8-bit image values are gamma-encoded by the camera, not proportional to light; "
    "supply a camera response curve fitted from an exposure bracket "
    "(lightcal.io.response.fit_response_debevec, Debevec & Malik 1997) as response=..., "
    "or pass assume_linear=True if the camera really wrote linear values"
)


def test_png8_refused_without_response(tmp_path: Path) -> None:
    path = tmp_path / "photo.png"
    assert cv2.imwrite(str(path), np.full((4, 4, 3), 100, dtype=np.uint8))
    with pytest.raises(InputError, match=re.escape(f"{path}: {EIGHT_BIT_MESSAGE}")):
        read_image(path)


def test_png8_assume_linear(tmp_path: Path) -> None:
    data = np.arange(20, dtype=np.uint8).reshape(4, 5) * 13
    data[0, :3] = (255, 254, 253)
    path = tmp_path / "linear8.png"
    assert cv2.imwrite(str(path), data)
    image = read_image(path, assume_linear=True)
    np.testing.assert_array_equal(image.values, data.astype(np.float64))
    assert image.white_level == 255
    # threshold 255 - 0.005 * 255 = 253.725
    expected_mask = np.zeros(data.shape, dtype=bool)
    expected_mask[0, :2] = True
    np.testing.assert_array_equal(image.saturated, expected_mask)
    assert image.bit_depth == 8


def test_png8_with_response_curve(tmp_path: Path) -> None:
    codes = np.arange(256) / 255.0
    curve = ResponseCurve(np.stack([codes**2.2, codes**2.0, codes**1.8], axis=1) + 1e-3)  # B, G, R
    bgr = np.random.default_rng(8).integers(0, 256, (4, 5, 3)).astype(np.uint8)
    bgr[0, 0] = (10, 20, 255)
    path = tmp_path / "photo.png"
    assert cv2.imwrite(str(path), bgr)
    image = read_image(path, response=curve)
    b = curve.values[bgr[..., 0], 0]
    g = curve.values[bgr[..., 1], 1]
    r = curve.values[bgr[..., 2], 2]
    np.testing.assert_allclose(image.values, LUMA[0] * r + LUMA[1] * g + LUMA[2] * b, rtol=1e-14)
    assert image.saturated[0, 0]
    # Through a curve, the top 5 % of the codes count as saturated (RESPONSE_SATURATION_CODE).
    np.testing.assert_array_equal(image.saturated, np.any(bgr >= 243, axis=-1))
    assert image.white_level == pytest.approx(
        LUMA[0] * (1 + 1e-3) + LUMA[1] * (1 + 1e-3) + LUMA[2] * (1 + 1e-3)
    )
    red = read_image(path, response=curve, channel="R")
    np.testing.assert_array_equal(red.values, r)
    np.testing.assert_array_equal(red.saturated, bgr[..., 2] >= 243)


def test_response_channel_mismatch(tmp_path: Path) -> None:
    path = tmp_path / "grey8.png"
    assert cv2.imwrite(str(path), np.zeros((3, 3), dtype=np.uint8))
    codes = np.linspace(0.01, 1, 256)
    with pytest.raises(
        InputError,
        match=re.escape(
            f"{path}: single-channel image but the response curve has 3 channels; "
            "fit a curve on single-channel images or read the image in colour"
        ),
    ):
        read_image(path, response=ResponseCurve(np.stack([codes] * 3, axis=1)))
    grey = read_image(path, response=ResponseCurve(codes))
    np.testing.assert_array_equal(grey.values, np.full((3, 3), 0.01))
    assert grey.white_level == 1.0


def test_response_refused_for_16_bit(tmp_path: Path) -> None:
    path = tmp_path / "grey.png"
    assert cv2.imwrite(str(path), _grey16())
    curve = ResponseCurve(np.linspace(0.01, 1, 256)[:, None])
    with pytest.raises(
        InputError,
        match=re.escape(
            f"{path}: a response curve applies only to 8-bit images; this image has 16 bits"
        ),
    ):
        read_image(path, response=curve)


def test_channel_errors(tmp_path: Path) -> None:
    grey = tmp_path / "grey.png"
    colour = tmp_path / "colour.png"
    assert cv2.imwrite(str(grey), _grey16())
    assert cv2.imwrite(str(colour), np.zeros((3, 3, 3), dtype=np.uint16))
    with pytest.raises(
        InputError,
        match=re.escape(
            f"{grey}: single-channel image has no channel 'R'; use 'auto' or 'luminance'"
        ),
    ):
        read_image(grey, channel="R")
    with pytest.raises(
        InputError,
        match=re.escape(
            f"{colour}: channel 'green_binned' needs a camera raw file with a colour filter array; "
            "for this image use 'auto', 'luminance', 'R', 'G' or 'B'"
        ),
    ):
        read_image(colour, channel="green_binned")


def test_missing_and_unsupported_files(tmp_path: Path) -> None:
    missing = tmp_path / "nope.png"
    with pytest.raises(InputError, match=re.escape(f"{missing}: file not found")):
        read_image(missing)
    bmp = tmp_path / "image.bmp"
    bmp.write_bytes(b"BM")
    with pytest.raises(InputError, match=re.escape(f"{bmp}: unsupported image extension '.bmp'")):
        read_image(bmp)
    broken = tmp_path / "broken.png"
    broken.write_bytes(b"not a png at all")
    with pytest.raises(InputError, match=re.escape(f"{broken}: not a readable PNG image")):
        read_image(broken)
    broken_tiff = tmp_path / "broken.tif"
    broken_tiff.write_bytes(b"not a tiff at all")
    with pytest.raises(InputError, match=re.escape(f"{broken_tiff}: not a readable TIFF image (")):
        read_image(broken_tiff)


def test_read_mask_is_read_image_above_zero(tmp_path: Path) -> None:
    """read_mask keeps read_image(assume_linear=True).values > 0 for every kind of file."""
    rng = np.random.default_rng(4)
    grey8 = (rng.random((6, 9)) > 0.5).astype(np.uint8) * 255
    colour16 = rng.integers(0, 3, (6, 9, 4)).astype(np.uint16)  # B, G, R, alpha
    colour16[..., 3] = 65535  # alpha alone never makes a pixel masked
    colour16[0, 0, :3] = 0
    signed = rng.normal(size=(6, 9))  # float data: the luminance decides
    cv2.imwrite(str(tmp_path / "grey.png"), grey8)
    cv2.imwrite(str(tmp_path / "colour.png"), colour16)
    tifffile.imwrite(tmp_path / "colour.tif", rng.integers(0, 2, (6, 9, 3)).astype(np.uint8))
    np.save(tmp_path / "signed.npy", signed)
    for name in ("grey.png", "colour.png", "colour.tif", "signed.npy"):
        mask = read_mask(tmp_path / name)
        assert mask.dtype == np.bool_ and mask.shape == (6, 9)
        expected = read_image(tmp_path / name, assume_linear=True).values > 0
        np.testing.assert_array_equal(mask, expected)
        assert 0 < mask.sum() < mask.size
    assert not read_mask(tmp_path / "colour.png")[0, 0]
    signed[2, 3] = np.nan
    np.save(tmp_path / "nan.npy", signed)
    with pytest.raises(InputError, match=re.escape("1 pixel values are NaN or infinite")):
        read_mask(tmp_path / "nan.npy")
    with pytest.raises(InputError, match=re.escape(f"{tmp_path / 'no.png'}: file not found")):
        read_mask(tmp_path / "no.png")


def test_bad_levels(tmp_path: Path) -> None:
    path = tmp_path / "grey.png"
    assert cv2.imwrite(str(path), _grey16())
    with pytest.raises(
        InputError,
        match=re.escape(
            "white_level: expected finite levels with white > black, "
            "got white 100.0 and black 200.0"
        ),
    ):
        read_image(path, black_level=200, white_level=100)


def _opencv_has_openexr() -> bool:
    return any(
        line.strip().startswith("OpenEXR:") and "NO" not in line.split(":", 1)[1]
        for line in cv2.getBuildInformation().splitlines()
    )


def test_exr(tmp_path: Path) -> None:
    path = tmp_path / "render.exr"
    data = np.random.default_rng(9).random((4, 6)).astype(np.float32)
    if _opencv_has_openexr():
        assert cv2.imwrite(str(path), data)
        np.testing.assert_array_equal(read_image(path).values, data.astype(np.float64))
    else:
        path.write_bytes(b"v/1\x01" + bytes(100))
        with pytest.raises(
            InputError,
            match=re.escape(
                f"{path}: this OpenCV build cannot read OpenEXR; "
                "convert the image to a 32-bit float TIFF or a .npy array"
            ),
        ):
            read_image(path)


def test_linear_image_is_immutable(tmp_path: Path) -> None:
    np.save(tmp_path / "f.npy", np.zeros((2, 2)))
    image = read_image(tmp_path / "f.npy")
    with pytest.raises(ValueError, match="read-only"):
        image.values[0, 0] = 1.0
    with pytest.raises(ValueError, match="read-only"):
        image.saturated[0, 0] = True
    with pytest.raises(
        InputError, match=re.escape("x: saturation mask shape (3,) differs from values (2, 2)")
    ):
        LinearImage(np.zeros((2, 2)), np.zeros(3, bool), 1.0, 0.0, None, "x", None)
