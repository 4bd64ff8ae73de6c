"""The Light tab's Water folder: the medium between the rig and the wall as numbers
(`medium.attenuation_per_m`, `backscatter_per_m`, `phase_g`; docs/model.md, "Medium"),
each in the core's range (`solve_settings.MEDIUM_BOUNDS`).

An edit renders the overlays through the water and starts the solve over from it
(`Actions.set_medium`); a refused value is said in the page and the field goes back.
After a solve that estimated c or beta the fields show the estimate, as the light's
pose fields do.
"""

from __future__ import annotations

from typing import Any

import viser

from lightcal.core.medium import Medium
from lightcal_app.controller import Controller
from lightcal_app.panels.base import Programmatic, TabPanel, rounded
from lightcal_app.solve_settings import MEDIUM_BOUNDS
from lightcal_app.state import Frame

DIGITS = 3
"""Decimals shown (the fields' step is 10^-DIGITS)."""

FIELDS: dict[str, tuple[str, str]] = {
    "attenuation_per_m": (
        "attenuation c (m⁻¹)",
        "medium.attenuation_per_m: the light lost per metre of path: each value is the "
        "wall's times exp(-c (d_light + d_camera)), the distances from the light and the "
        "camera to the wall point. 0: air; clear ocean water 0.05-0.5. The solve's start "
        "when it estimates it (Solve tab, estimate water).",
    ),
    "backscatter_per_m": (
        "backscatter β (m⁻¹)",
        "medium.backscatter_per_m: the beam scattered back into the camera along each "
        "pixel's ray (a veil), relative to the wall's reflectance. 0: none. Needs the "
        "camera fall-off radiance (Solve tab).",
    ),
    "phase_g": (
        "phase g",
        "medium.phase_g: the Henyey-Greenstein asymmetry of that scattering, -1 "
        "(backwards) to 1 (forwards); ocean water about 0.9. Only with backscatter.",
    ),
}
"""Per value of the medium: its label and hint."""

SYMBOLS = {"attenuation_per_m": "c", "backscatter_per_m": "β", "phase_g": "g"}
"""The symbol of each value in the folder's text (another name: itself)."""


def water_text(
    shown: Medium, start: Medium, estimated: tuple[str, ...], *, estimate_shown: bool
) -> str:
    """What the folder says of the values shown: `shown`, the solve's estimate when
    `estimate_shown`, else `start` (`estimated`: `medium.estimate`)."""
    fitted = " and ".join(SYMBOLS.get(name, name) for name in estimated)
    if estimated and estimate_shown:
        began = ", ".join(  # (no-break spaces: "c = 0.1" on one line)
            f"{SYMBOLS.get(name, name)}\u00a0=\u00a0{getattr(start, name):g}" for name in estimated
        )
        return f"Showing the solve's **estimate** of {fitted}; it started from {began}."
    if estimated:
        return f"The solve **estimates** {fitted}, starting from the value typed here."
    if shown.is_clear:
        return "**Air**: nothing attenuates or scatters between the rig and the wall."
    return "**Given**: the solve keeps these values."


class WaterPanel(TabPanel):
    """The Water folder (built in the current GUI container)."""

    def __init__(self, server: viser.ViserServer, ctl: Controller, flag: Programmatic) -> None:
        super().__init__(server, ctl, flag)
        gui = self.gui
        with ctl.state.lock:
            medium = ctl.state.shown_medium()
        step = 10.0**-DIGITS
        with gui.add_folder("Water", expand_by_default=True):
            self.fields: dict[str, Any] = {
                name: gui.add_number(
                    label,
                    rounded(getattr(medium, name), DIGITS),
                    min=MEDIUM_BOUNDS[name][0],
                    max=MEDIUM_BOUNDS[name][1],
                    step=step,
                    hint=hint,
                )
                for name, (label, hint) in FIELDS.items()
            }
            self.text = gui.add_markdown("")
        for name, handle in self.fields.items():
            handle.on_update(self.guard(self._edit(name, handle)))

    def _edit(self, name: str, handle: Any) -> Any:
        def edit(event: Any) -> None:
            self.ctl.set_medium(**{name: handle.value})

        return edit

    def update(self, frame: Frame) -> None:
        """The values shown (the solve's estimate, else those it starts from)."""
        if not frame.dirty & {"widgets", "scene"}:
            return
        st = self.ctl.state
        with st.lock:
            shown, start = st.shown_medium(), st.solve_project.medium.initial
            estimated = st.solve_settings.medium_estimate
            estimate_shown = st.shown_estimate() is not None
        for name, handle in self.fields.items():
            self.flag.assign(handle, rounded(getattr(shown, name), DIGITS))
        self.text.content = water_text(shown, start, estimated, estimate_shown=estimate_shown)
