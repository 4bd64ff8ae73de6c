"""What a result says of the medium and the surroundings: the medium (`medium`), per
colour channel solved jointly (`channels`) its lights' scales, its room light and its
medium, with their 1-sigmas (their lines for `lightcal calibrate`:
`lightcal.pipeline.result_text.channel_lines`), and the surroundings' estimated albedos
(`surroundings`)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from lightcal.core.medium import Medium, medium_from_description
from lightcal.core.scene import Light, Rig
from lightcal.core.solver import CalibrationModel
from lightcal.core.surroundings import Surroundings

__all__ = [
    "channel_scenes",
    "channel_scenes_at",
    "channel_summaries",
    "estimated_surroundings",
    "medium_summary",
    "medium_summary_at",
    "surroundings_summary",
]


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


def channel_scenes_at(model: CalibrationModel, x: np.ndarray) -> list[tuple[Rig, Medium, float]]:
    """Per colour channel of `model`, (its lights at their scales, its medium, its room
    light) at x, for the pictures (`lightcal.report.render_views`, the page's overlays);
    empty without channels."""
    lay = model.layout
    return [
        (lay.rig(x, ch), lay.medium_of(x, ch), lay.ambient(x, ch))
        for ch in range(len(lay.channels))
    ]


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


def medium_summary(
    medium: Medium, estimated: tuple[str, ...] = (), sigma: dict[str, float] | None = None
) -> dict:
    """The medium's parameters, which were estimated and their 1-sigma (a result's
    `medium`)."""
    return {**medium.describe(), "estimated": list(estimated), "sigma": dict(sigma or {})}


def medium_summary_at(model: CalibrationModel, x: np.ndarray, cov: np.ndarray) -> dict:
    """`medium_summary` of the solution x, sigmas from the covariance."""
    lay = model.layout
    estimated = lay.medium_unknown.estimate
    sigma = {
        name: math.sqrt(max(cov[lay.medium.start + k, lay.medium.start + k], 0.0))
        for k, name in enumerate(estimated)
    }
    return medium_summary(lay.medium_of(x), estimated, sigma)


def surroundings_summary(model: CalibrationModel, x: np.ndarray, cov: np.ndarray) -> dict | None:
    """The surroundings' albedos at x when the calibration estimates any ({"albedos":
    [per surface], "estimated": [surface indices], "sigma": {index: 1-sigma}}); None
    otherwise."""
    lay = model.layout
    albedos = lay.surface_albedos(x)
    if albedos is None or model.surroundings is None:
        return None
    estimated = list(model.surroundings.estimate_albedo)
    sigma = {str(k): _sigma(cov, lay.surface_albedo.start + j) for j, k in enumerate(estimated)}
    return {"albedos": albedos.tolist(), "estimated": estimated, "sigma": sigma}


def estimated_surroundings(
    surroundings: Surroundings | None, summary: dict | None
) -> Surroundings | None:
    """`surroundings` with the albedos a result estimated (its `surroundings`: None
    keeps the declared).

    Raises:
        ValueError: the summary's albedos are not one per surface in [0, 1).
    """
    if surroundings is None or summary is None:
        return surroundings
    albedos = summary.get("albedos")
    if not isinstance(albedos, list) or len(albedos) != len(surroundings.surfaces):
        raise ValueError(
            f"surroundings.albedos: expected {len(surroundings.surfaces)} values, one per "
            f"surface of the project, got {albedos!r}"
        )
    return surroundings.with_albedos(np.array(albedos, dtype=np.float64))
