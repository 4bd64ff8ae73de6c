"""The Light tab: the gizmo's image, per light its position and axis as numbers, the
flat ports the camera and the lights look and shine through (`ports_markdown`), the
water between the rig and the wall (`lightcal_app.panels.water`) and the surfaces near
the wall (`lightcal_app.panels.surroundings`)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import viser

from lightcal.core.light_axis import (
    axis_from_paper_angles,
    axis_roll_from_rotation,
    paper_angles_from_axis,
    rotation_from_axis,
)
from lightcal.core.pose import describe_pose
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.core.scene import Light
from lightcal.io.project import Project
from lightcal.pipeline.port_text import light_port_sentence, port_sentence
from lightcal_app.controller import Controller
from lightcal_app.limits import (
    AXIS_PITCH_LIMIT_DEG,
    AXIS_ROLL_LIMIT_DEG,
    POSITION_LIMIT_M,
    SPIN_LIMIT_DEG,
)
from lightcal_app.panels.base import Programmatic, TabPanel, rounded
from lightcal_app.panels.surroundings import SurroundingsPanel
from lightcal_app.panels.water import WaterPanel
from lightcal_app.state import Frame, LightGuess
from lightcal_app.text import md, md_prose

POSITION_LIMIT_MM = POSITION_LIMIT_M * 1e3


def pose_angles_deg(R_camera_light: np.ndarray) -> tuple[float, float, float]:
    """(roll, pitch, spin) in degrees of a light orientation: the paper's roll and pitch
    of the axis (`paper_angles_from_axis`, as the result file and the CLI give them) and
    the spin about the axis from the minimal rotation off +z (`axis_roll_from_rotation`;
    only a general light has one)."""
    R = np.asarray(R_camera_light, dtype=np.float64)
    roll, pitch = paper_angles_from_axis(R[:, 2])
    spin = axis_roll_from_rotation(R)[2]
    return math.degrees(roll), math.degrees(pitch), math.degrees(spin)


def rotation_from_angles_deg(roll_deg: float, pitch_deg: float, spin_deg: float) -> np.ndarray:
    """The inverse of `pose_angles_deg`: R_camera_light (3, 3)."""
    axis = axis_from_paper_angles(math.radians(roll_deg), math.radians(pitch_deg))
    spin = matrix_from_rotvec(np.array([0.0, 0.0, math.radians(spin_deg)]))
    return rotation_from_axis(axis) @ spin


def ports_markdown(project: Project) -> str:
    """The project's flat ports in words (`port_sentence`, `light_port_sentence`), one
    line each, the owner in bold: the camera's, then each ported light's with its beam's
    angles in the water; empty without a port."""
    lines = []
    if project.camera_port is not None:
        text = md_prose(port_sentence(project.camera_port, ""))
        lines.append(f"**camera**{text}")
    for u in project.lights:
        light = u.initial
        if light.port is not None:
            text = md_prose(light_port_sentence("", light.port, light.rid))
            lines.append(f"**{md(light.name)}**{text}")
    return "  \n".join(lines)


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
            self.beam_guess = gui.add_button(
                "Guess from the beam in the photos",
                hint="the light on the line through the beam's spots, placed by their "
                "brightness (one light; what initial: auto does)",
            )
            self.light_md = gui.add_markdown("")
            self.water = WaterPanel(server, ctl, flag)
            self.surroundings = SurroundingsPanel(server, ctl, flag)
        self.light_widgets: list[dict[str, Any]] = []
        self._folders: list[Any] = []
        self._build_light_widgets(st.project)
        self.ref_image.on_update(
            self.guard(
                lambda e: ctl.set_ref_image(ctl.state.project.names.index(self.ref_image.value))
            )
        )
        self.reset_guess.on_click(lambda e: ctl.reset_guess())
        self.beam_guess.on_click(self.guard(lambda e: ctl.guess_from_beam(e.client)))

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
                    roll, pitch, spin = pose_angles_deg(u.initial.R_camera_light)
                    w: dict[str, Any] = {
                        "position": gui.add_vector3(
                            "position (mm)",
                            (rounded(t[0], 2), rounded(t[1], 2), rounded(t[2], 2)),
                            step=0.1,
                            min=(-POSITION_LIMIT_MM,) * 3,
                            max=(POSITION_LIMIT_MM,) * 3,
                            hint="emitter position in the camera frame: x right, y down, z forward",
                        ),
                        "axis": gui.add_vector2(
                            "axis roll, pitch (deg)",
                            (rounded(roll, 3), rounded(pitch, 3)),
                            step=0.1,
                            min=(-AXIS_ROLL_LIMIT_DEG, -AXIS_PITCH_LIMIT_DEG),
                            max=(AXIS_ROLL_LIMIT_DEG, AXIS_PITCH_LIMIT_DEG),
                            hint="the paper's angles, as in the result: the optical axis "
                            "pitched about the camera y axis (+: towards +x), then rolled "
                            "about the camera x axis (+: towards -y)",
                            visible=u.kind() != "isotropic",
                        ),
                        "spin": gui.add_number(
                            "spin about the axis (deg)",
                            rounded(spin, 3),
                            step=0.1,
                            min=-SPIN_LIMIT_DEG,
                            max=SPIN_LIMIT_DEG,
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
            ctl.set_guess(j, t_camera_light=np.array(w["position"].value, dtype=float) / 1e3)

        def orientation(event: Any) -> None:
            roll, pitch = w["axis"].value
            R = rotation_from_angles_deg(float(roll), float(pitch), float(w["spin"].value))
            ctl.set_guess(j, R_camera_light=R)

        w["axis"].on_update(self.guard(orientation))
        w["spin"].on_update(self.guard(orientation))

    def set_project(self, project: Project) -> None:
        """Options that depend on the project (after an upload)."""
        self.ref_image.options = list(project.names)
        self.water.set_project(project)
        if len(self.light_widgets) != len(project.lights) or any(
            f.label != f"{u.initial.name} ({u.kind()})"
            for f, u in zip(self._folders, project.lights, strict=False)
        ):
            self._build_light_widgets(project)

    def update(self, frame: Frame) -> None:
        """The lights shown (estimate or guess) into the widgets and the text, the
        water's values and the surroundings."""
        self.water.update(frame)
        self.surroundings.update(frame)
        if not frame.dirty & {"widgets", "scene"}:
            return
        st = self.ctl.state
        with st.lock:
            self.flag.assign(self.ref_image, st.project.names[st.ref_image])
            names = [u.initial.name for u in st.project.lights]
            channels = st.project.channels
            ports = ports_markdown(st.project)
            # The state's lights, not the frame's: a frame is taken before the redraw, and
            # an edit that reached the state since must not be written back over.
            display = st.display if st.display is not None and st.display.current(st) else None
            lights: list[Light | LightGuess] = (
                list(display.rig.lights) if display is not None else list(st.guess)
            )
            poses = []
            for j, light in enumerate(lights[: len(self.light_widgets)]):
                t, R = light.t_camera_light, light.R_camera_light
                roll, pitch, spin = pose_angles_deg(R)
                w = self.light_widgets[j]
                self.flag.assign(w["position"], tuple(rounded(v, 2) for v in t * 1e3))
                self.flag.assign(w["axis"], (rounded(roll, 3), rounded(pitch, 3)))
                self.flag.assign(w["spin"], rounded(spin, 3))
                poses.append((light, t, R))
        lines = []
        for j, (light, t, R) in enumerate(poses):
            pose = describe_pose(R, t)
            ax = np.asarray(pose["axis_camera"]) + 0.0  # no "-0.0000"
            scale = f", scale {light.scale:.4g}" if isinstance(light, Light) else ""
            if scale and display is not None and len(display.channels) == len(channels) > 0:
                scale = ", scales " + ", ".join(  # each colour channel's (`sensor.channels`)
                    f"{md(ch)} {rig.lights[j].scale:.4g}"
                    for ch, (rig, _, _) in zip(channels, display.channels, strict=True)
                )
            lines.append(
                f"**{md(names[j])}**: axis ({ax[0]:+.4f}, {ax[1]:+.4f}, {ax[2]:+.4f}), "
                f"{pose['axis_angle_from_optical_axis_deg']:.2f}° from the optical axis{scale}"
            )
        source = (
            "current estimate"
            if display is not None and display.source == "estimate"
            else "initial guess"
        )
        self.light_md.content = (
            f"Showing the **{source}**. Drag the gizmo (orange camera) or type numbers; "
            "either starts the solve over from there.\n\n" + "  \n".join(lines)
        ) + (f"\n\n{ports}" if ports else "")
