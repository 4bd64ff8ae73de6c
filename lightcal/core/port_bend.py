"""The `port` cause's pattern: what bending every ray toward the camera's axis does.

A camera behind a flat window (a housing's port) in water sees the wall along rays bent
toward the port's normal: sin(theta_w) = sin(theta_a) / n at one interface of relative
index n (docs/model.md, "The camera's flat port"). A project that does not declare the
port puts every footprint too far from the optical axis. At "no effect", n = 1 + eps,
the bend moves each footprint centre P on the wall to P(eps); what that changes in a
pixel's value, to first order, is the irradiance's change

    q = d ln E(P(eps)) / d eps at eps = 0,   E(P) = I(u_light(P)) cos(theta_i) / |P - L|^2,

(I the light's RID in its own frame, theta_i the incidence on the wall z = 0): the
radiance a pixel sees of a Lambertian wall is the irradiance of its footprint. The
window's (n_air / n_w)^2 on radiance is a constant (the light's scale takes it) and its
Fresnel transmittance second order in eps. The medium's path lengths and a glossy wall's
change of B are left out: the pattern only has to look like the port's misfit.
"""

from __future__ import annotations

import numpy as np

from lightcal.core.scene import Light, View

#: The index step of the central difference of q (q is smooth in eps).
BEND_STEP = 1e-4


def _bent_centres(centres_world: np.ndarray, view: View, eps: float) -> np.ndarray:
    """(N, 3) where the rays from the camera centre through centres_world (N, 3) on the
    wall z = 0 meet it when an interface of relative index 1 + eps normal to the camera's
    axis bends them (NaN where they no longer meet it)."""
    R = view.R_camera_world
    rays = np.einsum("ij,kj->ik", centres_world - view.center_world, R)
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    tangential = rays[:, :2] / (1.0 + eps)
    along = np.sqrt(np.maximum(1.0 - np.sum(tangential**2, axis=1), 0.0))
    bent = np.einsum("ij,jk->ik", np.column_stack([tangential, along]), R)
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = -view.center_world[2] / bent[:, 2]
    out = view.center_world + lam[:, None] * bent
    out[~(lam > 0.0)] = np.nan
    return out


def _log_irradiance(points_world: np.ndarray, light: Light, view: View) -> np.ndarray:
    """(N,) ln E of `light` at points_world (N, 3) on the wall z = 0 (NaN behind it)."""
    L = light.position_world(view)
    a = points_world - L
    d = np.linalg.norm(a, axis=1)
    v = np.einsum("ij,jk->ik", a, light.rotation_world(view)) / d[:, None]
    theta = np.arccos(np.clip(v[:, 2], -1.0, 1.0))
    phi = np.arctan2(v[:, 1], v[:, 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.log(light.rid(theta, phi) * (L[2] / d) / d**2)


def port_bend_pattern(
    centres_world: np.ndarray, view: View, lights: tuple[Light, ...], brightest: np.ndarray
) -> np.ndarray:
    """q (N,) = d ln E / d eps of each footprint centre (N, 3) on the wall z = 0 under
    its brightest light (`brightest` (N,) indices into `lights`); 0 where undefined (a
    centre whose bent ray misses the wall, or where the light gives nothing)."""
    q = np.zeros(centres_world.shape[0])
    plus = _bent_centres(centres_world, view, BEND_STEP)
    minus = _bent_centres(centres_world, view, -BEND_STEP)
    for k, light in enumerate(lights):
        rows = brightest == k
        if not np.any(rows):
            continue
        with np.errstate(invalid="ignore"):
            diff = _log_irradiance(plus[rows], light, view) - _log_irradiance(
                minus[rows], light, view
            )
        q[rows] = diff / (2.0 * BEND_STEP)
    q[~np.isfinite(q)] = 0.0
    return q
