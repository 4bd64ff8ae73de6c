"""The Plan tab: where to put the camera next, and the uncertainty now (live).

The numbers come from `lightcal_app.plan_service` (`lightcal.pipeline.plan`, the
D-optimal criterion of `lightcal plan`); the suggested views are drawn as blue ghost
frusta (`lightcal_app.plan_scene`).
"""

from __future__ import annotations

import viser

from lightcal.pipeline.plan import Sigmas
from lightcal_app.controller import Controller
from lightcal_app.limits import PLAN_MAX_VIEWS, PLAN_WALL_SIZE_M
from lightcal_app.panels.base import Programmatic, TabPanel
from lightcal_app.state import EstimateKey, Frame, PlanShown, Readout
from lightcal_app.text import md, md_prose

INTRO = (
    "Where to photograph the wall next. For camera poses in front of the wall "
    "(distances 0.6-2.5 m, tilts up to 45 deg, any side, two rolls) lightcal predicts how "
    "much each would shrink the light's position and axis uncertainty, with the solver's "
    "own Jacobian (D-optimal: the smallest volume of the pose's confidence ellipsoid), and "
    "suggests the best, each added before the next is chosen. They appear as **blue "
    "frusta** in the 3D view."
)


def _sigma_parts(s: Sigmas, k: int) -> tuple[float, float | None]:
    return 1e3 * s.position_m[k], s.axis_deg[k]


def _change(before: float, after: float) -> str:
    if before <= 0.0:
        return ""
    return f" ({100.0 * (after - before) / before:+.0f} %)"


def readout_markdown(readout: Readout | None, current: EstimateKey) -> str:
    """The live read-out: each light's 1-sigma position and axis at the estimate shown."""
    if readout is None:
        return (
            "**Uncertainty now**: appears once pixels are selected (for a dense selection, "
            "when the solve pauses or ends)."
        )
    stale = "" if readout.key == current else " *(updating...)*"
    lines = [
        f"**Uncertainty now** at {md_prose(readout.where)}{stale} "
        f"(1 sigma, {md_prose(readout.noise)}; pixel noise only, the Result tab adds the "
        "camera poses'):  "
    ]
    for k, name in enumerate(readout.light_names):
        pos_mm, axis_deg = _sigma_parts(readout.sigmas, k)
        text = f"{md(name)}: position ± {pos_mm:.3g} mm"
        if axis_deg is not None:
            text += f", axis ± {axis_deg:.3g} deg"
        lines.append(text + "  ")
    return "\n".join(lines)


def plan_markdown(plan: PlanShown | None, current: EstimateKey) -> str:
    """The suggested views: where to put the camera, the predicted sigmas and gains."""
    if plan is None:
        return "No views suggested yet: press **Suggest views**."
    if not plan.views:
        return "No candidate view sees the lit wall within the wall size: enlarge it."
    stale = (
        ""
        if plan.now.key == current
        else " **Stale**: the guess, the selection or the solve changed since; press "
        "**Suggest views** again."
    )
    lines = [
        f"**Suggested next views** for {md_prose(plan.now.where)}.{stale}",
        "",
        "| # | where to put the camera | position ± (mm) | axis ± (deg) |",
        "|---|---|---|---|",
    ]
    names = plan.now.light_names
    for rank, pv in enumerate(plan.views, start=1):
        pos_cells, axis_cells = [], []
        for k, name in enumerate(names):
            who = f"{md(name)}: " if len(names) > 1 else ""
            p0, a0 = _sigma_parts(pv.before, k)
            p1, a1 = _sigma_parts(pv.after, k)
            pos_cells.append(f"{who}{p0:.3g} → {p1:.3g}{_change(p0, p1)}")
            if a0 is not None and a1 is not None:
                axis_cells.append(f"{who}{a0:.3g} → {a1:.3g}{_change(a0, a1)}")
        lines.append(
            f"| {rank} | {md_prose(pv.candidate.instruction())} | {'; '.join(pos_cells)} | "
            f"{'; '.join(axis_cells) or '-'} |"
        )
    first, last = plan.views[0].before, plan.views[-1].after
    total = [
        f"{md(name)} position {_change(_sigma_parts(first, k)[0], _sigma_parts(last, k)[0])}"
        for k, name in enumerate(names)
    ]
    lines += ["", f"All {len(plan.views)} together: {', '.join(total)}."]
    return "\n".join(lines)


class PlanPanel(TabPanel):
    """The Plan tab (built in the current GUI container)."""

    def __init__(self, server: viser.ViserServer, ctl: Controller, flag: Programmatic) -> None:
        super().__init__(server, ctl, flag)
        gui = self.gui
        gui.add_markdown(INTRO)
        self.readout_md = gui.add_markdown(readout_markdown(None, (0, 0, -1, "idle")))
        self.n_views = gui.add_slider(
            "views to suggest", min=1, max=PLAN_MAX_VIEWS, step=1, initial_value=3
        )
        lo, hi = PLAN_WALL_SIZE_M
        self.wall_size = gui.add_number(
            "wall size (m)",
            initial_value=3.0,
            min=lo,
            max=hi,
            step=0.1,
            hint="width and height of the free wall the suggested views must stay within",
        )
        self.suggest = gui.add_button(
            "Suggest views", icon=viser.Icon.CAMERA_PLUS, hint="a few seconds"
        )
        self.suggest.on_click(
            self.guard(
                lambda e: ctl.request_plan(self.n_views.value, self.wall_size.value, e.client)
            )
        )
        self.show = gui.add_checkbox("show suggested views in 3D", initial_value=True)
        self.show.on_update(self.guard(lambda e: ctl.set_show_plan(self.show.value)))
        self.plan_md = gui.add_markdown(plan_markdown(None, (0, 0, -1, "idle")))
        self._shown: tuple[str, str] = ("", "")

    def update(self, frame: Frame) -> None:
        if not frame.dirty & {"plan", "scene", "status", "plots", "widgets"}:
            return
        readout = readout_markdown(frame.readout, frame.estimate_key)
        plan = plan_markdown(frame.plan, frame.estimate_key)
        if (readout, plan) != self._shown:
            self._shown = (readout, plan)
            self.readout_md.content = readout
            self.plan_md.content = plan
        with self.ctl.state.lock:
            self.flag.assign(self.show, self.ctl.state.show_plan)
