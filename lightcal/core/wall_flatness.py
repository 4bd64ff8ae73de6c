"""A wall that is not quite flat, as the camera pose errors it is equivalent to.

The renderer's wall is the plane z = 0. A real wall deviates from its plane by a few
millimetres (plaster, a bowed board): a geometric error no photometric residual reveals,
because the light's pose absorbs it (a wall bowed 5 mm toward the cameras moves the
light ~5 mm). lightcal takes a declared flatness tolerance b (`wall.flatness_mm`) and
propagates it like the camera poses' covariance (docs/model.md, "Uncertainty").

The deviation is taken as a dome of depth b over a disc around the views' mean wall
point c, h(p) = b max(0, 1 - |p - c|^2 / R^2), R = `BOW_DISC_FACTOR` times the largest
distance of an image's wall point from c (at least `MIN_BOW_RADIUS_M`). Around image i's
wall point P_i (the centroid of its pixels' footprints) the wall is, to first order, the
plane through P_i + h_i z with slope g_i = grad h(P_i). Moving the world so that this
plane becomes z = 0 (a shift by -h_i z and a rotation omega_i = (-g_y, g_x, 0) about P_i)
leaves the wall where the model has it and moves the camera (and the light on it):

    delta_i = -R_i omega_i  (camera-frame rotation perturbation, R -> exp(delta) R),
    dc_i = -h_i z + omega_i x (C_i - P_i)  (camera centre, world),

per unit b: `bow_pose_perturbations`. The curvature within one image's footprint is of
second order and is left out.
"""

from __future__ import annotations

import numpy as np

from lightcal.core.scene import View

#: The dome's radius over the largest distance of an image's wall point from their mean.
BOW_DISC_FACTOR = 1.5
#: The dome's smallest radius, m.
MIN_BOW_RADIUS_M = 0.5


def bow_pose_perturbations(views: list[View], wall_points: np.ndarray) -> np.ndarray:
    """(K, 6) per image the pose perturbation (delta (camera frame, rad), dc (world, m))
    equivalent to a dome of unit depth (1 m) on the wall (module docstring).

    Args:
        views: the K images' camera poses.
        wall_points: (K, 3) each image's wall point (centroid of its footprints), world, m.
    """
    P = np.asarray(wall_points, dtype=np.float64)
    center = P[:, :2].mean(axis=0)
    offsets = P[:, :2] - center
    radius = max(BOW_DISC_FACTOR * float(np.max(np.linalg.norm(offsets, axis=1))), MIN_BOW_RADIUS_M)
    out = np.zeros((len(views), 6))
    for i, view in enumerate(views):
        d2 = float(offsets[i] @ offsets[i]) / radius**2
        inside = d2 < 1.0
        h = 1.0 - d2 if inside else 0.0
        g = -2.0 * offsets[i] / radius**2 if inside else np.zeros(2)
        omega = np.array([-g[1], g[0], 0.0])
        out[i, :3] = -view.R_camera_world @ omega
        out[i, 3:] = -h * np.array([0.0, 0.0, 1.0]) + np.cross(omega, view.center_world - P[i])
    return out
