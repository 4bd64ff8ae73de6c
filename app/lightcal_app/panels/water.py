"""The Light tab's Water folder: the medium between the rig and the wall as numbers
(`medium.attenuation_per_m`, `backscatter_per_m`, `phase_g`; docs/model.md, "Medium"),
each in the core's range (`solve_settings.MEDIUM_BOUNDS`).

An edit renders the overlays through the water and starts the solve over from it
(`Actions.set_medium`); a refused value is said in the page and the field goes back.
After a solve that estimated c or beta the fields show the estimate, as the light's
pose fields do. With `sensor.channels` (colour channels solved jointly) c and beta have
one field per channel ("attenuation c (R)", ...: the file's lists) and g one for all.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import viser

from lightcal.core.medium import Medium
from lightcal.io.project import Project
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

PER_CHANNEL = ("attenuation_per_m", "backscatter_per_m")
"""The values each colour channel has its own of (`sensor.channels`); g is shared."""


def field_keys(channels: Sequence[str]) -> list[tuple[str, int | None]]:
    """The folder's fields as (value, channel index or None: every channel's), in order:
    one per value without channels; with them c and beta per channel, then g."""
    if not channels:
        return [(name, None) for name in FIELDS]
    return [
        *((name, k) for name in PER_CHANNEL for k in range(len(channels))),
        ("phase_g", None),
    ]


def field_key(name: str, channel: int | None, channels: Sequence[str]) -> str:
    """The key of a field in `WaterPanel.fields`: the value's name, with the channel's in
    brackets for a value per channel ("attenuation_per_m[R]")."""
    return name if channel is None else f"{name}[{channels[channel]}]"


def water_text(
    shown: Medium | Sequence[Medium],
    start: Medium | Sequence[Medium],
    estimated: tuple[str, ...],
    *,
    estimate_shown: bool,
    channels: Sequence[str] = (),
    behind_port: bool = False,
) -> str:
    """What the folder says of the values shown: `shown`, the solve's estimate when
    `estimate_shown`, else `start` (`estimated`: `medium.estimate`); with `channels`, one
    medium of each per channel. `behind_port`: the project declares a flat port (its
    water's index), so a clear medium is clear water, not air."""
    shown_all = [shown] if isinstance(shown, Medium) else list(shown)
    start_all = [start] if isinstance(start, Medium) else list(start)
    fitted = " and ".join(SYMBOLS.get(name, name) for name in estimated)
    if estimated and estimate_shown:
        began = ", ".join(  # (no-break spaces: "c = 0.1" on one line)
            f"{SYMBOLS.get(name, name)}{_channel(channels, k, name)}\u00a0=\u00a0"
            f"{getattr(medium, name):g}"
            for name in estimated
            for k, medium in enumerate(start_all)
            if k == 0 or name in PER_CHANNEL
        )
        return f"Showing the solve's **estimate** of {fitted}; it started from {began}."
    if estimated:
        return f"The solve **estimates** {fitted}, starting from the value typed here."
    if all(m.is_clear for m in shown_all):
        if behind_port:
            return (
                "**Clear water** behind the flat port: nothing attenuates or scatters "
                "between the rig and the wall."
            )
        return "**Air**: nothing attenuates or scatters between the rig and the wall."
    return "**Given**: the solve keeps these values."


def _channel(channels: Sequence[str], k: int, name: str) -> str:
    """ " (R)" after a value per channel, nothing otherwise."""
    return f"\u00a0({channels[k]})" if channels and name in PER_CHANNEL else ""


class WaterPanel(TabPanel):
    """The Water folder (built in the current GUI container)."""

    def __init__(self, server: viser.ViserServer, ctl: Controller, flag: Programmatic) -> None:
        super().__init__(server, ctl, flag)
        self.folder = self.gui.add_folder("Water", expand_by_default=True)
        self.fields: dict[str, Any] = {}
        self.channels: tuple[str, ...] = ()
        self.text: Any = None
        with ctl.state.lock:
            project = ctl.state.project
        self._build(project)

    def _build(self, project: Project) -> None:
        """The fields of the project's `sensor.channels` (none: one of each) with its
        values (`update` then writes those shown)."""
        gui = self.gui
        for handle in [*self.fields.values(), *([self.text] if self.text else [])]:
            handle.remove()
        channels = self.channels = project.channels
        media = [m.initial for m in project.media] or [project.medium.initial]
        step = 10.0**-DIGITS
        with self.folder:
            self.fields = {}
            for name, k in field_keys(channels):
                label, hint = FIELDS[name]
                handle = gui.add_number(
                    label if k is None else label.replace(" (", f", {channels[k]} (", 1),
                    rounded(getattr(media[k or 0], name), DIGITS),
                    min=MEDIUM_BOUNDS[name][0],
                    max=MEDIUM_BOUNDS[name][1],
                    step=step,
                    hint=hint if k is None else f"{hint} Colour channel {channels[k]}'s.",
                )
                handle.on_update(self.guard(self._edit(name, k, handle)))
                self.fields[field_key(name, k, channels)] = handle
            self.text = gui.add_markdown("")

    def set_project(self, project: Project) -> None:
        """Another project: fields per colour channel when its channels differ."""
        if project.channels != self.channels:
            self._build(project)

    def _edit(self, name: str, channel: int | None, handle: Any) -> Any:
        def edit(event: Any) -> None:
            self.ctl.set_medium(channel, **{name: handle.value})

        return edit

    def update(self, frame: Frame) -> None:
        """The values shown (the solve's estimate, else those it starts from)."""
        if not frame.dirty & {"widgets", "scene"}:
            return
        st = self.ctl.state
        with st.lock:
            shown = st.shown_media()
            start = [m.initial for m in st.solve_project.media] or [st.solve_project.medium.initial]
            estimated = st.solve_settings.medium_estimate
            estimate_shown = st.shown_estimate() is not None
            channels = st.project.channels
            project = st.project
            behind_port = project.camera_port is not None or any(
                u.initial.port is not None for u in project.lights
            )
        if channels != self.channels or len(shown) != max(1, len(channels)):
            return  # another project's fields: `set_project` rebuilds them
        for name, k in field_keys(channels):
            value = rounded(getattr(shown[k or 0], name), DIGITS)
            self.flag.assign(self.fields[field_key(name, k, channels)], value)
        self.text.content = water_text(
            shown,
            start,
            estimated,
            estimate_shown=estimate_shown,
            channels=channels,
            behind_port=behind_port,
        )
