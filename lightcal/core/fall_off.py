"""The camera's fall-off estimated with the light: a radial polynomial whose coefficients
are free parameters of the solve (docs/model.md, "The fall-off estimated from the
photos").

    V(u, v) = 1 + c_1 r^2 + ... + c_K r^(2K),
    r = |(u, v) - ((W - 1) / 2, (H - 1) / 2)| / R,  R = hypot(W, H) / 2,

(u, v) the full-resolution pixel (a super-pixel of binning b at its centre:
b u_b + (b - 1) / 2), W x H the camera's full image: `RadialVignetting.centered`'s
convention (r = 1 at the sensor's corners), and that of `lightcal synth
--undeclared-vignetting`. V multiplies each pixel's rendered value above the offset,
whatever the sensor model (on top of `cos4` or a measured `map` it is what they leave).
It is applied outside the compiled renderer: m = b + V g sum_lights s Phi, so every
column of d m / d x the renderer gives is multiplied by V, and d m / d c_k =
g sum_lights s Phi r^(2k) (exact).

V is 1 at the image centre by construction: the lights' scales keep the overall level.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from lightcal.core.scene import View

FALL_OFF_MAX_ORDER = 3
"""At most c_1 r^2 ... c_3 r^6 (`RadialVignetting`'s flat-field fit takes as many)."""

FALL_OFF_BOUND = 3.0
"""Each coefficient is boxed to [-3, 3]: wide enough for a wide-angle lens's cos^4
(c_1 = -1.4, c_2 = 1.5 at 40 degrees half-diagonal), narrow enough that trf cannot
wander into a fall-off that changes sign across the image."""

FALL_OFF_MIN_VALUE = 0.02
"""A fall-off estimated below this (or above 1 / this) anywhere on the image is not a
lens's: the data do not determine it (`FallOffUnknown.implausible`)."""


@dataclass(frozen=True, eq=False)
class FallOffUnknown:
    """A radial fall-off to estimate jointly with the lights.

    Args:
        order: K, the number of coefficients (1 to `FALL_OFF_MAX_ORDER`).
        width: the camera's full-resolution image width, pixels.
        height: its height, pixels.
        binning: the side b of the super-pixels the selection works in (pixel indices
            of the footprints are in that binned grid).
    """

    order: int
    width: int
    height: int
    binning: int = 1

    def __post_init__(self) -> None:
        for name, value, low in (
            ("order", self.order, 1),
            ("width", self.width, 1),
            ("height", self.height, 1),
            ("binning", self.binning, 1),
        ):
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
                raise ValueError(f"fall-off: {name}: expected an integer >= {low}, got {value!r}")
        if self.order > FALL_OFF_MAX_ORDER:
            raise ValueError(
                f"fall-off: order: expected at most {FALL_OFF_MAX_ORDER}, got {self.order}"
            )

    @property
    def names(self) -> list[str]:
        """The parameters' names: fall_off.c1 ... fall_off.cK."""
        return [f"fall_off.c{k + 1}" for k in range(self.order)]

    @property
    def norm_radius_px(self) -> float:
        """R = hypot(W, H) / 2, full-resolution pixels."""
        return 0.5 * math.hypot(self.width, self.height)

    def r2(self, pixels: np.ndarray) -> np.ndarray:
        """(N,) r^2 of (binned) pixel indices `pixels` (N, 2) (u, v)."""
        b = self.binning
        p = np.asarray(pixels, dtype=np.float64) * b + 0.5 * (b - 1)
        du = p[:, 0] - 0.5 * (self.width - 1)
        dv = p[:, 1] - 0.5 * (self.height - 1)
        return (du * du + dv * dv) / self.norm_radius_px**2

    def powers(self, pixels: np.ndarray) -> np.ndarray:
        """(N, K) r^2, r^4, ..., r^(2K) of `pixels` (N, 2): d V / d c."""
        r2 = self.r2(pixels)
        return np.cumprod(np.repeat(r2[:, None], self.order, axis=1), axis=1)

    def factor(self, pixels: np.ndarray, coeffs: np.ndarray) -> np.ndarray:
        """(N,) V of `pixels` (N, 2) with coefficients `coeffs` (K,)."""
        return 1.0 + self.powers(pixels) @ np.asarray(coeffs, dtype=np.float64)

    def image(self, coeffs: np.ndarray) -> np.ndarray:
        """(H, W) V of every full-resolution pixel with coefficients `coeffs` (K,)."""
        v, u = np.mgrid[0 : self.height, 0 : self.width]
        pixels = np.stack([u.ravel(), v.ravel()], axis=1)
        full = FallOffUnknown(self.order, self.width, self.height)
        return full.factor(pixels, coeffs).reshape(self.height, self.width)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Box bounds (K,) of the coefficients."""
        return np.full(self.order, -FALL_OFF_BOUND), np.full(self.order, FALL_OFF_BOUND)

    def extremes(self, coeffs: np.ndarray) -> tuple[float, float]:
        """The smallest and largest V over the image (r from 0 to 1), on 201 radii."""
        r2 = np.linspace(0.0, 1.0, 201)
        v = 1.0 + np.cumprod(np.repeat(r2[:, None], self.order, axis=1), axis=1) @ coeffs
        return float(v.min()), float(v.max())

    def implausible(self, coeffs: np.ndarray) -> str | None:
        """Why the coefficients (K,) are not a lens's fall-off (None: they may be): V
        near or below 0 somewhere on the image, or a coefficient on its bound."""
        low, high = self.extremes(coeffs)
        if not (low >= FALL_OFF_MIN_VALUE and high <= 1.0 / FALL_OFF_MIN_VALUE):
            return f"the fall-off reaches {low:.3g} to {high:.3g} over the image"
        if np.any(np.abs(coeffs) >= FALL_OFF_BOUND * (1.0 - 1e-6)):
            return f"a fall-off coefficient reached its bound (+-{FALL_OFF_BOUND:g})"
        return None


def apply_fall_off(
    A: np.ndarray,
    total: np.ndarray,
    n_columns: int,
    powers: np.ndarray,
    coeffs: np.ndarray,
    columns: slice,
    gain: float,
) -> np.ndarray:
    """Multiply one image's rendered values and their derivatives by V; write d m / d c.

    Args:
        A: (N, n + 1) the image's system, columns 0..n-1 holding the renderer's
            d m / d x (before the gain and offset columns are written); changed in place.
        total: (N,) sum over lights of scale * flux; multiplied by V in place.
        n_columns: n, the parameter count.
        powers: (N, K) r^2 ... r^(2K) of the image's pixels (`FallOffUnknown.powers`).
        coeffs: (K,) the coefficients.
        columns: the coefficients' columns in A.
        gain: the image's gain g.

    Returns:
        (N,) V.
    """
    v = 1.0 + powers @ coeffs
    A[:, columns] = 0.0
    A[:, :n_columns] *= v[:, None]
    A[:, columns] = (gain * total)[:, None] * powers
    total *= v
    return v


class _Imaged(Protocol):
    """An image with its view (`lightcal.core.problem.ImageData`)."""

    @property
    def view(self) -> View: ...


class _SensorOptions(Protocol):
    """What `ambient_estimated` reads of the solver's options."""

    @property
    def estimate_ambient(self) -> bool: ...

    @property
    def estimate_offset(self) -> bool: ...


def ambient_estimated(images: Sequence[_Imaged], options: _SensorOptions) -> bool:
    """Whether the room light (g_i e_i a) is a parameter: when the options ask for it,
    unless an estimated offset b is the same column, every image having the same
    exposure e_i (to 1e-9 relative): both then add one constant to every pixel (free
    gains g_i start at 1 and barely tell them apart), and the offset is the room light."""
    if not options.estimate_ambient:
        return False
    if not options.estimate_offset:
        return True
    exposures = np.array([float(im.view.exposure) for im in images])
    return bool(np.ptp(exposures) > 1e-9 * np.abs(exposures).max())
