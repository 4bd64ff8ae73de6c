"""`render_image_fused`: a whole (binned) image of a rig of lights in one parallel pass.

Over 500 lines for a reason: the fused kernel and the row helpers it inlines belong
together (the wall factor is applied inside its light loop).

What `render.render_image` calls: the model of docs/model.md (the flux of each pixel's
footprint quad, `kernels.quad_flux`, times its sensor weight, `kernels.sensor`) for
every pixel, with less work per pixel than `flux_pixels` on the image's footprints.
Chunks of pixel rows run in parallel; per pixel row:

1. each corner row is back-projected once (each corner serves four pixels), and per
   light a = P - L and |a| are stored per corner (one square root per corner, not six
   per pixel);
2. the wall is z = 0, so the Van Oosterom-Strackee numerator a.((b - a) x (c - a)) is
   a_z (e1 x e2)_z exactly (`quad_terms`);
3. a quad's two triangles take one arctangent, by its odd series (`omega_series`);
   pixels outside the series' range (large solid angles) are flagged and redone by
   `quad_omega`;
4. cos^m is exp(m ln cos theta) by the branch-free `cos_power`, so that LLVM vectorises
   the pixel loop (error_model="numpy" removes the division-by-zero checks that
   otherwise block vectorisation);
5. the final value (offset + gain x flux, NaN where invalid) and the mask are written
   directly: no NumPy passes over the image afterwards.

The row helpers (`light_vectors_row`, `flux_row`, `sensor_row`) serve the image through
the camera's flat port too (`kernels.port_image`), whose corners come from the port.

Other RIDs (Gaussian, tables) take a scalar loop that needs theta = atan2(rho, u_z) per
pixel: correct, several times slower than cos^m. The numbers are those of the plain
kernels (`tests/kernel_reference.py`) and of the NumPy reference to ~1e-15 relative.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from lightcal.core.kernels.fastmath import atan2_nonneg, cos_power, rotate_transposed
from lightcal.core.kernels.quad_flux import quad_flux
from lightcal.core.kernels.sensor import (
    SENSOR_COS4,
    SENSOR_MAP,
    SENSOR_PAPER,
    cos4,
    paper_weight,
    quad_area,
    view_scalars,
    wall_point,
)
from lightcal.core.kernels.solid_angle import omega_series, quad_omega, quad_terms
from lightcal.core.kernels.wall import KIND_LAMBERTIAN, add_factor_row, point_factor
from lightcal.core.rid_eval import (
    KIND_COS_POWER,
    KIND_GRID_1D,
    KIND_GRID_2D,
    KIND_ISOTROPIC,
    KIND_TABLE_1D,
    KIND_TABLE_2D,
    RIDData,
    hermite,
    rid_value_direction,
    table2d_value_grad,
)
from lightcal.core.rid_grid import (
    grid1d_coord,
    grid1d_interp,
    grid2d_cell,
    grid2d_coords,
    grid2d_values_row,
)
from lightcal.core.rid_stack import RIDStack, light_rid


@numba.njit(cache=True, inline="always", error_model="numpy")
def _corner_row(
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
    j: int,
    n: int,
    view: tuple[float, ...],
    px: np.ndarray,
    py: np.ndarray,
    ok: np.ndarray,
) -> None:
    """Wall points (px, py) and hit flags of corners (j, 0..n-1) (`wall_point`).

    Missed corners get (0, 0): finite, so that the vectorised pixel loops run through them.
    """
    for u in range(n):
        x = grid_xy[j, u, 0]
        y = grid_xy[j, u, 1]
        px[u], py[u], ok[u] = wall_point(x, y, grid_ok[j, u], view, False)


@numba.njit(cache=True, inline="always", error_model="numpy")
def light_vectors_row(
    px: np.ndarray,
    py: np.ndarray,
    lx: float,
    ly: float,
    lz: float,
    ax: np.ndarray,
    ay: np.ndarray,
    la: np.ndarray,
) -> None:
    """a = P - L (x, y components; a_z = -lz) and |a| for a row of corners."""
    az = 0.0 - lz
    azz = az * az
    for u in range(px.shape[0]):
        tx = px[u] - lx
        ty = py[u] - ly
        ax[u] = tx
        ay[u] = ty
        la[u] = math.sqrt(tx * tx + ty * ty + azz)


@numba.njit(cache=True, inline="always", error_model="numpy")
def _pixel_terms(
    tpx: np.ndarray,
    tpy: np.ndarray,
    bpx: np.ndarray,
    bpy: np.ndarray,
    tax: np.ndarray,
    tay: np.ndarray,
    tla: np.ndarray,
    bax: np.ndarray,
    bay: np.ndarray,
    bla: np.ndarray,
    u: int,
    az: float,
) -> tuple[float, float, float, float, float, float]:
    """Triangle terms (n1, d1, n2, d2) and the centroid (mx, my) of pixel u of a row.

    Corners P1 = top[u], P2 = top[u + 1], P3 = bottom[u + 1], P4 = bottom[u] (the cyclic
    order of `pixel_footprints`).
    """
    x1 = tpx[u]
    y1 = tpy[u]
    x2 = tpx[u + 1]
    y2 = tpy[u + 1]
    x3 = bpx[u + 1]
    y3 = bpy[u + 1]
    x4 = bpx[u]
    y4 = bpy[u]
    n1, d1, n2, d2 = quad_terms(
        x1, y1, x2, y2, x3, y3, x4, y4,
        tax[u], tay[u], tla[u], tax[u + 1], tay[u + 1], tla[u + 1],
        bax[u + 1], bay[u + 1], bla[u + 1], bax[u], bay[u], bla[u], az,
    )  # fmt: skip
    mx = 0.25 * (x1 + x2 + x3 + x4)
    my = 0.25 * (y1 + y2 + y3 + y4)
    return n1, d1, n2, d2, mx, my


@numba.njit(cache=True, inline="always", error_model="numpy")
def _centroid_dir_light(
    tpx: np.ndarray,
    tpy: np.ndarray,
    bpx: np.ndarray,
    bpy: np.ndarray,
    u: int,
    lx: float,
    ly: float,
    az: float,
    R9: tuple[float, float, float, float, float, float, float, float, float],
) -> tuple[float, float, float]:
    """Unit direction from the light to pixel u's footprint centroid, in the light frame.

    R9 is R_world_light by columns (r00, r10, r20, r01, r11, r21, r02, r12, r22).
    """
    mx = 0.25 * (tpx[u] + tpx[u + 1] + bpx[u + 1] + bpx[u]) - lx
    my = 0.25 * (tpy[u] + tpy[u + 1] + bpy[u + 1] + bpy[u]) - ly
    inv = 1.0 / math.sqrt(mx * mx + my * my + az * az)  # one division, not three
    return rotate_transposed(mx * inv, my * inv, az * inv, R9)


@numba.njit(cache=True, error_model="numpy")
def flux_row(
    tpx: np.ndarray,
    tpy: np.ndarray,
    bpx: np.ndarray,
    bpy: np.ndarray,
    tax: np.ndarray,
    tay: np.ndarray,
    tla: np.ndarray,
    bax: np.ndarray,
    bay: np.ndarray,
    bla: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid: RIDData,
    n_sub: int,
    scale: float,
    ok_row: np.ndarray,
    om_row: np.ndarray,
    f_rows: np.ndarray,
    bad_row: np.ndarray,
    q: np.ndarray,
    gdummy: np.ndarray,
    acc_row: np.ndarray,
) -> None:
    """Add scale * Phi / I0 of one light to acc_row (w,) for the pixels of a row.

    Only pixels with ok_row set are guaranteed; the others may receive any value.
    f_rows: (3, w) scratch (the RID per pixel; the azimuth of 2-D tables or the row and
    cell number of their grid).
    """
    w = acc_row.shape[0]
    f_row = f_rows[0]
    lx = light_world[0]
    ly = light_world[1]
    lz = light_world[2]
    az = 0.0 - lz
    r02 = R_world_light[0, 2]
    r12 = R_world_light[1, 2]
    r22 = R_world_light[2, 2]
    kind = rid.kind
    if n_sub > 1:
        for u in range(w):
            if ok_row[u]:
                q[0, 0] = tpx[u]
                q[0, 1] = tpy[u]
                q[1, 0] = tpx[u + 1]
                q[1, 1] = tpy[u + 1]
                q[2, 0] = bpx[u + 1]
                q[2, 1] = bpy[u + 1]
                q[3, 0] = bpx[u]
                q[3, 1] = bpy[u]
                phi = quad_flux(q, lx, ly, lz, R_world_light, rid, n_sub, False, gdummy)
                acc_row[u] += scale * phi
        return
    n_bad = 0
    if kind == KIND_ISOTROPIC:
        for u in range(w):
            n1, d1, n2, d2, mx, my = _pixel_terms(
                tpx, tpy, bpx, bpy, tax, tay, tla, bax, bay, bla, u, az
            )
            om, bad = omega_series(n1, d1, n2, d2)
            acc_row[u] += 0.0 if bad else scale * om
            f_row[u] = 1.0
            bad_row[u] = bad
            n_bad += bad
    elif kind == KIND_COS_POWER:
        # Two loops: one loop with cos_power inline spills registers and runs slower.
        m = rid.params[0]
        for u in range(w):
            n1, d1, n2, d2, mx, my = _pixel_terms(
                tpx, tpy, bpx, bpy, tax, tay, tla, bax, bay, bla, u, az
            )
            om, bad = omega_series(n1, d1, n2, d2)
            mx = mx - lx
            my = my - ly
            rr = math.sqrt(mx * mx + my * my + az * az)
            f_row[u] = (r02 * mx + r12 * my + r22 * az) / rr  # cos(theta)
            om_row[u] = 0.0 if bad else om
            bad_row[u] = bad
            n_bad += bad
        for u in range(w):
            f = cos_power(f_row[u], m)
            acc_row[u] += scale * (om_row[u] * f)
            f_row[u] = f
    else:
        for u in range(w):
            n1, d1, n2, d2, mx, my = _pixel_terms(
                tpx, tpy, bpx, bpy, tax, tay, tla, bax, bay, bla, u, az
            )
            om_row[u], bad = omega_series(n1, d1, n2, d2)
            bad_row[u] = bad
            n_bad += bad
        R9 = (
            R_world_light[0, 0], R_world_light[1, 0], R_world_light[2, 0],
            R_world_light[0, 1], R_world_light[1, 1], R_world_light[2, 1],
            r02, r12, r22,
        )  # fmt: skip
        grid = rid.grid  # the grid kinds' nodes and (1 / h, s_max, s_back)
        inv_h, s_max, s_back = rid.params[2], rid.params[3], rid.params[4]
        if kind == KIND_TABLE_1D:
            # The angle from the axis (branch-free atan2, vectorised); the table reads
            # are gathers, which LLVM does not vectorise: a loop of their own.
            for u in range(w):
                ux, uy, uz = _centroid_dir_light(tpx, tpy, bpx, bpy, u, lx, ly, az, R9)
                f_row[u] = atan2_nonneg(math.sqrt(ux * ux + uy * uy), uz)
            knots = rid.theta_knots
            values = rid.values[0]
            slopes = rid.slopes[0]
            inv_h = rid.params[0]
            for u in range(w):
                f_row[u] = hermite(f_row[u], knots, values, slopes, inv_h)[0]
        elif kind == KIND_TABLE_2D:
            # Both angles vectorised (the azimuth by atan2_nonneg and the sign of uy),
            # the table (four rows around the azimuth) in a scalar pass.
            phi_row = f_rows[1]
            for u in range(w):
                ux, uy, uz = _centroid_dir_light(tpx, tpy, bpx, bpy, u, lx, ly, az, R9)
                f_row[u] = atan2_nonneg(math.sqrt(ux * ux + uy * uy), uz)
                a = atan2_nonneg(abs(uy), ux)
                phi_row[u] = -a if uy < 0.0 else a
            for u in range(w):
                f_row[u] = table2d_value_grad(f_row[u], phi_row[u], rid)[0]
        elif kind == KIND_GRID_1D:
            # The grid coordinate vectorised, the grid's gathers in a scalar pass.
            n = grid.shape[1] - 1
            for u in range(w):
                uz = _centroid_dir_light(tpx, tpy, bpx, bpy, u, lx, ly, az, R9)[2]
                f_row[u] = grid1d_coord(uz, n, inv_h, s_max, s_back)
            for u in range(w):
                f_row[u] = grid1d_interp(f_row[u], grid, inv_h)[0]
        elif kind == KIND_GRID_2D:
            y_row, cell_row = f_rows[1], f_rows[2]
            n = grid.shape[1]
            for u in range(w):
                ux, uy, uz = _centroid_dir_light(tpx, tpy, bpx, bpy, u, lx, ly, az, R9)
                x, y = grid2d_coords(ux, uy, uz, n, inv_h, s_max, s_back)
                f_row[u], y_row[u], cell_row[u] = x, y, grid2d_cell(x, y, n)
            grid2d_values_row(f_row, y_row, cell_row, grid, inv_h)
        else:
            for u in range(w):
                ux, uy, uz = _centroid_dir_light(tpx, tpy, bpx, bpy, u, lx, ly, az, R9)
                f_row[u] = rid_value_direction(ux, uy, uz, rid)
        for u in range(w):
            acc_row[u] += 0.0 if bad_row[u] else scale * (om_row[u] * f_row[u])
    if n_bad > 0:
        # Pixels outside the series' range (large solid angles): the general formula.
        for u in range(w):
            if bad_row[u] and ok_row[u]:
                n1, d1, n2, d2, mx, my = _pixel_terms(
                    tpx, tpy, bpx, bpy, tax, tay, tla, bax, bay, bla, u, az
                )
                acc_row[u] += scale * (quad_omega(n1, d1, n2, d2) * f_row[u])


@numba.njit(cache=True, error_model="numpy")
def sensor_row(
    sensor: int,
    grid_xy: np.ndarray,
    vignetting: np.ndarray,
    v: int,
    tpx: np.ndarray,
    tpy: np.ndarray,
    bpx: np.ndarray,
    bpy: np.ndarray,
    view: tuple[float, ...],
    bb: int,
    v_row: np.ndarray,
) -> None:
    """Per-pixel sensor factor of row v: V (radiance, cos4, map) or the paper weight / bb."""
    w = v_row.shape[0]
    g = grid_xy
    if sensor == SENSOR_PAPER:
        for u in range(w):
            wgt = paper_weight(
                tpx[u], tpy[u], tpx[u + 1], tpy[u + 1], bpx[u + 1], bpy[u + 1], bpx[u], bpy[u], view
            )
            v_row[u] = wgt / bb
    elif sensor == SENSOR_COS4:
        for u in range(w):
            v_row[u] = cos4(
                g[v, u, 0], g[v, u, 1], g[v, u + 1, 0], g[v, u + 1, 1],
                g[v + 1, u + 1, 0], g[v + 1, u + 1, 1], g[v + 1, u, 0], g[v + 1, u, 1],
            )  # fmt: skip
    elif sensor == SENSOR_MAP:
        for u in range(w):
            v_row[u] = vignetting[v, u]
    else:
        for u in range(w):
            v_row[u] = 1.0


@numba.njit(cache=True, parallel=True, error_model="numpy")
def render_image_fused(
    grid_xy: np.ndarray,
    grid_ok: np.ndarray,
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
    out: np.ndarray,
    out_invalid: np.ndarray,
) -> None:
    """Whole (binned) image of a rig in one pass: sensor weights, flux and the final values.

    Rows of pixels run in parallel in chunks; within a chunk, each corner row is
    back-projected once, and per light its vectors to the light and their norms once.

    Args:
        grid_xy: (H+1, W+1, 2) undistorted normalised corner coordinates (`corner_grid`).
        grid_ok: (H+1, W+1) corners whose undistortion succeeded.
        R_camera_world: (3, 3); center_world: (3,) camera centre, world frame, m.
        sensor: one of the SENSOR_* codes; vignetting: (H, W) map for SENSOR_MAP, else (1, 1).
        binning: b, super-pixel side in pixels.
        lights_world: (L, 3) emitter positions, world frame, m, all with z > 0.
        R_world_lights: (L, 3, 3) light orientations; light_scales: (L,) scales.
        rids: the lights' RIDs (`stack_rid_data`).
        n_sub: RID sub-sampling per side of each pixel's quad.
        exposure: the view's gain; offset: added to every valid value.
        wall_kind, wall_params, wall_tables: the wall model (`WallReflectance.data()`);
            each light's flux is multiplied by its B at the (super-)pixel's footprint
            centre, the mean of its quads' corners (skipped for a Lambertian wall).
        out: (H // b, W // b) written: offset + exposure sum_l scale_l B_l sum_k w_k Phi_k
            / I0, NaN where invalid.
        out_invalid: (H // b, W // b) written: True where some corner misses the wall.
    """
    hb = out.shape[0]
    wb = out.shape[1]
    b = binning
    bb = b * b
    w = wb * b
    n_l = lights_world.shape[0]
    n_chunks = min(hb, 64)
    per_pixel = b == 1 and sensor != SENSOR_PAPER
    view = view_scalars(R_camera_world, center_world)
    glossy = wall_kind != KIND_LAMBERTIAN
    for ch in numba.prange(n_chunks):
        r_begin = ch * hb // n_chunks
        r_end = (ch + 1) * hb // n_chunks
        px = np.empty((2, w + 1))
        py = np.empty((2, w + 1))
        cok = np.empty((2, w + 1), dtype=np.bool_)
        ax = np.empty((2, n_l, w + 1))
        ay = np.empty((2, n_l, w + 1))
        la = np.empty((2, n_l, w + 1))
        ok_row = np.empty(w, dtype=np.bool_)
        area_row = np.empty(w)
        v_row = np.empty(w)
        om_row = np.empty(w)
        f_rows = np.empty((3, w))
        bad_row = np.empty(w, dtype=np.bool_)
        acc_row = np.empty(w)
        total_row = np.empty(w)
        wall_scratch = np.empty((5, w))
        sp_cx = np.empty(wb)
        sp_cy = np.empty(wb)
        sp_phi = np.empty((n_l, wb))
        sp_area = np.empty(wb)
        sp_v = np.empty(wb)
        sp_ok = np.empty(wb, dtype=np.bool_)
        q = np.zeros((4, 3))
        gdummy = np.zeros(6)
        top = 0
        _corner_row(grid_xy, grid_ok, r_begin * b, w + 1, view, px[0], py[0], cok[0])
        for li in range(n_l):
            light_vectors_row(
                px[0],
                py[0],
                lights_world[li, 0],
                lights_world[li, 1],
                lights_world[li, 2],
                ax[0, li],
                ay[0, li],
                la[0, li],
            )
        for r in range(r_begin, r_end):
            if not per_pixel:
                sp_phi[:] = 0.0
                sp_cx[:] = 0.0
                sp_cy[:] = 0.0
                sp_area[:] = 0.0
                sp_v[:] = 0.0
                sp_ok[:] = True
            for jj in range(b):
                v = r * b + jj
                bot = 1 - top
                tpx = px[top]
                tpy = py[top]
                bpx = px[bot]
                bpy = py[bot]
                tok = cok[top]
                bok = cok[bot]
                _corner_row(grid_xy, grid_ok, v + 1, w + 1, view, bpx, bpy, bok)
                # Geometry: validity, area and sensor factor of each pixel of row v.
                for u in range(w):
                    ok_row[u] = tok[u] & tok[u + 1] & bok[u + 1] & bok[u]
                    area_row[u] = quad_area(
                        tpx[u],
                        tpy[u],
                        tpx[u + 1],
                        tpy[u + 1],
                        bpx[u + 1],
                        bpy[u + 1],
                        bpx[u],
                        bpy[u],
                    )
                sensor_row(sensor, grid_xy, vignetting, v, tpx, tpy, bpx, bpy, view, bb, v_row)
                if per_pixel:
                    acc_row[:] = 0.0
                    total_row[:] = 0.0
                for li in range(n_l):
                    light_vectors_row(
                        bpx,
                        bpy,
                        lights_world[li, 0],
                        lights_world[li, 1],
                        lights_world[li, 2],
                        ax[bot, li],
                        ay[bot, li],
                        la[bot, li],
                    )
                    if not per_pixel or glossy:
                        acc_row[:] = 0.0  # this light alone
                    flux_row(
                        tpx,
                        tpy,
                        bpx,
                        bpy,
                        ax[top, li],
                        ay[top, li],
                        la[top, li],
                        ax[bot, li],
                        ay[bot, li],
                        la[bot, li],
                        lights_world[li],
                        R_world_lights[li],
                        light_rid(rids, li),
                        n_sub,
                        light_scales[li] if per_pixel else 1.0,
                        ok_row,
                        om_row,
                        f_rows,
                        bad_row,
                        q,
                        gdummy,
                        acc_row,
                    )
                    if per_pixel:
                        if glossy:
                            # This light's flux times its B at each pixel's footprint centre.
                            add_factor_row(
                                wall_kind,
                                wall_params,
                                wall_tables,
                                lights_world[li],
                                center_world,
                                tpx,
                                tpy,
                                bpx,
                                bpy,
                                acc_row,
                                total_row,
                                w,
                                wall_scratch,
                            )
                        continue
                    # Binned or paper: Phi of each member pixel into its super-pixel.
                    if sensor == SENSOR_PAPER:
                        for c in range(wb):
                            for ii in range(b):
                                u = c * b + ii
                                sp_phi[li, c] += v_row[u] * acc_row[u]
                    else:
                        for c in range(wb):
                            for ii in range(b):
                                sp_phi[li, c] += acc_row[c * b + ii]
                if per_pixel:
                    # acc_row holds sum_l scale_l Phi_l / I0 of each pixel (B_l included).
                    if glossy:
                        acc_row[:] = total_row
                    for u in range(w):
                        okp = ok_row[u]
                        value = offset + exposure * ((v_row[u] / area_row[u]) * acc_row[u])
                        out[r, u] = value if okp else np.nan
                        out_invalid[r, u] = not okp
                else:
                    for c in range(wb):
                        for ii in range(b):
                            u = c * b + ii
                            sp_ok[c] &= ok_row[u]
                            sp_area[c] += area_row[u]
                            sp_v[c] += v_row[u]
                    if glossy:  # the super-pixel's footprint centre, for B
                        for c in range(wb):
                            for ii in range(b):
                                u = c * b + ii
                                sp_cx[c] += tpx[u] + tpx[u + 1] + bpx[u] + bpx[u + 1]
                                sp_cy[c] += tpy[u] + tpy[u + 1] + bpy[u] + bpy[u + 1]
                top = bot
            if per_pixel:
                continue
            for c in range(wb):
                if sp_ok[c]:
                    if glossy:
                        for li in range(n_l):
                            sp_phi[li, c] *= point_factor(
                                sp_cx[c] / (4.0 * bb),
                                sp_cy[c] / (4.0 * bb),
                                lights_world[li],
                                center_world,
                                wall_kind,
                                wall_params,
                                wall_tables,
                            )
                    total = 0.0
                    if sensor == SENSOR_PAPER:
                        for li in range(n_l):
                            total += light_scales[li] * sp_phi[li, c]
                    else:
                        wgt = (sp_v[c] / bb) / sp_area[c]
                        for li in range(n_l):
                            total += light_scales[li] * (wgt * sp_phi[li, c])
                    out[r, c] = offset + exposure * total
                    out_invalid[r, c] = False
                else:
                    out[r, c] = np.nan
                    out_invalid[r, c] = True
