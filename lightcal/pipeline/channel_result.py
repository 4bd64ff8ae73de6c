"""Colour channels solved jointly in the result (`channels`): per channel its lights'
scales, its room light and its medium, with their 1-sigmas; and their lines for
`lightcal calibrate` (`lightcal.pipeline.result_text.channel_lines`)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from lightcal.core.medium import Medium, medium_from_description
from lightcal.core.scene import Light, Rig
from lightcal.core.solver import CalibrationModel

__all__ = ["channel_scenes", "channel_summaries"]


def _sigma(cov: np.ndarray, k: int) -> float:
    return math.sqrt(max(float(cov[k, k]), 0.0))


def channel_summaries(model: CalibrationModel, x: np.ndarray, cov: np.ndarray) -> list[dict] | None:
    """Per channel {name, scales: {light: s}, scale_sigmas: {light: sigma}, ambient,
    ambient_sigma, medium: {attenuation_per_m, backscatter_per_m, phase_g, estimated,
    sigma}} at x; None without channels. A scale's sigma is s times its log's."""
    lay = model.layout
    if not lay.channels:
        return None
    out = []
    estimated = lay.medium_unknown.estimate
    for ch, name in enumerate(lay.channels):
        lights = lay.rig(x, ch).lights
        columns = lay.medium_columns(ch)
        ambient = lay.ambient_index_of(ch)
        out.append(
            {
                "name": name,
                "scales": {light.name: light.scale for light in lights},
                "scale_sigmas": {
                    light.name: light.scale * _sigma(cov, block.log_scale_of(ch))
                    for light, block in zip(lights, lay.blocks, strict=True)
                },
                "ambient": None if ambient is None else float(x[ambient]),
                "ambient_sigma": None if ambient is None else _sigma(cov, ambient),
                "medium": {
                    **lay.medium_of(x, ch).describe(),
                    "estimated": list(estimated),
                    "sigma": {nm: _sigma(cov, columns.start + k) for k, nm in enumerate(estimated)},
                },
            }
        )
    return out


def channel_scenes(
    channels: list[dict] | None, lights: list[Light], project_channels: tuple[str, ...]
) -> list[tuple[Rig, Medium, float]]:
    """Per channel of a result file's `channels`, (its lights at their scales, its
    medium, its room light) for `lightcal.report.render_views`; empty without channels.

    Raises:
        ValueError: the result's channels are not the project's (`sensor.channels`), a
            light has no scale in a channel, or a medium is malformed.
    """
    names = [str(ch.get("name")) for ch in channels or []]
    if names != list(project_channels):
        raise ValueError(
            f"channels: the result's are {names or 'none'}, the project's "
            f"{list(project_channels) or 'none'}; expected the project the result was made of"
        )
    out = []
    for ch in channels or []:
        scales = ch.get("scales") or {}
        missing = [light.name for light in lights if light.name not in scales]
        if missing:
            raise ValueError(f"channels: {ch['name']}: no scale for light {missing[0]!r}")
        rig = Rig(tuple(replace(light, scale=float(scales[light.name])) for light in lights))
        ambient = ch.get("ambient")
        out.append((rig, medium_from_description(ch.get("medium") or {}), float(ambient or 0.0)))
    return out
