"""The flux of one footprint quad and of one pixel's quads, with gradients.

The model (docs/model.md): a footprint quad Q on the wall receives the flux
Phi_Q = I0 * sum_j Omega_j f(w_j) over its n x n sub-quads (n = 1: the quad itself),
Omega_j the exact solid angle of sub-quad j seen from the light (`kernels.solid_angle`)
and w_j the direction from the light to its centroid, f the RID (`rid_eval`). A pixel's
flux is sum_k weight_k Phi_k over its quads k (one quad, or the b x b pixels of a binned
super-pixel), the weights carrying the sensor model (`kernels.sensor`). Gradients are
taken with respect to the light position (world frame) and a left rotation perturbation
of the light's orientation (world frame).

- `quad_flux`: the plain quad loop, any quad and sub-sampling, with gradients: the
  definition the fast paths are held to;
- `wall_quad_flux`: n = 1, no gradient, a quad on the wall z = 0 (shared corner norms,
  one arctangent per quad, cos^m without libm);
- `pixel_flux`: one pixel, quad by quad, taking `wall_quad_flux` where it applies;
- `pixel_flux_range`: `pixel_flux` over a range of pixels, the one compiled copy of the
  quad loop that every entry point calls. (Inlined into each of them, as it was, numba
  typed and lowered the whole quad loop, every RID kind with it, once per entry point
  and signature: most of the kernels' first compile.)
- `wall_flux_range`: the common case without gradients (n = 1, quads on the wall) for a
  range of pixels, compiled once and inlined by LLVM (`forceinline`) into the entry
  points: through a plain call it ran 1.4x slower (inside a parallel loop numba marks the
  arrays as not aliased). Pixels with a quad off the wall go to `pixel_flux_range`.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from lightcal.core.kernels.solid_angle import quad_omega, triangle_omega, wall_quad_terms
from lightcal.core.rid_eval import (
    KIND_ISOTROPIC,
    RIDData,
    rid_value_direction,
    rid_value_grad_direction,
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
def quad_flux(
    q: np.ndarray,
    lx: float,
    ly: float,
    lz: float,
    R_world_light: np.ndarray,
    rid: RIDData,
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
            o1, g1x, g1y, g1z = triangle_omega(lx, ly, lz, p1, p2, p3, want_grad)
            o2, g2x, g2y, g2z = triangle_omega(lx, ly, lz, p1, p3, p4, want_grad)
            omega = o1 + o2
            sign = 1.0
            if omega < 0.0:
                omega = -omega
                sign = -1.0
            if rid.kind == KIND_ISOTROPIC:
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
            f, gux, guy, guz = rid_value_grad_direction(ux, uy, uz, rid)
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


@numba.njit(cache=True, inline="always", error_model="numpy")
def wall_quad_flux(
    corners_world: np.ndarray,
    i: int,
    k: int,
    lx: float,
    ly: float,
    lz: float,
    R_world_light: np.ndarray,
    rid: RIDData,
) -> float:
    """Omega f of quad corners_world[i, k] (4, 3) on the wall z = 0.

    `quad_flux` with n = 1 and no gradient; indices, not a view: a view per pixel costs.
    """
    omega = quad_omega(*wall_quad_terms(corners_world, i, k, lx, ly, lz))
    if rid.kind == KIND_ISOTROPIC:
        return omega
    c = corners_world
    mx = 0.25 * (c[i, k, 0, 0] + c[i, k, 1, 0] + c[i, k, 2, 0] + c[i, k, 3, 0]) - lx
    my = 0.25 * (c[i, k, 0, 1] + c[i, k, 1, 1] + c[i, k, 2, 1] + c[i, k, 3, 1]) - ly
    az = 0.0 - lz
    r = math.sqrt(mx * mx + my * my + az * az)
    wx = mx / r
    wy = my / r
    wz = az / r
    ux = R_world_light[0, 0] * wx + R_world_light[1, 0] * wy + R_world_light[2, 0] * wz
    uy = R_world_light[0, 1] * wx + R_world_light[1, 1] * wy + R_world_light[2, 1] * wz
    uz = R_world_light[0, 2] * wx + R_world_light[1, 2] * wy + R_world_light[2, 2] * wz
    return omega * rid_value_direction(ux, uy, uz, rid)


@numba.njit(cache=True, inline="always")
def _on_wall(corners_world: np.ndarray, i: int, k: int) -> bool:
    """Whether quad k of pixel i lies on the wall z = 0 (the fast paths' condition)."""
    return (
        corners_world[i, k, 0, 2] == 0.0
        and corners_world[i, k, 1, 2] == 0.0
        and corners_world[i, k, 2, 2] == 0.0
        and corners_world[i, k, 3, 2] == 0.0
    )


@numba.njit(cache=True, inline="always")
def pixel_flux(
    i: int,
    corners_world: np.ndarray,
    weights: np.ndarray,
    valid: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid: RIDData,
    n_sub: int,
    want_grad: bool,
    allow_fast: bool,
    g: np.ndarray,
    gq: np.ndarray,
    out_flux: np.ndarray,
    out_grad: np.ndarray,
) -> None:
    """`flux_pixels` for pixel i, quad by quad; g and gq: (6,) scratch buffers.

    With allow_fast, n_sub = 1 and no gradients, quads on the wall take `wall_quad_flux`;
    every other quad takes `quad_flux` (the plain kernel).
    """
    n_k = corners_world.shape[1]
    lx = light_world[0]
    ly = light_world[1]
    lz = light_world[2]
    fast = allow_fast and n_sub == 1 and not want_grad
    acc = 0.0
    if want_grad:
        g[:] = 0.0
    if valid[i]:
        for k in range(n_k):
            if fast and _on_wall(corners_world, i, k):
                phi = wall_quad_flux(corners_world, i, k, lx, ly, lz, R_world_light, rid)
            else:
                # One call site: each inlined copy of `quad_flux` costs compile time.
                if want_grad:
                    gq[:] = 0.0
                phi = quad_flux(
                    corners_world[i, k], lx, ly, lz, R_world_light, rid, n_sub, want_grad, gq
                )
                if want_grad:
                    for d in range(6):
                        g[d] += weights[i, k] * gq[d]
            acc += weights[i, k] * phi
    out_flux[i] = acc
    if want_grad:
        for d in range(6):
            out_grad[i, d] = g[d]


@numba.njit(cache=True, forceinline=False)  # explicit: not inherited from a caller
def pixel_flux_range(
    i0: int,
    i1: int,
    corners_world: np.ndarray,
    weights: np.ndarray,
    valid: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid: RIDData,
    n_sub: int,
    want_grad: bool,
    allow_fast: bool,
    out_flux: np.ndarray,
    out_grad: np.ndarray,
) -> None:
    """`pixel_flux` for pixels i0 .. i1 - 1 (a call per range of pixels, not per pixel)."""
    g = np.zeros(6)
    gq = np.zeros(6)
    for i in range(i0, i1):
        pixel_flux(
            i,
            corners_world,
            weights,
            valid,
            light_world,
            R_world_light,
            rid,
            n_sub,
            want_grad,
            allow_fast,
            g,
            gq,
            out_flux,
            out_grad,
        )


@numba.njit(cache=True, forceinline=True, error_model="numpy")
def wall_flux_range(
    i0: int,
    i1: int,
    corners_world: np.ndarray,
    weights: np.ndarray,
    valid: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid: RIDData,
    out_flux: np.ndarray,
    out_grad: np.ndarray,
) -> None:
    """`pixel_flux_range` with n_sub = 1, no gradients and the fast path allowed: quads on
    the wall by `wall_quad_flux` here, a pixel with a quad off the wall by
    `pixel_flux_range` (the same numbers as `pixel_flux`)."""
    n_k = corners_world.shape[1]
    lx = light_world[0]
    ly = light_world[1]
    lz = light_world[2]
    # Typed values, not literals: numba would compile `pixel_flux_range` again for them.
    n_sub = int(1)  # noqa: UP018, RUF046 (not a literal type)
    want_grad = bool(False)  # noqa: UP018 (not a literal type)
    allow_fast = bool(True)  # noqa: UP018 (not a literal type)
    for i in range(i0, i1):
        if not valid[i]:
            out_flux[i] = 0.0
            continue
        acc = 0.0
        all_on_wall = True
        for k in range(n_k):
            if _on_wall(corners_world, i, k):
                phi = wall_quad_flux(corners_world, i, k, lx, ly, lz, R_world_light, rid)
                acc += weights[i, k] * phi
            else:
                all_on_wall = False
        if all_on_wall:
            out_flux[i] = acc
        else:
            pixel_flux_range(
                i,
                i + 1,
                corners_world,
                weights,
                valid,
                light_world,
                R_world_light,
                rid,
                n_sub,
                want_grad,
                allow_fast,
                out_flux,
                out_grad,
            )
