"""The Pixels tab: the selection strategy (for all images or one), regions and clicks."""

from __future__ import annotations

from typing import Any

import numpy as np
import viser

from lightcal.io.project import Project
from lightcal_app.controller import Controller
from lightcal_app.limits import (
    MAX_BINNING,
    MAX_GRID_STEP,
    MAX_PIXELS_PER_IMAGE,
    MAX_SEED,
    check_selection,
)
from lightcal_app.panels.base import LiveText, Programmatic, TabPanel
from lightcal_app.state import Frame, SelectionSettings
from lightcal_app.text import md

ALL_IMAGES = "all images"
RECT_MODES = ("include region", "exclude region")
CLICK_MODES = ("does nothing", "adds a pixel", "removes nearby pixels")
STRATEGIES = ("random", "grid", "all")
SELECTING = "selecting the pixels"


class PixelsPanel(TabPanel):
    """The Pixels tab (built in the current GUI container)."""

    def __init__(self, server: viser.ViserServer, ctl: Controller, flag: Programmatic) -> None:
        super().__init__(server, ctl, flag)
        gui = self.gui
        names = list(ctl.state.project.names)
        sel = ctl.state.selection
        self.sel_target = gui.add_dropdown(
            "settings apply to",
            [ALL_IMAGES, *names],
            initial_value=ALL_IMAGES,
            hint="edit the selection of every image, or give one image its own",
        )
        self.strategy = gui.add_dropdown("strategy", STRATEGIES, initial_value=sel.strategy)
        self.n_per_image = gui.add_number(
            "pixels per image (random)", sel.n_per_image, min=1, max=MAX_PIXELS_PER_IMAGE, step=1
        )
        self.grid_step = gui.add_number(
            "grid step (grid)", sel.grid_step, min=1, max=MAX_GRID_STEP, step=1
        )
        self.binning = gui.add_number(
            "binning b (all)", sel.binning, min=1, max=MAX_BINNING, step=1
        )
        self.seed = gui.add_number("seed", sel.seed, min=0, max=MAX_SEED, step=1)
        self.clear_override = gui.add_button("This image: use the settings of all images")
        gui.add_markdown(
            "**Regions**: hold *Shift* and drag over an image in the 3D view to draw a region "
            "(tip: *View > Look through image*). **Clicks** on an image add or remove pixels."
        )
        self.rect_mode = gui.add_dropdown(
            "shift-drag draws", RECT_MODES, initial_value=RECT_MODES[0]
        )
        self.click_mode = gui.add_dropdown(
            "a click on an image", CLICK_MODES, initial_value=CLICK_MODES[0]
        )
        self.clear_regions = gui.add_button("Clear all regions")
        self.clear_points = gui.add_button("Clear all clicked pixels")
        self.show_selection = gui.add_checkbox("show selection and masks on the images", True)
        self.selection_text = LiveText(gui)
        self._wire()

    def _settings(self) -> SelectionSettings:
        # What the page sent, checked against the widgets' ranges (InputError: refused).
        return SelectionSettings(
            *check_selection(  # type: ignore[arg-type]
                self.strategy.value,
                self.n_per_image.value,
                self.grid_step.value,
                self.binning.value,
                self.seed.value,
            )
        )

    def _wire(self) -> None:
        ctl = self.ctl

        def selection_changed(event: Any) -> None:
            target = self.sel_target.value
            self.selection_text.mark_stale(SELECTING)
            ctl.set_selection(self._settings(), image=None if target == ALL_IMAGES else target)

        for h in (self.strategy, self.n_per_image, self.grid_step, self.binning, self.seed):
            h.on_update(self.guard(selection_changed))
        self.sel_target.on_update(self.guard(lambda e: self.show_settings()))

        def clear_override(event: Any) -> None:
            if self.sel_target.value != ALL_IMAGES:
                self.selection_text.mark_stale(SELECTING)
                ctl.clear_selection_override(self.sel_target.value)

        def cleared(clear: Any) -> Any:
            def cb(event: Any) -> None:
                self.selection_text.mark_stale(SELECTING)
                clear()

            return cb

        self.clear_override.on_click(self.guard(clear_override))
        self.clear_regions.on_click(cleared(ctl.clear_regions))
        self.clear_points.on_click(cleared(ctl.clear_points))
        self.show_selection.on_update(
            self.guard(lambda e: ctl.set_show_selection(self.show_selection.value))
        )

        scene = self.server.scene

        @scene.on_click()
        def _(event: Any) -> None:
            mode = {"adds a pixel": "add", "removes nearby pixels": "remove"}.get(
                self.click_mode.value
            )
            if mode is not None:
                ctl.click(event.ray_origin, event.ray_direction, mode=mode, client=event.client)

        @scene.on_rect_select(modifier="shift")
        def _(event: Any) -> None:
            cam = event.client.camera
            ctl.rect(
                event.screen_min,
                event.screen_max,
                camera_position=np.array(cam.position),
                camera_wxyz=np.array(cam.wxyz),
                fov_y_rad=float(cam.fov),
                aspect=float(cam.aspect),
                include=self.rect_mode.value == RECT_MODES[0],
                client=event.client,
            )

    def show_settings(self) -> None:
        """The settings of the chosen target (all images or one) into the widgets."""
        st = self.ctl.state
        target = self.sel_target.value
        with st.lock, self.flag.writing():
            s = (
                st.selection
                if target == ALL_IMAGES
                else st.selection_per_image.get(target, st.selection)
            )
            self.flag.assign(self.strategy, s.strategy)
            self.flag.assign(self.n_per_image, s.n_per_image)
            self.flag.assign(self.grid_step, s.grid_step)
            self.flag.assign(self.binning, s.binning)
            self.flag.assign(self.seed, s.seed)

    def set_project(self, project: Project) -> None:
        self.sel_target.options = [ALL_IMAGES, *project.names]

    def update(self, frame: Frame) -> None:
        d = frame.dirty
        if d & {"widgets", "scene"}:
            self.show_settings()
            with self.ctl.state.lock:
                self.flag.assign(self.show_selection, self.ctl.state.show_selection)
        if d & {"selection", "status", "scene", "widgets"}:
            self.selection_text.show(self._selection_text(frame))

    def _selection_text(self, frame: Frame) -> str:
        names = self.ctl.state.project.names
        total = sum(frame.selection_summary)
        rows = [f"**{total} pixels** selected in {len(names)} images:  "]
        rows.append(
            ", ".join(f"{md(n)}: {k}" for n, k in zip(names, frame.selection_summary, strict=True))
        )
        n_regions = sum(len(r) for r in frame.regions)
        n_points = sum(len(p) for p in frame.points)
        if n_regions or n_points:
            rows.append(f"\n\n{n_regions} region(s) and {n_points} clicked pixel(s) apply.")
        return "\n".join(rows)
