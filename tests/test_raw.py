"""Camera raw through rawpy: tiny DNG files written with tifffile, exact expected values."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from lightcal.errors import InputError
from lightcal.io.exif import Exposure
from lightcal.io.images import read_image
from lightcal.io.raw import read_raw
from tests.raw_dng import write_dng

H, W = 24, 32
BLACK = 64
WHITE = 4095
# Saturation threshold: 4095 - 0.005 * (4095 - 64) = 4074.845.


def _mosaic(seed: int = 0, shape: tuple[int, int] = (H, W)) -> np.ndarray:
    mosaic = np.random.default_rng(seed).integers(100, 3000, shape).astype(np.uint16)
    # RGGB: (even, even) R, (even, odd) G1, (odd, even) G2, (odd, odd) B.
    mosaic[4, 5] = 4095  # G1 of cell (2, 2): clipped
    mosaic[7, 6] = 4080  # G2 of cell (3, 3): within the margin, saturated
    mosaic[9, 10] = 4070  # G2 of cell (4, 5): below the margin, not saturated
    mosaic[10, 10] = 4095  # R of cell (5, 5)
    mosaic[1, 1] = 30  # B of cell (0, 0): below black, stays negative
    return mosaic


@pytest.fixture
def dng(tmp_path: Path) -> tuple[Path, np.ndarray]:
    mosaic = _mosaic()
    path = write_dng(
        tmp_path / "flat.dng",
        mosaic,
        black_level=BLACK,
        white_level=WHITE,
        exposure_time=(1, 100),
        f_number=(28, 10),
        iso=400,
    )
    return path, mosaic


def test_green_binned_exact_values_and_mask(dng: tuple[Path, np.ndarray]) -> None:
    path, mosaic = dng
    image = read_raw(path)
    m = mosaic.astype(np.float64)
    expected = ((m[0::2, 1::2] - BLACK) + (m[1::2, 0::2] - BLACK)) / 2
    np.testing.assert_array_equal(image.values, expected)
    assert image.values.shape == (H // 2, W // 2)
    expected_mask = np.zeros((H // 2, W // 2), dtype=bool)
    expected_mask[2, 2] = True
    expected_mask[3, 3] = True
    np.testing.assert_array_equal(image.saturated, expected_mask)
    assert image.white_level == WHITE - BLACK
    assert image.black_level == BLACK
    assert image.bit_depth == 12
    assert image.binning == 2
    assert image.channel == "green_binned"
    assert image.source == str(path)
    assert image.exposure == Exposure(exposure_time_s=0.01, iso=400, f_number=2.8)


@pytest.mark.parametrize(
    ("channel", "offset", "saturated_cells"),
    [
        ("R", (0, 0), [(5, 5)]),
        ("G1", (0, 1), [(2, 2)]),
        ("G2", (1, 0), [(3, 3)]),
        ("B", (1, 1), []),
    ],
)
def test_single_sites_exact(
    dng: tuple[Path, np.ndarray],
    channel: str,
    offset: tuple[int, int],
    saturated_cells: list[tuple[int, int]],
) -> None:
    path, mosaic = dng
    image = read_raw(path, channel=channel)  # type: ignore[arg-type]
    dy, dx = offset
    np.testing.assert_array_equal(image.values, mosaic[dy::2, dx::2].astype(np.float64) - BLACK)
    expected_mask = np.zeros((H // 2, W // 2), dtype=bool)
    for cell in saturated_cells:
        expected_mask[cell] = True
    np.testing.assert_array_equal(image.saturated, expected_mask)
    assert image.binning == 2


def test_negative_values_after_black_are_kept(dng: tuple[Path, np.ndarray]) -> None:
    path, _ = dng
    assert read_raw(path, channel="B").values[0, 0] == 30 - BLACK


@pytest.mark.parametrize(
    ("pattern", "sites"),
    [
        # sites: offsets of R, G1 (red row), G2 (blue row), B in the 2x2 cell
        ("BGGR", {"R": (1, 1), "G1": (1, 0), "G2": (0, 1), "B": (0, 0)}),
        ("GRBG", {"R": (0, 1), "G1": (0, 0), "G2": (1, 1), "B": (1, 0)}),
        ("GBRG", {"R": (1, 0), "G1": (1, 1), "G2": (0, 0), "B": (0, 1)}),
    ],
)
def test_other_bayer_patterns(
    tmp_path: Path, pattern: str, sites: dict[str, tuple[int, int]]
) -> None:
    mosaic = np.random.default_rng(3).integers(100, 3000, (H, W)).astype(np.uint16)
    path = write_dng(tmp_path / "p.dng", mosaic, pattern=pattern)
    m = mosaic.astype(np.float64) - BLACK
    for channel, (dy, dx) in sites.items():
        np.testing.assert_array_equal(read_raw(path, channel=channel).values, m[dy::2, dx::2])  # type: ignore[arg-type]
    (g1y, g1x), (g2y, g2x) = sites["G1"], sites["G2"]
    np.testing.assert_array_equal(
        read_raw(path).values, (m[g1y::2, g1x::2] + m[g2y::2, g2x::2]) / 2
    )


def test_per_site_black_levels_and_odd_size(tmp_path: Path) -> None:
    mosaic = np.random.default_rng(4).integers(100, 3000, (23, 31)).astype(np.uint16)
    path = write_dng(tmp_path / "odd.dng", mosaic, black_level=(60, 70, 80, 90))
    m = mosaic[:22, :30].astype(np.float64)
    image = read_raw(path)
    np.testing.assert_array_equal(image.values, ((m[0::2, 1::2] - 70) + (m[1::2, 0::2] - 80)) / 2)
    assert image.values.shape == (11, 15)
    assert image.black_level == 75
    assert image.white_level == WHITE - 75
    np.testing.assert_array_equal(read_raw(path, channel="R").values, m[0::2, 0::2] - 60)
    np.testing.assert_array_equal(read_raw(path, channel="B").values, m[1::2, 1::2] - 90)


def test_user_levels_override_camera(dng: tuple[Path, np.ndarray]) -> None:
    path, mosaic = dng
    image = read_raw(path, channel="G1", user_black=100, user_white=3000)
    np.testing.assert_array_equal(image.values, mosaic[0::2, 1::2].astype(np.float64) - 100)
    assert image.white_level == 2900
    # threshold 3000 - 0.005 * 2900 = 2985.5
    np.testing.assert_array_equal(image.saturated, mosaic[0::2, 1::2] >= 2985.5)
    assert image.saturated.sum() >= 1


def _flat_field(red: int, green: int, blue: int) -> np.ndarray:
    mosaic = np.empty((H, W), dtype=np.uint16)
    mosaic[0::2, 0::2] = red + BLACK
    mosaic[0::2, 1::2] = green + BLACK
    mosaic[1::2, 0::2] = green + BLACK
    mosaic[1::2, 1::2] = blue + BLACK
    return mosaic


def test_luminance_of_flat_field(tmp_path: Path) -> None:
    mosaic = _flat_field(1000, 2000, 3000)
    mosaic[12, 16] = WHITE  # an R site, clipped
    path = write_dng(tmp_path / "flat.dng", mosaic)
    image = read_raw(path, channel="luminance")
    assert image.values.shape == (H, W)
    assert image.binning == 1
    expected = 0.2126 * 1000 + 0.7152 * 2000 + 0.0722 * 3000
    mask = np.zeros((H, W), dtype=bool)
    mask[10:15, 14:19] = True  # the demosaicing reach: 2 pixels around the clipped one
    np.testing.assert_array_equal(image.saturated, mask)
    # 16-bit output quantisation: 0.5 * 4095 / 65535 = 0.031 raw units per channel.
    np.testing.assert_allclose(image.values[~mask], expected, atol=0.05)
    assert image.white_level == pytest.approx(WHITE - BLACK)
    assert image.black_level == pytest.approx(BLACK)
    # read_image dispatches the same way
    np.testing.assert_array_equal(read_image(path, channel="luminance").values, image.values)


def test_luminance_with_camera_white_balance(tmp_path: Path) -> None:
    mosaic = _flat_field(500, 2000, 600)
    # AsShotNeutral (1/2, 1, 1/4): gains 2, 1, 4.
    path = write_dng(tmp_path / "wb.dng", mosaic, as_shot_neutral=[(1, 2), (1, 1), (1, 4)])
    plain = read_raw(path, channel="luminance")
    np.testing.assert_allclose(plain.values, 0.2126 * 500 + 0.7152 * 2000 + 0.0722 * 600, atol=0.05)
    balanced = read_raw(path, channel="luminance", use_camera_wb=True)
    expected = 0.2126 * 1000 + 0.7152 * 2000 + 0.0722 * 2400
    np.testing.assert_allclose(balanced.values, expected, atol=0.2)
    assert not balanced.saturated.any()


def test_camera_white_balance_missing(dng: tuple[Path, np.ndarray]) -> None:
    path, _ = dng
    with pytest.raises(
        InputError,
        match=re.escape(
            f"{path}: use_camera_wb: the file has no usable camera white balance; "
            "read it without white balance"
        ),
    ):
        read_raw(path, channel="luminance", use_camera_wb=True)


def test_read_image_dispatch_and_channels(dng: tuple[Path, np.ndarray]) -> None:
    path, _ = dng
    np.testing.assert_array_equal(read_image(path).values, read_raw(path).values)
    np.testing.assert_array_equal(
        read_image(path, channel="G2", black_level=0).values,
        read_raw(path, channel="G2", user_black=0).values,
    )
    with pytest.raises(
        InputError,
        match=re.escape(
            f"{path}: unknown raw channel 'G'; "
            "expected one of 'green_binned', 'luminance', 'R', 'G1', 'G2', 'B'"
        ),
    ):
        read_image(path, channel="G")


def test_uppercase_extension(tmp_path: Path) -> None:
    path = write_dng(tmp_path / "IMG_0001.DNG", _mosaic())
    assert read_image(path).binning == 2


def test_truncated_dng(tmp_path: Path, dng: tuple[Path, np.ndarray]) -> None:
    path, _ = dng
    cut = tmp_path / "cut.dng"
    cut.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    with pytest.raises(
        InputError,
        match=re.escape(f"{cut}: not a readable camera raw file (LibRaw: Input/output error)"),
    ):
        read_raw(cut)


def test_text_file_named_dng(tmp_path: Path) -> None:
    path = tmp_path / "notes.dng"
    path.write_text("these are my field notes, not a raw file\n" * 100)
    with pytest.raises(
        InputError,
        match=re.escape(
            f"{path}: not a readable camera raw file "
            "(LibRaw: Unsupported file format or not RAW file)"
        ),
    ):
        read_image(path)


def test_missing_raw_file(tmp_path: Path) -> None:
    path = tmp_path / "gone.dng"
    with pytest.raises(InputError, match=re.escape(f"{path}: file not found")):
        read_raw(path)


def test_response_curve_refused_for_raw(dng: tuple[Path, np.ndarray]) -> None:
    from lightcal.io.response import ResponseCurve

    path, _ = dng
    curve = ResponseCurve(np.linspace(0.01, 1, 256)[:, None])
    with pytest.raises(
        InputError,
        match=re.escape(
            f"{path}: camera raw data is already linear; "
            "a response curve applies only to 8-bit images"
        ),
    ):
        read_image(path, response=curve)


def test_linear_dng_without_mosaic(tmp_path: Path) -> None:
    import tifffile

    path = tmp_path / "linear.dng"
    identity = (1, 1, 0, 1, 0, 1, 0, 1, 1, 1, 0, 1, 0, 1, 0, 1, 1, 1)
    tags = [
        (271, "s", 0, "lightcal", True),
        (272, "s", 0, "test sensor", True),
        (50706, "B", 4, (1, 4, 0, 0), True),
        (50708, "s", 0, "lightcal test sensor", True),
        (50717, "H", 1, (4095,), True),
        (50721, "2i", 9, identity, True),
    ]
    rgb = np.full((24, 24, 3), 1000, dtype=np.uint16)
    tifffile.imwrite(path, rgb, photometric=34892, subfiletype=0, metadata=None, extratags=tags)
    with pytest.raises(
        InputError,
        match=re.escape(
            f"{path}: holds no colour filter mosaic (a linear DNG or a Foveon image); "
            "convert it to a 16-bit or float TIFF and read that"
        ),
    ):
        read_raw(path, channel="luminance")
