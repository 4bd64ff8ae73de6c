"""Plain vectorised NumPy implementation of the renderer: the reference and the baseline.

Same model as `lightcal.core.render` (docs/model.md), written for readability with array
operations only: footprints from `pixel_footprints`, sub-quads from
`subdivide_quads`, solid angles from `lightcal.core.solid_angle`, RID values through
`RID.__call__`. The tests hold the compiled kernels to it; `benchmarks/render.py` uses
it as the speed baseline.
"""

from __future__ import annotations

import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.footprint import Footprints, SensorModel, pixel_footprints
from lightcal.core.scene import Rig, View
from lightcal.core.solid_angle import quad_solid_angle, subdivide_quads


def flux_reference(
    footprints: Footprints, L_world: np.ndarray, R_world_light: np.ndarray, rid, n_sub: int
) -> np.ndarray:
    """sum_k weight_k sum_j Omega_j f(w_j) per pixel, (N,), 0 where invalid."""
    n, k = footprints.weights.shape
    valid = footprints.valid
    out = np.zeros(n)
    if not np.any(valid):
        return out
    quads = footprints.corners_world[valid].reshape(-1, 4, 3)
    sub = subdivide_quads(quads, n_sub)  # (M, n_sub^2, 4, 3)
    m = sub.shape[0] * sub.shape[1]
    flat = sub.reshape(m, 4, 3)
    omega = quad_solid_angle(L_world, flat)
    w = flat.mean(axis=1) - L_world
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    u = w @ R_world_light  # rows: R^T w, light frame
    theta = np.arctan2(np.hypot(u[:, 0], u[:, 1]), u[:, 2])
    phi = np.arctan2(u[:, 1], u[:, 0])
    f = rid(theta, phi)
    per_quad = (omega * f).reshape(-1, sub.shape[1]).sum(axis=1).reshape(-1, k)
    out[valid] = (footprints.weights[valid] * per_quad).sum(axis=1)
    return out


def render_pixels_reference(
    camera: Camera,
    view: View,
    rig: Rig,
    pixels: np.ndarray,
    *,
    sensor: SensorModel = "radiance",
    vignetting: np.ndarray | None = None,
    binning: int = 1,
    offset: float = 0.0,
    rid_subsamples: int = 1,
) -> np.ma.MaskedArray:
    """NumPy twin of `lightcal.core.render.render_pixels` (same arguments and result)."""
    fp = pixel_footprints(
        camera, view, pixels, sensor=sensor, vignetting=vignetting, binning=binning
    )
    total = np.zeros(len(fp))
    for light in rig.lights:
        L_world = light.position_world(view)
        if L_world[2] <= 0.0:
            continue
        total += light.scale * flux_reference(
            fp, L_world, light.rotation_world(view), light.rid, rid_subsamples
        )
    values = offset + view.exposure * total
    return np.ma.masked_array(np.where(fp.valid, values, np.nan), mask=~fp.valid)


def render_image_reference(
    camera: Camera,
    view: View,
    rig: Rig,
    *,
    chunk_rows: int = 64,
    **options: object,
) -> np.ma.MaskedArray:
    """NumPy twin of `lightcal.core.render.render_image`, rendered in bands of rows."""
    b = int(options.get("binning", 1))  # type: ignore[call-overload]
    hb, wb = camera.height // b, camera.width // b
    out = np.ma.masked_all((hb, wb))
    for start in range(0, hb, chunk_rows):
        rows = np.arange(start, min(hb, start + chunk_rows))
        vv, uu = np.meshgrid(rows, np.arange(wb), indexing="ij")
        pixels = np.stack([uu.ravel(), vv.ravel()], axis=1)
        vals = render_pixels_reference(camera, view, rig, pixels, **options)  # type: ignore[arg-type]
        out[rows[0] : rows[-1] + 1] = vals.reshape(vv.shape)
    return out
