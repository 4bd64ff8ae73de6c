"""Light-off photos (`images[i].dark`): found, checked against their image, subtracted.

A light-off ("dark") photo is the same view with the calibrated light off and the same
exposure: what the room light (and any offset the black level misses) puts on every
pixel. It is read exactly as its image is (same reader, black level, white level,
response curve or linearity, channel: `lightcal.pipeline.load`) and subtracted from it
before the fit, so that what is fitted is the light alone (docs/model.md, "Light-off
photos").

Checks, each an `InputError` naming the files and what differs:

- at project load (`dark_paths`): the file exists, is not the image itself, and is stored
  the way its image is (camera raw for a raw image, a developed image for a developed
  one): raw and developed data differ in levels, channels and linearity;
- at image load (`subtract_dark`): the same size, the same bits per sample, and the same
  exposure where both are known (the image's declared settings or EXIF, the dark's EXIF:
  exposure time, ISO, f-number, relative difference above `EXPOSURE_TOLERANCE`); a NaN or
  infinite pixel is refused by the reader already.

After subtraction, values may be a little negative (noise); a pixel saturated in either
photo is saturated.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from lightcal.errors import InputError
from lightcal.io.exif import Exposure
from lightcal.io.images import RAW_EXTENSIONS
from lightcal.io.linear_image import LinearImage
from lightcal.io.project_spec import ExposureSpec, ProjectFile

__all__ = ["EXPOSURE_TOLERANCE", "dark_level", "dark_paths", "declared_exposure", "subtract_dark"]

EXPOSURE_TOLERANCE = 1e-3
"""Largest relative difference of an exposure setting between a photo and its dark one."""


def dark_paths(
    spec: ProjectFile, folder: Path, source: Path, image_paths: list[Path]
) -> list[Path | None]:
    """Each image's light-off photo, resolved against `folder` and checked (module docstring).

    Args:
        spec: The project file.
        folder: The folder relative paths resolve against.
        source: The project file, for error messages.
        image_paths: (n,) the images' resolved paths.

    Returns:
        (n,) the dark photo of each image, or None.
    """
    out: list[Path | None] = []
    for i, (im, image_path) in enumerate(zip(spec.images, image_paths, strict=True)):
        if im.dark is None:
            out.append(None)
            continue
        field = f"images[{i}].dark"
        path = Path(im.dark)
        path = path if path.is_absolute() else folder / path
        if not path.is_file():
            raise InputError(source, f"{field}: light-off photo not found: {path}")
        if path.resolve() == image_path.resolve():
            raise InputError(
                source,
                f"{field}: the same file as images[{i}].path ({path.name}); expected a photo "
                "of the same view with the light off",
            )
        dark_raw = path.suffix.lower() in RAW_EXTENSIONS
        image_raw = image_path.suffix.lower() in RAW_EXTENSIONS
        if dark_raw != image_raw:
            kinds = ("a camera raw file", "a developed image (not camera raw)")
            raise InputError(
                source,
                f"{field}: {path.name} is {kinds[not dark_raw]} but its image "
                f"{image_path.name} is {kinds[not image_raw]}; expected the light-off photo "
                "stored as its image is (same camera output)",
            )
        out.append(path)
    return out


def declared_exposure(spec: ProjectFile, index: int) -> Exposure | None:
    """The exposure settings image `index` declares (`ExposureSpec`), or None."""
    e = spec.images[index].exposure
    if isinstance(e, ExposureSpec):
        return Exposure(e.exposure_time_s, e.iso, e.f_number)
    return None


_SETTINGS = (
    ("exposure_time_s", "exposure time", " s"),
    ("iso", "ISO", ""),
    ("f_number", "f-number", ""),
)


def _exposure_difference(image: Exposure, dark: Exposure) -> tuple[str, str, str] | None:
    """(setting, the dark's value, the image's) of the first setting known in both
    exposures that differs, or None."""
    for name, label, unit in _SETTINGS:
        mine, theirs = getattr(image, name), getattr(dark, name)
        if mine is None or theirs is None:
            continue
        if abs(mine - theirs) > EXPOSURE_TOLERANCE * max(abs(mine), abs(theirs)):
            return label, f"{theirs:g}{unit}", f"{mine:g}{unit}"
    return None


def subtract_dark(
    image: LinearImage,
    dark: LinearImage,
    *,
    image_path: Path,
    dark_path: Path,
    declared: Exposure | None = None,
) -> LinearImage:
    """The image with its light-off photo subtracted, after the checks (module docstring).

    Args:
        image: The photo, read.
        dark: Its light-off photo, read with the same reader options.
        image_path: The photo's file, for messages.
        dark_path: The light-off photo's file, for messages.
        declared: The exposure the project declares for the image (else its EXIF is
            compared).

    Returns:
        values image - dark, saturated where either is; levels and EXIF of the image.

    Raises:
        InputError: (naming the dark file) the sizes, bits per sample or exposures differ.
    """
    if dark.shape != image.shape:
        raise InputError(
            dark_path,
            f"the light-off photo is {dark.shape[1]}x{dark.shape[0]} pixels but its image "
            f"{image_path.name} is {image.shape[1]}x{image.shape[0]}; expected the same size",
        )
    if dark.bit_depth != image.bit_depth:

        def bits(b: int | None) -> str:
            return "float values" if b is None else f"{b} bits per sample"

        raise InputError(
            dark_path,
            f"the light-off photo has {bits(dark.bit_depth)} but its image "
            f"{image_path.name} has {bits(image.bit_depth)}; expected the same camera output",
        )
    reference = declared if declared is not None else image.exposure
    if reference is not None and dark.exposure is not None:
        differs = _exposure_difference(reference, dark.exposure)
        if differs is not None:
            label, theirs, mine = differs
            where = "declared for the image" if declared is not None else "the image's EXIF"
            raise InputError(
                dark_path,
                f"the light-off photo's {label} differs from its image {image_path.name}'s: "
                f"{theirs} (its EXIF) against {mine} ({where}); expected a light-off photo "
                "taken with the image's settings",
            )
    return dataclasses.replace(
        image,
        values=image.values - dark.values,
        saturated=image.saturated | dark.saturated,
    )


def dark_level(dark: LinearImage) -> float:
    """The mean value of a light-off photo (0 when negative or nothing is finite): the
    level whose shot noise adds to the noise model (docs/model.md, "Light-off photos")."""
    finite = dark.values[np.isfinite(dark.values)]
    mean = float(finite.mean()) if finite.size else 0.0
    return mean if math.isfinite(mean) and mean > 0.0 else 0.0
