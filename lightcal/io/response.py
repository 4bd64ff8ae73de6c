"""Camera response curve: turn 8-bit (gamma-encoded, JPEG) pixel values into linear ones.

An 8-bit image straight from a camera is not proportional to light: the camera applied
a tone curve (gamma, S-curve). The response curve f^-1 maps each code 0..255 back to a
value proportional to exposure (irradiance x time). It is fitted once per camera and
setting from a bracket of images of a static scene taken at known exposure times
(Debevec & Malik, "Recovering High Dynamic Range Radiance Maps from Photographs",
SIGGRAPH 1997), here with OpenCV's `cv2.createCalibrateDebevec`.

The curve's scale is arbitrary (OpenCV fixes f^-1(128) = 1): it does not matter for
light calibration, whose global scale is a free parameter anyway.

Channel order: a curve has one column per image channel, in the order of the images it
was fitted on. `lightcal.io.images.read_image` reads 8-bit files with `cv2.imread`, i.e.
in B, G, R order, so fit on images read the same way (`cv2.imread(path)`).
"""

from __future__ import annotations

import io
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from lightcal.errors import InputError
from lightcal.io.atomic import atomic_write_bytes, atomic_write_text
from lightcal.io.document import read_document

__all__ = ["RESPONSE_FILE_FORMAT", "ResponseCurve", "fit_response_debevec"]

RESPONSE_FILE_FORMAT = "lightcal.response_curve"
"""Value of the "format" field of a response curve saved as JSON."""

_JSON_VERSION = 1
_N_CODES = 256


@dataclass(frozen=True)
class ResponseCurve:
    """Inverse camera response: linear exposure value of each 8-bit code, per channel.

    Attributes:
        values: (256, C) float64, C in {1, 3}: `values[z, c]` is the linear value of
            code z in channel c; finite, > 0 and non-decreasing in z. Read-only.
    """

    values: NDArray[np.float64]

    def __post_init__(self) -> None:
        values = np.array(self.values, dtype=np.float64)
        if values.ndim == 1:
            values = values[:, None]
        if values.ndim != 2 or values.shape[0] != _N_CODES or values.shape[1] not in (1, 3):
            raise InputError(
                "values",
                "expected a response curve of shape (256, 1) or (256, 3), "
                f"got {np.shape(self.values)}",
            )
        if not np.all(np.isfinite(values)) or np.any(values <= 0):
            raise InputError("values", "expected finite response values > 0")
        if np.any(np.diff(values, axis=0) < 0):
            raise InputError(
                "values", "expected a response that does not decrease from code 0 to 255"
            )
        values.setflags(write=False)
        object.__setattr__(self, "values", values)

    @property
    def n_channels(self) -> int:
        """Number of channels C."""
        return int(self.values.shape[1])

    def linearize(self, image_uint8: ArrayLike) -> NDArray[np.float64]:
        """Map 8-bit codes to linear values.

        Args:
            image_uint8: (H, W) or (H, W, C) uint8, C equal to the curve's channel count
                (a one-channel curve applies to every channel).

        Returns:
            linear: float64 of the same shape.

        Raises:
            InputError: Not uint8, or a channel count the curve does not have.
        """
        image = np.asarray(image_uint8)
        if image.dtype != np.uint8:
            raise InputError("image", f"expected 8-bit (uint8) pixel values, got {image.dtype}")
        if image.ndim == 2:
            if self.n_channels != 1:
                raise InputError(
                    "image",
                    f"single-channel image but the response curve has {self.n_channels} channels; "
                    "fit a curve on single-channel images or read the image in colour",
                )
            return self.values[image, 0]
        if image.ndim != 3:
            raise InputError(
                "image", f"expected an image of shape (H, W) or (H, W, C), got {image.shape}"
            )
        if self.n_channels == 1:
            return self.values[image, 0]
        if image.shape[2] != self.n_channels:
            raise InputError(
                "image",
                f"image has {image.shape[2]} channels but the response curve has {self.n_channels}",
            )
        return np.stack([self.values[image[..., c], c] for c in range(self.n_channels)], axis=-1)

    def save(self, path: str | Path) -> None:
        """Write the curve atomically: `.npy` (a (256, C) float64 array) or `.json`.

        Raises:
            InputError: The extension is neither `.npy` nor `.json`.
        """
        path = Path(path)
        suffix = path.suffix.lower()
        if suffix == ".npy":
            buffer = io.BytesIO()
            np.save(buffer, self.values, allow_pickle=False)
            atomic_write_bytes(path, buffer.getvalue())
        elif suffix == ".json":
            document = {
                "format": RESPONSE_FILE_FORMAT,
                "version": _JSON_VERSION,
                "values": self.values.tolist(),
            }
            atomic_write_text(path, json.dumps(document, indent=1) + "\n")
        else:
            raise InputError(path, "unknown response curve extension; expected .npy or .json")

    @classmethod
    def load(cls, path: str | Path) -> ResponseCurve:
        """Read a curve written by `save` (or any (256, C) float array in a `.npy`).

        Raises:
            InputError: Missing file, unknown extension or content that is not a curve.
        """
        path = Path(path)
        if not path.is_file():
            raise InputError(path, "file not found")
        suffix = path.suffix.lower()
        if suffix == ".npy":
            try:
                values: Any = np.load(path, allow_pickle=False)
            except (ValueError, OSError, EOFError) as error:
                raise InputError(path, f"not a readable .npy array ({error})") from None
        elif suffix == ".json":
            document = read_document(path, what="response curve file", as_json=True)
            if not isinstance(document, dict) or document.get("format") != RESPONSE_FILE_FORMAT:
                raise InputError(
                    path, f'expected a JSON object with "format": "{RESPONSE_FILE_FORMAT}"'
                )
            if document.get("version") != _JSON_VERSION:
                raise InputError(
                    path,
                    f"unsupported version {document.get('version')!r}; expected {_JSON_VERSION}",
                )
            values = document.get("values")
        else:
            raise InputError(path, "unknown response curve extension; expected .npy or .json")
        try:
            array = np.asarray(values, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(path, "expected a (256, C) array of numbers") from None
        try:
            return cls(array)
        except InputError as error:
            raise InputError(path, error.detail) from None


def fit_response_debevec(
    images: Sequence[ArrayLike],
    exposure_times_s: Sequence[float] | ArrayLike,
    *,
    samples: int = 70,
    smoothness: float = 10.0,
    random_samples: bool = False,
) -> ResponseCurve:
    """Fit the inverse camera response from an exposure bracket (Debevec & Malik 1997).

    Args:
        images: P >= 2 images (H, W, 3) uint8 of the same static scene, same size.
        exposure_times_s: (P,) exposure time of each image in seconds, all > 0.
        samples: Number of pixel locations OpenCV samples.
        smoothness: Weight of the curve's second-difference penalty (Debevec's lambda).
        random_samples: Sample random locations instead of a regular grid.

    Returns:
        The fitted curve, (256, 3), channel order that of `images`.

    Raises:
        InputError: Fewer than two images, mismatched shapes or dtypes, bad times.
    """
    stack = [np.asarray(image) for image in images]
    if len(stack) < 2:
        raise InputError(
            "images", f"expected at least 2 images of an exposure bracket, got {len(stack)}"
        )
    first = stack[0]
    for index, image in enumerate(stack):
        if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
            raise InputError(
                f"images[{index}]",
                f"expected an (H, W, 3) uint8 image, got shape {image.shape} of {image.dtype}",
            )
        if image.shape != first.shape:
            raise InputError(
                f"images[{index}]",
                f"expected shape {first.shape} like images[0], got {image.shape}",
            )
    times = np.asarray(exposure_times_s, dtype=np.float64).reshape(-1)
    if times.size != len(stack):
        raise InputError(
            "exposure_times_s",
            f"expected {len(stack)} exposure times, one per image, got {times.size}",
        )
    if not np.all(np.isfinite(times)) or np.any(times <= 0):
        raise InputError("exposure_times_s", "expected finite exposure times > 0")
    calibrate = cv2.createCalibrateDebevec(int(samples), float(smoothness), bool(random_samples))
    curve = calibrate.process(
        [np.ascontiguousarray(image) for image in stack], times.astype(np.float32)
    )
    values = np.asarray(curve, dtype=np.float64).reshape(_N_CODES, 3)
    # OpenCV's least-squares curve may dip slightly where codes were never sampled
    # (the ends); a response is monotonic, so keep the running maximum.
    values = np.maximum.accumulate(values, axis=0)
    return ResponseCurve(values)
