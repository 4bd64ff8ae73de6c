"""The relative exposure of every image of a project (`images[i].exposure` or EXIF)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from lightcal.errors import InputError
from lightcal.io.project_spec import ExposureSpec

if TYPE_CHECKING:
    from lightcal.io.project_spec import ProjectFile


def _settings_value(e: Any) -> float:
    """t x ISO / N^2 with `ExposureSpec`'s defaults for settings unknown in every image."""
    iso = e.iso if e.iso is not None else 100.0
    f_number = e.f_number if e.f_number is not None else 1.0
    return float(e.exposure_time_s * iso / f_number**2)


def exposure_factors(spec: ProjectFile, image_paths: list[Path], source: Path) -> list[float]:
    """Relative exposure g_i of every image.

    An explicit factor is used as given. Settings (an `ExposureSpec`, or the file's EXIF
    when `exposure` is null) become t x ISO / N^2 relative to the first image that has
    settings. When some images have settings, every image without an explicit factor
    must have them too (else its exposure would be a guess); when none has, g_i = 1.
    """
    from lightcal.io.exif import Exposure, read_exposure

    settings: list[Exposure | None] = []
    for i, im in enumerate(spec.images):
        if isinstance(im.exposure, ExposureSpec):
            e = im.exposure
            settings.append(Exposure(e.exposure_time_s, e.iso, e.f_number))
        elif im.exposure is None:
            exif = read_exposure(image_paths[i])
            settings.append(exif if exif is not None and exif.exposure_time_s else None)
        else:
            settings.append(None)
    known = [e for e in settings if e is not None]
    factors = []
    for i, im in enumerate(spec.images):
        if isinstance(im.exposure, float | int) and not isinstance(im.exposure, bool):
            factors.append(float(im.exposure))
        elif settings[i] is not None:
            try:
                # Validates that the same settings are known in both (else a guess).
                settings[i].relative_factor(known[0])  # type: ignore[union-attr]
            except ValueError as exc:
                raise InputError(source, f"images[{i}].exposure: {exc}") from exc
            factors.append(_settings_value(settings[i]) / _settings_value(known[0]))
        elif known:
            raise InputError(
                source,
                f"images[{i}].exposure: not given and {image_paths[i].name} has no EXIF "
                "exposure time, while other images' exposures come from settings; "
                "give the exposure of every image",
            )
        else:
            factors.append(1.0)
    return factors
