"""Speed of the flat ports (docs/model.md, "The camera's flat port", "The light's flat
port") against the same work in air, measured in the same run.

Run `python benchmarks/ports.py` (about two minutes on 2 cores; `--quick` for a smoke run).
The scene: a 1200 x 800 camera (f 1100 px, distortion) 1.5 m from the wall, one cos^3
light 12 cm beside it, water of c = 0.3 /m; the camera's port d 20 mm, t 10 mm, the
light's d 15 mm, t 8 mm (acrylic into sea water). Rows:

- footprints: `wall_footprints` of N random pixels, straight rays against the camera's
  port (NumPy, refracted corner rays; once per solve);
- shade + gradients: `shade(want_grad=True)` of those N pixels as the solver calls it
  (footprints precomputed), in air, through the camera's port, with the light's port,
  and both;
- footprints, dense: every pixel of the view's, straight (on the camera's corner grid)
  and through the camera's port (read from its lattice, `camera_port_rays`; once per
  solve);
- shade + gradients, dense: every pixel of the view (footprints on the camera's corner
  grid, as a dense calibration has them), in air, with the light's port by the ratio
  path (`lightcal.core.light_port_dense`) and by every pixel's exact path, and through
  the camera's port;
- full frame: `render_view_image` of the whole frame: the fused kernel in air
  (`kernels.image`) and through the camera's port (`kernels.port_image`, on the port's
  cached corner lattice); with the light's port, its straight twin's fused image times
  the port's ratio, exact on a node grid (`lightcal.core.light_port_frame`); and, to
  compare, every pixel's footprint shaded ("per pixel": the camera's port by
  `render_image_per_pixel_through_port`, the light's by `render_image`);
- full frame with the veil: the same in water that scatters (beta 0.6 /m, g 0.8): in
  air and through the camera's port exact on `scatter_grid`'s nodes and interpolated
  between them (`add_scatter_image`; `port_veil_nodes` and the fused kernel); the
  light's port's veil exact on the frames' node grid.

Each figure is the best of several calls after a warm-up (numba kernels compiled and
caches filled). Nothing is asserted: the machine may be shared (the load average is
printed). Timings are wall-clock seconds (`time.perf_counter`).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from lightcal.core.camera import Camera  # noqa: E402
from lightcal.core.flat_port import FlatPort  # noqa: E402
from lightcal.core.medium import Medium  # noqa: E402
from lightcal.core.port_render import (  # noqa: E402
    render_image_per_pixel_through_port,
    render_view_image,
)
from lightcal.core.render import render_image, shade  # noqa: E402
from lightcal.core.rid import CosPowerRID  # noqa: E402
from lightcal.core.scene import Light, Rig, View  # noqa: E402
from lightcal.core.wall_mesh import wall_footprints  # noqa: E402

CAMERA_PORT = FlatPort(0.020, 0.010, 1.49, 1.333)
LIGHT_PORT = FlatPort(0.015, 0.008, 1.49, 1.333)
WATER = Medium(0.3)
VEIL = Medium(0.3, 0.6, 0.8)


def _best(fn: Callable[[], object], repeats: int) -> float:
    fn()  # warm-up: kernels, caches
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def _scene(width: int, height: int) -> tuple[Camera, View, Light]:
    f = 1100.0 * width / 1200.0
    camera = Camera.from_params(
        fx=f, fy=f, cx=(width - 1) / 2, cy=(height - 1) / 2, width=width, height=height,
        dist=(-0.05, 0.01, 0.0, 0.0),
    )  # fmt: skip
    view = View.looking_at(np.array([0.1, -0.05, 1.5]), np.array([0.0, 0.05, 0.0]))
    axis = np.array([-0.08, 0.0, 1.0])
    z = axis / np.linalg.norm(axis)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    R = np.stack([x, np.cross(z, x), z], axis=1)
    return camera, view, Light(CosPowerRID(3.0), np.array([0.12, 0.0, 0.02]), R)


def _frame_rows(title: str, frames: list[tuple[str, Callable[[], object]]], repeats: int) -> None:
    """Print each frame's best time and its ratio to the first's."""
    base = None
    for label, fn in frames:
        seconds = _best(fn, repeats)
        base = seconds if base is None else base
        print(f"{f'{title}: {label}':44s} {seconds:9.4f} {seconds / base:7.2f}")


def _dense_rows(camera: Camera, view: View, rigs: dict[str, Rig], repeats: int) -> None:
    """Footprints of every pixel of the view (straight: on the camera's corner grid;
    through the camera's port: read from its lattice), and shade + gradients of them (the
    dense calibrations' case): air, the light's port by the ratio path
    (`light_port_dense`) and by every pixel's exact path, the camera's port."""
    import lightcal.core.light_port_dense as dense

    v, u = np.mgrid[0 : camera.height, 0 : camera.width]
    pixels = np.stack([u.ravel(), v.ravel()], axis=1)
    n = len(pixels)
    made = {}
    base = None
    for label, port in (("straight", None), ("camera port", CAMERA_PORT)):
        seconds = _best(
            lambda port=port: wall_footprints(camera, view, pixels, mesh=None, port=port),
            max(1, repeats // 2),
        )
        made[label] = wall_footprints(camera, view, pixels, mesh=None, port=port)
        base = seconds if base is None else base
        row = f"footprints, dense ({n} px): {label}"
        print(f"{row:44s} {seconds:9.4f} {seconds / base:7.2f}")
    cases = [
        ("air", made["straight"], rigs["air"], dense.DENSE_PIXELS),
        ("light port", made["straight"], rigs["light port"], dense.DENSE_PIXELS),
        ("light port, every pixel exact", made["straight"], rigs["light port"], n + 1),
        ("camera port", made["camera port"], rigs["air"], dense.DENSE_PIXELS),
    ]
    base = None
    for label, fp, rig, threshold in cases:
        dense.DENSE_PIXELS, saved = threshold, dense.DENSE_PIXELS
        seconds = _best(
            lambda fp=fp, rig=rig: shade(fp, view, rig, want_grad=True, medium=WATER),
            max(1, repeats // 2) if "exact" in label else repeats,
        )
        dense.DENSE_PIXELS = saved
        base = seconds if base is None else base
        row = f"shade + gradients, dense ({n} px): {label}"
        print(f"{row:44s} {seconds:9.4f} {seconds / base:7.2f}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a small smoke run")
    args = parser.parse_args(argv)
    width, height = (300, 200) if args.quick else (1200, 800)
    counts = (1_000,) if args.quick else (4_000, 40_000)
    repeats = 2 if args.quick else 5
    camera, view, light = _scene(width, height)
    rigs = {"air": Rig.single(light), "light port": Rig.single(light.replace(port=LIGHT_PORT))}
    rng = np.random.default_rng(0)
    print(f"load average {os.getloadavg()[0]:.2f}; {width} x {height}, water c = 0.3 /m")
    print(f"{'row':44s} {'seconds':>9s} {'x air':>7s}")
    for n in counts:
        pixels = np.stack([rng.integers(0, width, n), rng.integers(0, height, n)], axis=1).astype(
            np.int64
        )
        air_fp = _best(lambda px=pixels: wall_footprints(camera, view, px, mesh=None), repeats)
        port_fp = _best(
            lambda px=pixels: wall_footprints(camera, view, px, mesh=None, port=CAMERA_PORT),
            repeats,
        )
        print(f"{f'footprints, {n} px: straight':44s} {air_fp:9.4f} {1.0:7.2f}")
        print(f"{f'footprints, {n} px: camera port':44s} {port_fp:9.4f} {port_fp / air_fp:7.2f}")
        footprints = {
            "air": wall_footprints(camera, view, pixels, mesh=None),
            "camera port": wall_footprints(camera, view, pixels, mesh=None, port=CAMERA_PORT),
        }
        base = None
        for fp_name, fp in footprints.items():
            for rig_name, rig in rigs.items():
                seconds = _best(
                    lambda fp=fp, rig=rig: shade(fp, view, rig, want_grad=True, medium=WATER),
                    repeats,
                )
                base = seconds if base is None else base
                label = "air" if (fp_name, rig_name) == ("air", "air") else (
                    " + ".join(n for n in (fp_name, rig_name) if n != "air")
                )  # fmt: skip
                row = f"shade + gradients, {n} px: {label}"
                print(f"{row:44s} {seconds:9.4f} {seconds / base:7.2f}")
    _dense_rows(camera, view, rigs, repeats)
    air, lit = rigs["air"], rigs["light port"]
    full = (("air", None, air), ("camera port", CAMERA_PORT, air),
            ("light port", None, lit), ("camera port + light port", CAMERA_PORT, lit))  # fmt: skip
    for title, medium in (("full frame", WATER), ("full frame, veil", VEIL)):
        frames: list[tuple[str, Callable[[], object]]] = [
            (label, partial(render_view_image, camera, view, rig, port=port, medium=medium))
            for label, port, rig in full
        ]
        per_pixel = [
            ("camera port, per pixel", partial(
                render_image_per_pixel_through_port, camera, view, air, CAMERA_PORT, medium=medium
            )),
            ("light port, per pixel", partial(render_image, camera, view, lit, medium=medium)),
        ]  # fmt: skip
        _frame_rows(title, [*frames, *per_pixel], repeats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
