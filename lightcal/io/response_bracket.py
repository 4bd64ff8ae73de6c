"""The photos of an exposure bracket for `lightcal response`: read as 8-bit colour images
as OpenCV reads them (B, G, R: the order `ResponseCurve.linearize` expects of images read
by `lightcal.io.images`), and the curve fitted on them (`fit_bracket_curve`).

Where the curve is fitted matters. OpenCV's Debevec takes its pixel locations on a regular
grid; a photo of a wall lit by a narrow beam is mostly one grey, so nearly every location
shows the same codes and the curve between them is left to the smoothness term: 20 %
wrong at codes 20-160 on `lightcal synth --real-world`'s bracket (300 locations).
`fit_bracket_curve` takes SAMPLE_SIDE^2 locations spread evenly over the codes of the
bracket's middle photo (`_CODE_BINS` bins, the same number of random locations from each
bin that has them, seeded), which OpenCV then uses all (packed into a square image): within
1 % at codes 30-250 on that bracket.
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np

from lightcal.errors import InputError
from lightcal.io.response import ResponseCurve, fit_response_debevec
from lightcal.io.text_files import check_regular_file

SAMPLE_SIDE = 30
"""`fit_bracket_curve` fits on SAMPLE_SIDE^2 pixel locations."""
SMOOTHNESS = 100.0
"""Debevec's lambda for that many locations (the data rows grow with them)."""
_CODE_BINS = 64


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


def grey_bracket_curve(curve: ResponseCurve, images: list[np.ndarray]) -> ResponseCurve:
    """The curve to save for a bracket: one channel when every photo is grey.

    A grey photo (one channel, or three equal ones) gives three equal columns, and a
    three-channel curve refuses the grey photos it was fitted on (`ResponseCurve.linearize`);
    a one-channel curve linearises grey and colour photos alike.

    Args:
        curve: The fitted (256, 3) curve.
        images: The bracket as `read_bracket_image` read it, (H, W, 3) each.
    """
    grey = all(
        np.array_equal(image[..., 0], image[..., 1])
        and np.array_equal(image[..., 0], image[..., 2])
        for image in images
    )
    if not grey or curve.n_channels == 1:
        return curve
    return ResponseCurve(curve.values.mean(axis=1, keepdims=True))


def fit_bracket_curve(images: list[np.ndarray], exposure_times_s: list[float]) -> ResponseCurve:
    """The response curve of a bracket, on locations spread over its codes (module doc).

    Args:
        images: P >= 2 photos (H, W, 3) uint8 as `read_bracket_image` reads them, same size.
        exposure_times_s: (P,) their exposure times, seconds.

    Returns:
        The curve: one channel when every photo is grey (`grey_bracket_curve`), else three.
    """
    order = np.argsort(exposure_times_s, kind="stable")
    middle = images[int(order[len(order) // 2])].mean(axis=2).ravel()
    bins = np.minimum((middle * (_CODE_BINS / 256.0)).astype(np.int64), _CODE_BINS - 1)
    n = SAMPLE_SIDE * SAMPLE_SIDE
    rng = np.random.default_rng(0)
    present = np.unique(bins)
    per_bin = -(-n // present.size)
    chosen = np.concatenate(
        [
            rng.choice(where, min(per_bin, where.size), replace=False)
            for where in (np.flatnonzero(bins == b) for b in present)
        ]
    )
    if chosen.size < n:  # few codes: fill up with other locations
        others = np.setdiff1d(np.arange(middle.size), chosen)
        extra = rng.choice(others, min(n - chosen.size, others.size), replace=False)
        chosen = np.concatenate([chosen, extra])
    chosen = rng.permutation(chosen)[:n]
    side = math.isqrt(chosen.size)
    chosen = chosen[: side * side]
    packed = [
        np.ascontiguousarray(image.reshape(-1, 3)[chosen].reshape(side, side, 3))
        for image in images
    ]
    curve = fit_response_debevec(
        packed, exposure_times_s, samples=side * side, smoothness=SMOOTHNESS
    )
    return grey_bracket_curve(curve, images)
