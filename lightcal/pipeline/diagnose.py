"""Diagnostics of a solution: the parameter covariance and the warnings about what the
data do not determine (views lacking variety, correlated parameters, dark lights)."""

from __future__ import annotations

import math

import numpy as np

from lightcal.core.render import shade
from lightcal.core.solver import CalibrationModel


def covariance(model: CalibrationModel, x: np.ndarray) -> np.ndarray:
    """Parameter covariance s^2 (J^T J)^-1, s^2 the residual variance (reduced chi^2)."""
    r = model.residuals(x)
    JtJ = model.normal_matrix(x)
    dof = max(model.m - model.layout.n, 1)
    s2 = float(r @ r) / dof
    try:
        return s2 * np.linalg.inv(JtJ)
    except np.linalg.LinAlgError:
        return s2 * np.linalg.pinv(JtJ)


def variety_warnings(model: CalibrationModel, cov: np.ndarray) -> list[str]:
    """Warnings when the views lack the distance/angle variety that constrains the pose."""
    warnings = []
    views = [im.view for im in model.images]
    dist = []
    axes = []
    for v in views:
        axis_world = v.R_camera_world[2]  # camera z in world coordinates
        dist.append(v.center_world[2] / max(-axis_world[2], 1e-9))
        axes.append(axis_world)
    dist_arr = np.array(dist)
    if len(views) < 3:
        warnings.append(
            f"only {len(views)} image(s): the paper used 12; use several views at "
            "different distances and angles"
        )
    if dist_arr.max() / dist_arr.min() < 1.25:
        warnings.append(
            f"camera-to-wall distances span only {dist_arr.min():.2f}-{dist_arr.max():.2f} m: "
            "the light's position along the view direction and its scale are poorly "
            "separated; add views nearer and farther from the wall"
        )
    A = np.array(axes)
    spread = max(math.degrees(math.acos(float(np.clip(a @ b, -1, 1)))) for a in A for b in A)
    if spread < 10.0:
        warnings.append(
            f"the views' directions differ by at most {spread:.1f} degrees: the light's "
            "orientation and lateral position are poorly separated; tilt the camera more"
        )
    sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    names = model.layout.names
    for b in model.layout.blocks:
        idx = [*range(b.pose.start, b.pose.stop), b.log_scale]
        sub = corr[np.ix_(idx, idx)]
        np.fill_diagonal(sub, 0.0)
        if np.nanmax(np.abs(sub)) > 0.995:
            a, c = np.unravel_index(np.nanargmax(np.abs(sub)), sub.shape)
            warnings.append(
                f"parameters {names[idx[a]]} and {names[idx[c]]} are correlated "
                f"({sub[a, c]:+.4f}): the views do not separate them; add views with more "
                "variety of distance and angle"
            )
    return warnings


def dark_light_warnings(
    model: CalibrationModel, x: np.ndarray, light_shares: np.ndarray | None = None
) -> list[str]:
    """Warnings for lights that light (almost) none of the selected pixels at x.

    Such a light's pose is not determined by the data: the solver may have parked it
    pointing away or behind the wall while another light explains the images (two
    similar beams close together invite this).

    Args:
        model: the model.
        x: the solution.
        light_shares: (L,) each light's share of the rendered values summed over the
            pixels, if already known (`lightcal.pipeline.fit_check.FitCheck`); else
            rendered here.
    """
    rig = model.layout.rig(x)
    share = light_shares if light_shares is not None else _light_shares(model, x)
    total = float(share.sum())
    out = []
    for light, s in zip(rig.lights, share, strict=True):
        if not (total > 0.0 and s > 1e-6 * total):
            out.append(
                f"light '{light.name}' lights none of the selected pixels at the solution "
                "(it points away or sits behind the wall): its pose is not determined; "
                "start it nearer its true pose, or calibrate the lights one at a time"
            )
    return out


def _light_shares(model: CalibrationModel, x: np.ndarray) -> np.ndarray:
    """(L,) sum over pixels of gain * scale * flux of each light at x."""
    gains = model.layout.gain_factors(x)
    share = np.zeros(len(model.layout.blocks))
    for i, im in enumerate(model.images):
        rig = model.layout.rig(x, im.channel)
        sh = shade(
            im.footprints,
            im.view,
            rig,
            rid_subsamples=model.options.rid_subsamples,
            wall=model.layout.wall_of(x),
            medium=model.layout.medium_of(x, im.channel),
        )
        share += gains[i] * np.array([light.scale for light in rig.lights]) * sh.flux.sum(axis=1)
    return share
