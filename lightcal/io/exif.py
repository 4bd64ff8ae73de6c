"""Exposure settings (time, ISO, f-number) from a file's EXIF tags.

TIFF-based files (DNG, NEF, ARW, CR2, PEF, TIFF, ...) are read with `tifffile`: the tags
of the first IFD (TIFF/EP and DNG put the exposure tags there) and of its Exif IFD
(tag 0x8769). Other files (JPEG, PNG, WebP, ...) are read with Pillow
(`Image.getexif()` and its Exif IFD). Values found in the Exif IFD win over those of
the first IFD. When ExposureTime or FNumber is missing, the APEX tags ShutterSpeedValue
(t = 2^-Tv) and ApertureValue (N = 2^(Av/2)) stand in.

Reading never fails on odd metadata: a tag that is missing, zero, negative, not finite,
a rational with a zero denominator or of an unexpected type is treated as absent, and a
file that cannot be parsed at all gives `None`.

Values given explicitly by the user (configuration or command line) always override the
ones read here; that is the caller's job: `Exposure.with_overrides` helps.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from lightcal.errors import InputError

__all__ = ["Exposure", "read_exposure"]

_TAG_EXPOSURE_TIME = 0x829A
_TAG_F_NUMBER = 0x829D
_TAG_ISO = 0x8827  # ISOSpeedRatings, called PhotographicSensitivity since EXIF 2.3
_TAG_SHUTTER_SPEED_VALUE = 0x9201
_TAG_APERTURE_VALUE = 0x9202
_TAG_EXIF_IFD = 0x8769

_TAG_NAMES = {
    _TAG_EXPOSURE_TIME: ("ExposureTime",),
    _TAG_F_NUMBER: ("FNumber",),
    _TAG_ISO: ("ISOSpeedRatings", "PhotographicSensitivity"),
    _TAG_SHUTTER_SPEED_VALUE: ("ShutterSpeedValue",),
    _TAG_APERTURE_VALUE: ("ApertureValue",),
}

_TIFF_MAGICS = (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+")


@dataclass(frozen=True)
class Exposure:
    """How much light one image collected, relative to another.

    Attributes:
        exposure_time_s: Shutter time in seconds, or None when unknown.
        iso: ISO sensitivity (gain), or None when unknown.
        f_number: Aperture f-number N, or None when unknown.
    """

    exposure_time_s: float | None = None
    iso: float | None = None
    f_number: float | None = None

    def __post_init__(self) -> None:
        for name in ("exposure_time_s", "iso", "f_number"):
            value = getattr(self, name)
            if value is None:
                continue
            if not isinstance(value, int | float) or not math.isfinite(value) or value <= 0:
                raise InputError(name, f"expected a finite number > 0 or None, got {value!r}")
            object.__setattr__(self, name, float(value))

    def relative_factor(self, reference: Exposure) -> float:
        """Gain of this exposure relative to `reference`: (t iso / N^2) / (t_ref iso_ref / N_ref^2).

        A setting unknown in both exposures is taken as equal (factor 1); a setting known
        in only one of them is an error, since the ratio would be a guess.

        Args:
            reference: The exposure the factor is relative to.

        Returns:
            factor: > 0; pixel values of this image are `factor` times those of the
                reference for the same scene radiance (linear sensor, no clipping).

        Raises:
            InputError: A setting is known for one exposure and not for the other.
        """
        factor = 1.0
        for name, power in (("exposure_time_s", 1.0), ("iso", 1.0), ("f_number", -2.0)):
            mine, theirs = getattr(self, name), getattr(reference, name)
            if mine is None and theirs is None:
                continue
            if mine is None or theirs is None:
                raise InputError(
                    name,
                    "known for only one of the two exposures being compared; "
                    "give it for both (or for neither) to compare their exposures",
                )
            factor *= (mine / theirs) ** power
        return factor

    def with_overrides(
        self,
        *,
        exposure_time_s: float | None = None,
        iso: float | None = None,
        f_number: float | None = None,
    ) -> Exposure:
        """A copy where every setting given (not None) replaces the one read from the file."""
        return replace(
            self,
            exposure_time_s=self.exposure_time_s if exposure_time_s is None else exposure_time_s,
            iso=self.iso if iso is None else iso,
            f_number=self.f_number if f_number is None else f_number,
        )


def read_exposure(path: str | Path) -> Exposure | None:
    """Read exposure time, ISO and f-number from a file's EXIF metadata.

    Args:
        path: An image or camera raw file.

    Returns:
        The settings found (each None when absent or unusable), or None when the file
        has none of them or cannot be parsed.
    """
    path = Path(path)
    try:
        with path.open("rb") as stream:
            magic = stream.read(4)
    except OSError:
        return None
    tags: dict[int, Any] = {}
    try:
        if magic in _TIFF_MAGICS:
            tags = _tags_tifffile(path)
        if not tags:
            tags = _tags_pillow(path)
    except Exception:
        # Metadata is optional: any parser failure on odd files means "unknown".
        return None

    exposure_time_s = _positive(tags.get(_TAG_EXPOSURE_TIME))
    if exposure_time_s is None:
        tv = _finite(tags.get(_TAG_SHUTTER_SPEED_VALUE))
        exposure_time_s = _positive(2.0**-tv) if tv is not None and abs(tv) < 64 else None
    f_number = _positive(tags.get(_TAG_F_NUMBER))
    if f_number is None:
        av = _finite(tags.get(_TAG_APERTURE_VALUE))
        f_number = _positive(2.0 ** (av / 2.0)) if av is not None and abs(av) < 64 else None
    iso = _positive(tags.get(_TAG_ISO), rational=False)
    if exposure_time_s is None and iso is None and f_number is None:
        return None
    return Exposure(exposure_time_s=exposure_time_s, iso=iso, f_number=f_number)


def _tags_tifffile(path: Path) -> dict[int, Any]:
    """Exposure tags of the first IFD, overridden by its Exif IFD's."""
    import tifffile

    found: dict[int, Any] = {}
    with tifffile.TiffFile(path) as tif:
        page = tif.pages.first
        for code in _TAG_NAMES:
            tag = page.tags.get(code)
            if tag is not None:
                found[code] = tag.value
        exif_tag = page.tags.get(_TAG_EXIF_IFD)
        if exif_tag is not None and isinstance(exif_tag.value, Mapping):
            found.update(_pick(exif_tag.value))
    return found


def _tags_pillow(path: Path) -> dict[int, Any]:
    """Exposure tags of Pillow's EXIF view, overridden by its Exif IFD's."""
    from PIL import Image

    with Image.open(path) as image:
        exif = image.getexif()
        found = _pick(exif)
        found.update(_pick(exif.get_ifd(_TAG_EXIF_IFD)))
    return found


def _pick(tags: Mapping[Any, Any]) -> dict[int, Any]:
    """The exposure tags of `tags`, keyed by tag code (`tags` keyed by code or by name)."""
    found: dict[int, Any] = {}
    for code, names in _TAG_NAMES.items():
        for key in (code, *names):
            if key in tags:
                found[code] = tags[key]
                break
    return found


def _finite(value: Any, *, rational: bool = True) -> float | None:
    """A tag value as a finite float, or None.

    Rationals come as (numerator, denominator) pairs (tifffile) or as objects (Pillow);
    with `rational=False` a sequence means several values, of which the first is used.
    """
    if isinstance(value, list | tuple):
        if rational and len(value) == 2 and all(isinstance(v, int) for v in value):
            numerator, denominator = value
            if denominator == 0:
                return None
            value = numerator / denominator
        elif len(value) >= 1:
            # Several values (e.g. ISOSpeedRatings with one entry per channel): the first.
            return _finite(value[0], rational=rational)
        else:
            return None
    try:
        number = float(value)
    except (TypeError, ValueError, ZeroDivisionError, OverflowError):
        return None
    return number if math.isfinite(number) else None


def _positive(value: Any, *, rational: bool = True) -> float | None:
    number = _finite(value, rational=rational)
    return number if number is not None and number > 0 else None
