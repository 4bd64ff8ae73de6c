"""The Solve tab: Step, Run, Pause, Reset, the status and the plots per iteration."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
import viser

from lightcal.io.project import Project
from lightcal_app.controller import Controller
from lightcal_app.panels.base import Programmatic, TabPanel
from lightcal_app.solve_display import light_angles_deg
from lightcal_app.solve_settings import (
    FALL_OFF_ORDERS,
    FALL_OFFS,
    MEDIUM_ESTIMATES,
    MEDIUM_WORDS,
    RID_ESTIMATES,
    WALL_MODELS,
    SolveSettings,
    settings_of,
)
from lightcal_app.state import MAX_ITERATION_S, Frame
from lightcal_app.text import md_prose

#: uPlot's padding (top, right, bottom, left), px: room for the top tick's label and the
#: last iteration's, which uPlot centres on the plot's edges (and so cut in half).
PLOT_PADDING = (12, 14, 0, 0)

COLOURS = ("#1c7ed6", "#2f9e44", "#e8590c", "#ae3ec9", "#f08c00", "#0c8599")


def status_text(frame: Any) -> str:
    """The solve's state, and the last iteration's numbers."""
    if not frame.history:
        return f"**{frame.solver_state}**: press Step or Run. {md_prose(frame.solver_message)}"
    last = frame.history[-1]
    return (
        f"**{frame.solver_state}** {md_prose(frame.solver_message)}  \n"
        f"iteration {last.iteration}, cost {last.cost:.6g}, "
        f"|gradient| {last.gradient_norm:.3g}, "
        f"{last.nfev} evaluations"
        + (" (re-weighted: pixel sigmas from the rendered values)" if last.reweighted else "")
    )


class SolvePanel(TabPanel):
    """The Solve tab (built in the current GUI container)."""

    def __init__(self, server: viser.ViserServer, ctl: Controller, flag: Programmatic) -> None:
        super().__init__(server, ctl, flag)
        gui = self.gui
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
        self.pace = gui.add_slider(
            "seconds per iteration",
            min=0.0,
            max=MAX_ITERATION_S,
            step=0.1,
            initial_value=ctl.state.min_iteration_s,
            hint="Run shows each iteration at least this long (0: full speed)",
        )
        self.pace.on_update(self.guard(lambda e: ctl.set_pace(self.pace.value)))
        self.status_md = gui.add_markdown("")
        self._build_settings(ctl.state.project)
        empty = np.zeros(0)
        # log10 of the cost on a linear axis: whole-number ticks that fit the axis (a
        # log-scale axis wrote 1,000,000,000 into 100 pixels and drew every minor tick).
        self.cost_plot = gui.add_uplot(
            (empty, empty),
            ({"label": "iteration"}, {"label": "log10 cost", "stroke": "#d9480f", "width": 2}),
            title="cost per iteration (log10)",
            axes=({}, {"size": 48}),
            scales={"x": {"time": False, "range": (None, None)}},
            aspect=1.6,
            padding=PLOT_PADDING,
        )
        self.position_plot = self._parameter_plot("position (mm, camera frame)")
        self.angle_plot = self._parameter_plot("light axis: roll and pitch (deg)")
        self.step_button.on_click(lambda e: ctl.step(e.client))
        self.run_button.on_click(lambda e: ctl.run(e.client))
        self.pause_button.on_click(lambda e: ctl.pause(e.client))
        self.reset_button.on_click(lambda e: ctl.reset(e.client))

    def _build_settings(self, project: Project) -> None:
        """ "What the solve fits": the project keys of `SolveSettings`, one widget each
        (an RID estimate per light), each named with the key a project file would set."""
        settings = settings_of(project)
        fall_offs = [f for f in FALL_OFFS if f != "map" or project.vignetting_path is not None]
        with self.gui.add_folder("What the solve fits", expand_by_default=True) as folder:
            self._settings_folder = folder
            self.wall_model = self.gui.add_dropdown(
                "wall",
                WALL_MODELS,
                initial_value=settings.wall_model,
                hint="wall.model: matte (lambertian), painted (plastic), rough matte "
                "(oren_nayar), or auto: lambertian, and the others where the fit test "
                "points at the wall",
            )
            self.mirror = self.gui.add_number(
                "exclude mirror (deg)",
                initial_value=settings.exclude_mirror_deg,
                min=0.0,
                max=89.0,
                step=0.5,
                hint="selection.exclude_mirror_deg: drop pixels this close to the mirror "
                "direction of the first estimate and solve again (0: keep all)",
            )
            self.offset = self.gui.add_checkbox(
                "estimate offset (black level)",
                settings.estimate_offset,
                hint="sensor.estimate_offset: a constant added to every pixel, the same in "
                "every image (a black level left in the images) estimated with the light",
            )
            self.ambient = self.gui.add_checkbox(
                "estimate room light",
                settings.estimate_ambient,
                hint="sensor.estimate_ambient: light from the room on the wall, which grows "
                "with each image's exposure, estimated with the light",
            )
            self.fall_off = self.gui.add_dropdown(
                "camera fall-off",
                fall_offs,
                initial_value=settings.fall_off,
                hint="sensor.model: radiance (none), cos4, paper (the paper's model) or "
                "map (the project's vignetting file)",
            )
            self.estimate_fall_off = self.gui.add_dropdown(
                "estimate fall-off",
                FALL_OFF_ORDERS,
                initial_value=FALL_OFF_ORDERS[settings.estimate_fall_off],
                hint="sensor.estimate_fall_off: a radial fall-off 1 + c1 r^2 + ... fitted "
                "with the light (r^2: order 1, to r^6: order 3); needs views at several "
                "distances",
            )
            self.medium = self.gui.add_dropdown(
                "estimate water",
                tuple(MEDIUM_ESTIMATES),
                initial_value=MEDIUM_WORDS.get(settings.medium_estimate, "none"),
                hint="medium.estimate: the water's attenuation c and backscatter beta fitted "
                "with the light, starting from the Light tab's Water values (none: as given; "
                "backscatter with the radiance fall-off only)",
            )
            self.rid_estimates = [
                self.gui.add_dropdown(
                    f"estimate RID: {u.initial.name}",
                    RID_ESTIMATES,
                    initial_value=value,
                    hint="lights[].estimate_rid: also fit the light's profile (cos_power: "
                    "one exponent; curve: a monotone curve) - symmetric lights only",
                )
                for u, value in zip(project.lights, settings.estimate_rid, strict=True)
            ]
        self._settings_lights = [u.initial.name for u in project.lights]
        self._settings_fall_offs = fall_offs
        changed = self.guard(lambda e: self.ctl.set_solve_settings(self._settings()))
        handles: list[Any] = [
            self.wall_model,
            self.mirror,
            self.offset,
            self.ambient,
            self.fall_off,
            self.estimate_fall_off,
            self.medium,
        ]
        for h in [*handles, *self.rid_estimates]:
            h.on_update(changed)

    def _settings(self) -> SolveSettings:
        with self.ctl.state.lock:
            settings = self.ctl.state.solve_settings  # the water's values: the Light tab's
        return replace(
            settings,
            wall_model=str(self.wall_model.value),
            exclude_mirror_deg=float(self.mirror.value),
            estimate_offset=bool(self.offset.value),
            fall_off=str(self.fall_off.value),
            estimate_rid=tuple(str(h.value) for h in self.rid_estimates),
            estimate_ambient=bool(self.ambient.value),
            estimate_fall_off=FALL_OFF_ORDERS.index(str(self.estimate_fall_off.value)),
            medium_estimate=MEDIUM_ESTIMATES[str(self.medium.value)],
        )

    def set_project(self, project: Project) -> None:
        """Another project: its lights' RID widgets, its fall-off choices."""
        fall_offs = [f for f in FALL_OFFS if f != "map" or project.vignetting_path is not None]
        names = [u.initial.name for u in project.lights]
        if names != self._settings_lights or fall_offs != self._settings_fall_offs:
            self._settings_folder.remove()
            self._build_settings(project)

    def _show_settings(self) -> None:
        st = self.ctl.state
        with st.lock:
            s = st.solve_settings
        self.flag.assign(self.wall_model, s.wall_model)
        self.flag.assign(self.mirror, s.exclude_mirror_deg)
        self.flag.assign(self.offset, s.estimate_offset)
        self.flag.assign(self.fall_off, s.fall_off)
        self.flag.assign(self.ambient, s.estimate_ambient)
        self.flag.assign(self.estimate_fall_off, FALL_OFF_ORDERS[s.estimate_fall_off])
        self.flag.assign(self.medium, MEDIUM_WORDS.get(s.medium_estimate, "none"))
        for handle, value in zip(self.rid_estimates, s.estimate_rid, strict=False):
            self.flag.assign(handle, value)

    def _parameter_plot(self, title: str) -> Any:
        empty = np.zeros(0)
        return self.gui.add_uplot(
            (empty, empty),
            ({"label": "iteration"}, {"label": "-"}),
            title=title,
            axes=({}, {"size": 64}),
            scales={"x": {"time": False, "range": (None, None)}},
            aspect=1.6,
            padding=PLOT_PADDING,
        )

    def update(self, frame: Frame) -> None:
        d = frame.dirty
        if d & {"widgets", "scene"}:
            self._show_settings()
        if d & {"plots", "scene"}:
            self._update_plots(frame)
        if d & {"status", "plots", "scene"}:
            self.status_md.content = status_text(frame)

    def _update_plots(self, frame: Frame) -> None:
        """Cost and parameters per iteration. The scales are set with the data: uPlot
        keeps its first scales on data pushes."""
        hist = frame.history
        it = np.array([h.iteration for h in hist], dtype=np.float64)
        x_range = (0.0, float(max(it.max(), 1.0))) if hist else (0.0, 1.0)
        log_cost = np.log10([max(h.cost, 1e-300) for h in hist]) if hist else np.zeros(0)
        if hist:
            lo, hi = math.floor(log_cost.min()), math.ceil(log_cost.max())
            cost_range = (float(lo), float(hi if hi > lo else lo + 1))
        else:
            cost_range = (0.0, 1.0)
        self.cost_plot.scales = {
            "x": {"time": False, "range": x_range},
            "y": {"range": cost_range},
        }
        self.cost_plot.data = (it, log_cost)
        # A later stage of the solve may add parameters (a wall `auto` tries): they come
        # after the first model's, whose columns the plots draw.
        names = list(frame.parameter_names)[: min((len(h.x) for h in hist), default=None)]
        xs = np.array([h.x[: len(names)] for h in hist]) if hist else np.zeros((0, len(names)))
        cols = [k for k, n in enumerate(names) if n.endswith("_m")]
        position = [(names[k].removesuffix("_m"), xs[:, k] * 1e3) for k in cols] if hist else []
        # The axis as the result and the Light tab give it (roll, pitch), not the
        # solver's own angles.
        angles = light_angles_deg(self.ctl.solve.first_model, [h.x for h in hist]) if hist else None
        axis = [
            (f"{name} {what}", values[:, c])
            for name, values in angles or []
            for c, what in enumerate(("roll", "pitch"))
        ]
        for plot, curves in ((self.position_plot, position), (self.angle_plot, axis)):
            self._draw_curves(plot, it, x_range, curves)

    @staticmethod
    def _draw_curves(
        plot: Any, it: np.ndarray, x_range: tuple[float, float], curves: list[tuple[str, Any]]
    ) -> None:
        """One uPlot of labelled curves over the iterations (empty without curves)."""
        if not curves:
            plot.data = (np.zeros(0), np.zeros(0))
            plot.series = ({"label": "iteration"}, {"label": "-"})
            return
        series: list[Any] = [{"label": "iteration"}] + [
            {"label": label, "stroke": COLOURS[c % len(COLOURS)], "width": 2}
            for c, (label, _) in enumerate(curves)
        ]
        values = np.stack([np.asarray(v, dtype=np.float64) for _, v in curves], axis=1)
        lo, hi = float(values.min()), float(values.max())
        pad = max(0.05 * (hi - lo), 1e-3 * max(abs(lo), abs(hi)), 1e-6)
        plot.scales = {
            "x": {"time": False, "range": x_range},
            "y": {"range": (lo - pad, hi + pad)},
        }
        plot.series = tuple(series)
        plot.data = (it, *(values[:, c] for c in range(values.shape[1])))
