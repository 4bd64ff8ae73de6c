"""The control panel: one class per tab (light, pixels, view, solve, result, plan,
files, explanation) in one tab group, and the messages box under it.

`Panels` builds them and passes each redraw's `Frame` to every tab's `update`, inside
the shared programmatic-write flag (see `lightcal_app.panels.base`).
"""

from __future__ import annotations

import viser

from lightcal.io.project import Project
from lightcal_app.controller import Controller
from lightcal_app.explain import PROJECT_FIGURES, add_explanation
from lightcal_app.panels.base import Programmatic
from lightcal_app.panels.files import FilesPanel
from lightcal_app.panels.light import LightPanel, pose_angles_deg, rotation_from_angles_deg
from lightcal_app.panels.pixels import PixelsPanel
from lightcal_app.panels.plan import PlanPanel
from lightcal_app.panels.result import ResultPanel
from lightcal_app.panels.solve import SolvePanel
from lightcal_app.panels.view import ViewPanel
from lightcal_app.state import Frame
from lightcal_app.text import md_prose

__all__ = ["Panels", "pose_angles_deg", "rotation_from_angles_deg"]


IDLE_LINE = "Ready: nothing running."
"""The busy line's text when the server is idle."""


class Panels:
    """Builds the GUI and keeps it in step with the state.

    Args:
        server: the viser server.
        controller: where user actions go.
    """

    def __init__(self, server: viser.ViserServer, controller: Controller) -> None:
        self.server = server
        self.ctl = controller
        self.flag = Programmatic()
        gui = server.gui
        gui.configure_theme(
            show_share_button=False,
            control_width="large",
            brand_color=(230, 120, 0),
        )
        gui.set_panel_label("lightcal: light pose calibration")
        flag = self.flag
        # Until the first redraw has put the scene in place: never an empty view unexplained.
        n = len(controller.state.project.names)
        self.loading_md = gui.add_markdown(
            f"**Loading**: rendering the pictures of the {n} images and building the "
            "scene (a few seconds)..."
        )
        # What the server is doing right now (set by the worker before the work starts).
        # Always one line, so that the panel below does not jump when work starts.
        self.work_md = gui.add_markdown(IDLE_LINE)
        self.tabs = gui.add_tab_group()
        light_tab = self.tabs.add_tab("Light", viser.Icon.BULB)
        self.light = LightPanel(server, controller, flag, light_tab)
        with self.tabs.add_tab("Pixels", viser.Icon.POINTER):
            self.pixels = PixelsPanel(server, controller, flag)
        with self.tabs.add_tab("View", viser.Icon.EYE):
            self.view = ViewPanel(server, controller, flag)
        with self.tabs.add_tab("Solve", viser.Icon.PLAYER_PLAY):
            self.solve = SolvePanel(server, controller, flag)
        with self.tabs.add_tab("Result", viser.Icon.LIST_CHECK):
            self.result = ResultPanel(server, controller, flag)
        with self.tabs.add_tab("Plan", viser.Icon.CAMERA_PLUS):
            self.plan = PlanPanel(server, controller, flag)
        with self.tabs.add_tab("Files", viser.Icon.FILE):
            self.files = FilesPanel(server, controller, flag)
        with self.tabs.add_tab("Explain", viser.Icon.HELP):
            self.explain_figures = add_explanation(gui, controller.state.project)
        self.rid_figure = self.explain_figures.get("rid.png")
        self.messages_md = gui.add_markdown("")
        self._messages_shown: str | None = None

    def show_work(self, text: str) -> None:
        """The busy line: "Working: <text>..." while the server works, `IDLE_LINE` when
        idle (one line either way: the panel does not shift)."""
        self.work_md.content = f"**Working**: {md_prose(text)}..." if text else IDLE_LINE

    def set_project(self, project: Project) -> None:
        """Options that depend on the project (after an upload)."""
        with self.flag.writing():
            self.light.set_project(project)
            self.pixels.set_project(project)
            self.view.set_project(project)
            self.solve.set_project(project)
            self.files.set_project(project)
            for key, handle in self.explain_figures.items():
                handle.image = PROJECT_FIGURES[key](project)

    def update(
        self, frame: Frame, *, legend_vmax: float | None, messages: list[tuple[str, str]]
    ) -> None:
        """Write the frame into the widgets (called by the redraw, in `server.atomic()`)."""
        with self.flag.writing():
            if self.loading_md.visible and "scene" in frame.dirty:
                self.loading_md.visible = False
            self.light.update(frame)
            self.pixels.update(frame)
            self.view.update(frame, legend_vmax=legend_vmax)
            self.solve.update(frame)
            self.result.update(frame)
            self.plan.update(frame)
            text = (  # names and paths come from files and users: shown, never rendered
                "\n".join(f"**{md_prose(t)}**: {md_prose(b)}  " for t, b in messages[-3:])
                if messages
                else ""
            )
            if text != self._messages_shown:
                self._messages_shown = text
                self.messages_md.content = text
