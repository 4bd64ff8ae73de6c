"""Single scattering of a light's beam along each pixel's ray (`lightcal.core.medium`):
per pixel with gradients, and on whole images.

Along the ray from the camera centre C towards the footprint centre P (unit direction o,
length t_w), the point X(t) = C + t o, t in [0, t_w], sees the light L at distance
r = |X - L| in the direction w = (X - L) / r; it scatters towards the camera with the
Henyey-Greenstein phase function of the angle between w and -o,

    p(mu) = (1 - g^2) / (4 pi (1 + g^2 - 2 g mu)^(3/2)),  mu = -w . o,

and the light reaching the camera is attenuated along both segments:

    S = integral_0^t_w p(mu) f(u) exp(-c (r + t)) / r^2 dt,

f the RID at u = R_world_light^T w. The 1 / r^2 peaks where the ray passes the light
(at t0, distance b): with t = t0 + b tan(phi), dt = r^2 / b dphi (equiangular
sampling, Kulla and Fajardo 2012) the integrand p f exp(-c (r + t)) / b is smooth, and
the integral a Gauss-Legendre sum over phi. The gradients are that rule applied to the
integrand's derivatives (the rule's nodes move with the light; the sum converges to the
derivative of the integral as the value does).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from lightcal.core.kernels.medium import centre_sums_row, corner_row
from lightcal.core.kernels.sensor import view_scalars
from lightcal.core.rid_eval import RIDData, rid_value_direction, rid_value_grad_direction

#: Below this many points the kernels run on the calling thread.
SERIAL_POINTS = 5_000

_FOUR_PI = 4.0 * math.pi


@numba.njit(cache=True, error_model="numpy")
def ray_integral(
    px: float,
    py: float,
    pz: float,
    camera: np.ndarray,
    light: np.ndarray,
    R_world_light: np.ndarray,
    rid: RIDData,
    c: float,
    g: float,
    s_nodes: np.ndarray,
    s_weights: np.ndarray,
    want_grad: bool,
    grad: np.ndarray,
) -> float:
    """S of the ray from `camera` (3,) to the wall point (px, py, pz) (module docstring).

    With want_grad, grad (8,) receives dS / d (L_world (3), delta_world (3), c, g), delta a
    left rotation perturbation of R_world_light. 0 (and zero gradients) for a point that
    is not finite.
    """
    if want_grad:
        grad[:] = 0.0
    dx = px - camera[0]
    dy = py - camera[1]
    dz = pz - camera[2]
    t_w = math.sqrt(dx * dx + dy * dy + dz * dz)
    if not (math.isfinite(t_w) and t_w > 0.0):
        return 0.0
    ox, oy, oz = dx / t_w, dy / t_w, dz / t_w
    # The ray's closest approach to the light: t0 along it, at distance b.
    vx, vy, vz = light[0] - camera[0], light[1] - camera[1], light[2] - camera[2]
    t0 = vx * ox + vy * oy + vz * oz
    b = math.sqrt(max(vx * vx + vy * vy + vz * vz - t0 * t0, 1e-18))
    phi_a = math.atan2(-t0, b)
    span = math.atan2(t_w - t0, b) - phi_a
    k = (1.0 - g * g) / _FOUR_PI
    total = 0.0
    for j in range(s_nodes.shape[0]):
        # Equiangular nodes: t = t0 + b tan(phi), dt = r^2 / b dphi.
        phi = phi_a + span * s_nodes[j]
        t = t0 + b * math.tan(phi)
        cos_phi = math.cos(phi)
        wt = s_weights[j] * span * b / (cos_phi * cos_phi)
        ax = camera[0] + t * ox - light[0]
        ay = camera[1] + t * oy - light[1]
        az = camera[2] + t * oz - light[2]
        r = math.sqrt(ax * ax + ay * ay + az * az)
        wx, wy, wz = ax / r, ay / r, az / r
        wo = wx * ox + wy * oy + wz * oz  # mu = -wo
        d = 1.0 + g * g + 2.0 * g * wo
        p = k / (d * math.sqrt(d))
        R = R_world_light
        ux = R[0, 0] * wx + R[1, 0] * wy + R[2, 0] * wz
        uy = R[0, 1] * wx + R[1, 1] * wy + R[2, 1] * wz
        uz = R[0, 2] * wx + R[1, 2] * wy + R[2, 2] * wz
        if want_grad:
            f, glx, gly, glz = rid_value_grad_direction(ux, uy, uz, rid)
        else:
            f = rid_value_direction(ux, uy, uz, rid)
        e = math.exp(-c * (r + t)) / (r * r)
        h = p * f * e
        total += wt * h
        if want_grad:
            # The RID's (tangential) gradient in the world frame.
            gx = R[0, 0] * glx + R[0, 1] * gly + R[0, 2] * glz
            gy = R[1, 0] * glx + R[1, 1] * gly + R[1, 2] * glz
            gz = R[2, 0] * glx + R[2, 1] * gly + R[2, 2] * glz
            # dp/dmu = 3 g k / d^(5/2); dmu/dL = (o - (w . o) w) / r; df/dL = -g_W / r;
            # d(exp(-c r) / r^2)/dL = (c + 2 / r) w exp(-c r) / r^2.
            a = wt * f * e * (3.0 * g * k / (d * d * math.sqrt(d))) / r
            bb = wt * p * e / r
            cc = wt * h * (c + 2.0 / r)
            grad[0] += a * (ox - wo * wx) - bb * gx + cc * wx
            grad[1] += a * (oy - wo * wy) - bb * gy + cc * wy
            grad[2] += a * (oz - wo * wz) - bb * gz + cc * wz
            q = wt * p * e  # d/d delta: p e (g_W x w)
            grad[3] += q * (gy * wz - gz * wy)
            grad[4] += q * (gz * wx - gx * wz)
            grad[5] += q * (gx * wy - gy * wx)
            grad[6] -= wt * (r + t) * h
            # dp/dg = p (-2 g / (1 - g^2) - 3 (g + w . o) / d).
            grad[7] += wt * h * (-2.0 * g / (1.0 - g * g) - 3.0 * (g + wo) / d)
    return total


@numba.njit(cache=True, error_model="numpy")
def _points_range(
    i0: int,
    i1: int,
    points: np.ndarray,
    camera: np.ndarray,
    light: np.ndarray,
    R_world_light: np.ndarray,
    rid: RIDData,
    c: float,
    g: float,
    s_nodes: np.ndarray,
    s_weights: np.ndarray,
    want_grad: bool,
    out: np.ndarray,
    out_grad: np.ndarray,
) -> None:
    g8 = np.zeros(8)
    per_point = camera.shape[0] > 1
    for i in range(i0, i1):
        out[i] = ray_integral(
            points[i, 0],
            points[i, 1],
            points[i, 2],
            camera[i] if per_point else camera[0],
            light,
            R_world_light,
            rid,
            c,
            g,
            s_nodes,
            s_weights,
            want_grad,
            g8,
        )
        if want_grad:
            out_grad[i, :] = g8


@numba.njit(cache=True, parallel=True, error_model="numpy")
def _points_parallel(
    points: np.ndarray,
    camera: np.ndarray,
    light: np.ndarray,
    R_world_light: np.ndarray,
    rid: RIDData,
    c: float,
    g: float,
    s_nodes: np.ndarray,
    s_weights: np.ndarray,
    want_grad: bool,
    out: np.ndarray,
    out_grad: np.ndarray,
) -> None:
    n = points.shape[0]
    n_chunks = min(n, 64)
    for ch in numba.prange(n_chunks):
        _points_range(
            ch * n // n_chunks,
            (ch + 1) * n // n_chunks,
            points,
            camera,
            light,
            R_world_light,
            rid,
            c,
            g,
            s_nodes,
            s_weights,
            want_grad,
            out,
            out_grad,
        )


def scatter_points(
    points_world: np.ndarray,
    camera_world: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid: RIDData,
    attenuation_per_m: float,
    phase_g: float,
    s_nodes: np.ndarray,
    s_weights: np.ndarray,
    out: np.ndarray,
    out_grad: np.ndarray | None,
) -> None:
    """S (N,) of the rays to wall points (N, 3) (`ray_integral`) from `camera_world`,
    (3,) one point for all (the camera centre) or (N, 3) one per ray (where it leaves
    the camera's flat port into the water); out_grad (N, 8) its gradients, or None."""
    args = (
        np.ascontiguousarray(points_world, dtype=np.float64),
        np.ascontiguousarray(np.reshape(camera_world, (-1, 3)), dtype=np.float64),
        np.ascontiguousarray(light_world, dtype=np.float64),
        np.ascontiguousarray(R_world_light, dtype=np.float64),
        rid,
        float(attenuation_per_m),
        float(phase_g),
        s_nodes,
        s_weights,
        out_grad is not None,
        out,
        out_grad if out_grad is not None else np.zeros((1, 8)),
    )
    n = len(points_world)
    if n < SERIAL_POINTS:
        _points_range(0, n, *args)
    else:
        _points_parallel(*args)


@numba.njit(cache=True, inline="always", error_model="numpy")
def grid_bracket(nodes: np.ndarray, k: int, x: int) -> tuple[int, int, float]:
    """The nodes around row (or column) x of an image interpolated between `nodes`
    (increasing, the first and last row among them): (k, k1, f), x at nodes[k] +
    f (nodes[k1] - nodes[k]); k is the previous call's (0 at first; x nondecreasing)."""
    m = nodes.shape[0]
    while k < m - 2 and nodes[k + 1] <= x:
        k += 1
    k1 = k + 1 if m > 1 else k
    f = (x - nodes[k]) / max(nodes[k1] - nodes[k], 1) if m > 1 else 0.0
    return k, k1, f


@numba.njit(cache=True, inline="always", error_model="numpy")
def bilinear(at_nodes: np.ndarray, i: int, i1: int, fy: float, j: int, j1: int, fx: float) -> float:
    """at_nodes (m, n) interpolated bilinearly between the brackets (i, i1, fy) and
    (j, j1, fx) of `grid_bracket`: the node's own value at a node (f = 0 or 1); NaN
    beside an invalid (NaN) node."""
    return (1.0 - fy) * ((1.0 - fx) * at_nodes[i, j] + fx * at_nodes[i, j1]) + fy * (
        (1.0 - fx) * at_nodes[i1, j] + fx * at_nodes[i1, j1]
    )


@numba.njit(cache=True, parallel=True, error_model="numpy")
def add_scatter_image(
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
    R_camera_world: np.ndarray,
    center_world: np.ndarray,
    binning: int,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid: RIDData,
    attenuation_per_m: float,
    phase_g: float,
    s_nodes: np.ndarray,
    s_weights: np.ndarray,
    factor: float,
    node_rows: np.ndarray,
    node_cols: np.ndarray,
    total: np.ndarray,
) -> None:
    """total += factor x S at every (super-)pixel's footprint centre (placed as
    `attenuate_image` places it); pixels whose total is NaN (invalid) are left alone.

    S is computed exactly at the nodes node_rows x node_cols (increasing, the first and
    last row and column of the image among them) and interpolated bilinearly between them
    (S is smooth across the image: the beam's features span many pixels); a pixel next to
    an invalid node gets its own exact S. Every node: exact everywhere.

    Args: as `kernels.medium.attenuate_image`, and R_world_light (3, 3), the light's RID,
        phase_g, the Gauss-Legendre nodes and weights on [0, 1], factor, node_rows (m,)
        and node_cols (n,) int64.
    """
    hb = total.shape[0]
    wb = total.shape[1]
    b = binning
    w = wb * b
    view = view_scalars(R_camera_world, center_world)
    norm = 1.0 / (4.0 * b * b)
    m = node_rows.shape[0]
    n = node_cols.shape[0]
    at_nodes = np.empty((m, n))
    # Pass 1: S at the nodes (NaN where the node pixel is invalid).
    for i in numba.prange(m):
        r = node_rows[i]
        rows_x = np.empty((2, w + 1))
        rows_y = np.empty((2, w + 1))
        sx = np.empty(wb)
        sy = np.empty(wb)
        g8 = np.zeros(8)
        corner_row(grid_xy, grid_ok, r * b, view, rows_x[0], rows_y[0])
        centre_sums_row(grid_xy, grid_ok, view, r, b, rows_x, rows_y, 0, sx, sy)
        for j in range(n):
            col = node_cols[j]
            if math.isfinite(total[r, col]):
                at_nodes[i, j] = ray_integral(
                    sx[col] * norm,
                    sy[col] * norm,
                    0.0,
                    center_world,
                    light_world,
                    R_world_light,
                    rid,
                    attenuation_per_m,
                    phase_g,
                    s_nodes,
                    s_weights,
                    False,
                    g8,
                )
            else:
                at_nodes[i, j] = np.nan
    # Pass 2: every pixel, interpolated (or exact beside an invalid node).
    n_chunks = min(hb, 64)
    for ch in numba.prange(n_chunks):
        rows_x = np.empty((2, w + 1))
        rows_y = np.empty((2, w + 1))
        sx = np.empty(wb)
        sy = np.empty(wb)
        g8 = np.zeros(8)
        r_begin = ch * hb // n_chunks
        top = 0
        corner_row(grid_xy, grid_ok, r_begin * b, view, rows_x[0], rows_y[0])
        i = 0
        for r in range(r_begin, (ch + 1) * hb // n_chunks):
            top = centre_sums_row(grid_xy, grid_ok, view, r, b, rows_x, rows_y, top, sx, sy)
            i, i1, fy = grid_bracket(node_rows, i, r)
            out = total[r]
            j = 0
            for col in range(wb):
                if not math.isfinite(out[col]):
                    continue
                j, j1, fx = grid_bracket(node_cols, j, col)
                v = bilinear(at_nodes, i, i1, fy, j, j1, fx)
                if not math.isfinite(v):
                    v = ray_integral(
                        sx[col] * norm,
                        sy[col] * norm,
                        0.0,
                        center_world,
                        light_world,
                        R_world_light,
                        rid,
                        attenuation_per_m,
                        phase_g,
                        s_nodes,
                        s_weights,
                        False,
                        g8,
                    )
                out[col] += factor * v
