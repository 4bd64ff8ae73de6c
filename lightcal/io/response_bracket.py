"""Reading the photos of an exposure bracket for `lightcal response`: 8-bit colour images
as OpenCV reads them (B, G, R: the order `ResponseCurve.linearize` expects of images read
by `lightcal.io.images`)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from lightcal.errors import InputError
from lightcal.io.text_files import check_regular_file


def read_bracket_image(path: Path) -> np.ndarray:
    """(H, W, 3) uint8, B G R; InputError naming the file when it is not an 8-bit photo."""
    check_regular_file(path, "photo")
    data = np.fromfile(path, dtype=np.uint8)
    image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if image is None:
        raise InputError(
            path, "not an image OpenCV can read; expected an 8-bit photo (JPEG, PNG, TIFF)"
        )
    if image.dtype != np.uint8:
        raise InputError(
            path,
            f"{image.dtype.itemsize * 8}-bit values: expected an 8-bit photo (a 16-bit or "
            "float image is linear already and needs no response curve)",
        )
    if image.ndim == 2:
        return np.ascontiguousarray(np.repeat(image[:, :, None], 3, axis=2))
    if image.shape[2] == 4:
        image = image[:, :, :3]
    return np.ascontiguousarray(image)
