"""Compiled (numba) per-pixel passes of the checks after a solve (`lightcal.core.misfit`,
`lightcal.pipeline.fit_check`) and of the noise estimate from an image
(`misfit.image_noise`: `noise_samples`, `binned_noise`).

A dense solve hands the checks millions of pixels per image; in NumPy each figure they
need (residuals in noise units, relative residuals, the noise weights' J^T W J, the
mirror and incidence angles) took several passes and (N,) temporaries, about a second
for 9.5 M pixels. Here each is one parallel pass over the rows, with the same arithmetic
as the NumPy formulation (`noise_residuals` bit for bit; the weighted Gram sum in another
order of additions; the angles by atan2 instead of arccos).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from lightcal.core.kernels.fastmath import atan2_nonneg

_CHUNKS = 64
_DEGREES = 180.0 / math.pi  # NumPy's np.degrees: x * (180 / pi)


@numba.njit(cache=True, parallel=True)
def noise_residuals(
    residual: np.ndarray,
    sigma: np.ndarray,
    observed: np.ndarray,
    offset: float,
    noise: np.ndarray,
    r_noise: np.ndarray,
    relative: np.ndarray,
    ratio: np.ndarray,
) -> None:
    """Per pixel, from the solver's weighted residual r = (m_obs - m_render) / sigma:

    - d = r sigma, the residual in value units, and m_render = m_obs - d;
    - sigma_n = sqrt(gain max(m_render - offset, 0) + read_variance) (the Poisson-Gaussian
      noise at the rendered value, `problem.poisson_gaussian_sigma`) when `noise` is
      (gain, read_variance), else sigma (`noise` empty);
    - r_noise = d / sigma_n, ratio = sigma / sigma_n;
    - relative = d / (m_render - offset) where m_render > offset, else 0.

    Args:
        residual, sigma, observed: (N,) float64.
        noise: (2,) or (0,) float64.
        r_noise, ratio: (N,) float64 out; relative: (N,) float32 out.
    """
    n = residual.shape[0]
    has_noise = noise.shape[0] == 2
    gain = noise[0] if has_noise else 0.0
    read_variance = noise[1] if has_noise else 0.0
    for ch in numba.prange(_CHUNKS):
        for i in range(ch * n // _CHUNKS, (ch + 1) * n // _CHUNKS):
            s = sigma[i]
            d = residual[i] * s
            above = (observed[i] - d) - offset
            signal = 0.0 if above < 0.0 else above  # np.maximum(above, 0): NaN stays NaN
            s_n = math.sqrt(gain * signal + read_variance) if has_noise else s
            r_noise[i] = d / s_n
            ratio[i] = s / s_n
            relative[i] = d / above if above > 0 else 0.0


@numba.njit(cache=True, parallel=True)
def add_weighted_gram(A: np.ndarray, n: int, ratio: np.ndarray, out: np.ndarray) -> None:
    """out (n, n) += sum_i J_i^T J_i / ratio_i^2 over the rows J_i = A[i, :n] of A (N, >= n),
    A in Fortran order.

    The noise's sandwich term when the solver's weights are not the noise weights
    (`fit_check.pixel_evidence`): partial sums per block of rows, added in block order.
    """
    rows = A.shape[0]
    partial = np.zeros((_CHUNKS, n, n))
    for ch in numba.prange(_CHUNKS):
        i0, i1 = ch * rows // _CHUNKS, (ch + 1) * rows // _CHUNKS
        w = np.empty(i1 - i0)
        for i in range(i0, i1):
            w[i - i0] = 1.0 / (ratio[i] * ratio[i])
        for a in range(n):
            for b in range(a + 1):
                partial[ch, a, b] = _weighted_dot(w, A[i0:i1, a], A[i0:i1, b])
    for ch in range(_CHUNKS):
        for a in range(n):
            for b in range(a + 1):
                out[a, b] += partial[ch, a, b]
                if b != a:
                    out[b, a] += partial[ch, a, b]


@numba.njit(cache=True, fastmath={"reassoc", "contract"})
def _weighted_dot(w: np.ndarray, x: np.ndarray, y: np.ndarray) -> float:
    """sum_i w_i x_i y_i (k,), its additions reordered so that the loop vectorises."""
    s = 0.0
    for i in range(w.shape[0]):
        s += w[i] * x[i] * y[i]
    return s


@numba.njit(cache=True, parallel=True, error_model="numpy")
def mirror_incidence(
    points_world: np.ndarray,
    lights_world: np.ndarray,
    lit: np.ndarray,
    camera_world: np.ndarray,
    mirror_deg: np.ndarray,
    incidence_deg: np.ndarray,
) -> None:
    """Mirror and incidence angles (degrees) at wall points, each for the light that gives
    the point the most of its value (`misfit.pixel_angles`, to 1e-12 degrees).

    mirror: the angle between the wall normal +z and the half vector h = l / |l| + v / |v|
    of the directions l to the light and v to the camera; incidence: between the normal
    and l. As atan2(|(h_x, h_y)|, h_z) and atan2(|(l_x, l_y)|, l_z) (`atan2_nonneg`, no
    libm call: the loop vectorises; no arccos, which loses half the digits near 0
    degrees). NaN points give NaN angles.

    Args:
        points_world: (N, 3) wall points, m.
        lights_world: (L, 3) light positions, m.
        lit: (L, N) each light's share of each point's value (the first largest wins, as
            np.argmax picks it).
        camera_world: (3,) camera centre, m.
        mirror_deg, incidence_deg: (N,) out (float32 or float64).
    """
    n = points_world.shape[0]
    n_lights = lights_world.shape[0]
    for ch in numba.prange(_CHUNKS):
        i0, i1 = ch * n // _CHUNKS, (ch + 1) * n // _CHUNKS
        # Gathered into columns first: the arithmetic on (N, 3) rows does not vectorise.
        to_light = np.empty((3, i1 - i0))
        to_camera = np.empty((3, i1 - i0))
        for i in range(i0, i1):
            j = 0
            for k in range(1, n_lights):
                if lit[k, i] > lit[j, i]:
                    j = k
            for c in range(3):
                to_light[c, i - i0] = lights_world[j, c] - points_world[i, c]
                to_camera[c, i - i0] = camera_world[c] - points_world[i, c]
        _angles_of(to_light, to_camera, mirror_deg[i0:i1], incidence_deg[i0:i1])


@numba.njit(cache=True, inline="always", error_model="numpy")
def _angles_of(
    to_light: np.ndarray, to_camera: np.ndarray, mirror_deg: np.ndarray, incidence_deg: np.ndarray
) -> None:
    """`mirror_incidence` for the directions (3, k) from k points to a light and the camera."""
    for i in range(to_light.shape[1]):
        lx, ly, lz = to_light[0, i], to_light[1, i], to_light[2, i]
        vx, vy, vz = to_camera[0, i], to_camera[1, i], to_camera[2, i]
        ln = math.sqrt(lx * lx + ly * ly + lz * lz)
        vn = math.sqrt(vx * vx + vy * vy + vz * vz)
        hx = lx / ln + vx / vn
        hy = ly / ln + vy / vn
        hz = lz / ln + vz / vn
        mirror = atan2_nonneg(math.sqrt(hx * hx + hy * hy), hz) * _DEGREES
        incidence = atan2_nonneg(math.sqrt(lx * lx + ly * ly), lz) * _DEGREES
        ok = lz == lz  # NaN points (pixels off the wall)
        mirror_deg[i] = mirror if ok else math.nan
        incidence_deg[i] = incidence if ok else math.nan


@numba.njit(cache=True)
def quantile_bin(edges: np.ndarray, x: float) -> int:
    """The quantile bin of `x` among the k = len(edges) - 1 bins (NumPy's
    clip(searchsorted(edges, x, side="right") - 1, 0, k - 1), NaN in the last)."""
    b = int(np.searchsorted(edges, x, side="right")) - 1
    return min(max(b, 0), edges.size - 2)


@numba.njit(cache=True, error_model="numpy")
def noise_samples(
    values: np.ndarray, usable: np.ndarray, rows: np.ndarray, offset: float
) -> tuple[np.ndarray, np.ndarray]:
    """The level and the Laplacian residual of every usable interior pixel of `rows`, for
    `misfit.image_noise`, in one pass (the NumPy formulation took a dozen full-size
    temporaries): with v = values - offset and the 3 x 3 neighbourhood of the pixel all
    usable, residual = v - (up + down + left + right) / 4 and level = the mean of the four
    diagonal neighbours, summed in the NumPy formulation's order (so equal to it bit for
    bit). Pixels with a non-finite residual or level are skipped.

    Args:
        values: (H, W) float64 linear values.
        usable: (H, W) bool.
        rows: (R,) int64 row indices in [1, H - 2].
        offset: subtracted from every value read.

    Returns:
        (level, residual), each (N,) float64, N <= R (W - 2), in row-major pixel order.
    """
    w = values.shape[1]
    level = np.empty(rows.size * max(w - 2, 0))
    residual = np.empty_like(level)
    k = 0
    for r in rows:
        for c in range(1, w - 1):
            ok = True
            for dy in range(-1, 2):
                for dx in range(-1, 2):
                    ok = ok and usable[r + dy, c + dx]
            if not ok:
                continue
            here = values[r, c] - offset
            up = values[r - 1, c] - offset
            down = values[r + 1, c] - offset
            left = values[r, c - 1] - offset
            right = values[r, c + 1] - offset
            n = here - 0.25 * (((up + down) + left) + right)
            d = 0.25 * (
                (
                    ((values[r - 1, c - 1] - offset) + (values[r + 1, c + 1] - offset))
                    + (values[r - 1, c + 1] - offset)
                )
                + (values[r + 1, c - 1] - offset)
            )
            if math.isfinite(n) and math.isfinite(d):
                level[k] = d
                residual[k] = n
                k += 1
    return level[:k], residual[:k]


@numba.njit(cache=True, parallel=True, error_model="numpy")
def binned_noise(
    level: np.ndarray, residual: np.ndarray, edges: np.ndarray, min_count: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per quantile bin of `level` (`quantile_bin`): its pixel count, the median level and
    the median absolute deviation of the residuals from their median (np.median's values:
    the middle order statistic, or the mean of the two). Bins of fewer than `min_count`
    pixels get NaN medians.

    Args:
        level, residual: (N,) float64 (`noise_samples`).
        edges: (k + 1,) ascending bin edges.

    Returns:
        (count (k,) int64, median level (k,), MAD (k,)).
    """
    k = edges.size - 1
    m = level.size
    count = np.zeros(k, dtype=np.int64)
    bins = np.empty(m, dtype=np.int64)
    for i in range(m):
        b = quantile_bin(edges, level[i])
        bins[i] = b
        count[b] += 1
    start = np.zeros(k + 1, dtype=np.int64)
    for b in range(k):
        start[b + 1] = start[b] + count[b]
    fill = start[:k].copy()
    by_bin_level = np.empty(m)
    by_bin_residual = np.empty(m)
    for i in range(m):
        b = bins[i]
        by_bin_level[fill[b]] = level[i]
        by_bin_residual[fill[b]] = residual[i]
        fill[b] += 1
    median_level = np.full(k, np.nan)
    mad = np.full(k, np.nan)
    for b in numba.prange(k):  # the medians, bin by bin on the thread pool
        if count[b] < min_count:
            continue
        median_level[b] = np.median(by_bin_level[start[b] : start[b + 1]])
        res = by_bin_residual[start[b] : start[b + 1]]
        centre = np.median(res)
        mad[b] = np.median(np.abs(res - centre))
    return count, median_level, mad
