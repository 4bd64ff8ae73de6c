"""The fast gradient path of `flux_pixels`: n = 1, quads on the wall z = 0.

The numbers of `quad_flux` (the model of docs/model.md, same formulas up to the order
of a few additions), computed for blocks of GRAD_BLOCK pixels in branch-free loops that
LLVM vectorises:

- the two triangles' Van Oosterom-Strackee terms share the corner norms l_k, and with
  the wall z = 0 the numerators are a_z (e1 x e2)_z with d num / d L = -(0, 0, (e1 x e2)_z);
- d den / d L of a triangle (a, b, c) is -(alpha a + beta b + gamma c) with
  alpha = (l_b l_c + b.c) / l_a + l_b + l_c (and cyclically), so the quad's gradient
  d Omega / d L = sum over the 4 corners of a coefficient times the corner's vector,
  minus the numerators' z terms;
- Omega itself by the one-arctangent series (`quad_omega`'s common case), the quads
  outside its range recomputed afterwards by `wall_quad_omega_signed`;
- cos^m: f = u_z^m and its tangential gradient m u_z^(m - 1) (e_z - u_z u), i.e. in the
  world frame (m f / u_z) (axis - u_z w): no arctangent, no arccosine.

Pixels with a quad off the wall take the quad loop (`pixel_flux_range`) afterwards.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from lightcal.core.kernels.fastmath import (
    ATAN_SERIES_MAX,
    atan2_nonneg,
    atan_series,
    cos_power,
    rotate_transposed,
)
from lightcal.core.kernels.quad_flux import pixel_flux_range
from lightcal.core.kernels.solid_angle import wall_quad_omega_signed
from lightcal.core.rid_eval import (
    AXIS_EPS,
    AXIS_RHO,
    KIND_COS_POWER,
    KIND_GRID_1D,
    KIND_GRID_2D,
    KIND_ISOTROPIC,
    KIND_TABLE_1D,
    KIND_TABLE_2D,
    RIDData,
    hermite,
    rid_value_grad_direction,
    table2d_value_grad,
)
from lightcal.core.rid_grid import (
    grid1d_coord,
    grid1d_interp,
    grid2d_coords,
    grid2d_gradient,
    grid2d_interp,
)

#: Pixels per block of the fast gradient path (its scratch rows stay in the L1 cache).
GRAD_BLOCK = 128
_N_SCRATCH = 28  # float rows of the block scratch (see `wall_grad_block`)


@numba.njit(cache=True, error_model="numpy")
def wall_grad_block(
    i0: int,
    i1: int,
    corners_world: np.ndarray,
    weights: np.ndarray,
    valid: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid: RIDData,
    scratch: np.ndarray,
    flags: np.ndarray,
    out_flux: np.ndarray,
    out_grad: np.ndarray,
) -> int:
    """`flux_pixels` with gradients and n = 1 for pixels i0 .. i1 - 1 (at most GRAD_BLOCK).

    Writes out_flux[i0:i1] and out_grad[i0:i1] for pixels whose quads all lie on the wall
    (0 for invalid pixels) and returns how many valid pixels have a quad off the wall:
    the caller computes those (flags[0] False) by `pixel_flux_range`.

    Args:
        scratch: (_N_SCRATCH, GRAD_BLOCK) float buffer; flags: (2, GRAD_BLOCK) bool buffer.
    """
    nb = i1 - i0
    n_k = corners_world.shape[1]
    lx = light_world[0]
    ly = light_world[1]
    lz = light_world[2]
    az = 0.0 - lz
    azz = az * az
    so = scratch[0]  # signed solid angle of quad k
    gox = scratch[1]  # its gradient d Omega / d L_world
    goy = scratch[2]
    goz = scratch[3]
    wxs = scratch[4]  # unit direction from the light to the quad's centroid
    wys = scratch[5]
    wzs = scratch[6]
    rs = scratch[7]  # distance from the light to the centroid
    fs = scratch[8]  # RID value
    gwx = scratch[9]  # its tangential gradient with respect to w, world frame
    gwy = scratch[10]
    gwz = scratch[11]
    acc = scratch[12]  # sum_k weight_k Phi_k
    ag0 = scratch[13]  # its gradient (L_world, delta_world)
    ag1 = scratch[14]
    ag2 = scratch[15]
    ag3 = scratch[16]
    ag4 = scratch[17]
    ag5 = scratch[18]
    xs1 = scratch[19]  # corners of quad k (unit stride: the geometry loop vectorises)
    ys1 = scratch[20]
    xs2 = scratch[21]
    ys2 = scratch[22]
    xs3 = scratch[23]
    ys3 = scratch[24]
    xs4 = scratch[25]
    ys4 = scratch[26]
    wts = scratch[27]  # weight of quad k
    on_wall = flags[0]
    bad = flags[1]
    for i in range(nb):
        acc[i] = 0.0
        ag0[i] = 0.0
        ag1[i] = 0.0
        ag2[i] = 0.0
        ag3[i] = 0.0
        ag4[i] = 0.0
        ag5[i] = 0.0
        on_wall[i] = True
    r00 = R_world_light[0, 0]
    r10 = R_world_light[1, 0]
    r20 = R_world_light[2, 0]
    r01 = R_world_light[0, 1]
    r11 = R_world_light[1, 1]
    r21 = R_world_light[2, 1]
    r02 = R_world_light[0, 2]
    r12 = R_world_light[1, 2]
    r22 = R_world_light[2, 2]
    R9 = (r00, r10, r20, r01, r11, r21, r02, r12, r22)
    for k in range(n_k):
        # Geometry: solid angle (series), its gradient, the direction to the centroid.
        for i in range(nb):
            p = i0 + i
            xs1[i] = corners_world[p, k, 0, 0]
            ys1[i] = corners_world[p, k, 0, 1]
            xs2[i] = corners_world[p, k, 1, 0]
            ys2[i] = corners_world[p, k, 1, 1]
            xs3[i] = corners_world[p, k, 2, 0]
            ys3[i] = corners_world[p, k, 2, 1]
            xs4[i] = corners_world[p, k, 3, 0]
            ys4[i] = corners_world[p, k, 3, 1]
            flat = (
                (corners_world[p, k, 0, 2] == 0.0)
                & (corners_world[p, k, 1, 2] == 0.0)
                & (corners_world[p, k, 2, 2] == 0.0)
                & (corners_world[p, k, 3, 2] == 0.0)
            )
            on_wall[i] = on_wall[i] & flat
            wts[i] = weights[p, k]
        n_bad = 0
        for i in range(nb):
            x1 = xs1[i]
            y1 = ys1[i]
            x2 = xs2[i]
            y2 = ys2[i]
            x3 = xs3[i]
            y3 = ys3[i]
            x4 = xs4[i]
            y4 = ys4[i]
            a_x = x1 - lx
            a_y = y1 - ly
            b_x = x2 - lx
            b_y = y2 - ly
            c_x = x3 - lx
            c_y = y3 - ly
            d_x = x4 - lx
            d_y = y4 - ly
            l1 = math.sqrt(a_x * a_x + a_y * a_y + azz)
            l2 = math.sqrt(b_x * b_x + b_y * b_y + azz)
            l3 = math.sqrt(c_x * c_x + c_y * c_y + azz)
            l4 = math.sqrt(d_x * d_x + d_y * d_y + azz)
            e1x = x2 - x1
            e1y = y2 - y1
            e2x = x3 - x1
            e2y = y3 - y1
            e3x = x4 - x1
            e3y = y4 - y1
            c1 = e1x * e2y - e1y * e2x
            c2 = e2x * e3y - e2y * e3x
            n1 = az * c1
            n2 = az * c2
            ab = a_x * b_x + a_y * b_y + azz
            ac = a_x * c_x + a_y * c_y + azz
            bc = b_x * c_x + b_y * c_y + azz
            ad = a_x * d_x + a_y * d_y + azz
            cd = c_x * d_x + c_y * d_y + azz
            d1 = l1 * l2 * l3 + ab * l3 + ac * l2 + bc * l1
            d2 = l1 * l3 * l4 + ac * l4 + ad * l3 + cd * l1
            den = d1 * d2 - n1 * n2
            x = (n1 * d2 + n2 * d1) / den
            b = (d1 <= 0.0) | (d2 <= 0.0) | (den <= 0.0) | (not abs(x) <= ATAN_SERIES_MAX)
            bad[i] = b
            n_bad += b
            so[i] = 2.0 * atan_series(x)
            # d omega_t = s_t (d_t d n_t - n_t d d_t), s_t = 2 / (n_t^2 + d_t^2).
            q1 = 1.0 / l1
            q2 = 1.0 / l2
            q3 = 1.0 / l3
            q4 = 1.0 / l4
            s1 = 2.0 / (n1 * n1 + d1 * d1)
            s2 = 2.0 / (n2 * n2 + d2 * d2)
            t1 = s1 * n1
            t2 = s2 * n2
            ca = t1 * ((l2 * l3 + bc) * q1 + l2 + l3) + t2 * ((l3 * l4 + cd) * q1 + l3 + l4)
            cb = t1 * ((l1 * l3 + ac) * q2 + l1 + l3)
            cc = t1 * ((l1 * l2 + ab) * q3 + l1 + l2) + t2 * ((l1 * l4 + ad) * q3 + l1 + l4)
            cdd = t2 * ((l1 * l3 + ac) * q4 + l1 + l3)
            gox[i] = ca * a_x + cb * b_x + cc * c_x + cdd * d_x
            goy[i] = ca * a_y + cb * b_y + cc * c_y + cdd * d_y
            goz[i] = az * (ca + cb + cc + cdd) - (s1 * d1 * c1 + s2 * d2 * c2)
            mx = 0.25 * (x1 + x2 + x3 + x4) - lx
            my = 0.25 * (y1 + y2 + y3 + y4) - ly
            r = math.sqrt(mx * mx + my * my + azz)
            wxs[i] = mx / r
            wys[i] = my / r
            wzs[i] = az / r
            rs[i] = r
        if n_bad > 0:
            # Large solid angles (light near the wall): the solid angle by `quad_omega`'s
            # branches; its gradient above holds everywhere.
            for i in range(nb):
                p = i0 + i
                if bad[i] and on_wall[i] and valid[p]:
                    so[i] = wall_quad_omega_signed(corners_world, p, k, lx, ly, lz)
        # The RID and its gradient with respect to the world direction w.
        grid = rid.grid  # the grid kinds' nodes and (1 / h, s_max, s_back)
        inv_h, s_max, s_back = rid.params[2], rid.params[3], rid.params[4]
        if rid.kind == KIND_ISOTROPIC:
            for i in range(nb):
                fs[i] = 1.0
                gwx[i] = 0.0
                gwy[i] = 0.0
                gwz[i] = 0.0
        elif rid.kind == KIND_COS_POWER:
            m = rid.params[0]
            for i in range(nb):
                wx = wxs[i]
                wy = wys[i]
                wz = wzs[i]
                uz = r02 * wx + r12 * wy + r22 * wz
                f = cos_power(uz, m)
                kf = m * f / (uz if uz > 0.0 else 1.0)
                fs[i] = f
                gwx[i] = kf * (r02 - uz * wx)
                gwy[i] = kf * (r12 - uz * wy)
                gwz[i] = kf * (r22 - uz * wz)
        elif rid.kind == KIND_TABLE_1D:
            # theta by the branch-free atan2 and the gradient vectorised; the table reads
            # (gathers, which LLVM does not vectorise) in a scalar loop between them.
            knots = rid.theta_knots
            values = rid.values[0]
            slopes = rid.slopes[0]
            inv_h = rid.params[0]
            # On the axis: the limit of f_t / sin(theta), as `rid_value_grad_direction`.
            a_axis = hermite(AXIS_EPS, knots, values, slopes, inv_h)[1] / AXIS_EPS
            for i in range(nb):
                ux, uy, uz = rotate_transposed(wxs[i], wys[i], wzs[i], R9)
                theta = atan2_nonneg(math.sqrt(ux * ux + uy * uy), uz)
                fs[i] = theta if on_wall[i] & valid[i0 + i] else 0.0
            for i in range(nb):
                fs[i], gwz[i] = hermite(fs[i], knots, values, slopes, inv_h)
            for i in range(nb):
                ux, uy, uz = rotate_transposed(wxs[i], wys[i], wzs[i], R9)
                rho = math.sqrt(ux * ux + uy * uy)
                f_t = gwz[i]
                axis = rho < AXIS_RHO
                a = a_axis if axis else f_t / rho
                gux = a * uz * ux
                guy = a * uz * uy
                guz = 0.0 if axis else -f_t * rho
                ok = on_wall[i] & valid[i0 + i]
                fs[i] = fs[i] if ok else 0.0
                gwx[i] = (r00 * gux + r01 * guy + r02 * guz) if ok else 0.0
                gwy[i] = (r10 * gux + r11 * guy + r12 * guz) if ok else 0.0
                gwz[i] = (r20 * gux + r21 * guy + r22 * guz) if ok else 0.0
        elif rid.kind == KIND_TABLE_2D:
            # As the 1-D table, with the azimuth: (theta, phi, rho) vectorised into
            # (fs, gwx, gwy); the table's (f, f_t, f_p) and the axis-safe f_t / rho into
            # (fs, gwz, gwx, gwy) by a scalar pass; the gradient vectorised.
            for i in range(nb):
                ux, uy, uz = rotate_transposed(wxs[i], wys[i], wzs[i], R9)
                rho = math.sqrt(ux * ux + uy * uy)
                ok = on_wall[i] & valid[i0 + i]
                a = atan2_nonneg(abs(uy), ux)
                fs[i] = atan2_nonneg(rho, uz) if ok else 0.0
                gwx[i] = (-a if uy < 0.0 else a) if ok else 0.0
                gwy[i] = rho if ok else 1.0
            for i in range(nb):
                rho = gwy[i]
                f, f_t, f_p = table2d_value_grad(fs[i], gwx[i], rid)
                if rho < AXIS_RHO:
                    # The limit of f_t / sin(theta), as `rid_value_grad_direction`.
                    a = table2d_value_grad(AXIS_EPS, gwx[i], rid)[1] / AXIS_EPS
                else:
                    a = f_t / rho
                fs[i] = f
                gwz[i] = f_t
                gwx[i] = f_p
                gwy[i] = a
            for i in range(nb):
                ux, uy, uz = rotate_transposed(wxs[i], wys[i], wzs[i], R9)
                rho = math.sqrt(ux * ux + uy * uy)
                axis = rho < AXIS_RHO
                a = gwy[i]
                b = 0.0 if axis else gwx[i] / (rho * rho)
                gux = a * uz * ux - b * uy
                guy = a * uz * uy + b * ux
                guz = 0.0 if axis else -gwz[i] * rho
                ok = on_wall[i] & valid[i0 + i]
                fs[i] = fs[i] if ok else 0.0
                gwx[i] = (r00 * gux + r01 * guy + r02 * guz) if ok else 0.0
                gwy[i] = (r10 * gux + r11 * guy + r12 * guz) if ok else 0.0
                gwz[i] = (r20 * gux + r21 * guy + r22 * guz) if ok else 0.0
        elif rid.kind == KIND_GRID_1D:
            # The grid coordinate and the gradient g (R e_z - uz w) vectorised (as cos^m),
            # the grid's (f, g = df/duz) in a scalar pass.
            n = grid.shape[1] - 1
            for i in range(nb):
                uz = r02 * wxs[i] + r12 * wys[i] + r22 * wzs[i]
                fs[i] = grid1d_coord(uz, n, inv_h, s_max, s_back)
            for i in range(nb):
                fs[i], gwz[i] = grid1d_interp(fs[i], grid, inv_h)
            for i in range(nb):
                wx = wxs[i]
                wy = wys[i]
                wz = wzs[i]
                uz = r02 * wx + r12 * wy + r22 * wz
                g = gwz[i]
                ok = on_wall[i] & valid[i0 + i]
                fs[i] = fs[i] if ok else 0.0
                gwx[i] = g * (r02 - uz * wx) if ok else 0.0
                gwy[i] = g * (r12 - uz * wy) if ok else 0.0
                gwz[i] = g * (r22 - uz * wz) if ok else 0.0
        elif rid.kind == KIND_GRID_2D:
            # The grid coordinates and the gradient (`grid2d_gradient`, rotated to the
            # world) vectorised, the grid's (f, df/dpx, df/dpy) in a scalar pass.
            n = grid.shape[1]
            for i in range(nb):
                ux, uy, uz = rotate_transposed(wxs[i], wys[i], wzs[i], R9)
                gwx[i], gwy[i] = grid2d_coords(ux, uy, uz, n, inv_h, s_max, s_back)
            for i in range(nb):
                fs[i], gwx[i], gwy[i] = grid2d_interp(gwx[i], gwy[i], grid, inv_h)
            for i in range(nb):
                ux, uy, uz = rotate_transposed(wxs[i], wys[i], wzs[i], R9)
                gux, guy, guz = grid2d_gradient(gwx[i], gwy[i], ux, uy, uz)
                ok = on_wall[i] & valid[i0 + i]
                fs[i] = fs[i] if ok else 0.0
                gwx[i] = (r00 * gux + r01 * guy + r02 * guz) if ok else 0.0
                gwy[i] = (r10 * gux + r11 * guy + r12 * guz) if ok else 0.0
                gwz[i] = (r20 * gux + r21 * guy + r22 * guz) if ok else 0.0
        else:
            for i in range(nb):
                if not (on_wall[i] and valid[i0 + i]):
                    fs[i] = 0.0
                    gwx[i] = 0.0
                    gwy[i] = 0.0
                    gwz[i] = 0.0
                    continue
                ux, uy, uz = rotate_transposed(wxs[i], wys[i], wzs[i], R9)
                f, gux, guy, guz = rid_value_grad_direction(ux, uy, uz, rid)
                fs[i] = f
                gwx[i] = r00 * gux + r01 * guy + r02 * guz
                gwy[i] = r10 * gux + r11 * guy + r12 * guz
                gwz[i] = r20 * gux + r21 * guy + r22 * guz
        # Accumulate weight_k Omega f and its gradient (signs as in `quad_flux`).
        for i in range(nb):
            wt = wts[i]
            s = so[i]
            omega = abs(s)
            f = fs[i]
            fsg = -f if s < 0.0 else f
            o_r = omega / rs[i]
            wx = wxs[i]
            wy = wys[i]
            wz = wzs[i]
            gx = gwx[i]
            gy = gwy[i]
            gz = gwz[i]
            acc[i] += wt * (omega * f)
            # d f / d L = -gw / r (gw tangential); d f / d delta = gw x w.
            ag0[i] += wt * (fsg * gox[i] - o_r * gx)
            ag1[i] += wt * (fsg * goy[i] - o_r * gy)
            ag2[i] += wt * (fsg * goz[i] - o_r * gz)
            ag3[i] += wt * (omega * (gy * wz - gz * wy))
            ag4[i] += wt * (omega * (gz * wx - gx * wz))
            ag5[i] += wt * (omega * (gx * wy - gy * wx))
    n_off = 0
    for i in range(nb):
        p = i0 + i
        ok = valid[p]
        out_flux[p] = acc[i] if ok else 0.0
        out_grad[p, 0] = ag0[i] if ok else 0.0
        out_grad[p, 1] = ag1[i] if ok else 0.0
        out_grad[p, 2] = ag2[i] if ok else 0.0
        out_grad[p, 3] = ag3[i] if ok else 0.0
        out_grad[p, 4] = ag4[i] if ok else 0.0
        out_grad[p, 5] = ag5[i] if ok else 0.0
        n_off += ok & (not on_wall[i])
    return n_off


@numba.njit(cache=True)
def wall_grad_range(
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
    """`flux_pixels` with gradients and n = 1 for pixels i0 .. i1 - 1, block by block."""
    scratch = np.empty((_N_SCRATCH, GRAD_BLOCK))
    flags = np.empty((2, GRAD_BLOCK), dtype=np.bool_)
    on_wall = flags[0]
    # Typed values, not literals: numba would compile `pixel_flux_range` again for
    # Literal[int](1) and the literal booleans.
    n_sub = int(1)  # noqa: UP018, RUF046 (not a literal type)
    want_grad = bool(True)  # noqa: UP018 (not a literal type)
    allow_fast = bool(False)  # noqa: UP018 (not a literal type)
    for b0 in range(i0, i1, GRAD_BLOCK):
        b1 = min(b0 + GRAD_BLOCK, i1)
        n_off = wall_grad_block(
            b0,
            b1,
            corners_world,
            weights,
            valid,
            light_world,
            R_world_light,
            rid,
            scratch,
            flags,
            out_flux,
            out_grad,
        )
        if n_off == 0:
            continue
        for i in range(b0, b1):
            if valid[i] and not on_wall[i - b0]:
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
