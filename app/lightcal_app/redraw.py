"""The one redraw: pictures on the frusta, the light, the rays and the panel, from a
`Frame` (a copy of the state), pushed inside `server.atomic()`.

Exact values stay on the server; the pictures are computed here (`OverlayImages`), with
renders cached per display so that a change of the selection alone does not re-render.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from lightcal.core.scene import Light
from lightcal_app.albedo_scene import AlbedoOnWall
from lightcal_app.overlays import OverlayImages, dimmed, draw_name, shared_vmax
from lightcal_app.plan_scene import PlanScene
from lightcal_app.scene3d import Scene3D
from lightcal_app.state import AppState, Display, Frame, LightGuess


class Redrawer:
    """Draws frames.

    Args:
        server: the viser server.
        state: the shared state (read for the project and messages; `drawn` is set).
        scene: the 3D view.
        overlays: the pictures of the current project.
    """

    def __init__(
        self, server: Any, state: AppState, scene: Scene3D, overlays: OverlayImages
    ) -> None:
        self.server = server
        self.state = state
        self.scene = scene
        self.plan_scene = PlanScene(scene.scene)
        self.albedo_wall = AlbedoOnWall(scene.scene)
        self.overlays = overlays
        self.panels: Any = None
        self.truth: list[LightGuess] | None = None
        self.timings: dict[str, float] = {}
        # Per (session_gen, iteration) drawn: the timings of the redraw that first showed
        # it (later redraws, e.g. of the Plan tab's read-out, do not overwrite them).
        self.iteration_timings: dict[tuple[int, int], dict[str, float]] = {}
        self.legend_vmax: float | None = None
        self._render_cache: dict[int, tuple[Display, np.ma.MaskedArray]] = {}

    def set_overlays(self, overlays: OverlayImages) -> None:
        """Another project's pictures."""
        self.overlays = overlays
        self._render_cache.clear()

    def pictures(self, frame: Frame) -> dict[int, np.ndarray]:
        ov = self.overlays
        names = ov.project.names
        display = frame.display
        rendered: dict[int, np.ma.MaskedArray] = {}
        for i, kind in enumerate(frame.overlay):
            if kind == "real" or display is None:
                continue
            cached = self._render_cache.get(i)
            if cached is not None and cached[0] is display:
                rendered[i] = cached[1]
            else:
                rendered[i] = ov.render(i, display)
                self._render_cache[i] = (display, rendered[i])
        residuals = [
            ov.residual(i, r) for i, r in rendered.items() if frame.overlay[i] == "residual"
        ]
        vmax = shared_vmax(residuals) if residuals else None
        self.legend_vmax = vmax
        out = {}
        for i, kind in enumerate(frame.overlay):
            rgb = ov.picture(i, kind, rendered=rendered.get(i), residual_vmax=vmax or 1.0)
            if frame.show_selection:
                rgb = ov.draw_selection(
                    rgb,
                    i,
                    selected=frame.selected[i],
                    binning=frame.selected_binning[i],
                    regions=frame.regions[i],
                    points=frame.points[i],
                )
            if frame.focus_image is not None and i != frame.focus_image:
                rgb = dimmed(rgb)
            out[i] = draw_name(rgb, names[i])
        return out

    def redraw(self, frame: Frame) -> None:
        t0 = time.perf_counter()
        d = frame.dirty
        st = self.state
        with st.lock:
            project = st.project
            surroundings = st.solve_project.surroundings  # as the page edits them
        pictures: dict[int, np.ndarray] = {}
        if d & {"overlays", "selection", "scene"}:
            pictures = self.pictures(frame)
        t1 = time.perf_counter()
        lights: list[Light | LightGuess] = (
            list(frame.display.rig.lights) if frame.display else list(frame.guess)
        )
        with self.server.atomic():
            if "scene" in d:
                self.scene.build(
                    project,
                    pictures=[pictures[i] for i in range(len(project.names))],
                    guess=list(frame.guess),
                    ref_image=frame.ref_image,
                    truth=self.truth,
                )
                if self.panels is not None:
                    self.panels.set_project(project)
            elif pictures:
                self.scene.set_pictures(pictures)
            if d & {"overlays", "scene"}:
                self.scene.set_focus(frame.focus_image, frame.ref_image)
                # Colour channels: the highlighted image's pictures, else the gizmo's image's.
                pictured = frame.ref_image if frame.focus_image is None else frame.focus_image
                self.scene.set_channel(project.channel_index(pictured))
            if d & {"light", "scene"}:
                self.scene.set_surroundings(surroundings)
                self.scene.set_lights(lights)
                rig = frame.display.rig if frame.display is not None else None
                self.scene.set_rays(rig, frame.wall_points, frame.rays_image)
                self.albedo_wall.draw(
                    frame.display.albedo if frame.display is not None else None,
                    visible=frame.show_albedo,
                    rebuilt="scene" in d,
                )
            if d & {"plan", "scene"}:
                self.scene.set_outlines_only(frame.show_plan and frame.plan is not None)
                self.plan_scene.draw(
                    frame.plan if frame.show_plan else None,
                    project.camera,
                    scale=self.scene.frustum_scale,
                    rebuilt="scene" in d,
                )
            if self.panels is not None:
                self.panels.update(frame, legend_vmax=self.legend_vmax, messages=list(st.messages))
        t2 = time.perf_counter()
        self.timings = {"pictures_s": t1 - t0, "send_s": t2 - t1, "redraw_s": t2 - t0}
        shown = (frame.session_gen, frame.iteration)
        if shown not in self.iteration_timings:
            if len(self.iteration_timings) > 64:  # only recent ones are asked for
                self.iteration_timings.clear()
            self.iteration_timings[shown] = self.timings
        with st.cond:
            if (frame.session_gen, frame.iteration) > st.drawn:
                st.drawn = (frame.session_gen, frame.iteration)
            st.cond.notify_all()
