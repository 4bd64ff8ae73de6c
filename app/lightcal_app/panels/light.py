"""The Light tab: the gizmo's image, and per light its position and axis as numbers."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import viser

from lightcal.core.pose import axis_roll_from_rotation, describe_pose, rotation_from_axis_roll
from lightcal.core.scene import Light
from lightcal.io.project import Project
from lightcal_app.controller import Controller
from lightcal_app.limits import POSITION_LIMIT_M, ROLL_LIMIT_DEG, TILT_LIMIT_DEG
from lightcal_app.panels.base import Programmatic, TabPanel, assign, rounded
from lightcal_app.state import Frame, LightGuess
from lightcal_app.text import md

POSITION_LIMIT_MM = POSITION_LIMIT_M * 1e3


def pose_angles_deg(R_camera_light: np.ndarray) -> tuple[float, float, float]:
    """(a, b, roll) in degrees of a light orientation (`axis_roll_from_rotation`)."""
    a, b, roll = axis_roll_from_rotation(R_camera_light)
    return math.degrees(a), math.degrees(b), math.degrees(roll)


def rotation_from_angles_deg(a_deg: float, b_deg: float, roll_deg: float) -> np.ndarray:
    """The inverse of `pose_angles_deg`."""
    return rotation_from_axis_roll(math.radians(a_deg), math.radians(b_deg), math.radians(roll_deg))


class LightPanel(TabPanel):
    """The Light tab (built inside `tab`)."""

    def __init__(
        self, server: viser.ViserServer, ctl: Controller, flag: Programmatic, tab: Any
    ) -> None:
        super().__init__(server, ctl, flag)
        self.tab = tab
        st = ctl.state
        names = list(st.project.names)
        gui = self.gui
        with tab:
            self.ref_image = gui.add_dropdown(
                "gizmo on image",
                names,
                initial_value=names[st.ref_image],
                hint="the camera pose on which the draggable light gizmo is drawn",
            )
            self.reset_guess = gui.add_button("Back to the project's initial guess")
            self.light_md = gui.add_markdown("")
        self.light_widgets: list[dict[str, Any]] = []
        self._folders: list[Any] = []
        self._build_light_widgets(st.project)
        self.ref_image.on_update(
            self.guard(
                lambda e: ctl.set_ref_image(ctl.state.project.names.index(self.ref_image.value))
            )
        )
        self.reset_guess.on_click(lambda e: ctl.reset_guess())

    def _build_light_widgets(self, project: Project) -> None:
        gui = self.gui
        for h in self._folders:
            h.remove()
        self._folders = []
        self.light_widgets = []
        with self.tab:
            for j, u in enumerate(project.lights):
                folder = gui.add_folder(f"{u.initial.name} ({u.kind()})", order=-10 + j)
                self._folders.append(folder)
                with folder:
                    t = u.initial.t_camera_light * 1e3
                    a, b, roll = pose_angles_deg(u.initial.R_camera_light)
                    w: dict[str, Any] = {
                        "position": gui.add_vector3(
                            "position (mm)",
                            (rounded(t[0], 2), rounded(t[1], 2), rounded(t[2], 2)),
                            step=0.1,
                            min=(-POSITION_LIMIT_MM,) * 3,
                            max=(POSITION_LIMIT_MM,) * 3,
                            hint="emitter position in the camera frame: x right, y down, z forward",
                        ),
                        "tilt": gui.add_vector2(
                            "axis tilt a, b (deg)",
                            (rounded(a, 3), rounded(b, 3)),
                            step=0.1,
                            min=(-TILT_LIMIT_DEG,) * 2,
                            max=(TILT_LIMIT_DEG,) * 2,
                            hint="angle of the light axis from the optical axis towards +x (a) "
                            "and +y (b); the tilt is hypot(a, b)",
                            visible=u.kind() != "isotropic",
                        ),
                        "roll": gui.add_number(
                            "roll about the axis (deg)",
                            rounded(roll, 3),
                            step=0.1,
                            min=-ROLL_LIMIT_DEG,
                            max=ROLL_LIMIT_DEG,
                            visible=u.kind() == "general",
                        ),
                    }
                self.light_widgets.append(w)
                self._wire_light(j, w)

    def _wire_light(self, j: int, w: dict[str, Any]) -> None:
        ctl = self.ctl

        @w["position"].on_update
        @self.guard
        def _(event: Any) -> None:
            ctl.set_guess(j, position_m=np.array(w["position"].value, dtype=float) / 1e3)

        def orientation(event: Any) -> None:
            a, b = w["tilt"].value
            R = rotation_from_angles_deg(float(a), float(b), float(w["roll"].value))
            ctl.set_guess(j, R_camera_light=R)

        w["tilt"].on_update(self.guard(orientation))
        w["roll"].on_update(self.guard(orientation))

    def set_project(self, project: Project) -> None:
        """Options that depend on the project (after an upload)."""
        self.ref_image.options = list(project.names)
        if len(self.light_widgets) != len(project.lights) or any(
            f.label != f"{u.initial.name} ({u.kind()})"
            for f, u in zip(self._folders, project.lights, strict=False)
        ):
            self._build_light_widgets(project)

    def update(self, frame: Frame) -> None:
        """The lights shown (estimate or guess) into the widgets and the text."""
        if not frame.dirty & {"widgets", "scene"}:
            return
        st = self.ctl.state
        with st.lock:
            assign(self.ref_image, st.project.names[st.ref_image])
            names = [u.initial.name for u in st.project.lights]
        lights: list[Light | LightGuess] = (
            list(frame.display.rig.lights) if frame.display is not None else list(frame.guess)
        )
        lines = []
        for j, light in enumerate(lights[: len(self.light_widgets)]):
            if isinstance(light, Light):
                t, R = light.t_camera_light, light.R_camera_light
            else:
                t, R = light.position_m, light.R_camera_light
            a, b, roll = pose_angles_deg(R)
            w = self.light_widgets[j]
            assign(w["position"], tuple(rounded(v, 2) for v in t * 1e3))
            assign(w["tilt"], (rounded(a, 3), rounded(b, 3)))
            assign(w["roll"], rounded(roll, 3))
            pose = describe_pose(R, t)
            ax = np.asarray(pose["axis_camera"]) + 0.0  # no "-0.0000"
            scale = f", scale {light.scale:.4g}" if isinstance(light, Light) else ""
            lines.append(
                f"**{md(names[j])}**: axis ({ax[0]:+.4f}, {ax[1]:+.4f}, {ax[2]:+.4f}), "
                f"{pose['axis_angle_from_optical_axis_deg']:.2f}° from the optical axis{scale}"
            )
        source = (
            "current estimate"
            if frame.display is not None and frame.display.source == "estimate"
            else "initial guess"
        )
        self.light_md.content = (
            f"Showing the **{source}**. Drag the gizmo (orange camera) or type numbers; "
            "either starts the solve over from there.\n\n" + "  \n".join(lines)
        )
