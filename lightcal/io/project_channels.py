"""Colour channels solved jointly (`sensor.channels`): each photo one project entry per
channel, and what the joint solve refuses."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from lightcal.core.problem import MediumUnknown
from lightcal.core.scene import View
from lightcal.errors import InputError
from lightcal.io.project_spec import ProjectFile

if TYPE_CHECKING:
    from lightcal.io.project import Project

__all__ = ["check_channel_terms", "with_channels"]


def with_channels(project: Project, media: tuple[MediumUnknown, ...]) -> Project:
    """`project` with every image one entry per `sensor.channels` (see `Project`)."""
    channels = tuple(project.spec.sensor.channels or ())
    n = len(project.names)
    order = [(k, ch) for k in range(n) for ch in range(len(channels))]

    def each(values: list) -> list:
        return [values[k] for k, _ in order] if values else []

    return dataclasses.replace(
        project,
        views=each(project.views),
        image_paths=each(project.image_paths),
        mask_paths=each(project.mask_paths),
        names=[f"{project.names[k]}[{channels[ch]}]" for k, ch in order],
        pose_covariances=each(project.pose_covariances),
        pose_intrinsics_jacobians=each(project.pose_intrinsics_jacobians),
        dark_paths=each(project.dark_paths),
        channels=channels,
        channel_of=[ch for _, ch in order],
        spec_index=[k for k, _ in order],
        media=media,
    )


def check_channel_terms(spec: ProjectFile, views: list[View], source: Path) -> None:
    """What colour channels solved jointly do not model: the wall's albedo map and the
    surroundings' bounce (colours both), and one offset beside each channel's room light
    when every image has the same exposure (the two are then one column per channel)."""
    if not spec.sensor.channels:
        return
    for key, present in (
        ("wall.albedo_map", spec.wall.albedo_map is not None),
        ("surroundings", spec.surroundings is not None),
    ):
        if present:
            raise InputError(
                source,
                f"{key}: modelled for one channel, not beside sensor.channels; calibrate "
                "each channel on its own (sensor.channel)",
            )
    exposures = np.array([v.exposure for v in views])
    same = np.ptp(exposures) <= 1e-9 * np.abs(exposures).max()
    if spec.sensor.estimate_offset and spec.sensor.estimate_ambient and same:
        raise InputError(
            source,
            "sensor.estimate_offset: with sensor.channels and every image at the same "
            "exposure the one offset cannot be told from each channel's room light; "
            "expected estimate_offset false (the room light per channel) or images of "
            "different exposures",
        )
