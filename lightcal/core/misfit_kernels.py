"""Compiled (numba) per-pixel passes of the checks after a solve (`lightcal.core.misfit`,
`lightcal.pipeline.fit_check`).

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
def order_statistics(values: np.ndarray, ranks: np.ndarray) -> np.ndarray:
    """The values at 0-based positions `ranks` (k,) of `values` (m,) sorted ascending
    (NaN-free), without sorting them: a histogram of 65536 equal bins between the
    smallest and largest value finds each rank's bin, and only those bins' values are
    gathered and sorted (values in a lower bin are never larger: the bin index is a
    monotone function of the value). Three passes over `values` where np.partition at a
    dozen ranks takes several.

    Returns:
        (k,) in the dtype of `values`.
    """
    m = values.shape[0]
    k = ranks.shape[0]
    out = np.empty(k, dtype=values.dtype)
    lo = values[0]
    hi = values[0]
    for i in range(m):
        v = values[i]
        lo = min(lo, v)
        hi = max(hi, v)
    if not hi > lo:
        out[:] = lo
        return out
    n_bins = 65536
    scale = n_bins / (float(hi) - float(lo))
    counts = np.zeros(n_bins, dtype=np.int64)
    for i in range(m):
        counts[min(int((float(values[i]) - float(lo)) * scale), n_bins - 1)] += 1
    start = np.zeros(n_bins + 1, dtype=np.int64)
    for b in range(n_bins):
        start[b + 1] = start[b] + counts[b]
    bin_of = np.empty(k, dtype=np.int64)
    offset = np.full(n_bins, -1, dtype=np.int64)
    gathered = 0
    for j in range(k):
        b = np.searchsorted(start, ranks[j], side="right") - 1
        bin_of[j] = b
        if offset[b] < 0:
            offset[b] = gathered
            gathered += counts[b]
    buffer = np.empty(gathered, dtype=values.dtype)
    fill = offset.copy()
    for i in range(m):
        b = min(int((float(values[i]) - float(lo)) * scale), n_bins - 1)
        if offset[b] >= 0:
            buffer[fill[b]] = values[i]
            fill[b] += 1
    for b in range(n_bins):
        if offset[b] >= 0:
            buffer[offset[b] : offset[b] + counts[b]].sort()
    for j in range(k):
        b = bin_of[j]
        out[j] = buffer[offset[b] + ranks[j] - start[b]]
    return out
