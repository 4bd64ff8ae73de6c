"""Colour channels solved jointly: one pose, each channel its lights' scales, room light
and medium (`lightcal.core.problem.ParameterLayout`); what the joint solve refuses."""

from __future__ import annotations

from lightcal.core.image_data import ImageData
from lightcal.core.solver_options import SolverOptions
from lightcal.core.surroundings import Surroundings

__all__ = ["check_channels"]


def check_channels(
    images: list[ImageData],
    channels: tuple[str, ...],
    options: SolverOptions,
    surroundings: Surroundings | None,
) -> None:
    """Refuse images of channels the layout lacks and what the joint solve does not model
    per channel: the wall's albedo map and the surroundings' bounce (both colours)."""
    n = max(1, len(channels))
    for im in images:
        if im.channel >= n:
            raise ValueError(f"{im.name}: channel {im.channel}: expected an index below {n}")
    if len(channels) > 1 and (options.albedo_map is not None or surroundings is not None):
        raise ValueError(
            "channels: the albedo map and the surroundings are modelled for one channel; "
            "calibrate each channel on its own"
        )
