"""Speed of the bounce term of declared surroundings (`lightcal.core.bounce`, issue 26).

Run `python benchmarks/bounce.py` (about a minute on 2 cores). The scene is the Mitsuba
`interreflection` scenario's corner (a ceiling 2.8 m and a side wall 2.4 m long, both
0.5 m deep) seen by 12 views of a 480 x 320 camera at 0.8-2.5 m, N random pixels a view:

- build: the world-fixed map (mesh, transfers, the LU factor) and each view's pixel map,
  as `CalibrationModel` makes them once per calibration;
- evaluation: every view's bounce with its 6 pose derivatives (what one solver iteration
  adds) and without them;
- direct: `light_flux` with gradients on the same pixels, for scale;
- water (`--water`, 1000 pixels a view): an evaluation with the pose derivatives in air,
  in water of a given c (the first also makes the transfers at c), and with d/dc at a new
  c each time (an estimated c: the transfers and their slopes made each time).

No figure is asserted: the machine may be shared; the load average is printed.
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

from lightcal.core.blas_threads import single_threaded_blas
from lightcal.core.bounce_term import BounceTerm
from lightcal.core.camera import Camera
from lightcal.core.footprint import pixel_footprints
from lightcal.core.medium import AIR, Medium
from lightcal.core.render import light_flux
from lightcal.core.rid import CosPowerRID
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.core.scene import Light, View
from lightcal.core.surroundings import Surface, Surroundings
from lightcal.synthetic.scenes import SceneConfig, sample_views


def _scene() -> tuple[Camera, list[View], Light, Surroundings]:
    camera = Camera.from_params(fx=432.0, fy=432.0, cx=239.5, cy=159.5, width=480, height=320)
    views = sample_views(SceneConfig(n_views=12), np.random.default_rng(0))
    tilt = matrix_from_rotvec(np.array([-0.245, 0.0, 0.0]))  # the axis 14 deg up
    light = Light(CosPowerRID(2.4), np.array([0.08, 0.02, 0.0]), tilt)
    ceiling = Surface(
        np.array([-2.2, -0.7, 0.0]), np.array([2.8, 0, 0]), np.array([0, 0, 0.5]), 0.8
    )
    side = Surface(np.array([0.6, -0.7, 0.0]), np.array([0, 2.4, 0]), np.array([0, 0, 0.5]), 0.8)
    return camera, views, light, Surroundings((ceiling, side), 0.8)


def main() -> None:
    camera, views, light, surroundings = _scene()
    rng = np.random.default_rng(1)
    print(f"load average {os.getloadavg()[0]:.2f}; 12 views of 480 x 320")
    print(
        f"{'patch_m':>8s} {'pixels':>8s} {'build s':>8s} {'eval+grad s':>12s} "
        f"{'eval s':>8s} {'direct+grad s':>14s}"
    )
    for patch in (0.1, 0.05):
        for n in (100, 1000, 10_000):
            fps = []
            for view in views:
                pix = np.column_stack(
                    [rng.integers(0, camera.width, n), rng.integers(0, camera.height, n)]
                ).astype(np.int32)
                fp = pixel_footprints(camera, view, pix)
                fps.append(fp.subset(fp.valid))
            t0 = time.perf_counter()
            term = BounceTerm(
                Surroundings(surroundings.surfaces, surroundings.wall_albedo, patch), fps
            )
            build = time.perf_counter() - t0
            t0 = time.perf_counter()
            for i, view in enumerate(views):
                term.flux(i, view, light, want_grad=True)
            grad = time.perf_counter() - t0
            t0 = time.perf_counter()
            for i, view in enumerate(views):
                term.flux(i, view, light, want_grad=False)
            plain = time.perf_counter() - t0
            t0 = time.perf_counter()
            for fp, view in zip(fps, views, strict=True):
                light_flux(fp, view, light, want_grad=True)
            direct = time.perf_counter() - t0
            print(f"{patch:8.2f} {n:8d} {build:8.2f} {grad:12.3f} {plain:8.3f} {direct:14.3f}")


def water() -> None:
    """The cost of the medium: seconds per evaluation of the 12 views (module docstring)."""
    camera, views, light, surroundings = _scene()
    rng = np.random.default_rng(1)
    fps = []
    for view in views:
        pix = np.column_stack(
            [rng.integers(0, camera.width, 1000), rng.integers(0, camera.height, 1000)]
        ).astype(np.int32)
        fp = pixel_footprints(camera, view, pix)
        fps.append(fp.subset(fp.valid))
    term = BounceTerm(surroundings, fps)

    def evaluation(medium: Medium, want_dc: bool = False) -> str:
        t0 = time.perf_counter()
        with single_threaded_blas():  # as `CalibrationModel` evaluates
            for i, view in enumerate(views):
                term.flux(i, view, light, want_grad=True, medium=medium, want_dc=want_dc)
        return f"{time.perf_counter() - t0:.3f}"

    print(f"load average {os.getloadavg()[0]:.2f}; patch_m 0.1, 1000 pixels a view")
    print("air:", *(evaluation(AIR) for _ in range(3)))
    print("c = 0.3 given:", *(evaluation(Medium(0.3)) for _ in range(3)))
    print("c estimated:", *(evaluation(Medium(c), True) for c in (0.31, 0.32, 0.33)))


if __name__ == "__main__":
    water() if "--water" in sys.argv[1:] else main()
