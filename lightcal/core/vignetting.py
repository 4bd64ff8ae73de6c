"""Sensor fall-off (vignetting): a radial polynomial model, its fit from flat fields,
and the validation of a measured per-pixel map.

Radial model (the `map` fall-off of docs/model.md, in its parametric form):

    V(u, v) = 1 + c1 r^2 + c2 r^4 + c3 r^6 (+ ...),
    r = |(u, v) - centre_px| / R,  R = hypot(width, height) / 2,

with pixel (u, v) = (column, row), centres at integers. R, the half diagonal of the
sensor, depends on the image size only (not on the fitted centre), so r = 1 at a
corner of the sensor when the centre is the image centre ((W - 1) / 2, (H - 1) / 2).
V = 1 at the centre by construction; a flat field is then `gain * V`.

A measured map is normalised so that its maximum is 1 (default) or its value at the
image centre is 1 (bilinear at ((W - 1) / 2, (H - 1) / 2)).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from lightcal.errors import InputError

_OUTLIER_SIGMAS = 5.0
"""Residuals beyond this many robust standard deviations are rejected between fits."""

_MAX_TRIM_ROUNDS = 4
"""At most this many (fit -> reject outliers) rounds."""


def _check_size(width: int, height: int) -> tuple[int, int]:
    """Return (width, height) as ints if both are positive ints, else raise InputError."""
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value <= 0:
            raise InputError(name, f"expected a positive int, got {value!r}")
    return int(width), int(height)


@dataclass(frozen=True, eq=False)
class RadialVignetting:
    """Radial polynomial fall-off `V = 1 + sum_k c_k r^(2k)`, r normalised by the half diagonal.

    Attributes:
        center_px: (2,) (u, v) centre of the fall-off, pixels (centres at integers).
        coeffs: (k,) c_1 ... c_k, the coefficients of r^2, r^4, ..., r^(2k).
        width: Image width the model describes, pixels.
        height: Image height, pixels.
    """

    center_px: NDArray[np.float64]
    coeffs: NDArray[np.float64]
    width: int
    height: int

    def __post_init__(self) -> None:
        width, height = _check_size(self.width, self.height)
        center = np.array(self.center_px, dtype=np.float64)
        if center.shape != (2,) or not np.all(np.isfinite(center)):
            raise InputError(
                "center_px", f"expected a finite (2,) (u, v) centre, got {center.tolist()}"
            )
        coeffs = np.array(self.coeffs, dtype=np.float64)
        if coeffs.ndim != 1 or coeffs.size == 0 or not np.all(np.isfinite(coeffs)):
            raise InputError(
                "coeffs", f"expected a finite (k,) vector with k >= 1, got {coeffs.tolist()}"
            )
        center.flags.writeable = False
        coeffs.flags.writeable = False
        object.__setattr__(self, "center_px", center)
        object.__setattr__(self, "coeffs", coeffs)
        object.__setattr__(self, "width", width)
        object.__setattr__(self, "height", height)

    @classmethod
    def centered(cls, coeffs: ArrayLike, *, width: int, height: int) -> RadialVignetting:
        """A model centred on the image centre ((W - 1) / 2, (H - 1) / 2)."""
        w, h = _check_size(width, height)
        return cls(
            center_px=np.array([(w - 1) / 2.0, (h - 1) / 2.0]),
            coeffs=np.asarray(coeffs, dtype=np.float64),
            width=w,
            height=h,
        )

    @property
    def norm_radius_px(self) -> float:
        """R = hypot(width, height) / 2, the radius where r = 1, pixels."""
        return 0.5 * math.hypot(self.width, self.height)

    def evaluate(self, pixels: ArrayLike) -> NDArray[np.float64]:
        """V at pixel positions.

        Args:
            pixels: (N, 2) (u, v) pixel coordinates.

        Returns:
            values: (N,) fall-off, 1 at the centre.
        """
        points = np.asarray(pixels, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 2:
            raise InputError("pixels", f"expected an (N, 2) array, got shape {points.shape}")
        rho = _rho(points[:, 0], points[:, 1], self.center_px, self.norm_radius_px)
        return _polynomial(rho, self.coeffs)

    def image(self, width: int | None = None, height: int | None = None) -> NDArray[np.float64]:
        """V on every pixel of the image.

        Args:
            width: Expected image width (e.g. the camera's); defaults to the model's.
            height: Expected image height; defaults to the model's.

        Returns:
            values: (height, width) fall-off.

        Raises:
            InputError: `width` x `height` differs from the model's image size.
        """
        w = self.width if width is None else width
        h = self.height if height is None else height
        if (w, h) != (self.width, self.height):
            raise InputError(
                "vignetting",
                f"expected a camera of {self.width} x {self.height} pixels (the model's "
                f"size), got {w} x {h}",
            )
        v, u = np.mgrid[0:h, 0:w].astype(np.float64)
        return _polynomial(_rho(u, v, self.center_px, self.norm_radius_px), self.coeffs)


def _rho(
    u: NDArray[np.float64], v: NDArray[np.float64], center: NDArray[np.float64], radius: float
) -> NDArray[np.float64]:
    """r^2 = |(u, v) - center|^2 / R^2, any shape."""
    return ((u - center[0]) ** 2 + (v - center[1]) ** 2) / (radius * radius)


def _polynomial(rho: NDArray[np.float64], coeffs: NDArray[np.float64]) -> NDArray[np.float64]:
    """1 + c1 rho + c2 rho^2 + ... by Horner's rule (rho = r^2)."""
    acc = np.zeros_like(rho)
    for c in coeffs[::-1]:
        acc = (acc + c) * rho
    return 1.0 + acc


# --------------------------------------------------------------------------- fit


@dataclass(frozen=True)
class _Samples:
    """Flat-field samples for the fit: K images, each with M_k samples (concatenated)."""

    u: NDArray[np.float64]  # (M,) sample column, pixels
    v: NDArray[np.float64]  # (M,) sample row, pixels
    value: NDArray[np.float64]  # (M,) observed value / the image's median
    weight: NDArray[np.float64]  # (M,) sqrt of the number of pixels averaged
    image: NDArray[np.intp]  # (M,) image index


def _block_samples(
    image: NDArray[np.float64], valid: NDArray[np.bool_], block: int
) -> tuple[NDArray[np.float64], ...]:
    """Average the valid pixels of `block` x `block` tiles; coordinates are the valid mean.

    Returns:
        u, v, value, count: (M,) each, over the tiles with at least one valid pixel.
    """
    h, w = image.shape
    if block == 1:
        rows_valid, cols_valid = np.nonzero(valid)
        return (
            cols_valid.astype(np.float64),
            rows_valid.astype(np.float64),
            image[valid],
            np.ones(rows_valid.size),
        )
    hp, wp = -(-h // block) * block, -(-w // block) * block
    pad_valid = np.zeros((hp, wp), dtype=bool)
    pad_valid[:h, :w] = valid
    pad_image = np.zeros((hp, wp))
    pad_image[:h, :w] = np.where(valid, image, 0.0)
    rows, cols = np.mgrid[0:hp, 0:wp].astype(np.float64)

    def tiles(a: NDArray[np.float64]) -> NDArray[np.float64]:
        return a.reshape(hp // block, block, wp // block, block).sum(axis=(1, 3)).ravel()

    weight = pad_valid.astype(np.float64)
    count = tiles(weight)
    keep = count > 0
    count = count[keep]
    value = tiles(pad_image)[keep] / count
    u = tiles(cols * weight)[keep] / count
    v = tiles(rows * weight)[keep] / count
    return u, v, value, count


def _collect_samples(
    images: Sequence[ArrayLike],
    valid_masks: Sequence[ArrayLike] | None,
    *,
    max_samples_per_image: int,
) -> tuple[_Samples, int, int]:
    """Validate the flat fields and turn them into fit samples."""
    if len(images) == 0:
        raise InputError("images", "expected at least one flat-field image, got none")
    if valid_masks is not None and len(valid_masks) != len(images):
        raise InputError(
            "valid_masks",
            f"expected one mask per image ({len(images)}), got {len(valid_masks)}",
        )
    arrays = [np.asarray(image, dtype=np.float64) for image in images]
    shape = arrays[0].shape
    if len(shape) != 2:
        raise InputError("images[0]", f"expected a 2-D (H, W) image, got shape {shape}")
    height, width = shape
    parts: list[tuple[NDArray[np.float64], ...]] = []
    for k, array in enumerate(arrays):
        if array.shape != shape:
            raise InputError(
                f"images[{k}]", f"expected the shape of images[0], {shape}, got {array.shape}"
            )
        if valid_masks is None:
            valid = np.ones(shape, dtype=bool)
        else:
            valid = np.asarray(valid_masks[k])
            if valid.shape != shape or valid.dtype != np.bool_:
                raise InputError(
                    f"valid_masks[{k}]",
                    f"expected a bool array of shape {shape}, got {valid.dtype} {valid.shape}",
                )
        bad = valid & ~np.isfinite(array)
        if np.any(bad):
            raise InputError(
                f"images[{k}]",
                f"expected finite values, got {int(np.count_nonzero(bad))} NaN or infinite "
                "pixels (exclude them with valid_masks)",
            )
        n_valid = int(np.count_nonzero(valid))
        if n_valid == 0:
            raise InputError(f"images[{k}]", "expected valid pixels, got none")
        level = float(np.median(array[valid]))
        if not level > 0.0:
            raise InputError(
                f"images[{k}]",
                f"expected a flat field with positive values, got median {level:g}",
            )
        block = max(1, math.ceil(math.sqrt(n_valid / max_samples_per_image)))
        u, v, value, count = _block_samples(array / level, valid, block)
        parts.append((u, v, value, np.sqrt(count), np.full(u.size, k, dtype=np.intp)))
    samples = _Samples(*(np.concatenate(columns) for columns in zip(*parts, strict=True)))
    return samples, width, height


@dataclass(frozen=True)
class _FlatFieldProblem:
    """Weighted residuals w (g_k V(u, v) - value) of the flat-field model and their Jacobian.

    Parameters `params` = (g_1 .. g_K, [cx, cy,] c_1 .. c_n): the centre is fitted when
    `center_px` is None, else fixed to it.
    """

    samples: _Samples
    n_images: int
    n_coeffs: int
    center_px: NDArray[np.float64] | None
    radius: float

    def _split(
        self, params: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """(gains (K,), centre (2,), coeffs (n,))."""
        k = self.n_images
        if self.center_px is None:
            return params[:k], params[k : k + 2], params[k + 2 :]
        return params[:k], self.center_px, params[k:]

    def residuals(self, params: NDArray[np.float64]) -> NDArray[np.float64]:
        """(M,) weighted residuals."""
        gains, center, coeffs = self._split(params)
        s = self.samples
        rho = _rho(s.u, s.v, center, self.radius)
        return s.weight * (gains[s.image] * _polynomial(rho, coeffs) - s.value)

    def relative_residuals(self, params: NDArray[np.float64]) -> NDArray[np.float64]:
        """(M,) value / g_k - V, unweighted: the error in units of V."""
        gains = params[: self.n_images]
        return self.residuals(params) / (self.samples.weight * gains[self.samples.image])

    def jacobian(self, params: NDArray[np.float64]) -> NDArray[np.float64]:
        """(M, P) derivatives of `residuals` with respect to `params`."""
        gains, center, coeffs = self._split(params)
        s = self.samples
        du = s.u - center[0]
        dv = s.v - center[1]
        rho = (du * du + dv * dv) / (self.radius * self.radius)
        weighted_gain = s.weight * gains[s.image]
        jacobian = np.zeros((params.size, s.u.size)).T  # column-major, as MINPACK wants
        falloff = s.weight * _polynomial(rho, coeffs)
        for k in range(self.n_images):
            jacobian[:, k] = np.where(s.image == k, falloff, 0.0)
        power = weighted_gain
        for j in range(self.n_coeffs):  # d/dc_j = w g rho^j
            power = power * rho
            jacobian[:, params.size - self.n_coeffs + j] = power
        if self.center_px is None:
            # dV/drho = sum_j j c_j rho^(j-1); drho/dcx = -2 du / R^2, likewise for cy.
            dfalloff = np.zeros_like(rho)
            for j in range(self.n_coeffs, 0, -1):
                dfalloff = dfalloff * rho + j * coeffs[j - 1]
            scale = weighted_gain * dfalloff * (-2.0 / (self.radius * self.radius))
            jacobian[:, self.n_images] = scale * du
            jacobian[:, self.n_images + 1] = scale * dv
        return jacobian


def fit_radial_vignetting(
    images: Sequence[ArrayLike],
    *,
    valid_masks: Sequence[ArrayLike] | None = None,
    fit_center: bool = True,
    n_coeffs: int = 3,
    max_samples_per_image: int = 100_000,
) -> tuple[RadialVignetting, float]:
    """Fit a radial fall-off to flat-field images, each with its own unknown gain.

    Model: image_k(u, v) = g_k V(u, v). Least squares (scipy, analytic Jacobian) over
    the gains g_k, the coefficients and, with `fit_center`, the centre (else the image
    centre). V = 1 at the centre by construction, so the gains carry the brightness.
    Robustness: after each fit, samples whose residual exceeds 5 robust standard
    deviations (1.4826 x median absolute residual) are dropped and the fit is redone,
    which removes a few saturated or hot pixels; mask larger defects with `valid_masks`.
    Large images are reduced to about `max_samples_per_image` samples by averaging
    the valid pixels of square tiles (a sample sits at its valid pixels' mean position).

    Args:
        images: K flat-field images (H, W), the same size, positive, black level removed.
        valid_masks: K (H, W) bool arrays, True where a pixel may be used; default all.
        fit_center: Fit the centre (u, v) too; else it is ((W - 1) / 2, (H - 1) / 2).
        n_coeffs: Number k of coefficients c_1 .. c_k (1 to 6).
        max_samples_per_image: Sample budget per image before tiles are averaged.

    Returns:
        model: The fitted fall-off, for images of W x H.
        rms: RMS of `image_k / g_k - V` over the samples kept, dimensionless.

    Raises:
        InputError: No images, shapes differ, a non-finite valid pixel, a non-positive
            flat field, too few samples, or a fit whose V is not positive on the image.
    """
    if isinstance(n_coeffs, bool) or not isinstance(n_coeffs, int) or not 1 <= n_coeffs <= 6:
        raise InputError("n_coeffs", f"expected an int from 1 to 6, got {n_coeffs!r}")
    if (
        isinstance(max_samples_per_image, bool)
        or not isinstance(max_samples_per_image, int)
        or max_samples_per_image < 100
    ):
        raise InputError(
            "max_samples_per_image", f"expected an int >= 100, got {max_samples_per_image!r}"
        )
    samples, width, height = _collect_samples(
        images, valid_masks, max_samples_per_image=max_samples_per_image
    )
    n_images = len(images)
    center0 = np.array([(width - 1) / 2.0, (height - 1) / 2.0])
    fixed_center = None if fit_center else center0
    n_params = n_images + (2 if fit_center else 0) + n_coeffs
    radius = 0.5 * math.hypot(width, height)

    params = np.concatenate(
        [np.ones(n_images), center0 if fit_center else np.empty(0), np.zeros(n_coeffs)]
    )
    full_problem = _FlatFieldProblem(
        samples=samples,
        n_images=n_images,
        n_coeffs=n_coeffs,
        center_px=fixed_center,
        radius=radius,
    )
    keep = np.ones(samples.u.size, dtype=bool)
    for round_index in range(_MAX_TRIM_ROUNDS):
        if np.count_nonzero(keep) < 2 * n_params:
            raise InputError(
                "images",
                f"expected at least {2 * n_params} usable samples for {n_params} parameters, "
                f"got {int(np.count_nonzero(keep))}",
            )
        subset = _Samples(
            u=samples.u[keep],
            v=samples.v[keep],
            value=samples.value[keep],
            weight=samples.weight[keep],
            image=samples.image[keep],
        )
        problem = _FlatFieldProblem(
            samples=subset,
            n_images=n_images,
            n_coeffs=n_coeffs,
            center_px=fixed_center,
            radius=radius,
        )
        result = least_squares(
            problem.residuals, params, jac=problem.jacobian, method="lm", x_scale="jac"
        )
        params = result.x
        relative = np.abs(full_problem.relative_residuals(params))
        sigma = 1.4826 * float(np.median(relative[keep]))
        new_keep = relative <= max(_OUTLIER_SIGMAS * sigma, 1e-12)
        if np.array_equal(new_keep, keep) or round_index == _MAX_TRIM_ROUNDS - 1:
            break  # params are the fit to `keep`
        keep = new_keep

    center = params[n_images : n_images + 2] if fit_center else center0
    model = RadialVignetting(
        center_px=center, coeffs=params[-n_coeffs:], width=width, height=height
    )
    rms = float(np.sqrt(np.mean(full_problem.relative_residuals(params)[keep] ** 2)))
    corners = np.array(
        [[-0.5, -0.5], [width - 0.5, -0.5], [-0.5, height - 0.5], [width - 0.5, height - 0.5]]
    )
    lowest = float(min(model.image().min(), model.evaluate(corners).min()))
    if not lowest > 0.0:
        raise InputError(
            "images",
            f"the fitted fall-off reaches {lowest:.3g}, expected V > 0 everywhere: "
            "check the flat fields (black level, saturation) or use fewer coefficients",
        )
    return model, rms


# --------------------------------------------------------------------------- map


def vignetting_from_map(
    values: ArrayLike,
    *,
    width: int,
    height: int,
    normalise: Literal["max", "center"] = "max",
    source: str = "vignetting map",
) -> NDArray[np.float64]:
    """Validate a measured per-pixel fall-off map and normalise it.

    Args:
        values: (H, W) the map, any positive scale (e.g. a smoothed flat field).
        width: The camera's image width W.
        height: The camera's image height H.
        normalise: "max" divides by the maximum; "center" by the bilinear value at
            the image centre ((W - 1) / 2, (H - 1) / 2).
        source: Names the map (a file path) in errors.

    Returns:
        map: (H, W) float64, positive, 1 at the maximum or at the centre.

    Raises:
        InputError: Not 2-D, a size different from the camera's (expected vs got),
            non-finite or non-positive values, an unknown `normalise`.
    """
    w, h = _check_size(width, height)
    array = np.array(values, dtype=np.float64)
    if array.ndim != 2:
        raise InputError(source, f"expected a 2-D (H, W) map, got shape {array.shape}")
    if array.shape != (h, w):
        raise InputError(
            source,
            f"expected a map of the camera's size {w} x {h} (W x H), "
            f"got {array.shape[1]} x {array.shape[0]}",
        )
    finite = np.isfinite(array)
    if not np.all(finite):
        raise InputError(
            source,
            f"expected finite values, got {int(np.count_nonzero(~finite))} NaN or infinite pixels",
        )
    if not np.all(array > 0.0):
        raise InputError(
            source,
            f"expected positive values, got {int(np.count_nonzero(array <= 0.0))} pixels <= 0 "
            f"(minimum {float(array.min()):g})",
        )
    if normalise == "max":
        reference = float(array.max())
    elif normalise == "center":
        reference = _bilinear_center(array)
    else:
        raise InputError("normalise", f"expected 'max' or 'center', got {normalise!r}")
    return array / reference


def _bilinear_center(array: NDArray[np.float64]) -> float:
    """Bilinear value at ((W - 1) / 2, (H - 1) / 2): the mean of the 1, 2 or 4 middle pixels."""
    h, w = array.shape
    rows = [(h - 1) // 2, h // 2]
    cols = [(w - 1) // 2, w // 2]
    return float(array[np.ix_(rows, cols)].mean())
