"""Exposure settings from EXIF: DNG (IFD0 tags), JPEG / PNG / TIFF (Exif IFD), odd tags."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from PIL import Image, TiffImagePlugin

from lightcal.errors import InputError
from lightcal.io.exif import Exposure, read_exposure
from lightcal.io.images import read_image
from tests.raw_dng import write_dng

TAG_EXIF_IFD = 0x8769


def _exif(**tags: object) -> Image.Exif:
    exif = Image.Exif()
    ifd = exif.get_ifd(TAG_EXIF_IFD)
    for code, value in tags.items():
        ifd[int(code, 16)] = value
    return exif


def test_dng_ifd0_tags(tmp_path: Path) -> None:
    mosaic = np.full((24, 24), 1000, dtype=np.uint16)
    path = write_dng(tmp_path / "a.dng", mosaic, exposure_time=(1, 250), f_number=(56, 10), iso=800)
    assert read_exposure(path) == Exposure(exposure_time_s=0.004, iso=800, f_number=5.6)


def test_dng_zero_denominator_is_absent(tmp_path: Path) -> None:
    mosaic = np.full((24, 24), 1000, dtype=np.uint16)
    path = write_dng(tmp_path / "a.dng", mosaic, exposure_time=(1, 0), iso=100)
    assert read_exposure(path) == Exposure(exposure_time_s=None, iso=100, f_number=None)


def test_jpeg_exif_ifd(tmp_path: Path) -> None:
    path = tmp_path / "photo.jpg"
    exif = _exif(
        **{
            "0x829a": TiffImagePlugin.IFDRational(1, 60),
            "0x829d": TiffImagePlugin.IFDRational(8, 1),
            "0x8827": 200,
        }
    )
    Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(path, exif=exif)
    assert read_exposure(path) == Exposure(exposure_time_s=1 / 60, iso=200, f_number=8.0)


def test_png_exif_chunk(tmp_path: Path) -> None:
    path = tmp_path / "photo.png"
    exif = _exif(**{"0x829a": TiffImagePlugin.IFDRational(1, 30)})
    Image.fromarray(np.zeros((8, 8), np.uint16)).save(path, exif=exif.tobytes())
    assert read_exposure(path) == Exposure(exposure_time_s=1 / 30)
    # and read_image attaches it
    image = read_image(path)
    assert image.exposure == Exposure(exposure_time_s=1 / 30)


def test_tiff_exif_ifd_through_tifffile(tmp_path: Path) -> None:
    path = tmp_path / "frame.tif"
    info = TiffImagePlugin.ImageFileDirectory_v2()
    info[TAG_EXIF_IFD] = {
        0x829A: TiffImagePlugin.IFDRational(1, 125),
        0x829D: TiffImagePlugin.IFDRational(4, 1),
        0x8827: 1600,
    }
    Image.fromarray(np.full((6, 6), 1000, np.uint16)).save(path, tiffinfo=info)
    assert read_exposure(path) == Exposure(exposure_time_s=0.008, iso=1600, f_number=4.0)
    assert read_image(path).exposure == Exposure(exposure_time_s=0.008, iso=1600, f_number=4.0)


def test_apex_values_stand_in(tmp_path: Path) -> None:
    path = tmp_path / "apex.jpg"
    # Tv = 7 -> t = 1/128 s; Av = 5 -> N = 2^2.5
    exif = _exif(
        **{"0x9201": TiffImagePlugin.IFDRational(7, 1), "0x9202": TiffImagePlugin.IFDRational(5, 1)}
    )
    Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(path, exif=exif)
    exposure = read_exposure(path)
    assert exposure is not None
    assert exposure.exposure_time_s == pytest.approx(1 / 128, rel=1e-12)
    assert exposure.f_number == pytest.approx(2**2.5, rel=1e-12)
    assert exposure.iso is None


def test_odd_tags_never_crash(tmp_path: Path) -> None:
    path = tmp_path / "odd.jpg"
    exif = _exif(
        **{"0x829a": "fast", "0x829d": TiffImagePlugin.IFDRational(-2, 1), "0x8827": (0, 100)}
    )
    Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(path, exif=exif)
    assert read_exposure(path) is None


def test_absent_or_unreadable(tmp_path: Path) -> None:
    plain = tmp_path / "plain.jpg"
    Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(plain)
    assert read_exposure(plain) is None
    text = tmp_path / "notes.tif"
    text.write_text("II*\x00 but not really a TIFF")
    assert read_exposure(text) is None
    assert read_exposure(tmp_path / "missing.jpg") is None


def test_relative_factor() -> None:
    reference = Exposure(exposure_time_s=0.01, iso=100, f_number=2.0)
    brighter = Exposure(exposure_time_s=0.04, iso=200, f_number=4.0)
    # (0.04 * 200 / 16) / (0.01 * 100 / 4) = 0.5 / 0.25
    assert brighter.relative_factor(reference) == pytest.approx(2.0, rel=1e-15)
    assert reference.relative_factor(brighter) == pytest.approx(0.5, rel=1e-15)
    # unknown in both: taken as equal
    assert Exposure(exposure_time_s=0.02).relative_factor(Exposure(exposure_time_s=0.01)) == 2.0
    with pytest.raises(
        InputError,
        match=re.escape(
            "iso: known for only one of the two exposures being compared; "
            "give it for both (or for neither) to compare their exposures"
        ),
    ):
        Exposure(exposure_time_s=0.02, iso=100).relative_factor(Exposure(exposure_time_s=0.01))


def test_validation_and_overrides() -> None:
    with pytest.raises(
        InputError, match=re.escape("f_number: expected a finite number > 0 or None, got -2.0")
    ):
        Exposure(f_number=-2.0)
    read = Exposure(exposure_time_s=0.01, iso=100, f_number=2.8)
    assert read.with_overrides(iso=400) == Exposure(exposure_time_s=0.01, iso=400, f_number=2.8)
    assert read.with_overrides() == read
