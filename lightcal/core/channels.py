"""Colour channels solved jointly: one pose, each channel its lights' scales, room light
and medium (`lightcal.core.problem.ParameterLayout`); what the joint solve refuses."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from lightcal.core.image_data import ImageData
from lightcal.core.medium import MediumUnknown
from lightcal.core.surroundings import Surroundings

if TYPE_CHECKING:  # solver_options imports the problem, which imports this
    from lightcal.core.solver_options import SolverOptions

__all__ = ["channel_media", "check_channels"]


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


def channel_media(
    channels: tuple[str, ...],
    medium: MediumUnknown | None,
    media: Sequence[MediumUnknown] | None,
) -> list[MediumUnknown]:
    """One medium per channel (one without channels), each estimating the same."""
    if len(channels) == 1 or len(set(channels)) != len(channels):
        raise ValueError(f"channels: expected 2 or more distinct names, got {list(channels)}")
    if media is None:
        return [medium if medium is not None else MediumUnknown()] * max(1, len(channels))
    media = list(media)
    if len(media) != max(1, len(channels)):
        raise ValueError(
            f"medium: expected one per channel ({max(1, len(channels))}), got {len(media)}"
        )
    if any(m.estimate != media[0].estimate for m in media):
        raise ValueError("medium: expected every channel to estimate the same parameters")
    return media
