"""The control panel: tabs for the light, the pixels, the view, the solve, the result,
files and an explanation of the model.

Every handle is server-level (`server.gui`), so all browsers see the same panel. The
callbacks only call `Controller` actions (state changes under the lock, queued
requests); `Panels.update` writes the state back into the widgets during a redraw. Its
writes fire the widgets' own callbacks with `client None`; a thread-local flag makes
those callbacks ignore them, so they are not taken for user edits.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
import viser

from lightcal.core.pose import (
    angles_from_axis,
    axis_from_angles,
    describe_pose,
    rotation_from_axis,
)
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.core.scene import Light
from lightcal.io.project import Project
from lightcal_app.controller import Controller
from lightcal_app.demo_truth import read_truth_lights, truth_path_for
from lightcal_app.explain import add_explanation
from lightcal_app.overlays import legend_picture
from lightcal_app.state import OVERLAY_KINDS, Frame, LightGuess, SelectionSettings
from lightcal_app.uploads import (
    MAX_UPLOAD_BYTES,
    format_size,
    receive_image,
    receive_project,
    receive_rid,
)

ALL_IMAGES = "all images"
AS_ALL = "(as all images)"
RECT_MODES = ("include region", "exclude region")
CLICK_MODES = ("does nothing", "adds a pixel", "removes nearby pixels")
STRATEGIES = ("random", "grid", "all")


def pose_angles_deg(R_camera_light: np.ndarray) -> tuple[float, float, float]:
    """(a, b, roll) in degrees of a light orientation: the axis chart angles
    (`lightcal.core.pose.angles_from_axis`: a tilts towards +x, b towards +y) and the
    roll about the axis relative to the minimal rotation from +z."""
    axis = R_camera_light[:, 2]
    a, b = angles_from_axis(axis / np.linalg.norm(axis))
    R0 = rotation_from_axis(axis / np.linalg.norm(axis))
    twist = R0.T @ R_camera_light  # a rotation about +z
    roll = math.atan2(twist[1, 0], twist[0, 0])
    return math.degrees(a), math.degrees(b), math.degrees(roll)


def rotation_from_angles_deg(a_deg: float, b_deg: float, roll_deg: float) -> np.ndarray:
    """The inverse of `pose_angles_deg`."""
    axis = axis_from_angles(math.radians(a_deg), math.radians(b_deg))
    return rotation_from_axis(axis) @ matrix_from_rotvec(
        np.array([0.0, 0.0, math.radians(roll_deg)])
    )


def assign(handle: Any, value: Any) -> None:
    """Set a widget's value (viser sends it to every browser and fires its callbacks)."""
    handle.value = value


def _round(v: float, digits: int) -> float:
    return float(round(float(v), digits))


class Panels:
    """Builds the GUI and keeps it in step with the state.

    Args:
        server: the viser server.
        controller: where user actions go.
        upload_limit_bytes: the per-file upload cap shown in the page.
    """

    def __init__(
        self,
        server: viser.ViserServer,
        controller: Controller,
        *,
        upload_limit_bytes: int = MAX_UPLOAD_BYTES,
    ) -> None:
        self.server = server
        self.ctl = controller
        self.upload_limit = upload_limit_bytes
        self._local = threading.local()
        gui = server.gui
        gui.configure_theme(
            show_share_button=False,
            control_width="large",
            brand_color=(230, 120, 0),
        )
        gui.set_panel_label("lightcal: light pose calibration")
        st = controller.state
        names = list(st.project.names)
        self.tabs = gui.add_tab_group()
        self._light_tab = self.tabs.add_tab("Light", viser.Icon.BULB)
        self._pixels_tab = self.tabs.add_tab("Pixels", viser.Icon.POINTER)
        self._view_tab = self.tabs.add_tab("View", viser.Icon.EYE)
        self._solve_tab = self.tabs.add_tab("Solve", viser.Icon.PLAYER_PLAY)
        self._result_tab = self.tabs.add_tab("Result", viser.Icon.LIST_CHECK)
        self._files_tab = self.tabs.add_tab("Files", viser.Icon.FILE)
        self._explain_tab = self.tabs.add_tab("Explain", viser.Icon.HELP)
        self.light_widgets: list[dict[str, Any]] = []
        self._light_folder_handles: list[Any] = []
        with self._light_tab:
            self.ref_image = gui.add_dropdown(
                "gizmo on image",
                names,
                initial_value=names[st.ref_image],
                hint="the camera pose on which the draggable light gizmo is drawn",
            )
            self.reset_guess = gui.add_button("Back to the project's initial guess")
            self.light_md = gui.add_markdown("")
        self._build_light_widgets(st.project)
        with self._pixels_tab:
            self._build_pixels(names)
        with self._view_tab:
            self._build_view(names)
        with self._solve_tab:
            self._build_solve()
        with self._result_tab:
            self.result_md = gui.add_markdown("")
            # Residuals against the mirror / incidence angle (the fit test's picture).
            self.fit_plot = gui.add_image(
                np.full((8, 8, 3), 255, dtype=np.uint8), label="residuals vs angle", visible=False
            )
            self.download_result = gui.add_button(
                "Download result (JSON)", icon=viser.Icon.DOWNLOAD
            )
            self.download_report = gui.add_button("Download report (zip)", icon=viser.Icon.DOWNLOAD)
        with self._files_tab:
            self._build_files()
        with self._explain_tab:
            add_explanation(gui)
        self.messages_md = gui.add_markdown("")
        self._wire()

    # ------------------------------------------------------------------ building

    @contextmanager
    def programmatic(self) -> Iterator[None]:
        """Widget writes inside are not user edits."""
        old = getattr(self._local, "on", False)
        self._local.on = True
        try:
            yield
        finally:
            self._local.on = old

    def _is_programmatic(self) -> bool:
        return bool(getattr(self._local, "on", False))

    def _build_light_widgets(self, project: Project) -> None:
        gui = self.server.gui
        for h in self._light_folder_handles:
            h.remove()
        self._light_folder_handles = []
        self.light_widgets = []
        with self._light_tab:
            for j, u in enumerate(project.lights):
                folder = gui.add_folder(f"{u.initial.name} ({u.kind()})", order=-10 + j)
                self._light_folder_handles.append(folder)
                with folder:
                    t = u.initial.t_camera_light * 1e3
                    position = (_round(t[0], 2), _round(t[1], 2), _round(t[2], 2))
                    a, b, roll = pose_angles_deg(u.initial.R_camera_light)
                    w: dict[str, Any] = {
                        "position": gui.add_vector3(
                            "position (mm)",
                            position,
                            step=0.1,
                            hint="emitter position in the camera frame: x right, y down, z forward",
                        ),
                        "tilt": gui.add_vector2(
                            "axis tilt a, b (deg)",
                            (_round(a, 3), _round(b, 3)),
                            step=0.1,
                            hint="angle of the light axis from the optical axis towards +x (a) "
                            "and +y (b); the tilt is hypot(a, b)",
                            visible=u.kind() != "isotropic",
                        ),
                        "roll": gui.add_number(
                            "roll about the axis (deg)",
                            _round(roll, 3),
                            step=0.1,
                            visible=u.kind() == "general",
                        ),
                    }
                self.light_widgets.append(w)
                self._wire_light(j, w)

    def _build_pixels(self, names: list[str]) -> None:
        gui = self.server.gui
        sel = self.ctl.state.selection
        self.sel_target = gui.add_dropdown(
            "settings apply to",
            [ALL_IMAGES, *names],
            initial_value=ALL_IMAGES,
            hint="edit the selection of every image, or give one image its own",
        )
        self.strategy = gui.add_dropdown("strategy", STRATEGIES, initial_value=sel.strategy)
        self.n_per_image = gui.add_number(
            "pixels per image (random)", sel.n_per_image, min=1, step=1
        )
        self.grid_step = gui.add_number("grid step (grid)", sel.grid_step, min=1, step=1)
        self.binning = gui.add_number("binning b (all)", sel.binning, min=1, max=64, step=1)
        self.seed = gui.add_number("seed", sel.seed, step=1)
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
        self.selection_md = gui.add_markdown("")

    def _build_view(self, names: list[str]) -> None:
        gui = self.server.gui
        self.overlay_all = gui.add_dropdown(
            "images show",
            OVERLAY_KINDS,
            initial_value=self.ctl.state.overlay_default,
            hint="real image, image rendered with the current light, or real minus rendered",
        )
        self.overlay_image = gui.add_dropdown("image", names, initial_value=names[0])
        self.overlay_one = gui.add_dropdown(
            "this image shows", [AS_ALL, *OVERLAY_KINDS], initial_value=AS_ALL
        )
        self.look_through = gui.add_button("Look through image", icon=viser.Icon.CAMERA)
        self.rays = gui.add_dropdown(
            "rays from the light for",
            ["none", "all", *names],
            initial_value=self.ctl.state.rays_image,
        )
        self.legend_md = gui.add_markdown(
            "**Residual colours** (shown when an image shows *residual*):"
        )
        self.legend = gui.add_image(legend_picture(1.0), label="residual scale", format="png")

    def _build_solve(self) -> None:
        gui = self.server.gui
        self.step_button = gui.add_button(
            "Step", icon=viser.Icon.PLAYER_TRACK_NEXT, hint="one iteration"
        )
        self.run_button = gui.add_button(
            "Run", icon=viser.Icon.PLAYER_PLAY, hint="until convergence"
        )
        self.pause_button = gui.add_button("Pause", icon=viser.Icon.PLAYER_PAUSE)
        self.reset_button = gui.add_button(
            "Reset", icon=viser.Icon.REFRESH, hint="stop and go back to the initial guess"
        )
        self.status_md = gui.add_markdown("")
        empty = np.zeros(0)
        self.cost_plot = gui.add_uplot(
            (empty, empty),
            ({"label": "iteration"}, {"label": "cost", "stroke": "#d9480f", "width": 2}),
            title="cost (log scale)",
            axes=({}, {"size": 100}),
            scales={"x": {"time": False, "range": (None, None)}, "y": {"distr": 3, "log": 10}},
            aspect=1.6,
        )
        self.position_plot = gui.add_uplot(
            (empty, empty),
            ({"label": "iteration"}, {"label": "-"}),
            title="position (mm, camera frame)",
            axes=({}, {"size": 64}),
            scales={"x": {"time": False, "range": (None, None)}},
            aspect=1.6,
        )
        self.angle_plot = gui.add_uplot(
            (empty, empty),
            ({"label": "iteration"}, {"label": "-"}),
            title="axis angles (deg)",
            axes=({}, {"size": 64}),
            scales={"x": {"time": False, "range": (None, None)}},
            aspect=1.6,
        )

    def _build_files(self) -> None:
        gui = self.server.gui
        gui.add_markdown(
            "The session (guess, selection, regions, solve) is **autosaved** after every change"
            + (f" to `{self.ctl.session_path}`" if self.ctl.session_path else "")
            + " and restored at start."
        )
        self.save_session = gui.add_button("Save session", icon=viser.Icon.DEVICE_FLOPPY)
        self.reload_session = gui.add_button("Reload saved session")
        self.upload_session = gui.add_upload_button("Load a session file", mime_type=".json")
        gui.add_markdown(
            f"**Uploads** (at most {format_size(self.upload_limit)} per file; a zip may unpack "
            "to 500 MB): "
            "a project (zip of project.json, camera file and images, or a project file), "
            "an image replacing the project image of the same file name, or an IES/LDT file "
            "as a light's RID. Every upload is checked with the project readers first."
        )
        self.upload_project = gui.add_upload_button(
            "Upload a project", mime_type=".zip,.json,.yaml,.yml"
        )
        self.upload_image = gui.add_upload_button(
            "Upload an image", mime_type="image/*,.tif,.tiff,.npy,.exr,.dng"
        )
        names = [u.initial.name for u in self.ctl.state.project.lights]
        self.rid_light = gui.add_dropdown("RID file for light", names, initial_value=names[0])
        self.upload_rid = gui.add_upload_button("Upload an IES/LDT file", mime_type=".ies,.ldt")

    # ------------------------------------------------------------------ callbacks

    def _guard(self, fn: Callable[[Any], None]) -> Callable[[Any], None]:
        def cb(event: Any) -> None:
            if event.client is None and self._is_programmatic():
                return
            fn(event)

        return cb

    def _wire_light(self, j: int, w: dict[str, Any]) -> None:
        ctl = self.ctl

        @w["position"].on_update
        @self._guard
        def _(event: Any) -> None:
            ctl.set_guess(j, position_m=np.array(w["position"].value, dtype=float) / 1e3)

        def orientation(event: Any) -> None:
            a, b = w["tilt"].value
            R = rotation_from_angles_deg(float(a), float(b), float(w["roll"].value))
            ctl.set_guess(j, R_camera_light=R)

        w["tilt"].on_update(self._guard(orientation))
        w["roll"].on_update(self._guard(orientation))

    def _selection_from_widgets(self) -> SelectionSettings:
        return SelectionSettings(
            self.strategy.value,  # type: ignore[arg-type]
            max(1, int(self.n_per_image.value)),
            max(1, int(self.grid_step.value)),
            max(1, int(self.binning.value)),
            int(self.seed.value),
        )

    def _wire(self) -> None:
        ctl = self.ctl
        g = self._guard

        self.ref_image.on_update(
            g(lambda e: ctl.set_ref_image(ctl.state.project.names.index(self.ref_image.value)))
        )
        self.reset_guess.on_click(lambda e: ctl.reset_guess())

        def selection_changed(event: Any) -> None:
            target = self.sel_target.value
            ctl.set_selection(
                self._selection_from_widgets(), image=None if target == ALL_IMAGES else target
            )

        for h in (self.strategy, self.n_per_image, self.grid_step, self.binning, self.seed):
            h.on_update(g(selection_changed))

        def target_changed(event: Any) -> None:
            self._show_selection_settings()

        self.sel_target.on_update(target_changed)

        def clear_override(event: Any) -> None:
            if self.sel_target.value != ALL_IMAGES:
                ctl.clear_selection_override(self.sel_target.value)

        self.clear_override.on_click(clear_override)
        self.clear_regions.on_click(lambda e: ctl.clear_regions())
        self.clear_points.on_click(lambda e: ctl.clear_points())
        self.show_selection.on_update(
            g(lambda e: ctl.set_show_selection(self.show_selection.value))
        )
        self.overlay_all.on_update(g(lambda e: ctl.set_overlay(self.overlay_all.value)))

        def overlay_one(event: Any) -> None:
            v = self.overlay_one.value
            ctl.set_overlay(None if v == AS_ALL else v, image=self.overlay_image.value)  # type: ignore[arg-type]

        self.overlay_one.on_update(g(overlay_one))

        def overlay_image(event: Any) -> None:
            with ctl.state.lock:
                v = ctl.state.overlay_per_image.get(self.overlay_image.value, AS_ALL)
            with self.programmatic():
                assign(self.overlay_one, v)

        self.overlay_image.on_update(overlay_image)
        self.look_through.on_click(self._look_through)
        self.rays.on_update(g(lambda e: ctl.set_rays(self.rays.value)))
        self.step_button.on_click(lambda e: ctl.step())
        self.run_button.on_click(lambda e: ctl.run())
        self.pause_button.on_click(lambda e: ctl.pause())
        self.reset_button.on_click(lambda e: ctl.reset())
        self.download_result.on_click(lambda e: ctl.request_download("result", e.client))
        self.download_report.on_click(lambda e: ctl.request_download("report", e.client))
        self.save_session.on_click(lambda e: ctl.save_session(e.client))
        self.reload_session.on_click(lambda e: ctl.load_saved_session(e.client))

        @self.upload_session.on_upload
        def _(event: Any) -> None:
            f = self.upload_session.value
            ctl.load_session_bytes(f.name, f.content, event.client)

        self.upload_project.on_upload(self._on_project_upload)
        self.upload_image.on_upload(self._on_image_upload)
        self.upload_rid.on_upload(self._on_rid_upload)

        scene = self.server.scene

        @scene.on_click()
        def _(event: Any) -> None:
            mode = {"adds a pixel": "add", "removes nearby pixels": "remove"}.get(
                self.click_mode.value
            )
            if mode is not None:
                ctl.click(np.array(event.ray_origin), np.array(event.ray_direction), mode=mode)

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

    def _look_through(self, event: Any) -> None:
        """Move the browser's camera (all browsers when the click has no client) to the
        chosen image's camera, looking at the wall as the image does."""
        st = self.ctl.state
        with st.lock:
            i = st.project.names.index(self.overlay_image.value)
            view = st.project.views[i]
            fov = st.project.camera.fov_y_rad
        R_wc = view.R_camera_world.T
        centre = view.center_world
        clients = (
            [event.client] if event.client is not None else list(self.server.get_clients().values())
        )
        for client in clients:
            with client.atomic():
                client.camera.fov = min(math.radians(100.0), 1.15 * fov)
                client.camera.up_direction = -R_wc[:, 1]
                client.camera.position = centre - 0.02 * R_wc[:, 2]
                client.camera.look_at = centre + float(centre[2]) * R_wc[:, 2]

    def _upload(self, handle: Any, event: Any, receive: Callable[[str, bytes], None]) -> None:
        f = handle.value
        try:
            receive(f.name, f.content)
        except Exception as exc:
            self.ctl.notify(event.client, f"Upload rejected: {f.name}", str(exc), error=True)

    def _on_project_upload(self, event: Any) -> None:
        ctl = self.ctl

        def receive(name: str, content: bytes) -> None:
            project, loaded = receive_project(
                name, content, ctl.upload_root, limit=self.upload_limit
            )
            truth = None
            truth_file = truth_path_for(project.path)
            if ctl.truth is not None and truth_file.is_file():  # demo mode: its ghost too
                truth = read_truth_lights(truth_file)
                if len(truth) != len(project.lights):
                    truth = None
            ctl.switch_project(
                project,
                loaded,
                truth=truth,
                keep_choices=False,
                client=event.client,
                note=f"Project {name} loaded: {len(project.names)} images.",
            )

        self._upload(self.upload_project, event, receive)

    def _on_image_upload(self, event: Any) -> None:
        ctl = self.ctl

        def receive(name: str, content: bytes) -> None:
            with ctl.state.lock:
                project = ctl.state.project
            new, loaded, index = receive_image(
                name, content, project, ctl.upload_root, limit=self.upload_limit
            )
            ctl.switch_project(
                new,
                loaded,
                truth=ctl.truth,
                keep_choices=True,
                client=event.client,
                note=f"Image {project.names[index]} replaced by {name}.",
            )

        self._upload(self.upload_image, event, receive)

    def _on_rid_upload(self, event: Any) -> None:
        ctl = self.ctl

        def receive(name: str, content: bytes) -> None:
            with ctl.state.lock:
                project = ctl.state.project
            names = [u.initial.name for u in project.lights]
            j = names.index(self.rid_light.value) if self.rid_light.value in names else 0
            new, loaded = receive_rid(
                name, content, project, j, ctl.upload_root, limit=self.upload_limit
            )
            ctl.switch_project(
                new,
                loaded,
                truth=ctl.truth,
                keep_choices=True,
                client=event.client,
                note=f"Light {names[j]} now uses the RID of {name}.",
            )

        self._upload(self.upload_rid, event, receive)

    # ------------------------------------------------------------------ updates (worker)

    def set_project(self, project: Project) -> None:
        """Options that depend on the project (after an upload)."""
        names = list(project.names)
        with self.programmatic():
            for h in (self.ref_image, self.overlay_image):
                h.options = names
            self.sel_target.options = [ALL_IMAGES, *names]
            self.rays.options = ["none", "all", *names]
            lights = [u.initial.name for u in project.lights]
            self.rid_light.options = lights
        if len(self.light_widgets) != len(project.lights) or any(
            f.label != f"{u.initial.name} ({u.kind()})"
            for f, u in zip(self._light_folder_handles, project.lights, strict=False)
        ):
            self._build_light_widgets(project)

    def _show_selection_settings(self) -> None:
        st = self.ctl.state
        target = self.sel_target.value
        with st.lock:
            s = (
                st.selection
                if target == ALL_IMAGES
                else st.selection_per_image.get(target, st.selection)
            )
        with self.programmatic():
            assign(self.strategy, s.strategy)
            assign(self.n_per_image, s.n_per_image)
            assign(self.grid_step, s.grid_step)
            assign(self.binning, s.binning)
            assign(self.seed, s.seed)

    def update(
        self, frame: Frame, *, legend_vmax: float | None, messages: list[tuple[str, str]]
    ) -> None:
        """Write the frame into the widgets (called by the redraw, in `server.atomic()`)."""
        d = frame.dirty
        with self.programmatic():
            if d & {"widgets", "scene"}:
                self._sync_light_widgets(frame)
                self._show_selection_settings()
                st = self.ctl.state
                with st.lock:
                    assign(self.overlay_all, st.overlay_default)
                    assign(self.show_selection, st.show_selection)
                    assign(self.rays, st.rays_image)
                    assign(self.ref_image, st.project.names[st.ref_image])
            if d & {"selection", "status", "scene"}:
                self.selection_md.content = self._selection_text(frame)
            if d & {"plots", "scene"}:
                self._update_plots(frame)
            if d & {"status", "plots", "scene"}:
                self.status_md.content = self._status_text(frame)
            if d & {"result", "scene"}:
                from lightcal_app.results import result_markdown

                self.result_md.content = result_markdown(frame.result, state=frame.solver_state)
                fit = frame.result.fit if frame.result is not None else None
                if fit:
                    from lightcal.io.figures import angle_residual_figure

                    self.fit_plot.image = angle_residual_figure(fit, size=(720, 300))
                self.fit_plot.visible = bool(fit)
            if (
                legend_vmax is not None
                and d & {"overlays", "scene"}
                and getattr(self, "_legend_shown", None) != legend_vmax
            ):
                self._legend_shown = legend_vmax
                self.legend.image = legend_picture(legend_vmax)
                self.legend_md.content = (
                    f"**Residual colours**: real − rendered, ±{legend_vmax:.4g} pixel values "
                    "(99th percentile over the images shown as residual; grey: no value)."
                )
            text = "\n".join(f"**{t}**: {b}  " for t, b in messages[-3:]) if messages else ""
            if text != getattr(self, "_messages_shown", None):
                self._messages_shown = text
                self.messages_md.content = text

    def _sync_light_widgets(self, frame: Frame) -> None:
        lights: list[Light | LightGuess] = (
            list(frame.display.rig.lights) if frame.display is not None else list(frame.guess)
        )
        lines = []
        for j, light in enumerate(lights):
            if j >= len(self.light_widgets):
                break
            if isinstance(light, Light):
                t, R = light.t_camera_light, light.R_camera_light
            else:
                t, R = light.position_m, light.R_camera_light
            a, b, roll = pose_angles_deg(R)
            w = self.light_widgets[j]
            assign(w["position"], tuple(_round(v, 2) for v in t * 1e3))
            assign(w["tilt"], (_round(a, 3), _round(b, 3)))
            assign(w["roll"], _round(roll, 3))
            pose = describe_pose(R, t)
            ax = np.asarray(pose["axis_camera"]) + 0.0  # no "-0.0000"
            scale = f", scale {light.scale:.4g}" if isinstance(light, Light) else ""
            lines.append(
                f"**{self.ctl.state.project.lights[j].initial.name}**: axis ({ax[0]:+.4f}, "
                f"{ax[1]:+.4f}, {ax[2]:+.4f}), "
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

    def _selection_text(self, frame: Frame) -> str:
        names = self.ctl.state.project.names
        total = sum(frame.selection_summary)
        rows = [f"**{total} pixels** selected in {len(names)} images:  "]
        rows.append(
            ", ".join(f"{n}: {k}" for n, k in zip(names, frame.selection_summary, strict=True))
        )
        n_regions = sum(len(r) for r in frame.regions)
        n_points = sum(len(p) for p in frame.points)
        if n_regions or n_points:
            rows.append(f"\n\n{n_regions} region(s) and {n_points} clicked pixel(s) apply.")
        return "\n".join(rows)

    def _status_text(self, frame: Frame) -> str:
        if not frame.history:
            return f"**{frame.solver_state}**: press Step or Run. {frame.solver_message}"
        last = frame.history[-1]
        return (
            f"**{frame.solver_state}** {frame.solver_message}  \n"
            f"iteration {last.iteration}, cost {last.cost:.6g}, "
            f"|gradient| {last.gradient_norm:.3g}, "
            f"{last.nfev} evaluations"
            + (" (re-weighted: pixel sigmas from the rendered values)" if last.reweighted else "")
        )

    def _update_plots(self, frame: Frame) -> None:
        """Cost and parameters per iteration. The scales are set with the data: uPlot
        keeps its first scales on data pushes."""
        hist = frame.history
        it = np.array([h.iteration for h in hist], dtype=np.float64)
        x_range = (0.0, float(max(it.max(), 1.0))) if hist else (0.0, 1.0)
        cost = np.array([max(h.cost, 1e-300) for h in hist], dtype=np.float64)
        if hist:
            lo = 10.0 ** math.floor(math.log10(cost.min()))
            hi = 10.0 ** math.ceil(math.log10(cost.max()))
            cost_range = (lo, hi if hi > lo else 10 * lo)
        else:
            cost_range = (1.0, 10.0)
        self.cost_plot.scales = {
            "x": {"time": False, "range": x_range},
            "y": {"distr": 3, "log": 10, "range": cost_range},
        }
        self.cost_plot.data = (it, cost)
        names = list(frame.parameter_names)
        xs = np.array([h.x for h in hist]) if hist else np.zeros((0, len(names)))
        colours = ("#1c7ed6", "#2f9e44", "#e8590c", "#ae3ec9", "#f08c00", "#0c8599")
        for plot, suffix, factor in (
            (self.position_plot, "_m", 1e3),
            (self.angle_plot, "_rad", 180.0 / math.pi),
        ):
            cols = [k for k, n in enumerate(names) if n.endswith(suffix)]
            if not cols or not hist:
                plot.data = (np.zeros(0), np.zeros(0))
                plot.series = ({"label": "iteration"}, {"label": "-"})
                continue
            series: list[Any] = [{"label": "iteration"}] + [
                {
                    "label": names[k].removesuffix(suffix),
                    "stroke": colours[c % len(colours)],
                    "width": 2,
                }
                for c, k in enumerate(cols)
            ]
            values = xs[:, cols] * factor
            lo, hi = float(values.min()), float(values.max())
            pad = max(0.05 * (hi - lo), 1e-3 * max(abs(lo), abs(hi)), 1e-6)
            plot.scales = {
                "x": {"time": False, "range": x_range},
                "y": {"range": (lo - pad, hi + pad)},
            }
            plot.series = tuple(series)
            plot.data = (it, *(values[:, c] for c in range(len(cols))))
