"""The Light tab's Surroundings folder: the surfaces near the wall whose bounce light the
model adds (the project file's `surroundings:`; docs/model.md, "Inter-reflection") as
numbers: the wall's albedo, the mesh's patch side, the bounces kept and, per surface,
its albedo, corner and edges, with a button to remove it; a surface can be added, and
the project's surroundings brought back.

An edit is checked as the project file is (`lightcal_app.surroundings_settings`); taken,
it redraws the surfaces in the 3D view, renders the overlays with their bounce light
and starts the solve over with them (`Actions.edit_surroundings`); refused, the page
says why, naming the key, and the field goes back. The session file keeps them.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import viser

from lightcal.core.surroundings import PATCH_RANGE_M
from lightcal.io.surroundings_spec import SurroundingsSpec
from lightcal_app.controller import Controller
from lightcal_app.panels.base import Programmatic, TabPanel
from lightcal_app.state import Frame
from lightcal_app.surroundings_settings import (
    with_new_surface,
    with_surface_values,
    with_values,
    without_surface,
)
from lightcal_app.text import md

VECTORS = (
    ("corner_m", "corner (m)", "a corner of the rectangle, world frame (the wall is z = 0)"),
    ("edge_u_m", "edge u (m)", "its first edge from that corner"),
    ("edge_v_m", "edge v (m)", "its second edge from that corner"),
)
"""A surface's vectors: (key, label, hint)."""


def bounces_value(value: float) -> int | float | None:
    """The bounces field's number as `surroundings.bounces` (0: all, None); a number
    that is not whole stays as typed, for the file's check to refuse it."""
    v = float(value)
    if v == 0.0:
        return None
    return int(v) if v.is_integer() else v


def surroundings_text(spec: SurroundingsSpec | None, project: SurroundingsSpec | None) -> str:
    """What the folder says of the surroundings the solve uses (`spec`) against the
    project file's (`project`)."""
    if spec is None:
        head = "**None**: nothing near the wall sends light back to it."
        if project is not None:
            head += " (The project file declares some: *Back to the project's*.)"
        return head
    names = ", ".join(
        md(s.name) if s.name else f"surfaces[{k}]" for k, s in enumerate(spec.surfaces)
    )
    source = "as the project file declares them" if spec == project else "**edited** in the page"
    return (
        f"**{len(spec.surfaces)} surface{'s' if len(spec.surfaces) > 1 else ''}** ({names}), "
        f"{source}: their bounce light is in the overlays and the solve. The solve drops "
        "the pixels a surface hides or shadows from the light. Each edit rebuilds the "
        "bounce map (seconds)."
    )


class SurroundingsPanel(TabPanel):
    """The Surroundings folder (built in the current GUI container)."""

    def __init__(self, server: viser.ViserServer, ctl: Controller, flag: Programmatic) -> None:
        super().__init__(server, ctl, flag)
        gui = self.gui
        with ctl.state.lock:
            spec = ctl.state.solve_settings.surroundings
        shown = spec or SurroundingsSpec.model_construct(surfaces=[])
        lo, hi = PATCH_RANGE_M
        with gui.add_folder("Surroundings", expand_by_default=spec is not None) as folder:
            self.folder = folder
            self.text = gui.add_markdown("")
            self.wall_albedo = gui.add_number(
                "wall albedo (bounce)",
                shown.wall_albedo,
                min=0.0,
                max=1.0,
                step=0.01,
                hint="surroundings.wall_albedo: the wall's diffuse reflectance for the bounce "
                "light, above 0 and below 1 (most of the bounce goes wall -> surface -> wall)",
                disabled=spec is None,
            )
            self.patch = gui.add_number(
                "patch (m)",
                shown.patch_m,
                min=lo,
                max=hi,
                step=0.01,
                hint=f"surroundings.patch_m: the side of the mesh's patches, {lo:g} to {hi:g} m "
                "(the wall's cells: half); finer is slower",
                disabled=spec is None,
            )
            self.bounces = gui.add_number(
                "bounces (0: all)",
                0 if shown.bounces is None else shown.bounces,
                min=0,
                max=50,
                step=1,
                hint="surroundings.bounces: keep paths of up to this many reflections "
                "(1 to 50; 0: all, as in a room; 3: a path tracer's max_depth 5)",
                disabled=spec is None,
            )
            self.add_button = gui.add_button(
                "Add a surface", hint="a ceiling along the top of the views; type its numbers"
            )
            self.reset_button = gui.add_button("Back to the project's surroundings")
        self.surfaces: list[dict[str, Any]] = []
        self._surface_folders: list[Any] = []
        self._names: tuple[str, ...] | None = None
        self._build_surfaces(spec)
        self._edit(self.wall_albedo, lambda s, v: with_values(s, wall_albedo=float(v)))
        self._edit(self.patch, lambda s, v: with_values(s, patch_m=float(v)))
        self._edit(self.bounces, lambda s, v: with_values(s, bounces=bounces_value(v)))
        self.add_button.on_click(self.guard(lambda e: self._add()))
        self.reset_button.on_click(self.guard(lambda e: ctl.reset_surroundings()))

    def _add(self) -> None:
        with self.ctl.state.lock:
            project = self.ctl.state.project
        self.ctl.edit_surroundings(lambda s: with_new_surface(s, project))

    def _edit(
        self, handle: Any, edit: Callable[[SurroundingsSpec | None, Any], SurroundingsSpec | None]
    ) -> None:
        def changed(event: Any) -> None:
            value = handle.value
            self.ctl.edit_surroundings(lambda s: edit(s, value))

        handle.on_update(self.guard(changed))

    def _build_surfaces(self, spec: SurroundingsSpec | None) -> None:
        """One folder per surface: its albedo, corner, edges and a Remove button."""
        for h in self._surface_folders:
            h.remove()
        self._surface_folders, self.surfaces = [], []
        surfaces = [] if spec is None else spec.surfaces
        self._names = tuple(s.name for s in surfaces)
        gui = self.gui
        for k, s in enumerate(surfaces):
            where = f"surroundings.surfaces[{k}]"
            with self.folder, gui.add_folder(s.name or f"surfaces[{k}]") as sub:
                self._surface_folders.append(sub)
                w: dict[str, Any] = {
                    "albedo": gui.add_number(
                        "albedo",
                        s.albedo,
                        min=0.0,
                        max=1.0,
                        step=0.01,
                        hint=f"{where}.albedo: its diffuse reflectance, 0 to below 1",
                    ),
                    **{
                        key: gui.add_vector3(label, tuple(getattr(s, key)), step=0.01, hint=words)
                        for key, label, words in VECTORS
                    },
                    "remove": gui.add_button(f"Remove {s.name or f'surfaces[{k}]'}"),
                }
            self.surfaces.append(w)
            self._wire_surface(k, w)

    def _wire_surface(self, k: int, w: dict[str, Any]) -> None:
        self._edit(w["albedo"], lambda s, v: with_surface_values(s, k, albedo=float(v)))
        for key, _, _ in VECTORS:
            self._edit(w[key], self._vector_edit(k, key))
        w["remove"].on_click(
            self.guard(lambda e: self.ctl.edit_surroundings(lambda s: without_surface(s, k)))
        )

    @staticmethod
    def _vector_edit(
        k: int, key: str
    ) -> Callable[[SurroundingsSpec | None, Any], SurroundingsSpec | None]:
        def edit(spec: SurroundingsSpec | None, value: Any) -> SurroundingsSpec | None:
            return with_surface_values(spec, k, **{key: [float(c) for c in value]})

        return edit

    def update(self, frame: Frame) -> None:
        """The surroundings the solve uses into the widgets (a folder per surface)."""
        if not frame.dirty & {"widgets", "scene"}:
            return
        st = self.ctl.state
        with st.lock:
            spec = st.solve_settings.surroundings
            project = st.project.spec.surroundings
        surfaces = [] if spec is None else spec.surfaces
        if tuple(s.name for s in surfaces) != self._names or len(surfaces) != len(self.surfaces):
            self._build_surfaces(spec)
        for handle in (self.wall_albedo, self.patch, self.bounces):
            if handle.disabled != (spec is None):
                handle.disabled = spec is None  # the section's values need a surface
        if spec is not None:
            self.flag.assign(self.wall_albedo, spec.wall_albedo)
            self.flag.assign(self.patch, spec.patch_m)
            self.flag.assign(self.bounces, 0 if spec.bounces is None else spec.bounces)
        for s, w in zip(surfaces, self.surfaces, strict=True):
            self.flag.assign(w["albedo"], s.albedo)
            for key, _, _ in VECTORS:
                self.flag.assign(w[key], tuple(getattr(s, key)))
        self.text.content = surroundings_text(spec, project)
