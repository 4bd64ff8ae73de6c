"""OpenCV lens distortion on normalised image coordinates (numba kernels).

The model is OpenCV's rational model with tangential terms, exactly as
`cv2.projectPoints` applies it (thin-prism and tilt terms are not supported):

    r2 = x^2 + y^2
    c  = (1 + k1 r2 + k2 r2^2 + k3 r2^3) / (1 + k4 r2 + k5 r2^2 + k6 r2^3)
    xd = x c + 2 p1 x y + p2 (r2 + 2 x^2)
    yd = y c + p1 (r2 + 2 y^2) + 2 p2 x y

`dist` is always a float64 array of length 8, `(k1, k2, p1, p2, k3, k4, k5, k6)`,
zero padded (see `pad_distortion`). With zero padding the 4- and 5-coefficient
OpenCV models are special cases of the 8-coefficient one.

The scalar kernels `distort_normalized` and `undistort_normalized` are
`numba.njit` functions that other njit kernels may call directly.

Valid region: the distortion map is only invertible where it does not fold over.
`undistort_normalized` reports `ok=False` when its Newton iteration does not
converge, or when the solution lies where the map's Jacobian determinant is
<= 0 or the radial factor `c` is <= 0 (points mirrored through the optical axis),
i.e. outside the region where the model describes a real lens.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

N_DIST = 8
"""Length of the zero-padded distortion vector `(k1, k2, p1, p2, k3, k4, k5, k6)`."""

ACCEPTED_DIST_LENGTHS = (0, 4, 5, 8)
"""Numbers of OpenCV distortion coefficients that `pad_distortion` accepts."""

_MAX_ITERATIONS = 60
_STEP_TOL = 1e-15
_RESIDUAL_TOL = 1e-15
_ACCEPT_TOL = 1e-12


def pad_distortion(coeffs: ArrayLike) -> NDArray[np.float64]:
    """Zero-pad OpenCV distortion coefficients to the 8-vector used by the kernels.

    Args:
        coeffs: (n,) with n in (0, 4, 5, 8): `(k1, k2, p1, p2[, k3[, k4, k5, k6]])`.
            Any array with n elements and at most one non-unit axis is accepted
            (OpenCV stores them as 1 x n or n x 1 matrices).

    Returns:
        dist: (8,) float64 `(k1, k2, p1, p2, k3, k4, k5, k6)`, a new array.

    Raises:
        ValueError: The number of coefficients is not 0, 4, 5 or 8.
    """
    flat = np.asarray(coeffs, dtype=np.float64).reshape(-1)
    n = flat.size
    if n not in ACCEPTED_DIST_LENGTHS:
        raise ValueError(f"distortion coefficients: expected 0, 4, 5 or 8 values, got {n}")
    dist = np.zeros(N_DIST, dtype=np.float64)
    dist[:n] = flat
    return dist


@numba.njit(cache=True)
def _radial_factor(r2: float, dist: NDArray[np.float64]) -> tuple[float, float]:
    """Radial factor c(r2) and its derivative dc/dr2."""
    k1, k2, k3 = dist[0], dist[1], dist[4]
    k4, k5, k6 = dist[5], dist[6], dist[7]
    num = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    den = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
    dnum = k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3)
    dden = k4 + r2 * (2.0 * k5 + 3.0 * r2 * k6)
    c = num / den
    dc = (dnum * den - num * dden) / (den * den)
    return c, dc


@numba.njit(cache=True)
def distort_normalized(x: float, y: float, dist: NDArray[np.float64]) -> tuple[float, float]:
    """Apply OpenCV distortion to one normalised point.

    Args:
        x: Undistorted normalised coordinate x/z.
        y: Undistorted normalised coordinate y/z.
        dist: (8,) `(k1, k2, p1, p2, k3, k4, k5, k6)`.

    Returns:
        (xd, yd): the distorted normalised coordinates, as `cv2.projectPoints`
        computes them before applying K.
    """
    p1, p2 = dist[2], dist[3]
    x2 = x * x
    y2 = y * y
    xy = x * y
    r2 = x2 + y2
    k1, k2, k3 = dist[0], dist[1], dist[4]
    k4, k5, k6 = dist[5], dist[6], dist[7]
    num = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    den = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
    c = num / den
    xd = x * c + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x2)
    yd = y * c + p1 * (r2 + 2.0 * y2) + 2.0 * p2 * xy
    return xd, yd


@numba.njit(cache=True)
def distortion_jacobian(
    x: float, y: float, dist: NDArray[np.float64]
) -> tuple[float, float, float, float]:
    """Analytic Jacobian of `distort_normalized` at one point.

    Args:
        x: Undistorted normalised coordinate x/z.
        y: Undistorted normalised coordinate y/z.
        dist: (8,) `(k1, k2, p1, p2, k3, k4, k5, k6)`.

    Returns:
        (dxd_dx, dxd_dy, dyd_dx, dyd_dy).
    """
    p1, p2 = dist[2], dist[3]
    r2 = x * x + y * y
    c, dc = _radial_factor(r2, dist)
    dxd_dx = c + 2.0 * x * x * dc + 2.0 * p1 * y + 6.0 * p2 * x
    dxd_dy = 2.0 * x * y * dc + 2.0 * p1 * x + 2.0 * p2 * y
    dyd_dx = 2.0 * x * y * dc + 2.0 * p1 * x + 2.0 * p2 * y
    dyd_dy = c + 2.0 * y * y * dc + 6.0 * p1 * y + 2.0 * p2 * x
    return dxd_dx, dxd_dy, dyd_dx, dyd_dy


@numba.njit(cache=True)
def undistort_normalized(
    xd: float, yd: float, dist: NDArray[np.float64]
) -> tuple[float, float, bool]:
    """Invert `distort_normalized` for one point by damped Newton iteration.

    Newton's method with the analytic 2x2 Jacobian, started at `(xd, yd)`; a step
    that does not reduce the residual is halved (up to 30 times). It stops when
    a full step is below 1e-15 relative to `1 + |x| + |y|` (or the residual is
    below 1e-15 relative to `1 + |xd| + |yd|`, or no step reduces it any more);
    the answer is accepted only if it reproduces `(xd, yd)` to 1e-12 relative.

    Args:
        xd: Distorted normalised coordinate.
        yd: Distorted normalised coordinate.
        dist: (8,) `(k1, k2, p1, p2, k3, k4, k5, k6)`.

    Returns:
        (x, y, ok): the undistorted normalised point and whether it is valid.
        `ok` is False (and x, y are NaN) for a non-finite input, when the
        iteration does not converge, or when the solution lies outside the
        model's valid region (Jacobian determinant <= 0 or radial factor <= 0
        there, where the distortion map folds over).
    """
    nan = np.nan
    if not (np.isfinite(xd) and np.isfinite(yd)):
        return nan, nan, False
    x = xd
    y = yd
    fx, fy = distort_normalized(x, y, dist)
    ex = fx - xd
    ey = fy - yd
    err = ex * ex + ey * ey
    scale = 1.0 + abs(xd) + abs(yd)
    converged = err <= (_RESIDUAL_TOL * scale) ** 2
    it = 0
    while not converged and it < _MAX_ITERATIONS:
        it += 1
        a, b, c, d = distortion_jacobian(x, y, dist)
        det = a * d - b * c
        if det == 0.0 or not np.isfinite(det):
            break
        sx = (d * ex - b * ey) / det
        sy = (a * ey - c * ex) / det
        step = 1.0
        accepted = False
        for _ in range(30):
            xn = x - step * sx
            yn = y - step * sy
            gx, gy = distort_normalized(xn, yn, dist)
            enx = gx - xd
            eny = gy - yd
            errn = enx * enx + eny * eny
            if errn < err or errn == 0.0:
                accepted = True
                break
            step *= 0.5
        if not accepted:
            # No decrease along the Newton direction: either converged to
            # round-off or stuck; the residual test below decides.
            break
        x = xn
        y = yn
        ex = enx
        ey = eny
        err = errn
        if step == 1.0 and abs(sx) + abs(sy) <= _STEP_TOL * (1.0 + abs(x) + abs(y)):
            converged = True
    # Whatever stopped the loop, the answer must reproduce the input.
    converged = err <= (_ACCEPT_TOL * scale) ** 2
    if not converged or not (np.isfinite(x) and np.isfinite(y)):
        return nan, nan, False
    a, b, c, d = distortion_jacobian(x, y, dist)
    radial, _ = _radial_factor(x * x + y * y, dist)
    if a * d - b * c <= 0.0 or radial <= 0.0:
        return nan, nan, False
    return x, y, True


@numba.njit(cache=True)
def distort_points(xy: NDArray[np.float64], dist: NDArray[np.float64]) -> NDArray[np.float64]:
    """Apply distortion to many normalised points.

    Args:
        xy: (N, 2) undistorted normalised coordinates.
        dist: (8,) `(k1, k2, p1, p2, k3, k4, k5, k6)`.

    Returns:
        xy_distorted: (N, 2).
    """
    n = xy.shape[0]
    out = np.empty((n, 2), dtype=np.float64)
    for i in range(n):
        out[i, 0], out[i, 1] = distort_normalized(xy[i, 0], xy[i, 1], dist)
    return out


@numba.njit(cache=True)
def undistort_points(
    xy_distorted: NDArray[np.float64], dist: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Invert distortion for many normalised points (see `undistort_normalized`).

    Args:
        xy_distorted: (N, 2) distorted normalised coordinates.
        dist: (8,) `(k1, k2, p1, p2, k3, k4, k5, k6)`.

    Returns:
        xy: (N, 2) undistorted normalised coordinates, NaN where not ok.
        ok: (N,) bool, False where the inversion failed or left the valid region.
    """
    n = xy_distorted.shape[0]
    out = np.empty((n, 2), dtype=np.float64)
    ok = np.empty(n, dtype=np.bool_)
    for i in range(n):
        x, y, good = undistort_normalized(xy_distorted[i, 0], xy_distorted[i, 1], dist)
        out[i, 0] = x
        out[i, 1] = y
        ok[i] = good
    return out, ok
