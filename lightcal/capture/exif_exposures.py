"""The exposure entries `lightcal init` writes for its images, from their EXIF settings.

When every accepted image carries EXIF exposure settings, the project gets them (the
calibration uses them relative to the first image): the settings themselves when every
image has an exposure time, else the factors relative to the first image; when none
does, no entry (every image exposure 1); when only some do, or they are inconsistent, a
warning says so and every image gets exposure 1.
"""

from __future__ import annotations

from collections.abc import Sequence

from lightcal.errors import InputError
from lightcal.io.exif import Exposure
from lightcal.io.project import ExposureSpec

__all__ = ["exposure_specs"]


def exposure_specs(
    names: Sequence[str], exposures: Sequence[Exposure | None], warnings: list[str]
) -> list[float | ExposureSpec | None]:
    """The project's exposure entries of the accepted images (see the module docstring).

    Args:
        names: The images' file names, for the warnings.
        exposures: Their EXIF exposure settings, None where absent.
        warnings: Gets a line when the settings are ignored.
    """
    known = [e for e in exposures if e is not None]
    if not known:
        return [None] * len(exposures)
    if len(known) < len(exposures):
        missing = [n for n, e in zip(names, exposures, strict=True) if e is None]
        warnings.append(
            f"EXIF exposure found in {len(known)} of {len(exposures)} images (missing in "
            f"{', '.join(missing[:3])}{', ...' if len(missing) > 3 else ''}): ignored, every "
            "image gets exposure 1; give the exposures in the project or estimate per-image "
            "gains (solver.estimate_gains)"
        )
        return [1.0] * len(exposures)
    reference = known[0]
    try:
        factors = [e.relative_factor(reference) for e in known]
    except InputError as exc:
        warnings.append(
            f"EXIF exposure settings are inconsistent across the images ({exc.source} "
            f"{exc.detail}): ignored, every image gets exposure 1"
        )
        return [1.0] * len(exposures)
    if all(e.exposure_time_s is not None for e in known):
        specs: list[float | ExposureSpec | None] = []
        for e in known:
            assert e.exposure_time_s is not None
            settings: dict[str, float] = {"exposure_time_s": e.exposure_time_s}
            if e.iso is not None:
                settings["iso"] = e.iso
            if e.f_number is not None:
                settings["f_number"] = e.f_number
            specs.append(ExposureSpec(**settings))
        return specs
    return list(factors)
