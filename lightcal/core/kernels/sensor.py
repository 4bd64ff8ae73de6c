"""The sensor side of the renderer: pixel corners on the wall and the sensor weights.

One implementation for the three kernels that need them (`kernels.image`, the fused
full image; `footprint_kernels`, footprints of any pixels; the plain reference kernels
of the tests). From docs/model.md: a pixel corner's ray meets the wall z = 0, and a
pixel's value is offset + gain * sum_lights scale * sum_k weight_k Phi_k, with the sensor
weight of its quads k

- ``radiance`` (`SENSOR_RADIANCE`): 1 / A, A the footprint's area (`quad_area`);
- ``cos4`` (`SENSOR_COS4`): cos^4(alpha) / A (`cos4`), alpha the angle between the
  optical axis and the ray through the mean of the pixel's undistorted corners;
- ``map`` (`SENSOR_MAP`): V(u, v) / A, V a per-pixel fall-off map;
- ``paper`` (`SENSOR_PAPER`): cos(theta_v) / d^2 per quad (`paper_weight`), d the
  distance from the quad's centroid to the camera centre, theta_v the viewing angle.

The arithmetic is the NumPy formulation's that `tests/test_footprint_kernels.py` keeps
as the footprints' reference, operation for operation (the rounding of its matrix
product included, see `wall_point`), so that the footprints match it bit for bit.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from lightcal.core.kernels.fastmath import fma

SENSOR_RADIANCE = 0
SENSOR_COS4 = 1
SENSOR_PAPER = 2
SENSOR_MAP = 3


@numba.njit(cache=True, inline="always")
def view_scalars(R_camera_world: np.ndarray, center_world: np.ndarray) -> tuple[float, ...]:
    """A view as 12 scalars, R_camera_world row by row and the camera centre C.

    Values, not array elements, for the functions below: a loop that stores into arrays
    must reload array elements (the store might alias them), not values.
    """
    R = R_camera_world
    C = center_world
    return (
        R[0, 0], R[0, 1], R[0, 2], R[1, 0], R[1, 1], R[1, 2], R[2, 0], R[2, 1], R[2, 2],
        C[0], C[1], C[2],
    )  # fmt: skip


@numba.njit(cache=True, inline="always", error_model="numpy")
def wall_point(
    x: float, y: float, ok: bool, view: tuple[float, ...], fma_rounding: bool
) -> tuple[float, float, bool]:
    """Where the ray of undistorted normalised coordinates (x, y) meets the wall z = 0.

    The ray d = R^T (x, y, 1), the point C + lambda d with lambda = -C_z / d_z (its z is
    exactly 0). Branch-free, for vectorised loops.

    Two roundings of d_k = x R[0, k] + y R[1, k] + R[2, k]: with fma_rounding, as
    `(N, 3) @ (3, 3)` rounds it in OpenBLAS's FMA kernels, fl(fma(y, R[1, k], fl(x R[0, k]))
    + R[2, k]) (the footprints: their NumPy reference, bit for bit); else the plain
    products and sums, left to right (the full-image kernel, whose numbers predate this
    function). They differ by an ulp in a corner, which the solid angle of a footprint
    ~5000 times smaller than its distance from the world origin (24 MP at 1.6 m) amplifies
    to ~1e-12 relative; the same number in both places costs that in one of them.

    Args:
        x, y: the corner's undistorted normalised coordinates; ok: they are valid.
        view: `view_scalars` of the view.
        fma_rounding: which rounding (a constant at each call: compiled away).

    Returns:
        (p_x, p_y, hit): hit when ok, d_z < 0 and lambda > 0; (0, 0) (finite) on a miss.
    """
    r00, r01, r02, r10, r11, r12, r20, r21, r22, c0, c1, c2 = view
    if fma_rounding:
        dx = fma(y, r10, x * r00) + r20
        dy = fma(y, r11, x * r01) + r21
        dz = fma(y, r12, x * r02) + r22
    else:
        dx = r00 * x + r10 * y + r20
        dy = r01 * x + r11 * y + r21
        dz = r02 * x + r12 * y + r22
    lam = -c2 / dz
    hit = ok & (dz < 0.0) & (lam > 0.0)
    px = c0 + lam * dx if hit else 0.0
    py = c1 + lam * dy if hit else 0.0
    return px, py, hit


@numba.njit(cache=True, inline="always", error_model="numpy")
def quad_area(
    x1: float, y1: float, x2: float, y2: float, x3: float, y3: float, x4: float, y4: float
) -> float:
    """Area of the quad P1 P2 P3 P4 (cyclic) on the wall: half its diagonals' cross product."""
    return 0.5 * abs((x3 - x1) * (y4 - y2) - (y3 - y1) * (x4 - x2))


@numba.njit(cache=True, inline="always", error_model="numpy")
def paper_weight(
    x1: float,
    y1: float,
    x2: float,
    y2: float,
    x3: float,
    y3: float,
    x4: float,
    y4: float,
    view: tuple[float, ...],
) -> float:
    """cos(theta_v) / d^2 of the wall quad P1..P4 seen from the camera centre C (`paper`).

    d = |C - centroid|, cos(theta_v) = C_z / d (the wall's normal is +z); view:
    `view_scalars` of the view.
    """
    c0 = view[9]
    c1 = view[10]
    c2 = view[11]
    ox = c0 - (((x1 + x2) + x3) + x4) / 4.0
    oy = c1 - (((y1 + y2) + y3) + y4) / 4.0
    d2 = (ox * ox + c2 * c2) + oy * oy  # numpy.einsum's order
    return (c2 / math.sqrt(d2)) / d2


@numba.njit(cache=True, inline="always", error_model="numpy")
def cos4(
    x1: float, y1: float, x2: float, y2: float, x3: float, y3: float, x4: float, y4: float
) -> float:
    """cos^4(alpha) of a pixel: alpha the angle of the ray through the mean of its four
    undistorted normalised corners (x_k, y_k) from the optical axis (`cos4`)."""
    mx = (((x1 + x2) + x3) + x4) / 4.0
    my = (((y1 + y2) + y3) + y4) / 4.0
    cos2 = 1.0 / (1.0 + (mx * mx + my * my))
    return cos2 * cos2
