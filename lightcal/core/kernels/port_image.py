"""`render_image_port_fused`: a whole (binned) image seen through the camera's flat port
in one parallel pass (`lightcal.core.port_render.render_image_through_port`).

The fused kernel of `kernels.image` with the corners of the camera's port lattice
(`lightcal.core.port_footprints.camera_port_rays`: each pixel corner's exit point X_p
from the port and its direction in the water, camera frame, traced once per camera and
port) in place of the straight back-projected rays. Per pixel row:

1. each corner row is moved to the world (X_p = R^T X_c + C, w = R^T w_c) and met with
   the wall z = 0 once (`port_corner_row`); each corner serves four pixels;
2. each light's flux on the pixels' quads is `kernels.image`'s row helpers' (the same
   solid angles and RID, any RID kind, RID sub-sampling);
3. each (super-)pixel's sensor weight is the port's (docs/model.md, "The camera's flat
   port"): its pixels' sensor terms (`radiance` 1, `cos4` the fall-off in the air, `map`
   V) times the port's Fresnel transmittance of their rays, over the footprint's area;
4. per light, the wall's B and the medium's T at the footprint centre P (the mean of its
   quads' corners), the camera side of both taken from the mean exit point X_p of the
   pixel's corners (the viewing direction P -> X_p, the path |P - X_p|); and the veil,
   the single-scattering integral S along the refracted ray from X_p to P
   (`kernels.backscatter.ray_integral`) times the pixel's mean Fresnel transmittance.
   S is exact on the nodes of `medium.scatter_grid` (`port_veil_nodes`, a pass before
   the image's) and interpolated bilinearly between them by the in-air image's code
   (`kernels.backscatter.grid_bracket`, `bilinear`), exact beside an invalid node.

The numbers are those of every pixel's footprint through the port shaded by
`lightcal.core.render.shade` (`port_render.render_image_per_pixel_through_port`), to
round-off, but for the veil between the nodes (`tests/test_port_fused.py`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from lightcal.core.kernels.backscatter import bilinear, grid_bracket, ray_integral
from lightcal.core.kernels.fastmath import exp_real
from lightcal.core.kernels.image import flux_row, light_vectors_row, sensor_row
from lightcal.core.kernels.sensor import quad_area, view_scalars
from lightcal.core.kernels.wall import KIND_LAMBERTIAN, point_factor
from lightcal.core.rid_stack import RIDStack, light_rid


@numba.njit(cache=True, inline="always", error_model="numpy")
def port_corner_row(
    exits_camera: np.ndarray,
    dirs_camera: np.ndarray,
    corner_ok: np.ndarray,
    j: int,
    view: tuple[float, ...],
    px: np.ndarray,
    py: np.ndarray,
    ok: np.ndarray,
    ex: np.ndarray,
    ey: np.ndarray,
    ez: np.ndarray,
) -> None:
    """Wall points (px, py), hit flags `ok` and exit points (ex, ey, ez), world frame, m,
    of the port lattice's corners (j, 0..n-1), n = px.shape[0].

    X_p = R^T X_c + C and w = R^T w_c (`view`: `view_scalars`); the corner meets the wall
    at X_p + lambda w, lambda = -X_p,z / w_z, when it went through the port, w_z < 0 and
    0 < lambda < inf (`port_footprints.wall_hits`). Missed corners get (0, 0) and an exit
    (0, 0, 0): finite, so that the vectorised pixel loops run through them.
    """
    r00, r01, r02, r10, r11, r12, r20, r21, r22, c0, c1, c2 = view
    for u in range(px.shape[0]):
        xc = exits_camera[j, u, 0]
        yc = exits_camera[j, u, 1]
        zc = exits_camera[j, u, 2]
        dxc = dirs_camera[j, u, 0]
        dyc = dirs_camera[j, u, 1]
        dzc = dirs_camera[j, u, 2]
        xw = xc * r00 + yc * r10 + zc * r20 + c0
        yw = xc * r01 + yc * r11 + zc * r21 + c1
        zw = xc * r02 + yc * r12 + zc * r22 + c2
        dx = dxc * r00 + dyc * r10 + dzc * r20
        dy = dxc * r01 + dyc * r11 + dzc * r21
        dz = dxc * r02 + dyc * r12 + dzc * r22
        lam = -zw / dz
        hit = corner_ok[j, u] & (dz < 0.0) & (lam > 0.0) & (lam < math.inf)
        px[u] = xw + lam * dx if hit else 0.0
        py[u] = yw + lam * dy if hit else 0.0
        ok[u] = hit
        ex[u] = xw if hit else 0.0
        ey[u] = yw if hit else 0.0
        ez[u] = zw if hit else 0.0


@numba.njit(cache=True, inline="always", error_model="numpy")
def add_centre_sums(
    b: int,
    wb: int,
    tpx: np.ndarray,
    tpy: np.ndarray,
    tex: np.ndarray,
    bpx: np.ndarray,
    bpy: np.ndarray,
    bex: np.ndarray,
    centres: np.ndarray,
) -> None:
    """centres (5, wb) += the sums of the wall points (x, y) and exit points (x, y, z) of
    the corners of a row of pixels' quads, per super-pixel (top corners t, bottom b)."""
    if b == 1:  # the same sums, in loops the compiler vectorises
        for c in range(wb):
            centres[0, c] += tpx[c] + tpx[c + 1] + bpx[c + 1] + bpx[c]
            centres[1, c] += tpy[c] + tpy[c + 1] + bpy[c + 1] + bpy[c]
        for k in range(3):
            for c in range(wb):
                centres[2 + k, c] += tex[k, c] + tex[k, c + 1] + (bex[k, c + 1] + bex[k, c])
        return
    for c in range(wb):
        for ii in range(b):
            u = c * b + ii
            centres[0, c] += tpx[u] + tpx[u + 1] + bpx[u + 1] + bpx[u]
            centres[1, c] += tpy[u] + tpy[u + 1] + bpy[u + 1] + bpy[u]
            for k in range(3):
                centres[2 + k, c] += tex[k, u] + tex[k, u + 1] + (bex[k, u + 1] + bex[k, u])


@numba.njit(cache=True, parallel=True, error_model="numpy")
def port_veil_nodes(
    exits_camera: np.ndarray,
    dirs_camera: np.ndarray,
    corner_ok: np.ndarray,
    R_camera_world: np.ndarray,
    center_world: np.ndarray,
    binning: int,
    node_rows: np.ndarray,
    node_cols: np.ndarray,
    lights_world: np.ndarray,
    R_world_lights: np.ndarray,
    rids: RIDStack,
    c_per_m: float,
    phase_g: float,
    s_nodes: np.ndarray,
    s_weights: np.ndarray,
    out: np.ndarray,
) -> None:
    """out (L, m, n): each light's veil integral S at the (super-)pixels node_rows (m,)
    x node_cols (n,) (`medium.scatter_grid`'s), the footprint centre and mean exit point
    summed as `render_image_port_fused` sums them (the same numbers); NaN at a node
    whose footprint is invalid. Arguments as `render_image_port_fused`'s."""
    b = binning
    wb = (exits_camera.shape[1] - 1) // b
    w = wb * b
    m = node_rows.shape[0]
    n = node_cols.shape[0]
    view = view_scalars(R_camera_world, center_world)
    norm = 1.0 / (4.0 * b * b)
    for i in numba.prange(m):
        r = node_rows[i]
        px = np.empty((2, w + 1))
        py = np.empty((2, w + 1))
        cok = np.empty((2, w + 1), dtype=np.bool_)
        exits = np.empty((2, 3, w + 1))
        sp_ok = np.ones(wb, dtype=np.bool_)
        centres = np.zeros((5, wb))
        camera = np.empty(3)
        g8 = np.zeros(8)
        top = 0
        port_corner_row(
            exits_camera, dirs_camera, corner_ok, r * b, view,
            px[0], py[0], cok[0], exits[0, 0], exits[0, 1], exits[0, 2],
        )  # fmt: skip
        for jj in range(b):
            bot = 1 - top
            port_corner_row(
                exits_camera, dirs_camera, corner_ok, r * b + jj + 1, view,
                px[bot], py[bot], cok[bot], exits[bot, 0], exits[bot, 1], exits[bot, 2],
            )  # fmt: skip
            for u in range(w):
                sp_ok[u // b] &= cok[top, u] & cok[top, u + 1] & cok[bot, u + 1] & cok[bot, u]
            add_centre_sums(
                b, wb, px[top], py[top], exits[top], px[bot], py[bot], exits[bot], centres
            )
            top = bot
        for li in range(lights_world.shape[0]):
            rid = light_rid(rids, li)
            for j in range(n):
                col = node_cols[j]
                if not sp_ok[col]:
                    out[li, i, j] = np.nan
                    continue
                for k in range(3):
                    camera[k] = centres[2 + k, col] * norm
                out[li, i, j] = ray_integral(
                    centres[0, col] * norm, centres[1, col] * norm, 0.0, camera,
                    lights_world[li], R_world_lights[li], rid, c_per_m, phase_g,
                    s_nodes, s_weights, False, g8,
                )  # fmt: skip


@numba.njit(cache=True, inline="always", error_model="numpy")
def _light_factors(
    wb: int,
    light: np.ndarray,
    c_per_m: float,
    wall_kind: int,
    wall_params: np.ndarray,
    wall_tables: np.ndarray,
    centres: np.ndarray,
    factor: np.ndarray,
    camera: np.ndarray,
    exponent: np.ndarray,
) -> None:
    """factor (wb,) *= B x T of one light at the footprint centres of a row of
    super-pixels. centres: (5, wb) the centres' x, y and the mean exit points' x, y, z;
    camera: (3,) and exponent: (wb,) scratch."""
    lx, ly, lz = light[0], light[1], light[2]
    if wall_kind != KIND_LAMBERTIAN:
        for c in range(wb):
            camera[0] = centres[2, c]
            camera[1] = centres[3, c]
            camera[2] = centres[4, c]
            factor[c] *= point_factor(
                centres[0, c], centres[1, c], light, camera, wall_kind, wall_params, wall_tables
            )
    if c_per_m > 0.0:
        # T = exp(-c (|P - L| + |P - X_p|)): two loops, each vectorised (one loop with
        # exp inline is not).
        for c in range(wb):
            ax = centres[0, c] - lx
            ay = centres[1, c] - ly
            vx = centres[0, c] - centres[2, c]
            vy = centres[1, c] - centres[3, c]
            vz = centres[4, c]
            path = math.sqrt(ax * ax + ay * ay + lz * lz) + math.sqrt(vx * vx + vy * vy + vz * vz)
            exponent[c] = -c_per_m * path
        for c in range(wb):
            factor[c] *= exp_real(exponent[c])


@numba.njit(cache=True, parallel=True, error_model="numpy")
def render_image_port_fused(
    exits_camera: np.ndarray,
    dirs_camera: np.ndarray,
    grid_xy: np.ndarray,
    corner_ok: np.ndarray,
    fresnel: np.ndarray,
    R_camera_world: np.ndarray,
    center_world: np.ndarray,
    sensor: int,
    vignetting: np.ndarray,
    binning: int,
    lights_world: np.ndarray,
    R_world_lights: np.ndarray,
    light_scales: np.ndarray,
    rids: RIDStack,
    n_sub: int,
    exposure: float,
    offset: float,
    wall_kind: int,
    wall_params: np.ndarray,
    wall_tables: np.ndarray,
    medium: np.ndarray,
    s_nodes: np.ndarray,
    s_weights: np.ndarray,
    node_rows: np.ndarray,
    node_cols: np.ndarray,
    veil_nodes: np.ndarray,
    out: np.ndarray,
    out_invalid: np.ndarray,
) -> None:
    """Whole (binned) image of a rig through the camera's flat port in one pass; the
    first five arguments are `port_footprints.camera_port_rays`'.

    Args:
        exits_camera, dirs_camera: (H+1, W+1, 3) every pixel corner's exit point from the
            port (m) and unit direction in the water, camera frame (NaN where not ok).
        grid_xy: (H+1, W+1, 2) their undistorted normalised coordinates (`cos4`'s).
        corner_ok: (H+1, W+1) corners undistorted and through the port.
        fresnel: (H, W) the port's Fresnel transmittance of every pixel's rays.
        R_camera_world: (3, 3); center_world: (3,) camera centre, world frame, m.
        sensor: SENSOR_RADIANCE, SENSOR_COS4 or SENSOR_MAP; vignetting: (H, W) map for
            SENSOR_MAP, else (1, 1).
        binning: b, super-pixel side in pixels.
        lights_world: (L, 3) emitter positions, world frame, m; a light with z <= 0
            lights nothing, its veil included (as `render.shade` and air's image).
        R_world_lights: (L, 3, 3) light orientations; light_scales: (L,) scales.
        rids: the lights' RIDs (`stack_rid_data`); n_sub: RID sub-sampling per side.
        exposure: the view's gain; offset: added to every valid value.
        wall_kind, wall_params, wall_tables: the wall model (`WallReflectance.data()`).
        medium: (3,) c (1/m), the backscatter coefficient beta (1/m) and the phase
            function's g.
        s_nodes, s_weights: the veil's Gauss-Legendre nodes and weights on [0, 1].
        node_rows (m,), node_cols (n,): `medium.scatter_grid`'s nodes; veil_nodes:
            (L, m, n) S there (`port_veil_nodes`), interpolated between them (exact
            beside a NaN); unused (any shape) without backscatter.
        out: (H // b, W // b) written: offset + exposure sum_l scale_l (B_l T_l sum_k
            w_k Phi_k / I0 + beta S_l t), t the mean Fresnel transmittance, NaN where
            invalid; S_l interpolated from veil_nodes.
        out_invalid: (H // b, W // b) written: True where some corner misses the wall.
    """
    hb = out.shape[0]
    wb = out.shape[1]
    b = binning
    bb = b * b
    w = wb * b
    n_l = lights_world.shape[0]
    n_chunks = min(hb, 64)
    view = view_scalars(R_camera_world, center_world)
    c_per_m, beta, phase_g = medium[0], medium[1], medium[2]
    per_light = wall_kind != KIND_LAMBERTIAN or c_per_m > 0.0
    need_points = per_light or beta > 0.0
    norm = 1.0 / (4.0 * bb)
    for ch in numba.prange(n_chunks):
        r_begin = ch * hb // n_chunks
        r_end = (ch + 1) * hb // n_chunks
        px = np.empty((2, w + 1))
        py = np.empty((2, w + 1))
        cok = np.empty((2, w + 1), dtype=np.bool_)
        exits = np.empty((2, 3, w + 1))
        ax = np.empty((2, n_l, w + 1))
        ay = np.empty((2, n_l, w + 1))
        la = np.empty((2, n_l, w + 1))
        ok_row = np.empty(w, dtype=np.bool_)
        om_row = np.empty(w)
        f_rows = np.empty((3, w))
        bad_row = np.empty(w, dtype=np.bool_)
        acc_row = np.empty(w)
        v_row = np.empty(w)
        sp_phi = np.empty((n_l, wb))
        sp_area = np.empty(wb)
        sp_v = np.empty(wb)
        sp_t = np.empty(wb)
        sp_ok = np.empty(wb, dtype=np.bool_)
        centres = np.empty((5, wb))  # sums, then the centres' x, y and exits' x, y, z
        factor = np.empty(wb)
        exponent = np.empty(wb)
        total = np.empty(wb)
        camera = np.empty(3)
        q = np.zeros((4, 3))
        gdummy = np.zeros(6)
        g8 = np.zeros(8)
        top = 0
        i, i1, fy = 0, 0, 0.0  # the veil's nodes about row r (`grid_bracket`)
        ex0 = exits[0]
        port_corner_row(
            exits_camera, dirs_camera, corner_ok, r_begin * b, view,
            px[0], py[0], cok[0], ex0[0], ex0[1], ex0[2],
        )  # fmt: skip
        for li in range(n_l):
            lw = lights_world[li]
            light_vectors_row(px[0], py[0], lw[0], lw[1], lw[2], ax[0, li], ay[0, li], la[0, li])
        for r in range(r_begin, r_end):
            sp_phi[:] = 0.0
            sp_area[:] = 0.0
            sp_v[:] = 0.0
            sp_t[:] = 0.0
            sp_ok[:] = True
            centres[:] = 0.0
            for jj in range(b):
                v = r * b + jj
                bot = 1 - top
                tpx, tpy, tok, tex = px[top], py[top], cok[top], exits[top]
                bpx, bpy, bok, bex = px[bot], py[bot], cok[bot], exits[bot]
                port_corner_row(
                    exits_camera, dirs_camera, corner_ok, v + 1, view,
                    bpx, bpy, bok, bex[0], bex[1], bex[2],
                )  # fmt: skip
                # Geometry: validity, area and sensor weight (times the port's Fresnel
                # transmittance) of each pixel of row v, summed into its super-pixel.
                sensor_row(sensor, grid_xy, vignetting, v, tpx, tpy, bpx, bpy, view, bb, v_row)
                for u in range(w):
                    ok_row[u] = tok[u] & tok[u + 1] & bok[u + 1] & bok[u]
                if b == 1:  # the same sums, in loops the compiler vectorises
                    for u in range(w):
                        sp_ok[u] = ok_row[u]
                        sp_area[u] = quad_area(
                            tpx[u], tpy[u], tpx[u + 1], tpy[u + 1],
                            bpx[u + 1], bpy[u + 1], bpx[u], bpy[u],
                        )  # fmt: skip
                        sp_v[u] = v_row[u] * fresnel[v, u]
                        sp_t[u] = fresnel[v, u]
                for c in range(wb if b > 1 else 0):
                    for ii in range(b):
                        u = c * b + ii
                        sp_ok[c] &= ok_row[u]
                        sp_area[c] += quad_area(
                            tpx[u], tpy[u], tpx[u + 1], tpy[u + 1],
                            bpx[u + 1], bpy[u + 1], bpx[u], bpy[u],
                        )  # fmt: skip
                        sp_v[c] += v_row[u] * fresnel[v, u]
                        sp_t[c] += fresnel[v, u]
                if need_points:  # the footprint centres and the mean exit points
                    add_centre_sums(b, wb, tpx, tpy, tex, bpx, bpy, bex, centres)
                for li in range(n_l):
                    lw = lights_world[li]
                    if lw[2] <= 0.0:
                        continue  # on or behind the wall: it lights nothing
                    light_vectors_row(
                        bpx, bpy, lw[0], lw[1], lw[2], ax[bot, li], ay[bot, li], la[bot, li]
                    )
                    acc_row[:] = 0.0
                    flux_row(
                        tpx, tpy, bpx, bpy,
                        ax[top, li], ay[top, li], la[top, li],
                        ax[bot, li], ay[bot, li], la[bot, li],
                        lw, R_world_lights[li], light_rid(rids, li), n_sub, 1.0,
                        ok_row, om_row, f_rows, bad_row, q, gdummy, acc_row,
                    )  # fmt: skip
                    if b == 1:
                        sp_phi[li, :] = acc_row
                    else:
                        for c in range(wb):
                            for ii in range(b):
                                sp_phi[li, c] += acc_row[c * b + ii]
                top = bot
            # The super-pixels of row r: weight, B and T per light, the veil, the value.
            if beta > 0.0:
                i, i1, fy = grid_bracket(node_rows, i, r)
            for c in range(wb):
                total[c] = 0.0
                for k in range(5):
                    centres[k, c] *= norm
                sp_v[c] = (sp_v[c] / bb) / sp_area[c]  # the sensor weight
            for li in range(n_l):
                lw = lights_world[li]
                scale = light_scales[li]
                if lw[2] > 0.0:
                    for c in range(wb):
                        factor[c] = sp_v[c] * sp_phi[li, c]
                    if per_light:
                        _light_factors(
                            wb, lw, c_per_m, wall_kind, wall_params, wall_tables,
                            centres, factor, camera, exponent,
                        )  # fmt: skip
                    for c in range(wb):
                        total[c] += scale * factor[c]
                if beta > 0.0 and lw[2] > 0.0:  # behind the wall: no veil either
                    k_veil = scale * beta / bb
                    j = 0
                    for c in range(wb):
                        if sp_ok[c]:
                            j, j1, fx = grid_bracket(node_cols, j, c)
                            s = bilinear(veil_nodes[li], i, i1, fy, j, j1, fx)
                            if not math.isfinite(s):  # beside an invalid node: exact
                                camera[0] = centres[2, c]
                                camera[1] = centres[3, c]
                                camera[2] = centres[4, c]
                                s = ray_integral(
                                    centres[0, c], centres[1, c], 0.0, camera, lw,
                                    R_world_lights[li], light_rid(rids, li), c_per_m,
                                    phase_g, s_nodes, s_weights, False, g8,
                                )  # fmt: skip
                            total[c] += k_veil * (s * sp_t[c])
            for c in range(wb):
                okc = sp_ok[c]
                out[r, c] = offset + exposure * total[c] if okc else np.nan
                out_invalid[r, c] = not okc
