"""The estimated albedo map of a calibration in the result (`wall.albedo_map`): the grid,
the albedo at its nodes (relative to the wall's mean; null where no selected pixel saw
the wall), its range and spread, in words for `lightcal calibrate` and the report."""

from __future__ import annotations

import math

import numpy as np

from lightcal.core.albedo_map import AlbedoGrid, AlbedoMap
from lightcal.core.camera import Camera
from lightcal.core.scene import View
from lightcal.core.solver import CalibrationModel


def albedo_map_summary(model: CalibrationModel, x: np.ndarray) -> dict | None:
    """The albedo map at x, JSON-ready; None when the project does not estimate one.

    Keys: origin_xy_m (world x, y of node (0, 0)), spacing_m, shape ([ny, nx]), values
    (ny rows of nx, the albedo over its mean at each node, None where unseen),
    nodes_seen, pixels_per_node (the selected pixels over the nodes they see), range
    ([min, max] over the seen nodes), rms (of albedo - 1 over them), formula.
    """
    albedo = model.albedo_map(x)
    if albedo is None:
        return None
    image = albedo.image()
    seen = np.isfinite(image)
    n_seen = int(seen.sum())
    low, high = albedo.seen_range()
    spread = image[seen] - 1.0
    g = albedo.grid
    return {
        "origin_xy_m": g.origin_xy_m.tolist(),
        "spacing_m": g.spacing_m,
        "shape": list(g.shape),
        "values": [[None if math.isnan(v) else float(v) for v in row] for row in image],
        "nodes_seen": n_seen,
        "pixels_per_node": model.m / max(n_seen, 1),
        "range": [low, high],
        "rms": float(np.sqrt(np.mean(spread**2))) if n_seen else 0.0,
        "formula": "a(x, y) bilinear between the nodes origin_xy_m + spacing_m (i, j), "
        "values[j][i]; every value above the offset is multiplied by a at its wall point",
    }


def albedo_map_of(summary: dict) -> AlbedoMap:
    """The map of a summary (`albedo_map_summary`, or a result file's `albedo_map`)."""
    grid = AlbedoGrid(
        np.asarray(summary["origin_xy_m"], dtype=np.float64),
        float(summary["spacing_m"]),
        (int(summary["shape"][0]), int(summary["shape"][1])),
    )
    values = np.array(
        [[math.nan if v is None else v for v in row] for row in summary["values"]],
        dtype=np.float64,
    ).ravel()
    seen = np.isfinite(values)
    return AlbedoMap(grid, np.where(seen, values - 1.0, 0.0), seen.astype(np.float64))


def albedo_image(albedo: AlbedoMap, camera: Camera, view: View) -> np.ndarray:
    """(H, W) the albedo at each pixel centre's wall point (1 off the map)."""
    v, u = np.mgrid[0 : camera.height, 0 : camera.width]
    rays, valid = camera.rays_camera(np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float64))
    rays_world = rays @ view.R_camera_world  # R^T ray, row by row
    c = view.center_world
    t = -c[2] / rays_world[:, 2]
    points = c[:2] + t[:, None] * rays_world[:, :2]
    points[~(valid & (t > 0.0))] = np.nan
    return albedo.factor(points).reshape(camera.height, camera.width)


def albedo_text(summary: dict) -> str:
    """One line on the estimated albedo map."""
    low, high = summary["range"]
    return (
        f"wall albedo map: {summary['nodes_seen']} nodes every "
        f"{summary['spacing_m'] * 1000:.3g} mm seen ({summary['pixels_per_node']:.3g} pixels "
        f"a node), {low:.3f} to {high:.3f} of its mean (RMS {100 * summary['rms']:.2g} %)"
    )
