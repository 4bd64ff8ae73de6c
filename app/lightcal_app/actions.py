"""What the user can do: every action changes `AppState` under its lock or queues a
typed request for the worker, and returns at once (viser runs callbacks in a thread
pool, so several may run at the same time). No viser import: `Controller` adds the
worker and the services.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from lightcal.core.light_axis import rotation_from_axis
from lightcal.core.rotations import as_finite_array, matrix_from_quaternion_wxyz
from lightcal.errors import InputError, LightcalError
from lightcal.io.surroundings_spec import SurroundingsSpec
from lightcal.pipeline.auto_start import beam_guess
from lightcal_app.limits import check_plan, check_position_m, check_rotation, check_selection
from lightcal_app.picking import FrustumPlane, pick, rect_to_polygon
from lightcal_app.requests import (
    DownloadKind,
    LoadSavedSession,
    Pause,
    PlanViews,
    PrepareDownload,
    Reset,
    RestorePrevious,
    SaveSession,
    Solve,
)
from lightcal_app.solve_service import Notify
from lightcal_app.solve_settings import (
    SolveSettings,
    check_settings,
    medium_with,
    project_for_solve,
)
from lightcal_app.state import (
    ALL_DIRT,
    MAX_ITERATION_S,
    AppState,
    Dirt,
    LightGuess,
    OverlayKind,
    SelectionSettings,
    UserRegion,
)


def _pixel_part(settings: SolveSettings) -> SolveSettings:
    """The settings without those that leave the selection as it is."""
    return replace(settings, medium=None, albedo_map=None, surroundings=None)


class Actions:
    """The user's actions on the shared state (thread-safe, non-blocking).

    Args:
        state: the shared state.
        planes: the frustum planes of the 3D view (turn clicks into pixels).
        notify: shows a message in the page.
    """

    def __init__(
        self,
        state: AppState,
        *,
        planes: Callable[[], Sequence[FrustumPlane | None]],
        notify: Notify,
    ) -> None:
        self.state = state
        self._planes = planes
        self._notify = notify

    def _base_pose(self, j: int) -> LightGuess:
        st = self.state
        d = st.shown_estimate()
        if d is not None and j < len(d.rig.lights):
            light = d.rig.lights[j]
            return LightGuess(light.t_camera_light.copy(), light.R_camera_light.copy())
        return st.guess[j]

    def set_guess(
        self,
        j: int,
        *,
        t_camera_light: np.ndarray | None = None,
        R_camera_light: np.ndarray | None = None,
    ) -> None:
        """Change light j's initial guess (what is not given stays as shown now)."""
        st = self.state
        # Values from a page, checked before they touch the state (InputError: refused).
        new_pos = None if t_camera_light is None else check_position_m(t_camera_light)
        new_R = None if R_camera_light is None else check_rotation(R_camera_light)
        with st.lock:
            base = self._base_pose(j)
            pos = base.t_camera_light if new_pos is None else new_pos
            R = base.R_camera_light if new_R is None else new_R
            guess = list(st.guess)
            guess[j] = LightGuess(pos.copy(), R.copy())
            st.guess = guess
            st.resume_x = None
            st.resume_end = None
            st.setup_changed(selection=False)

    def reset_guess(self) -> None:
        """Back to the project's initial guess."""
        st = self.state
        with st.lock:
            st.guess = [
                LightGuess(u.initial.t_camera_light.copy(), u.initial.R_camera_light.copy())
                for u in st.project.lights
            ]
            st.resume_x = None
            st.resume_end = None
            st.setup_changed(selection=False)

    def guess_from_beam(self, client: Any = None) -> None:
        """The light's guess from where its beam falls in the images
        (`lightcal.pipeline.auto_start.beam_guess`, what `initial: auto` does); refused
        (InputError) with several lights or when no image shows the beam."""
        st = self.state
        with st.lock:
            project, loaded = st.project, st.loaded
        if len(project.lights) != 1:
            raise InputError(
                "initial", "the beam gives one light's guess; this project has several lights"
            )
        guess = beam_guess(project, loaded)
        if guess is None:
            raise InputError("initial", "no image shows the light's beam (dark, or masked)")
        self.set_guess(
            0,
            t_camera_light=guess.position_camera,
            R_camera_light=rotation_from_axis(guess.axis_camera),
        )
        x, y, z = guess.position_camera * 1e3
        self._notify(
            client,
            "Guess from the beam",
            f"position ({x:+.0f}, {y:+.0f}, {z:+.0f}) mm from {len(guess.sightings)} spots: "
            f"{guess.how}",
        )

    def set_selection(self, settings: SelectionSettings, *, image: str | None = None) -> None:
        """Pixel selection settings for every image (image None) or one image."""
        settings = SelectionSettings(
            *check_selection(
                settings.strategy,
                settings.n_per_image,
                settings.grid_step,
                settings.binning,
                settings.seed,
            )  # type: ignore[arg-type]
        )
        st = self.state
        with st.lock:
            if image is None:
                if settings == st.selection:
                    return
                st.selection = settings
            else:
                st.image_index(image)
                if st.selection_per_image.get(image) == settings:
                    return
                st.selection_per_image[image] = settings
            st.resume_x = None
            st.resume_end = None
            st.setup_changed(selection=True)

    def set_solve_settings(self, settings: SolveSettings) -> None:
        """What the solve fits (wall model, mirror exclusion, offset, fall-off, RID
        estimates): the solve starts over on the project with those keys set. Refused
        (InputError naming the project key) when the project does not accept them."""
        st = self.state
        with st.lock:
            project = st.project
            if settings == st.solve_settings:
                return
        check_settings(project, settings)
        solve_project = project_for_solve(project, settings)
        with st.lock:
            if st.project is not project:
                return  # another project arrived meanwhile
            # The fall-off changes which pixels are usable: the selection is redone (the
            # water's values, the albedo map and the surroundings leave it as it is).
            selection = _pixel_part(settings) != _pixel_part(st.solve_settings)
            st.solve_settings = settings
            st.solve_project = solve_project
            st.resume_x = None
            st.resume_end = None
            st.setup_changed(selection=selection)

    def set_medium(self, channel: int | None = None, **values: object) -> None:
        """The water's values typed in the page (`attenuation_per_m`, `backscatter_per_m`,
        `phase_g`; of colour channel `channel`, or of all when None); the others stay as
        shown now (after a solve: its estimate). The overlays render through it and the
        solve starts over from it. Refused (InputError naming the key) when out of the
        core's range, or backscatter with a camera fall-off other than radiance."""
        st = self.state
        with st.lock:
            settings, shown = st.solve_settings, st.shown_media()
            channels = st.project.channels
        if channel is not None and not 0 <= channel < len(channels):
            raise InputError("medium", f"expected a channel of sensor.channels, got {channel}")
        if not channels:
            self.set_solve_settings(replace(settings, medium=medium_with(shown[0], values)))
            return
        media = tuple(
            medium_with(m, values) if channel in (None, k) else m for k, m in enumerate(shown)
        )
        self.set_solve_settings(replace(settings, medium=media[0], media=media))

    def edit_surroundings(
        self, edit: Callable[[SurroundingsSpec | None], SurroundingsSpec | None]
    ) -> None:
        """The surroundings the solve uses now, edited by `edit` (one of
        `lightcal_app.surroundings_settings`' edits, or a section): the overlays' bounce
        light, the 3D view and the next solve take them. Refused (InputError naming the
        key, as for the project file) when the file would refuse them."""
        st = self.state
        with st.lock:
            settings = st.solve_settings
        self.set_solve_settings(replace(settings, surroundings=edit(settings.surroundings)))

    def reset_surroundings(self) -> None:
        """Back to the project file's surroundings."""
        with self.state.lock:
            spec = self.state.project.spec.surroundings
        self.edit_surroundings(lambda _: spec)

    def clear_selection_override(self, image: str) -> None:
        """Image `image` uses the global selection settings again."""
        st = self.state
        with st.lock:
            if st.selection_per_image.pop(image, None) is not None:
                st.setup_changed(selection=True)

    def add_region(self, region: UserRegion) -> None:
        """Add an include/exclude region."""
        st = self.state
        with st.lock:
            if region.image is not None:
                st.image_index(region.image)
            st.regions = [*st.regions, region]
            st.resume_x = None
            st.resume_end = None
            st.setup_changed(selection=True)

    def clear_regions(self, image: str | None = None) -> None:
        """Remove the user regions of one image (or all)."""
        st = self.state
        with st.lock:
            keep = [r for r in st.regions if image is not None and r.image != image]
            if len(keep) != len(st.regions):
                st.regions = keep
                st.setup_changed(selection=True)

    def add_point(self, index: int, u: float, v: float) -> None:
        """Add a clicked pixel of image `index` (full-resolution coordinates)."""
        st = self.state
        with st.lock:
            cam = st.loaded.camera
            ui, vi = round(u), round(v)
            if not (0 <= ui < cam.width and 0 <= vi < cam.height):
                return
            name = st.project.names[index]
            pts = st.points.setdefault(name, [])
            if (ui, vi) not in pts:
                pts.append((ui, vi))
                st.setup_changed(selection=True)

    def remove_points_near(self, index: int, u: float, v: float, *, radius_px: float = 8.0) -> None:
        """Remove clicked pixels of image `index` within `radius_px` of (u, v)."""
        st = self.state
        with st.lock:
            name = st.project.names[index]
            pts = st.points.get(name, [])
            keep = [p for p in pts if (p[0] - u) ** 2 + (p[1] - v) ** 2 > radius_px**2]
            if len(keep) != len(pts):
                st.points[name] = keep
                st.setup_changed(selection=True)

    def clear_points(self, image: str | None = None) -> None:
        """Remove the clicked pixels of one image (or all)."""
        st = self.state
        with st.lock:
            if image is None:
                changed = any(st.points.values())
                st.points = {}
            else:
                changed = bool(st.points.pop(image, None))
            if changed:
                st.setup_changed(selection=True)

    def set_overlay(self, kind: OverlayKind | None, *, image: str | None = None) -> None:
        """What the frusta show: for every image (image None), or for one (kind None: as all)."""
        st = self.state
        with st.lock:
            if image is None:
                assert kind is not None
                st.overlay_default = kind
            elif kind is None:
                st.overlay_per_image.pop(image, None)
            else:
                st.image_index(image)
                st.overlay_per_image[image] = kind
            st.mark("overlays", "widgets", changed=True)

    def set_show_selection(self, show: bool) -> None:
        st = self.state
        with st.lock:
            st.show_selection = bool(show)
            st.mark("selection", "widgets", changed=True)

    def set_show_albedo(self, show: bool) -> None:
        """Draw the estimated albedo map on the wall, or not."""
        st = self.state
        with st.lock:
            st.show_albedo = bool(show)
            st.mark("light", "widgets", changed=True)

    def set_rays(self, which: str) -> None:
        """Rays for "none", "all" or one image name."""
        st = self.state
        with st.lock:
            if which not in ("none", "all"):
                st.image_index(which)
            st.rays_image = which
            st.mark("light", "widgets", changed=True)

    def set_focus(self, image: str | None) -> None:
        """Highlight one image (its frustum framed, the other pictures dimmed); None: none."""
        st = self.state
        with st.lock:
            if image is not None:
                st.image_index(image)  # ValueError naming it when unknown
            st.focus_image = image
            st.mark("overlays", "widgets")

    def set_ref_image(self, index: int) -> None:
        """Put the gizmo on image `index`'s camera."""
        st = self.state
        with st.lock:
            if not 0 <= index < len(st.project.names) or index == st.ref_image:
                return
            st.ref_image = index
            st.mark(*ALL_DIRT, changed=True)

    def set_pace(self, seconds: float) -> None:
        """Run's minimum time per iteration in the page (0: as fast as it is drawn)."""
        value = float(seconds)
        if not math.isfinite(value):
            raise InputError("seconds per iteration", f"expected a number, got {seconds!r}")
        st = self.state
        with st.lock:
            st.min_iteration_s = min(max(value, 0.0), MAX_ITERATION_S)

    def request_plan(self, n: object, wall_size_m: object, client: Any = None) -> None:
        """Suggest the next views (Plan tab); values checked here (InputError: refused)."""
        views, size = check_plan(n, wall_size_m)
        self.state.request(PlanViews(views, size, client=client))

    def set_show_plan(self, show: bool) -> None:
        """Show or hide the suggested views in the 3D view."""
        st = self.state
        with st.lock:
            st.show_plan = bool(show)
            st.mark("plan")

    def step(self, client: Any = None) -> None:
        self.state.request(Solve("step", client=client))

    def run(self, client: Any = None) -> None:
        self.state.request(Solve("run", client=client))

    def pause(self, client: Any = None) -> None:
        self.state.request(Pause(client=client))

    def reset(self, client: Any = None) -> None:
        self.state.request(Reset(client=client))

    def refused(self, client: Any, exc: LightcalError, *dirt: Dirt) -> None:
        """A value from a page was refused: the page is told why and shows the state again."""
        self._notify(client, "Value refused", str(exc), error=True)
        self.state.mark(*dirt)

    def click(
        self, origin: np.ndarray, direction: np.ndarray, *, mode: str, client: Any = None
    ) -> None:
        """A click in the 3D view: add or remove a pixel of the image under it."""
        if mode not in ("add", "remove"):
            return
        try:
            origin = as_finite_array(origin, (3,), name="click ray origin")
            direction = as_finite_array(direction, (3,), name="click ray direction")
        except LightcalError as exc:
            self.refused(client, exc)
            return
        hit = pick(self._planes(), origin, direction)
        if hit is None:
            return
        i, u, v = hit
        if mode == "add":
            self.add_point(i, u, v)
        else:
            self.remove_points_near(i, u, v)

    def rect(
        self,
        screen_min: tuple[float, float],
        screen_max: tuple[float, float],
        *,
        camera_position: np.ndarray,
        camera_wxyz: np.ndarray,
        fov_y_rad: float,
        aspect: float,
        include: bool,
        client: Any = None,
    ) -> UserRegion | None:
        """A rectangle dragged in the 3D view: a region on the image under its centre."""
        try:
            screen_min = tuple(as_finite_array(screen_min, (2,), name="rectangle corner"))
            screen_max = tuple(as_finite_array(screen_max, (2,), name="rectangle corner"))
            camera_position = as_finite_array(camera_position, (3,), name="camera position")
            camera_wxyz = as_finite_array(camera_wxyz, (4,), name="camera orientation")
            fov_y_rad, aspect = as_finite_array((fov_y_rad, aspect), (2,), name="camera field")
        except LightcalError as exc:
            self.refused(client, exc)
            return None
        hit = rect_to_polygon(
            self._planes(),
            camera_position,
            camera_wxyz,
            fov_y_rad=fov_y_rad,
            aspect=aspect,
            screen_min=screen_min,
            screen_max=screen_max,
        )
        if hit is None:
            self._notify(
                client,
                "No image under the rectangle",
                "Shift-drag over an image on a camera frustum (tip: View > Look through image).",
            )
            return None
        index, poly = hit
        region = UserRegion(
            "polygon",
            tuple((float(u), float(v)) for u, v in poly),
            include,
            self.state.project.names[index],
        )
        self.add_region(region)
        return region

    def request_download(
        self,
        what: DownloadKind,
        client: Any = None,
        export_format: str | None = None,
        *,
        full_size: bool = False,
    ) -> None:
        """Queue a download: "result", "report" (its figures at print size with
        `full_size`), "session" or "export" (in a format of `lightcal.io.export.FORMATS`)."""
        request = PrepareDownload(
            what, export_format=export_format, full_size=bool(full_size), client=client
        )
        self.state.request(request)

    def save_session(self, client: Any = None) -> None:
        self.state.request(SaveSession(client=client))

    def load_saved_session(self, client: Any = None) -> None:
        self.state.request(LoadSavedSession(client=client))

    def restore_previous(self, client: Any = None) -> None:
        self.state.request(RestorePrevious(client=client))

    def on_gizmo(
        self, j: int, t_camera_light: np.ndarray, wxyz: np.ndarray, client: Any
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """The light's gizmo was dragged to `t_camera_light`, `wxyz` (as the page sent them).

        Returns:
            the pose taken (position, R), or None when refused (the gizmo goes back).
        """
        try:
            R = matrix_from_quaternion_wxyz(wxyz)
            self.set_guess(j, t_camera_light=t_camera_light, R_camera_light=R)
        except LightcalError as exc:
            self.refused(client, exc, "light")
            return None
        return np.asarray(t_camera_light, dtype=np.float64), R
