"""The Solve tab: Step, Run, Pause, Reset, the status and the plots per iteration."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import viser

from lightcal_app.controller import Controller
from lightcal_app.panels.base import Programmatic, TabPanel
from lightcal_app.state import MAX_ITERATION_S, Frame
from lightcal_app.text import md_prose

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
        )
        self.position_plot = self._parameter_plot("position (mm, camera frame)")
        self.angle_plot = self._parameter_plot("axis angles (deg)")
        self.step_button.on_click(lambda e: ctl.step(e.client))
        self.run_button.on_click(lambda e: ctl.run(e.client))
        self.pause_button.on_click(lambda e: ctl.pause(e.client))
        self.reset_button.on_click(lambda e: ctl.reset(e.client))

    def _parameter_plot(self, title: str) -> Any:
        empty = np.zeros(0)
        return self.gui.add_uplot(
            (empty, empty),
            ({"label": "iteration"}, {"label": "-"}),
            title=title,
            axes=({}, {"size": 64}),
            scales={"x": {"time": False, "range": (None, None)}},
            aspect=1.6,
        )

    def update(self, frame: Frame) -> None:
        d = frame.dirty
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
        names = list(frame.parameter_names)
        # A later stage of the solve may add parameters (a wall `auto` tries): they come
        # after the first model's, whose columns the plots draw.
        xs = np.array([h.x[: len(names)] for h in hist]) if hist else np.zeros((0, len(names)))
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
                    "stroke": COLOURS[c % len(COLOURS)],
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
