"""Triangle meshes of synthetic walls: what `lightcal synth --declare-wall-mesh` writes.

The true wall of a synthetic dataset is the plane z = 0 or the height field of a bowed
wall (`height_field.BowedWall`). `height_field_mesh` samples it on a regular grid of
`spacing_m` (each cell two triangles) over the rectangle that holds every view's image
on the plane z = 0, widened by `margin_m`. Linear interpolation of the paraboloid cap
departs from it by at most depth (spacing / R)^2 / 4 inside the disc (5 mm, R = 1 m,
2 cm: 0.5 um) and by about slope x spacing / 4 across its rim, where its slope jumps
(5 mm: 50 um).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.scene import View
from lightcal.core.wall_mesh import WallMesh
from lightcal.io.wall_mesh_file import write_wall_mesh
from lightcal.synthetic.height_field import BowedWall

#: The file `lightcal synth --declare-wall-mesh` writes beside project.json.
WALL_MESH_NAME = "wall_mesh.ply"


def image_extent_on_plane(
    camera: Camera, views: list[View], margin_m: float
) -> tuple[float, float, float, float]:
    """(x_min, y_min, x_max, y_max) of every view's image border on z = 0, widened by
    margin_m (a border ray that misses the plane is left out), metres."""
    w, h = camera.width, camera.height
    t = np.linspace(0.0, 1.0, 17)
    border = (
        np.concatenate(
            [
                np.stack([t * w, np.zeros_like(t)], 1),
                np.stack([t * w, np.full_like(t, h)], 1),
                np.stack([np.zeros_like(t), t * h], 1),
                np.stack([np.full_like(t, w), t * h], 1),
            ]
        )
        - 0.5
    )
    rays, ok = camera.rays_camera(border)
    points = []
    for view in views:
        d = rays[ok] @ view.R_camera_world
        c = view.center_world
        hit = d[:, 2] < 0.0
        lam = -c[2] / d[hit, 2]
        points.append(c[:2] + lam[:, None] * d[hit, :2])
    xy = np.concatenate(points)
    lo = xy.min(axis=0) - margin_m
    hi = xy.max(axis=0) + margin_m
    return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


def height_field_mesh(
    shape: BowedWall | None,
    extent: tuple[float, float, float, float],
    spacing_m: float = 0.02,
) -> WallMesh:
    """The wall `shape` (None: the plane z = 0) on a grid of `spacing_m` over `extent`
    (x_min, y_min, x_max, y_max), each cell split along its diagonal."""
    x0, y0, x1, y1 = extent
    nx = max(1, int(np.ceil((x1 - x0) / spacing_m)))
    ny = max(1, int(np.ceil((y1 - y0) / spacing_m)))
    xs = np.linspace(x0, x1, nx + 1)
    ys = np.linspace(y0, y1, ny + 1)
    gx, gy = np.meshgrid(xs, ys)
    xy = np.stack([gx.ravel(), gy.ravel()], 1)
    z = np.zeros(len(xy)) if shape is None else shape.height(xy)
    vertices = np.concatenate([xy, z[:, None]], axis=1)
    j, i = np.mgrid[0:ny, 0:nx]
    a = (j * (nx + 1) + i).ravel()
    b, c, d = a + 1, a + nx + 2, a + nx + 1
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return WallMesh(vertices, faces)


def write_synthetic_wall_mesh(
    folder: Path, camera: Camera, views: list[View], shape: BowedWall | None
) -> str:
    """Write the mesh of the dataset's true wall as `WALL_MESH_NAME` in folder; returns
    its name (relative to the project file)."""
    extent = image_extent_on_plane(camera, views, margin_m=0.3)
    write_wall_mesh(folder / WALL_MESH_NAME, height_field_mesh(shape, extent))
    return WALL_MESH_NAME
