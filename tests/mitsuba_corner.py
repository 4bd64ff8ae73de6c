"""Mitsuba 3's bounce of `lightcal synth --corner`'s ceiling and side wall, to check the
brute-force reference (`lightcal.synthetic.bounce_reference`) against.

The views, camera and light of the `clean` Mitsuba dataset (`tests.mitsuba_datasets`:
its smooth spot, read back as a table RID), a Lambertian wall of albedo 0.8 as a 12 m
square around where the views look, the corner's two surfaces (`corner_surroundings` at
0.7 m, 0.5 m deep, albedo 0.8, two-sided) as rectangles; the bounce is the `path` render
(`max_depth` 16) less the `direct` render, in Mitsuba's radiance (albedo / pi times
lightcal's irradiance).
"""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from lightcal.core.scene import Rig, View
from lightcal.synthetic.bounce_reference import CornerBounce, corner_surroundings
from lightcal.synthetic.height_field import BowedWall, surface_points
from lightcal.synthetic.imaging import _wall_extent, view_target_center
from tests.mitsuba_datasets import (
    _diffuse,
    _mitsuba,
    _plane_rectangle,
    _render,
    _sensor_dict,
    _spot,
    _transform,
    mitsuba_variant,
    session_dataset,
    truth_scene,
)

ALBEDO = 0.8
WALL_HALF_M = 6.0
MAX_DEPTH = 16


def _scene(mi: Any, camera: Any, view: View, light: Any, surfaces: Any, spp: int, path: bool):
    """The Mitsuba scene of one view: `path` (`max_depth` 16) or `direct`."""
    target = view_target_center([view])
    scene: dict[str, Any] = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": MAX_DEPTH}
        if path
        else {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0},
        "sensor": _sensor_dict(mi, camera, view, spp),
        "wall": _plane_rectangle(
            mi,
            np.array([target[0], target[1], 0.0]),
            np.array([WALL_HALF_M, 0.0, 0.0]),
            np.array([0.0, WALL_HALF_M, 0.0]),
            _diffuse(ALBEDO),
        ),
        "light": _spot(mi, _transform(light.rotation_world(view), light.position_world(view))),
    }
    two_sided = {"type": "twosided", "bsdf": _diffuse(ALBEDO)}
    for k, s in enumerate(surfaces):
        centre = s.corner_world + s.edge_u_world / 2 + s.edge_v_world / 2
        scene[f"surface_{k}"] = _plane_rectangle(
            mi, centre, s.edge_u_world / 2, s.edge_v_world / 2, two_sided
        )
    return scene


def _blocks(image: NDArray, size: int) -> NDArray:
    """(H // size, W // size) the means of size x size blocks."""
    h, w = image.shape[0] // size * size, image.shape[1] // size * size
    return image[:h, :w].reshape(h // size, size, w // size, size).mean(axis=(1, 3))


def corner_ratios(
    tmp_path_factory: pytest.TempPathFactory, *, views: int, spp: int, block: int
) -> tuple[NDArray, list[float]]:
    """The reference's bounce / Mitsuba's over the blocks of block x block pixels that
    see lit wall only (the surfaces' masks eroded by 2 pixels) and whose bounce is above
    1 % of the signal, and each view's sum ratio over them. 240 x 160 views."""
    project = session_dataset(
        tmp_path_factory, "clean", views=views, width=240, height=160, sensor="clean"
    )
    truth = truth_scene(project)
    camera = truth.camera
    view_list = [View(v.R_camera_world, v.t_camera_world, 1.0) for v in truth.views]
    light = truth.light.replace(scale=1.0)
    rig = Rig.single(light)
    surroundings = corner_surroundings(view_target_center(view_list), 0.7, 0.5, ALBEDO)
    reference = CornerBounce(surroundings, _wall_extent(camera, view_list))
    mi = _mitsuba(mitsuba_variant())
    ratios, sums = [], []
    for i, view in enumerate(view_list):
        full = _render(
            mi, _scene(mi, camera, view, light, surroundings.surfaces, spp, True), spp, i
        )
        direct = _render(
            mi, _scene(mi, camera, view, light, surroundings.surfaces, 16, False), 16, i
        )
        points, valid = surface_points(camera, view, BowedWall(0.0))
        seen = valid & ~reference.hidden(rig, view, points)
        seen = cv2.erode(seen.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
        ours = reference.image_bounce(rig, view, points, valid) * ALBEDO / math.pi
        whole = _blocks(seen.astype(np.float64), block) == 1.0
        theirs_b, ours_b = _blocks(full - direct, block), _blocks(ours, block)
        selected = whole & (theirs_b > 0.01 * _blocks(full, block))
        ratios.append(ours_b[selected] / theirs_b[selected])
        sums.append(float(ours_b[selected].sum() / theirs_b[selected].sum()))
    return np.concatenate(ratios), sums
