"""Colour channels solved jointly in the result (`channels`): per channel its lights'
scales, its room light and its medium, with their 1-sigmas; and their lines for
`lightcal calibrate` (`lightcal.pipeline.result_text.channel_lines`)."""

from __future__ import annotations

import math

import numpy as np

from lightcal.core.solver import CalibrationModel

__all__ = ["channel_summaries"]


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
