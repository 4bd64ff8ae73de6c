"""The suggested next views in the 3D view: ghost frusta with their rank (Plan tab).

Each view of a plan (`lightcal_app.state.PlanShown`) is drawn as a blue wireframe frustum
`/plan/<k>` at its camera pose (world frame, docs/model.md), the size of the project's
frusta, with a label "next <rank>" and a line from the camera to the wall point it aims
at. `PlanScene` only draws what it is given. viser draws no frustum in front of another,
so while a plan is shown the photos' frusta are outlines (`Scene3D.set_outlines_only`): no
picture hides a suggested view.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.rotations import quaternion_wxyz_from_matrix
from lightcal_app.state import PlanShown

PLAN_RGB = (30, 110, 235)


class PlanScene:
    """The ghost frusta of a plan.

    Args:
        scene: the viser scene (server-level: every browser sees the same).
    """

    def __init__(self, scene: Any) -> None:
        self.scene = scene
        self.handles: list[Any] = []

    def draw(self, plan: PlanShown | None, camera: Camera, *, scale: float, rebuilt: bool) -> None:
        """Replace the drawn plan by `plan` (None: nothing drawn).

        Args:
            plan: the views to draw.
            camera: the project's intrinsics (the frusta's field of view and aspect).
            scale: the size of the project's frusta (viser's frustum scale).
            rebuilt: the scene was just reset (the old nodes are gone already).
        """
        if not rebuilt:
            for h in self.handles:
                h.remove()
        self.handles = []
        if plan is None:
            return
        for k, pv in enumerate(plan.views):
            view = pv.candidate.view
            R_wc = view.R_camera_world.T
            centre = view.center_world
            frustum = self.scene.add_camera_frustum(
                f"/plan/{k}",
                fov=camera.fov_y_rad,
                aspect=camera.aspect,
                scale=scale,
                thickness=2.5,
                thickness_units="screen",
                color=PLAN_RGB,
                wxyz=quaternion_wxyz_from_matrix(R_wc),
                position=centre,
                cast_shadow=False,
                receive_shadow=False,
            )
            self.scene.add_label(f"/plan/{k}/label", f"next {k + 1}")  # goes with its frustum
            target = np.array([*pv.candidate.target_world, 0.0])
            aim = self.scene.add_line_segments(
                f"/plan_aim/{k}",
                np.array([[centre, target]], dtype=np.float32),
                PLAN_RGB,
                thickness=1.0,
                thickness_units="screen",
            )
            self.handles += [frustum, aim]
