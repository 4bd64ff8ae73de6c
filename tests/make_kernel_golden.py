"""Write tests/data/kernel_golden.npz: renderer outputs that later versions must keep.

Run from the repository root with the version to record on the path:
`python tests/make_kernel_golden.py` (the file in the repository was written at commit
2ad8fa0, the last one with `lightcal/core/render_kernels.py`, before its kernels were
split into `lightcal/core/kernels/`). `tests/test_kernel_golden.py` compares the current
code with it to 1e-12 relative.

Only the public API (`render_image`, `pixel_footprints`, `shade`), so that the script
runs unchanged on any version. The cases cover every kernel path: the fused full image
(every RID, every sensor model, binning, RID sub-sampling, large solid angles, a
high-resolution crop whose footprints are ~5000 times smaller than their distance from
the origin) and `flux_pixels` (values without and with gradients, n = 1 and 2, binning,
a light near the wall).

The tables are recorded with their exact knot interpolation; since the renderer resamples
them on grids (`lightcal.core.rid_tabulate`), `cases(exact_tables=True)` renders them
that way (`RID.exact_data`) for the 1e-12 comparison, and `cases()` on the grids.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from lightcal.core import render
from lightcal.core.camera import Camera
from lightcal.core.rid import (
    RID,
    CosPowerRID,
    GaussianRID,
    IsotropicRID,
    SymmetricTableRID,
    Table2DRID,
)
from lightcal.core.scene import Light, Rig, View

PATH = Path(__file__).resolve().parent / "data" / "kernel_golden.npz"


def _rotation(rx: float, ry: float) -> np.ndarray:
    cx, sx, cy, sy = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry)
    return np.array([[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]]) @ np.array(
        [[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]]
    )


class _ExactTable(RID):
    """A table RID rendered by its exact knot interpolation, not its grid."""

    def __init__(self, table: RID) -> None:
        self.table = table
        self.symmetric = table.symmetric

    def data(self):  # type: ignore[no-untyped-def]
        return self.table.exact_data()


def _rids(exact_tables: bool) -> dict[str, RID]:
    theta = np.linspace(0.0, 1.4, 8)
    phi = np.linspace(0.0, 2 * math.pi, 6, endpoint=False)
    values = np.cos(theta)[None, :] ** 2 * (1.0 + 0.3 * np.cos(phi)[:, None]) + 0.05
    knots = np.linspace(0.0, 1.5, 9)
    table_1d: RID = SymmetricTableRID(knots, np.cos(knots) + 0.1)
    table_2d: RID = Table2DRID(theta, phi, values)
    if exact_tables:
        table_1d, table_2d = _ExactTable(table_1d), _ExactTable(table_2d)
    return {
        "isotropic": IsotropicRID(),
        "cos_power": CosPowerRID(3.7),
        "gaussian": GaussianRID(0.6),
        "table_1d": table_1d,
        "table_2d": table_2d,
    }


DIST = (-0.12, 0.03, 0.0007, -0.0011, -0.004)
SMALL = Camera.from_params(fx=30.0, fy=30.6, cx=12.2, cy=8.1, width=24, height=18, dist=DIST)
#: 48 x 32 pixels of a 6000 x 4000, f = 5400 px camera, near its corner.
CROP = Camera.from_params(
    fx=5400.0,
    fy=5400.0,
    cx=-2400.0,
    cy=-1500.0,
    width=48,
    height=32,
    dist=(-0.12, 0.05, 0.001, -0.0005, -0.01),
)
WIDE = Camera.from_params(fx=8.0, fy=8.0, cx=11.5, cy=8.5, width=24, height=18)
VIEW = View.looking_at(np.array([0.3, -0.2, 1.4]), np.array([0.05, 0.1, 0.0]), exposure=1.7)
CROP_VIEW = View.looking_at(np.array([0.25, -0.15, 1.6]), np.array([0.0, 0.1, 0.0]))
WIDE_VIEW = View.looking_at(np.array([0.0, 0.0, 0.05]), np.array([0.0, 1.0, 0.0]))


def _light(
    rid: RID, t: tuple[float, float, float] = (0.08, -0.05, 0.02), scale: float = 1.3
) -> Light:
    return Light(rid, np.array(t), _rotation(0.15, -0.1), scale=scale)


def _light_at_world(rid: RID, view: View, p_world: np.ndarray, R_world_light: np.ndarray) -> Light:
    R = view.R_camera_world
    return Light(rid, R @ p_world + view.t_camera_world, R @ R_world_light)


def _images(exact_tables: bool) -> Iterator[tuple[str, np.ndarray]]:
    rids = _rids(exact_tables)
    for name, rid in rids.items():
        yield (
            f"image__{name}",
            render.render_image(SMALL, VIEW, Rig.single(_light(rid)), offset=0.25),
        )
    two = Rig((_light(rids["cos_power"]), _light(rids["table_2d"], (-0.1, 0.0, 0.0), 0.4)))
    vmap = np.random.default_rng(6).uniform(0.5, 1.0, (SMALL.height, SMALL.width))
    for sensor in ("radiance", "cos4", "paper", "map"):
        for b in (1, 3):
            img = render.render_image(
                SMALL, VIEW, two, sensor=sensor, vignetting=vmap, binning=b, offset=0.01
            )
            yield f"image__{sensor}_b{b}", img
    sub = Rig((_light(rids["gaussian"]), _light(rids["isotropic"], (0.0, 0.1, 0.0))))
    for b in (1, 2):
        yield (
            f"image__nsub3_b{b}",
            render.render_image(SMALL, VIEW, sub, rid_subsamples=3, binning=b),
        )
    near = _light_at_world(rids["isotropic"], WIDE_VIEW, np.array([0.0, 0.04, 1e-3]), np.eye(3))
    yield "image__horizon", render.render_image(WIDE, WIDE_VIEW, Rig.single(near))
    for name in ("cos_power", "table_1d"):
        light = Light(rids[name], np.array([0.12, 0.0, 0.0]), _rotation(0.12, 0.0))
        yield f"image__crop_{name}", render.render_image(CROP, CROP_VIEW, Rig.single(light))
    light = Light(rids["cos_power"], np.array([0.12, 0.0, 0.0]), _rotation(0.12, 0.0))
    yield (
        "image__crop_paper",
        render.render_image(CROP, CROP_VIEW, Rig.single(light), sensor="paper"),
    )


def _axis_down(tilt_x: float, tilt_y: float) -> np.ndarray:
    return _rotation(math.pi - tilt_x, tilt_y)


def _shadings(exact_tables: bool) -> Iterator[tuple[str, np.ndarray]]:
    rids = _rids(exact_tables)
    poses = {
        "above": (np.array([0.12, -0.05, 0.8]), _axis_down(0.2, -0.1)),
        "near_wall": (np.array([0.05, 0.1, 0.003]), _axis_down(1.2, 0.3)),
    }
    rng = np.random.default_rng(11)
    pixels = {
        b: np.stack([rng.integers(0, 24 // b, 60), rng.integers(0, 18 // b, 60)], 1) for b in (1, 2)
    }
    footprints = {b: render.pixel_footprints(SMALL, VIEW, pixels[b], binning=b) for b in (1, 2)}
    crop_pixels = np.stack([rng.integers(0, 48, 60), rng.integers(0, 32, 60)], 1)
    for name, rid in rids.items():
        for pose, (p_world, R_wl) in poses.items():
            light = _light_at_world(rid, VIEW, p_world, R_wl)
            for b, n_sub in ((1, 1), (2, 1), (1, 2)):
                key = f"{name}_{pose}_b{b}_n{n_sub}"
                yield from _shade(key, footprints[b], VIEW, light, n_sub)
        light = Light(rid, np.array([0.12, 0.0, 0.0]), _rotation(0.12, 0.0))
        fp = render.pixel_footprints(CROP, CROP_VIEW, crop_pixels)
        yield from _shade(f"{name}_crop_b1_n1", fp, CROP_VIEW, light, 1)


def _shade(
    key: str, fp: render.Footprints, view: View, light: Light, n_sub: int
) -> Iterator[tuple[str, np.ndarray]]:
    rig = Rig.single(light)
    plain = render.shade(fp, view, rig, rid_subsamples=n_sub)
    grad = render.shade(fp, view, rig, rid_subsamples=n_sub, want_grad=True)
    assert grad.grad_position is not None and grad.grad_rotation is not None
    yield f"shade__{key}__flux", plain.flux[0]
    yield f"shade__{key}__flux_grad_path", grad.flux[0]
    yield (
        f"shade__{key}__grad",
        np.concatenate([grad.grad_position[0], grad.grad_rotation[0]], axis=1),
    )


def cases(*, exact_tables: bool = False) -> Iterator[tuple[str, np.ndarray]]:
    """(key, array) of every recorded output; images as float arrays with NaN where masked.

    exact_tables: render the table RIDs by their knot interpolation (as recorded).
    """
    for key, img in _images(exact_tables):
        yield key, np.ma.filled(img.astype(np.float64), np.nan)
    yield from _shadings(exact_tables)


def main() -> int:
    data = dict(cases(exact_tables=True))
    PATH.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(PATH, **data)
    print(f"{PATH}: {len(data)} arrays, {PATH.stat().st_size:,} bytes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
