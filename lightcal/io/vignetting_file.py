"""Fall-off (vignetting) files: measured per-pixel maps and fitted radial models.

Per-pixel maps (any positive scale; normalised on loading, see
`lightcal.core.vignetting.vignetting_from_map`):

- `.npy`: a 2-D numeric array (no pickles);
- `.png`: a single-channel 8- or 16-bit image;
- `.tif` / `.tiff`: a single-channel image, float or integer.

Radial models (`lightcal.core.vignetting.RadialVignetting`) are JSON files:

    {"format": "lightcal.radial_vignetting", "version": 1,
     "width": 6000, "height": 4000, "center_px": [2999.5, 1999.5],
     "coeffs": [-0.3, 0.05, -0.01], "fit_rms": 0.002}

with V = 1 + c1 r^2 + c2 r^4 + ..., r = |(u, v) - center_px| / (hypot(width, height) / 2),
pixel centres at integers. `fit_rms` (dimensionless, may be null) is informative only.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Final, Literal

import cv2
import numpy as np
import tifffile
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, ValidationError

from lightcal.core.vignetting import RadialVignetting, vignetting_from_map
from lightcal.errors import InputError
from lightcal.io.atomic import atomic_write_text
from lightcal.io.text_files import read_text

MAP_SUFFIXES = (".npy", ".png", ".tif", ".tiff")
"""Suffixes of per-pixel fall-off maps."""

MODEL_FORMAT: Final = "lightcal.radial_vignetting"
"""The `format` tag of a radial model JSON file."""


class RadialVignettingFile(BaseModel):
    """On-disk form of a radial fall-off model (JSON)."""

    model_config = ConfigDict(extra="forbid", strict=True)

    format: Literal["lightcal.radial_vignetting"]
    version: Literal[1]
    width: int
    height: int
    center_px: tuple[float, float]
    coeffs: list[float]
    fit_rms: float | None = None


def _read_raw_map(path: Path) -> NDArray[np.float64]:
    """The file's pixel values as a float64 array (any number of dimensions)."""
    suffix = path.suffix.lower()
    if suffix == ".npy":
        try:
            array = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise InputError(path, f"not a readable .npy array: {exc}") from exc
    elif suffix == ".png":
        array = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if array is None:
            raise InputError(path, "not a readable PNG image")
    else:
        try:
            array = tifffile.imread(path)
        except (OSError, ValueError, tifffile.TiffFileError) as exc:
            raise InputError(path, f"not a readable TIFF image: {exc}") from exc
    if not (np.issubdtype(array.dtype, np.integer) or np.issubdtype(array.dtype, np.floating)):
        raise InputError(path, f"expected numeric pixel values, got dtype {array.dtype}")
    if array.ndim == 3 and array.shape[2] == 1:
        array = array[:, :, 0]
    if array.ndim != 2:
        raise InputError(
            path, f"expected a single-channel (H, W) map, got an array of shape {array.shape}"
        )
    return array.astype(np.float64)


def load_vignetting_map(
    path: str | Path,
    *,
    width: int,
    height: int,
    normalise: Literal["max", "center"] = "max",
) -> NDArray[np.float64]:
    """Load a per-pixel fall-off map for a camera of `width` x `height`.

    Args:
        path: A .npy, .png (8/16-bit) or .tif/.tiff file holding one (H, W) channel.
        width: The camera's image width.
        height: The camera's image height.
        normalise: "max" (maximum -> 1) or "center" (image centre -> 1).

    Returns:
        map: (height, width) float64, positive.

    Raises:
        InputError: Missing or unreadable file, unsupported suffix, several channels,
            a size other than the camera's, non-finite or non-positive values.
    """
    file = Path(path)
    if file.suffix.lower() not in MAP_SUFFIXES:
        raise InputError(
            file, f"unsupported suffix {file.suffix!r}: expected one of {', '.join(MAP_SUFFIXES)}"
        )
    if not file.is_file():
        raise InputError(file, "file not found: expected a fall-off map")
    raw = _read_raw_map(file)
    return vignetting_from_map(
        raw, width=width, height=height, normalise=normalise, source=str(file)
    )


def save_radial_vignetting(
    path: str | Path, model: RadialVignetting, *, fit_rms: float | None = None
) -> None:
    """Write a radial fall-off model as JSON, atomically (old file intact on failure).

    Args:
        path: The .json file to write; its folder must exist.
        model: The model.
        fit_rms: The fit's RMS (dimensionless), stored for information.
    """
    if fit_rms is not None and not math.isfinite(fit_rms):
        raise InputError("fit_rms", f"expected a finite number or None, got {fit_rms!r}")
    content = RadialVignettingFile(
        format=MODEL_FORMAT,
        version=1,
        width=model.width,
        height=model.height,
        center_px=(float(model.center_px[0]), float(model.center_px[1])),
        coeffs=[float(c) for c in model.coeffs],
        fit_rms=None if fit_rms is None else float(fit_rms),
    )
    atomic_write_text(path, json.dumps(content.model_dump(), indent=2) + "\n")


def load_radial_vignetting(path: str | Path) -> RadialVignetting:
    """Read a radial fall-off model written by `save_radial_vignetting`.

    Raises:
        InputError: Missing file, invalid JSON (with the line), a missing, extra or
            wrongly typed field (named), invalid values.
    """
    file = Path(path)
    text = read_text(file, "radial fall-off JSON file")
    try:
        json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(file, f"not valid JSON: {exc.msg}", line=exc.lineno) from exc
    try:
        content = RadialVignettingFile.model_validate_json(text)
    except ValidationError as exc:
        first = exc.errors()[0]
        field = ".".join(str(part) for part in first["loc"]) or "(top level)"
        raise InputError(file, f"field {field}: {first['msg']}") from exc
    try:
        return RadialVignetting(
            center_px=np.array(content.center_px),
            coeffs=np.array(content.coeffs),
            width=content.width,
            height=content.height,
        )
    except InputError as exc:
        raise InputError(file, f"field {exc.source}: {exc.detail}") from exc


def load_vignetting(
    path: str | Path,
    *,
    width: int,
    height: int,
    normalise: Literal["max", "center"] = "max",
) -> NDArray[np.float64]:
    """Per-pixel fall-off for a camera from either kind of file.

    A .json radial model is evaluated on every pixel (V = 1 at its centre; `normalise`
    does not apply); a map is loaded with `load_vignetting_map`.

    Returns:
        map: (height, width) float64.
    """
    file = Path(path)
    if file.suffix.lower() != ".json":
        return load_vignetting_map(file, width=width, height=height, normalise=normalise)
    model = load_radial_vignetting(file)
    try:
        return model.image(width, height)
    except InputError as exc:
        raise InputError(file, exc.detail) from exc
