"""The View tab: what the images on the frusta show, looking through an image, rays."""

from __future__ import annotations

import math
from typing import Any

import viser

from lightcal.core.albedo_map import AlbedoMap
from lightcal.io.project import Project
from lightcal_app.albedo_scene import albedo_picture
from lightcal_app.controller import Controller
from lightcal_app.overlays import legend_picture
from lightcal_app.panels.base import LiveText, Programmatic, TabPanel
from lightcal_app.state import OVERLAY_KINDS, Frame

AS_ALL = "(as all images)"
DRAWING = "drawing the pictures"
LEGEND_BEFORE = "**Residual colours** (shown when an image shows *residual*):"

SCENE_LEGEND = """**In the scene**
- *light grey*: the **wall** (its plane, z = 0 of the world, or its mesh); each image on its
  **camera's frustum** (*dark* frame; *orange* frame: the camera that carries the light
  gizmo; thick *crimson* frame: the highlighted image, the other pictures faded)
- *orange*: the **light** (bulb) at its pose in each camera, with its **cones** (the
  RID's half-intensity and cut-off angles) and, on the gizmo's camera, the draggable
  **gizmo** (arrows move it, rings turn it)
- *yellow*: **rays** from the light to the selected pixels' spots on the wall (rays for)
- *green* bulb: the **true light** (demo data only): where the solve should end
- *blue* / *red* on the wall: the wall's estimated **albedo map** (darker / brighter than
  its mean; when the solve estimates it)
- *translucent tan*: the **surroundings** (a ceiling, side wall: their bounce light is
  in the model), each labelled with its albedo; edit them in Light > Surroundings

**On the images**
- *green*: **selected pixels** (dots; a dense selection as its outline)
- *magenta*: **masked** pixels: markers, stray light, saturation (never fitted)
- *green* / *red* lines: include / exclude **regions**; *yellow* crosses: clicked pixels"""
"""What every mark of the 3-D scene and the pictures means (the colours of
`lightcal_app.scene3d` and `lightcal_app.overlays`)."""


def albedo_words(albedo: AlbedoMap | None) -> str:
    """The albedo map's colours on the wall, with their scale; empty without a map."""
    if albedo is None:
        return ""
    vmax = albedo_picture(albedo, max_side_px=1).vmax
    return (
        f"**Albedo map** on the wall: the albedo over its mean, colours to ±{100 * vmax:.2g} % "
        "(blue darker, red brighter; the grey wall where no pixel saw it)."
    )


class ViewPanel(TabPanel):
    """The View tab (built in the current GUI container)."""

    def __init__(self, server: viser.ViserServer, ctl: Controller, flag: Programmatic) -> None:
        super().__init__(server, ctl, flag)
        gui = self.gui
        st = ctl.state
        names = list(st.project.names)
        self.overlay_all = gui.add_dropdown(
            "images show",
            OVERLAY_KINDS,
            initial_value=st.overlay_default,
            hint="real image, image rendered with the current light, or real minus rendered",
        )
        self.overlay_image = gui.add_dropdown("image", names, initial_value=names[0])
        self.focus = gui.add_checkbox(
            "highlight this image",
            initial_value=False,
            hint="frame its frustum in crimson and fade the other pictures",
        )
        self.overlay_one = gui.add_dropdown(
            "this image shows", [AS_ALL, *OVERLAY_KINDS], initial_value=AS_ALL
        )
        self.look_through = gui.add_button("Look through image", icon=viser.Icon.CAMERA)
        self.rays = gui.add_dropdown(
            "rays from the light for", ["none", "all", *names], initial_value=st.rays_image
        )
        self.show_albedo = gui.add_checkbox(
            "show the albedo map on the wall",
            initial_value=st.show_albedo,
            hint="the wall's albedo map the solve estimates (Solve tab), drawn on the wall",
        )
        self.albedo_md = gui.add_markdown("")
        self.scene_legend = gui.add_markdown(SCENE_LEGEND)
        self.legend_text = LiveText(gui, LEGEND_BEFORE)
        self.legend = gui.add_image(legend_picture(1.0), label="residual scale", format="png")
        self._legend_shown: float | None = None
        self._wire()

    def _wire(self) -> None:
        ctl = self.ctl
        g = self.guard

        def overlay_all(event: Any) -> None:
            self.legend_text.mark_stale(DRAWING)
            ctl.set_overlay(self.overlay_all.value)

        self.overlay_all.on_update(g(overlay_all))

        def overlay_one(event: Any) -> None:
            v = self.overlay_one.value
            self.legend_text.mark_stale(DRAWING)
            ctl.set_overlay(None if v == AS_ALL else v, image=self.overlay_image.value)  # type: ignore[arg-type]

        self.overlay_one.on_update(g(overlay_one))

        def overlay_image(event: Any) -> None:
            with ctl.state.lock, self.flag.writing():
                v = ctl.state.overlay_per_image.get(self.overlay_image.value, AS_ALL)
                self.flag.assign(self.overlay_one, v)

        self.overlay_image.on_update(overlay_image)

        def focus(event: Any) -> None:
            ctl.set_focus(self.overlay_image.value if self.focus.value else None)

        self.focus.on_update(g(focus))
        self.overlay_image.on_update(g(focus))
        self.look_through.on_click(self._look_through)
        self.rays.on_update(g(lambda e: ctl.set_rays(self.rays.value)))
        self.show_albedo.on_update(g(lambda e: ctl.set_show_albedo(self.show_albedo.value)))

    def _look_through(self, event: Any) -> None:
        """Move the browser's camera (all browsers when the click has no client) to the
        chosen image's camera, looking at the wall as the image does."""
        st = self.ctl.state
        with st.lock:
            i = st.project.names.index(self.overlay_image.value)
            view = st.project.views[i]
            fov = st.project.camera.fov_y_rad
        R_wc = view.R_camera_world.T
        center = view.center_world
        # Looking through an image, the rays' bands would cover it: they are turned off
        # (the "rays from the light for" menu turns them on again).
        self.ctl.set_rays("none")
        clients = (
            [event.client] if event.client is not None else list(self.server.get_clients().values())
        )
        for client in clients:
            with client.atomic():
                client.camera.fov = min(math.radians(100.0), 1.15 * fov)
                client.camera.up_direction = -R_wc[:, 1]
                client.camera.position = center - 0.02 * R_wc[:, 2]
                client.camera.look_at = center + float(center[2]) * R_wc[:, 2]

    def set_project(self, project: Project) -> None:
        self.overlay_image.options = list(project.names)
        self.rays.options = ["none", "all", *project.names]

    def update(self, frame: Frame, *, legend_vmax: float | None) -> None:
        d = frame.dirty
        if d & {"widgets", "scene"}:
            st = self.ctl.state
            with st.lock:
                self.flag.assign(self.overlay_all, st.overlay_default)
                self.flag.assign(self.rays, st.rays_image)
                self.flag.assign(self.focus, st.focus_image is not None)
                self.flag.assign(self.show_albedo, st.show_albedo)
                if st.focus_image is not None:
                    self.flag.assign(self.overlay_image, st.focus_image)
        if d & {"light", "scene", "widgets"}:
            albedo = frame.display.albedo if frame.display is not None else None
            self.albedo_md.content = albedo_words(albedo)
        if not d & {"overlays", "scene", "widgets"}:
            return
        if legend_vmax is not None and self._legend_shown != legend_vmax:
            self._legend_shown = legend_vmax
            self.legend.image = legend_picture(legend_vmax)
        if self._legend_shown is None:
            self.legend_text.show(LEGEND_BEFORE)
        else:
            self.legend_text.show(
                f"**Residual colours**: real − rendered, ±{self._legend_shown:.4g} pixel "
                "values (99th percentile over the images shown as residual; grey: no value)."
            )
