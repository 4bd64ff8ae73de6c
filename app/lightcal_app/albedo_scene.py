"""The wall's estimated albedo map in the 3D view (`wall.albedo_map`).

The map (`lightcal.core.albedo_map.AlbedoMap`, world x, y on the wall z = 0) is drawn as
the image `/albedo_map` lying on the wall a hair in front of it (towards the cameras), one
block of picture pixels per grid node, centred on the node: the picture covers the grid's
extent (its nodes, half a spacing to spare). Colours as the report's figure
(`lightcal.report.albedo_figure`): albedo / mean - 1 on the diverging map
(`lightcal.colormap.diverging_rgb`: blue darker than the mean, red brighter) in bands of
vmax / RESIDUAL_STEPS, vmax the 99th percentile of |albedo / mean - 1| over the nodes the
pixels saw; nodes no pixel saw are transparent (the wall shows through). viser lays an
image's rows along its local +y: with the identity rotation, row j is the grid's row j.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from lightcal.colormap import diverging_rgb, robust_vmax, stepped
from lightcal.core.albedo_map import AlbedoMap

MAX_SIDE_PX = 512
"""The picture's long side at most (each node a square block of pixels)."""
WALL_GAP_M = 0.002
"""How far in front of the wall (towards the cameras, +z) the picture lies: above the
wall's grid (at 1 mm) and clear of its plane."""


@dataclass(frozen=True)
class AlbedoPicture:
    """The map as a picture on the wall.

    Attributes:
        rgba: (H, W, 4) uint8, row j along world +y, transparent where unseen.
        width_m, height_m: its size on the wall along world x and y, metres.
        center_xy_m: (2,) world x, y of its centre.
        vmax: the albedo / mean - 1 of the darkest colours.
    """

    rgba: np.ndarray
    width_m: float
    height_m: float
    center_xy_m: np.ndarray
    vmax: float


def albedo_picture(albedo: AlbedoMap, *, max_side_px: int = MAX_SIDE_PX) -> AlbedoPicture:
    """The picture of `albedo` (see the module docstring)."""
    values = albedo.image() - 1.0  # (ny, nx), NaN where unseen
    seen = np.isfinite(values)
    vmax = robust_vmax(values)
    rgb = diverging_rgb(stepped(values, vmax), vmax)
    alpha = np.where(seen, 255, 0).astype(np.uint8)
    rgba = np.concatenate([rgb, alpha[..., None]], axis=-1)
    grid = albedo.grid
    ny, nx = grid.shape
    k = max(1, max_side_px // max(ny, nx))
    # Square blocks: the browser's texture filter blends only at the nodes' edges.
    rgba = np.repeat(np.repeat(rgba, k, axis=0), k, axis=1)
    s = grid.spacing_m
    center = grid.origin_xy_m + 0.5 * s * (np.array([nx, ny], dtype=np.float64) - 1.0)
    return AlbedoPicture(np.ascontiguousarray(rgba), nx * s, ny * s, center, vmax)


class AlbedoOnWall:
    """The node `/albedo_map`: the shown estimate's map, or nothing.

    Args:
        scene: the viser scene (server-level: every browser sees the same).
    """

    def __init__(self, scene: Any) -> None:
        self.scene = scene
        self.handle: Any = None
        self.shown: AlbedoMap | None = None
        self.picture: AlbedoPicture | None = None

    def draw(self, albedo: AlbedoMap | None, *, visible: bool, rebuilt: bool) -> None:
        """Show `albedo` (None: remove the picture), drawn or hidden (`visible`).

        Args:
            albedo: the map to draw.
            visible: shown (the View tab's toggle) or kept hidden.
            rebuilt: the scene was just reset (the old node is gone already).
        """
        if rebuilt:
            self.handle, self.shown, self.picture = None, None, None
        if albedo is None:
            if self.handle is not None:
                self.handle.remove()
            self.handle, self.shown, self.picture = None, None, None
            return
        if albedo is not self.shown or self.handle is None:
            pic = albedo_picture(albedo)
            self.handle = self.scene.add_image(
                "/albedo_map",
                pic.rgba,
                pic.width_m,
                pic.height_m,
                format="png",
                cast_shadow=False,
                receive_shadow=False,
                position=(float(pic.center_xy_m[0]), float(pic.center_xy_m[1]), WALL_GAP_M),
                visible=visible,
            )
            self.shown, self.picture = albedo, pic
        elif self.handle.visible != visible:
            self.handle.visible = visible
