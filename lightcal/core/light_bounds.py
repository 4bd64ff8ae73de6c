"""Box bounds of the solver's parameters that keep every light in front of the wall.

trf needs a light that cannot step through the wall (behind it the model renders nothing
and its gradients vanish): `parameter_bounds` boxes each light's position in the camera
frame from its start and the views.
"""

from __future__ import annotations

import numpy as np

from lightcal.core.problem import ImageData, ParameterLayout

# How far beyond the span of its start and the camera centre a light may move (m).
LIGHT_MOUNT_MARGIN_M = 0.5


#: The largest albedo a surroundings' surface may be estimated at (a surface that
#: reflects all it receives would make the bounce's series diverge).
MAX_SURFACE_ALBEDO = 0.999


def parameter_bounds(
    layout: ParameterLayout, images: list[ImageData], position_bound_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """Box bounds that keep every light in front of the wall in every view.

    Each light's lateral (camera x, y) position is boxed to the span of its start and
    the camera centre, widened by d, and its forward position z below z_max(d), the
    largest z that keeps the light in front of the wall in every view for any lateral
    position in the box. d is the largest value (up to LIGHT_MOUNT_MARGIN_M) that leaves
    at least a quarter of the start's forward room z_max(0) - z0. Scales and RID
    parameters stay unbounded: bounding them degrades trf's steps (it scales
    variables by their distance to finite bounds); the model clips their
    exponentials instead (`ParameterLayout`). Wall parameters and fall-off coefficients
    keep their models' boxes.

    Args:
        layout: the parameter vector's layout (its start x0, blocks and wall columns).
        images: the selected pixels of each image (their views).
        position_bound_m: no light coordinate beyond this, m (`SolverOptions`).

    Returns:
        (lo, hi), (n,) each; -inf / inf where unbounded.
    """
    lo = np.full(layout.n, -np.inf)
    hi = np.full(layout.n, np.inf)
    b = position_bound_m
    x0 = layout.x0
    for block in layout.blocks:
        s = block.pose.start
        # The lateral box spans the start and the camera centre (lights are mounted
        # near it), widened by d on every side.
        near = np.minimum(x0[s : s + 2], 0.0)
        far = np.maximum(x0[s : s + 2], 0.0)
        z0 = float(x0[s + 2])

        def z_max(d: float, near: np.ndarray = near, far: np.ndarray = far) -> float:
            z = b
            for im in images:
                R = im.view.R_camera_world
                if R[2, 2] >= 0.0:
                    continue  # the camera axis does not point at the wall
                # world z = c_z + sum_k R[k, 2] t_k, worst case over the lateral box.
                worst = im.view.center_world[2]
                for k in range(2):
                    worst += min(R[k, 2] * (near[k] - d), R[k, 2] * (far[k] + d))
                z = min(z, 0.98 * worst / -R[2, 2])
            return z

        room = z_max(0.0) - z0
        d = min(b, LIGHT_MOUNT_MARGIN_M)
        while d > 1e-3 and z_max(d) - z0 < 0.25 * room:
            d *= 0.8
        lo[s : s + 2] = np.maximum(near - d, -b)
        hi[s : s + 2] = np.minimum(far + d, b)
        lo[s + 2] = max(min(z0, 0.0) - LIGHT_MOUNT_MARGIN_M, -b)
        hi[s + 2] = max(z_max(d), z0 + 1e-9)
    lo[layout.wall], hi[layout.wall] = layout.wall_bounds()
    lo[layout.medium], hi[layout.medium] = layout.medium_bounds()
    lo[layout.surface_albedo], hi[layout.surface_albedo] = 0.0, MAX_SURFACE_ALBEDO
    if layout.fall_off_unknown is not None:
        lo[layout.fall_off], hi[layout.fall_off] = layout.fall_off_unknown.bounds()
    return lo, hi
