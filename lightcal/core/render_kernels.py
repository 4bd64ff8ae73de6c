"""Compiled (numba) kernels of the energy-preserving renderer.

The model (see docs/conventions.md and MODEL.md): a footprint quad Q on the wall
receives the flux Phi_Q = I0 * sum_j Omega_j f(w_j) over its n x n sub-quads (n = 1:
the quad itself), Omega_j the exact solid angle of sub-quad j seen from the light and
w_j the direction from the light to its centroid. Pixel values are
offset + gain * sum_lights scale * sum_k weight_k Phi_k over the quads k of a pixel
(one quad, or the b x b pixels of a binned super-pixel), the weights carrying the
sensor model. These kernels compute the flux sums and, for the solver, their gradients
with respect to the light position (world frame) and a left rotation perturbation of
the light's orientation (world frame).

`lightcal.core.render_reference` is the plain NumPy implementation of the same model
that the tests compare these kernels against.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from lightcal.core.rid_eval import KIND_ISOTROPIC, rid_value_grad_direction

SENSOR_RADIANCE = 0
SENSOR_COS4 = 1
SENSOR_PAPER = 2
SENSOR_MAP = 3


@numba.njit(cache=True, inline="always", fastmath=False)
def _triangle(
    lx: float,
    ly: float,
    lz: float,
    p1: tuple[float, float, float],
    p2: tuple[float, float, float],
    p3: tuple[float, float, float],
    want_grad: bool,
) -> tuple[float, float, float, float]:
    """Signed solid angle of a triangle seen from (lx, ly, lz) and its gradient."""
    ax = p1[0] - lx
    ay = p1[1] - ly
    az = p1[2] - lz
    bx = p2[0] - lx
    by = p2[1] - ly
    bz = p2[2] - lz
    cx = p3[0] - lx
    cy = p3[1] - ly
    cz = p3[2] - lz
    e1x = p2[0] - p1[0]
    e1y = p2[1] - p1[1]
    e1z = p2[2] - p1[2]
    e2x = p3[0] - p1[0]
    e2y = p3[1] - p1[1]
    e2z = p3[2] - p1[2]
    nx = e1y * e2z - e1z * e2y
    ny = e1z * e2x - e1x * e2z
    nz = e1x * e2y - e1y * e2x
    num = ax * nx + ay * ny + az * nz
    la = math.sqrt(ax * ax + ay * ay + az * az)
    lb = math.sqrt(bx * bx + by * by + bz * bz)
    lc = math.sqrt(cx * cx + cy * cy + cz * cz)
    ab = ax * bx + ay * by + az * bz
    ac = ax * cx + ay * cy + az * cz
    bc = bx * cx + by * cy + bz * cz
    den = la * lb * lc + ab * lc + ac * lb + bc * la
    omega = 2.0 * math.atan2(num, den)
    if not want_grad:
        return omega, 0.0, 0.0, 0.0
    # d num / dL = -(e1 x e2); d den / dL = -(sum of the terms below).
    ka = lb * lc / la + bc / la
    kb = la * lc / lb + ac / lb
    kc = la * lb / lc + ab / lc
    gdx = ka * ax + kb * bx + kc * cx + (ax + bx) * lc + (ax + cx) * lb + (bx + cx) * la
    gdy = ka * ay + kb * by + kc * cy + (ay + by) * lc + (ay + cy) * lb + (by + cy) * la
    gdz = ka * az + kb * bz + kc * cz + (az + bz) * lc + (az + cz) * lb + (bz + cz) * la
    s = 2.0 / (num * num + den * den)
    # d omega = s (den d num - num d den), with d num = -n and d den = -gd.
    return (
        omega,
        s * (-den * nx + num * gdx),
        s * (-den * ny + num * gdy),
        s * (-den * nz + num * gdz),
    )


@numba.njit(cache=True, inline="always")
def _bilerp(q: np.ndarray, s: float, t: float) -> tuple[float, float, float]:
    """Point (s, t) of the bilinear patch through the quad q (4, 3); corners at s, t in {0, 1}."""
    if s == 0.0 and t == 0.0:
        return q[0, 0], q[0, 1], q[0, 2]
    if s == 1.0 and t == 0.0:
        return q[1, 0], q[1, 1], q[1, 2]
    if s == 1.0 and t == 1.0:
        return q[2, 0], q[2, 1], q[2, 2]
    if s == 0.0 and t == 1.0:
        return q[3, 0], q[3, 1], q[3, 2]
    w1 = (1 - s) * (1 - t)
    w2 = s * (1 - t)
    w3 = s * t
    w4 = (1 - s) * t
    return (
        w1 * q[0, 0] + w2 * q[1, 0] + w3 * q[2, 0] + w4 * q[3, 0],
        w1 * q[0, 1] + w2 * q[1, 1] + w3 * q[2, 1] + w4 * q[3, 1],
        w1 * q[0, 2] + w2 * q[1, 2] + w3 * q[2, 2] + w4 * q[3, 2],
    )


@numba.njit(cache=True, inline="always")
def _quad_flux(
    q: np.ndarray,
    lx: float,
    ly: float,
    lz: float,
    R_world_light: np.ndarray,
    rid_kind: int,
    rid_params: np.ndarray,
    rid_theta: np.ndarray,
    rid_phi: np.ndarray,
    rid_values: np.ndarray,
    rid_slopes: np.ndarray,
    n_sub: int,
    want_grad: bool,
    grad: np.ndarray,
) -> float:
    """Flux sum_j Omega_j f(w_j) of one planar quad q (4, 3), split n_sub x n_sub.

    When want_grad, adds d flux / d L_world to grad[0:3] and d flux / d delta_world
    (left rotation perturbation of the light) to grad[3:6].
    """
    total = 0.0
    for jt in range(n_sub):
        # k / n (a division, not k * (1 / n)) so neighbouring sub-quads share exact edges.
        t0 = jt / n_sub
        t1 = (jt + 1) / n_sub
        for js in range(n_sub):
            s0 = js / n_sub
            s1 = (js + 1) / n_sub
            p1 = _bilerp(q, s0, t0)
            p2 = _bilerp(q, s1, t0)
            p3 = _bilerp(q, s1, t1)
            p4 = _bilerp(q, s0, t1)
            o1, g1x, g1y, g1z = _triangle(lx, ly, lz, p1, p2, p3, want_grad)
            o2, g2x, g2y, g2z = _triangle(lx, ly, lz, p1, p3, p4, want_grad)
            omega = o1 + o2
            sign = 1.0
            if omega < 0.0:
                omega = -omega
                sign = -1.0
            if rid_kind == KIND_ISOTROPIC:
                total += omega
                if want_grad:
                    grad[0] += sign * (g1x + g2x)
                    grad[1] += sign * (g1y + g2y)
                    grad[2] += sign * (g1z + g2z)
                continue
            # Direction from the light to the sub-quad's centroid, world and light frames.
            mx = 0.25 * (p1[0] + p2[0] + p3[0] + p4[0]) - lx
            my = 0.25 * (p1[1] + p2[1] + p3[1] + p4[1]) - ly
            mz = 0.25 * (p1[2] + p2[2] + p3[2] + p4[2]) - lz
            r = math.sqrt(mx * mx + my * my + mz * mz)
            wx = mx / r
            wy = my / r
            wz = mz / r
            ux = R_world_light[0, 0] * wx + R_world_light[1, 0] * wy + R_world_light[2, 0] * wz
            uy = R_world_light[0, 1] * wx + R_world_light[1, 1] * wy + R_world_light[2, 1] * wz
            uz = R_world_light[0, 2] * wx + R_world_light[1, 2] * wy + R_world_light[2, 2] * wz
            f, gux, guy, guz = rid_value_grad_direction(
                ux, uy, uz, rid_kind, rid_params, rid_theta, rid_phi, rid_values, rid_slopes
            )
            total += omega * f
            if want_grad:
                # Gradient of f with respect to the world direction w (tangential).
                gwx = (
                    R_world_light[0, 0] * gux
                    + R_world_light[0, 1] * guy
                    + R_world_light[0, 2] * guz
                )
                gwy = (
                    R_world_light[1, 0] * gux
                    + R_world_light[1, 1] * guy
                    + R_world_light[1, 2] * guz
                )
                gwz = (
                    R_world_light[2, 0] * gux
                    + R_world_light[2, 1] * guy
                    + R_world_light[2, 2] * guz
                )
                # d w / d L = -(I - w w^T) / r; gw is tangential, so d f / d L = -gw / r.
                grad[0] += f * sign * (g1x + g2x) - omega * gwx / r
                grad[1] += f * sign * (g1y + g2y) - omega * gwy / r
                grad[2] += f * sign * (g1z + g2z) - omega * gwz / r
                # Left perturbation R -> exp(delta) R moves w to w + w x delta,
                # so d f / d delta = gw x w.
                grad[3] += omega * (gwy * wz - gwz * wy)
                grad[4] += omega * (gwz * wx - gwx * wz)
                grad[5] += omega * (gwx * wy - gwy * wx)
    return total


@numba.njit(cache=True, parallel=True)
def flux_pixels(
    corners_world: np.ndarray,
    weights: np.ndarray,
    valid: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid_kind: int,
    rid_params: np.ndarray,
    rid_theta: np.ndarray,
    rid_phi: np.ndarray,
    rid_values: np.ndarray,
    rid_slopes: np.ndarray,
    n_sub: int,
    want_grad: bool,
    out_flux: np.ndarray,
    out_grad: np.ndarray,
) -> None:
    """Weighted footprint flux of pixels for one light; writes (not adds) the outputs.

    Args:
        corners_world: (N, K, 4, 3) the K footprint quads of each pixel, world frame, m.
        weights: (N, K) sensor weights of each quad.
        valid: (N,) pixels to compute; others get 0.
        light_world: (3,) emitter position, world frame, m. Must have z > 0.
        R_world_light: (3, 3) light orientation in the world frame.
        rid_*: the fields of `RIDData`.
        n_sub: RID sub-sampling per side of each quad.
        want_grad: compute out_grad.
        out_flux: (N,) sum_k weight_k Phi_k / I0.
        out_grad: (N, 6) d out_flux / d (L_world (3), delta_world (3)); untouched if not want_grad.
    """
    n = corners_world.shape[0]
    n_k = corners_world.shape[1]
    lx = light_world[0]
    ly = light_world[1]
    lz = light_world[2]
    for i in numba.prange(n):
        g = np.zeros(6)
        acc = 0.0
        if valid[i]:
            gq = np.zeros(6)
            for k in range(n_k):
                if want_grad:
                    gq[:] = 0.0
                phi = _quad_flux(
                    corners_world[i, k],
                    lx,
                    ly,
                    lz,
                    R_world_light,
                    rid_kind,
                    rid_params,
                    rid_theta,
                    rid_phi,
                    rid_values,
                    rid_slopes,
                    n_sub,
                    want_grad,
                    gq,
                )
                acc += weights[i, k] * phi
                if want_grad:
                    for d in range(6):
                        g[d] += weights[i, k] * gq[d]
        out_flux[i] = acc
        if want_grad:
            for d in range(6):
                out_grad[i, d] = g[d]


@numba.njit(cache=True, inline="always")
def _corner_world(
    x: float, y: float, R_camera_world: np.ndarray, center: np.ndarray, out: np.ndarray
) -> bool:
    """Intersect the ray of normalised camera coordinates (x, y) with z = 0; False on a miss."""
    dx = R_camera_world[0, 0] * x + R_camera_world[1, 0] * y + R_camera_world[2, 0]
    dy = R_camera_world[0, 1] * x + R_camera_world[1, 1] * y + R_camera_world[2, 1]
    dz = R_camera_world[0, 2] * x + R_camera_world[1, 2] * y + R_camera_world[2, 2]
    if not (dz < 0.0):
        return False
    lam = -center[2] / dz
    if not (lam > 0.0):
        return False
    out[0] = center[0] + lam * dx
    out[1] = center[1] + lam * dy
    out[2] = 0.0
    return True


@numba.njit(cache=True, parallel=True)
def geometry_image(
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
    R_camera_world: np.ndarray,
    center_world: np.ndarray,
    sensor: int,
    vignetting: np.ndarray,
    binning: int,
    out_weight: np.ndarray,
    out_valid: np.ndarray,
) -> None:
    """Per-pixel sensor weights of a (binned) full image; see `flux_image`.

    Args:
        grid_xy: (H+1, W+1, 2) undistorted normalised coordinates of the pixel corners.
        grid_ok: (H+1, W+1) corners whose undistortion succeeded.
        R_camera_world: (3, 3); center_world: (3,) camera centre, world frame, m.
        sensor: one of the SENSOR_* codes.
        vignetting: (H, W) fall-off map for SENSOR_MAP, else any (1, 1) array.
        binning: b, super-pixel side in pixels.
        out_weight: (H // b, W // b, b * b) weight of each member pixel's flux.
        out_valid: (H // b, W // b) pixels whose every corner lands on the wall.
    """
    hb = out_valid.shape[0]
    wb = out_valid.shape[1]
    b = binning
    for r in numba.prange(hb):
        q = np.empty((4, 3))
        for cidx in range(wb):
            ok = True
            area = 0.0
            vsum = 0.0
            for jj in range(b):
                v = r * b + jj
                for ii in range(b):
                    u = cidx * b + ii
                    xs = (
                        grid_xy[v, u, 0],
                        grid_xy[v, u + 1, 0],
                        grid_xy[v + 1, u + 1, 0],
                        grid_xy[v + 1, u, 0],
                    )
                    ys = (
                        grid_xy[v, u, 1],
                        grid_xy[v, u + 1, 1],
                        grid_xy[v + 1, u + 1, 1],
                        grid_xy[v + 1, u, 1],
                    )
                    oks = (
                        grid_ok[v, u]
                        and grid_ok[v, u + 1]
                        and grid_ok[v + 1, u + 1]
                        and grid_ok[v + 1, u]
                    )
                    if not oks:
                        ok = False
                        break
                    for k in range(4):
                        if not _corner_world(xs[k], ys[k], R_camera_world, center_world, q[k]):
                            ok = False
                    if not ok:
                        break
                    a = 0.5 * abs(
                        (q[2, 0] - q[0, 0]) * (q[3, 1] - q[1, 1])
                        - (q[2, 1] - q[0, 1]) * (q[3, 0] - q[1, 0])
                    )
                    k_idx = jj * b + ii
                    if sensor == SENSOR_PAPER:
                        mx = 0.25 * (q[0, 0] + q[1, 0] + q[2, 0] + q[3, 0]) - center_world[0]
                        my = 0.25 * (q[0, 1] + q[1, 1] + q[2, 1] + q[3, 1]) - center_world[1]
                        mz = -center_world[2]
                        d2 = mx * mx + my * my + mz * mz
                        out_weight[r, cidx, k_idx] = (
                            (center_world[2] / math.sqrt(d2)) / d2 / (b * b)
                        )
                    else:
                        area += a
                        if sensor == SENSOR_COS4:
                            xm = 0.25 * (xs[0] + xs[1] + xs[2] + xs[3])
                            ym = 0.25 * (ys[0] + ys[1] + ys[2] + ys[3])
                            c2 = 1.0 / (1.0 + xm * xm + ym * ym)
                            vsum += c2 * c2
                        elif sensor == SENSOR_MAP:
                            vsum += vignetting[v, u]
                        else:
                            vsum += 1.0
                if not ok:
                    break
            out_valid[r, cidx] = ok
            if ok and sensor != SENSOR_PAPER:
                w = (vsum / (b * b)) / area
                for k_idx in range(b * b):
                    out_weight[r, cidx, k_idx] = w


@numba.njit(cache=True, parallel=True)
def flux_image(
    grid_xy: np.ndarray,
    R_camera_world: np.ndarray,
    center_world: np.ndarray,
    weight: np.ndarray,
    valid: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid_kind: int,
    rid_params: np.ndarray,
    rid_theta: np.ndarray,
    rid_phi: np.ndarray,
    rid_values: np.ndarray,
    rid_slopes: np.ndarray,
    n_sub: int,
    scale: float,
    out: np.ndarray,
) -> None:
    """Add scale * sum_k weight_k Phi_k / I0 of one light to every valid (super-)pixel.

    Args:
        grid_xy: (H+1, W+1, 2) undistorted normalised corner coordinates.
        R_camera_world, center_world: the view; light_world (3,), R_world_light (3, 3): the light.
        weight, valid: from `geometry_image`.
        rid_*: the fields of `RIDData`; n_sub: RID sub-sampling per side.
        scale: the light's scale.
        out: (H // b, W // b) accumulator.
    """
    hb = valid.shape[0]
    wb = valid.shape[1]
    b = round(math.sqrt(weight.shape[2]))
    lx = light_world[0]
    ly = light_world[1]
    lz = light_world[2]
    for r in numba.prange(hb):
        q = np.empty((4, 3))
        dummy = np.zeros(6)
        for cidx in range(wb):
            if not valid[r, cidx]:
                continue
            acc = 0.0
            for jj in range(b):
                v = r * b + jj
                for ii in range(b):
                    u = cidx * b + ii
                    _corner_world(
                        grid_xy[v, u, 0], grid_xy[v, u, 1], R_camera_world, center_world, q[0]
                    )
                    _corner_world(
                        grid_xy[v, u + 1, 0],
                        grid_xy[v, u + 1, 1],
                        R_camera_world,
                        center_world,
                        q[1],
                    )
                    _corner_world(
                        grid_xy[v + 1, u + 1, 0],
                        grid_xy[v + 1, u + 1, 1],
                        R_camera_world,
                        center_world,
                        q[2],
                    )
                    _corner_world(
                        grid_xy[v + 1, u, 0],
                        grid_xy[v + 1, u, 1],
                        R_camera_world,
                        center_world,
                        q[3],
                    )
                    phi = _quad_flux(
                        q,
                        lx,
                        ly,
                        lz,
                        R_world_light,
                        rid_kind,
                        rid_params,
                        rid_theta,
                        rid_phi,
                        rid_values,
                        rid_slopes,
                        n_sub,
                        False,
                        dummy,
                    )
                    acc += weight[r, cidx, jj * b + ii] * phi
            out[r, cidx] += scale * acc
