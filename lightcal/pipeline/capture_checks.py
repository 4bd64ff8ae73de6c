"""Capture sets that would make a result look better than it is, said in the result's
warnings: images taken from one camera pose (a copy of a view adds no information about
the light but counts its noise again, so the sigmas shrink without the pose being better
known), and a set of one pose only."""

from __future__ import annotations

import math

import numpy as np

from lightcal.core.scene import View
from lightcal.io.project import Project

SAME_POSITION_M = 0.002
"""Camera centres closer than this (and turned less than `SAME_ANGLE_DEG`) are one pose."""
SAME_ANGLE_DEG = 0.2


def same_pose_warnings(project: Project, used: set[str]) -> list[str]:
    """Warnings for the images of `used` (names) taken from one camera pose. A photo read
    in several colour channels (`sensor.channels`) is one image here: its channels are
    one exposure, not repeated views."""
    views: list[tuple[str, View]] = []
    photos: set[int] = set()
    for i, (name, view) in enumerate(zip(project.names, project.views, strict=True)):
        if name in used and project.spec_image(i) not in photos:
            photos.add(project.spec_image(i))
            views.append((project.photo_name(i), view))
    groups: list[list[str]] = []
    poses: list[tuple[np.ndarray, np.ndarray]] = []
    for name, view in views:
        for k, (centre, R) in enumerate(poses):
            angle = math.degrees(
                math.acos(min(1.0, max(-1.0, (np.trace(R.T @ view.R_camera_world) - 1) / 2)))
            )
            if np.linalg.norm(view.center_world - centre) < SAME_POSITION_M and (
                angle < SAME_ANGLE_DEG
            ):
                groups[k].append(name)
                break
        else:
            poses.append((view.center_world, view.R_camera_world))
            groups.append([name])
    out = [
        f"images {', '.join(g)} were taken from one camera pose (within "
        f"{SAME_POSITION_M * 1e3:g} mm and {SAME_ANGLE_DEG:g} deg): a repeated view adds no "
        "information about the light but counts its noise again, so the sigmas are too small; "
        "keep one of them, or move the camera between shots"
        for g in groups
        if len(g) > 1
    ]
    if len(groups) == 1 and views:
        out.append(
            "every image was taken from one camera pose: the light's distance along its axis "
            "rests on the fall-off of one view alone; photograph the wall from several "
            "distances and angles (lightcal plan suggests where)"
        )
    return out
