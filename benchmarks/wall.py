"""Speed of the wall models against the Lambertian fast path (targets: within 2x).

Run `python benchmarks/wall.py` (about a minute on 2 cores) or `--quick`. Rows:

- full frame: `render_image` of a W x H distorted camera (cos^m light), best of several
  warm renders: Lambertian, plastic, Oren-Nayar;
- pixels with gradients: `shade(..., want_grad=True)` of N random pixels with precomputed
  footprints, what the solver's Jacobian costs per light and image;
- Jacobian: `CalibrationModel.jacobian` of 12 images x N pixels, light pose and scale
  (Lambertian) against the same plus the plastic wall's roughness and specular weight;
- solve: `run_least_squares` of 12 x 100 pixels (the paper's size), Lambertian data and
  model against plastic data with the plastic model estimated.

Ratios are against the Lambertian row measured in the same run. Nothing is asserted: the
machine may be shared (the load average is printed).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

os.environ.setdefault("OMP_WAIT_POLICY", "passive")

from lightcal.core.camera import Camera  # noqa: E402
from lightcal.core.footprint import pixel_footprints  # noqa: E402
from lightcal.core.pose import axis_from_angles, rotation_from_axis  # noqa: E402
from lightcal.core.problem import ImageData, LightUnknown, WallUnknown  # noqa: E402
from lightcal.core.render import render_image, shade  # noqa: E402
from lightcal.core.rid import CosPowerRID  # noqa: E402
from lightcal.core.scene import Light, Rig, View  # noqa: E402
from lightcal.core.solver import CalibrationModel, SolverOptions, run_least_squares  # noqa: E402
from lightcal.core.wall import LAMBERTIAN, OrenNayarWall, PlasticWall  # noqa: E402
from lightcal.synthetic.scenes import SceneConfig, sample_views  # noqa: E402

WALLS = {
    "lambertian": LAMBERTIAN,
    "plastic": PlasticWall.from_albedo(0.3, 1.5, 0.8),
    "oren_nayar": OrenNayarWall(math.radians(20.0)),
}


def best(fn: Callable[[], object], repeats: int) -> float:
    out = math.inf
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        out = min(out, time.perf_counter() - t)
    return out


def camera(width: int, height: int) -> Camera:
    f = 0.9 * width
    return Camera.from_params(
        fx=f, fy=f, cx=(width - 1) / 2, cy=(height - 1) / 2, width=width, height=height,
        dist=(-0.08, 0.02, 2e-4, -1e-4),
    )  # fmt: skip


def light() -> Light:
    return Light(
        CosPowerRID.from_half_angle(math.radians(30.0)),
        np.array([0.1, -0.03, 0.01]),
        rotation_from_axis(axis_from_angles(0.08, -0.06)),
        scale=1000.0,
    )


def views(n: int) -> list[View]:
    return sample_views(SceneConfig(n_views=n), np.random.default_rng(0))


def row(name: str, seconds: float, base: float) -> None:
    print(f"  {name:<34} {seconds * 1e3:10.2f} ms   {seconds / base:5.2f}x", flush=True)


def bench_full_frame(width: int, height: int, repeats: int) -> None:
    cam, rig, view = camera(width, height), Rig.single(light()), views(1)[0]
    print(f"full frame {width} x {height} (render_image, best of {repeats})")
    base = 0.0
    for name, wall in WALLS.items():
        render_image(cam, view, rig, wall=wall)  # compile, corner grid
        t = best(lambda wall=wall: render_image(cam, view, rig, wall=wall), repeats)
        base = base or t
        row(name, t, base)


def bench_pixels(width: int, height: int, n: int, repeats: int) -> None:
    cam, rig, view = camera(width, height), Rig.single(light()), views(1)[0]
    rng = np.random.default_rng(1)
    px = np.stack([rng.integers(0, width, n), rng.integers(0, height, n)], axis=1)
    fp = pixel_footprints(cam, view, px)
    print(f"{n} pixels with gradients (shade, want_grad, best of {repeats})")
    base = 0.0
    for name, wall in WALLS.items():
        shade(fp, view, rig, want_grad=True, wall=wall)
        t = best(lambda wall=wall: shade(fp, view, rig, want_grad=True, wall=wall), repeats)
        base = base or t
        row(name, t, base)


def images(cam: Camera, n_views: int, n: int, wall) -> list[ImageData]:
    rig = Rig.single(light())
    out = []
    rng = np.random.default_rng(2)
    for i, view in enumerate(views(n_views)):
        px = np.stack([rng.integers(0, cam.width, 3 * n), rng.integers(0, cam.height, 3 * n)], 1)
        fp = pixel_footprints(cam, view, px)
        values = shade(fp, view, rig, wall=wall).values.filled(np.nan)
        keep = np.nonzero(fp.valid & (values > 1e-3 * np.nanmax(values)))[0][:n]
        fp = fp.subset(keep)
        obs = values[keep]
        out.append(ImageData(f"v{i}", view, fp, obs, np.sqrt(0.5 * obs + 4.0)))
    return out


def bench_jacobian(width: int, height: int, n: int, repeats: int) -> None:
    cam = camera(width, height)
    start = light().replace(t_camera_light=np.array([0.08, 0.0, 0.0]))
    print(f"Jacobian of 12 images x {n} pixels (CalibrationModel.jacobian, best of {repeats})")
    base = 0.0
    for name, wall in (("lambertian", None), ("plastic (2 wall parameters)", "plastic")):
        true_wall = WALLS["plastic"] if wall else LAMBERTIAN
        unknown = (
            WallUnknown(PlasticWall(0.4, 1.5, 1.0), ("roughness", "specular_weight"))
            if wall
            else None
        )
        model = CalibrationModel(
            images(cam, 12, n, true_wall), [LightUnknown(start)], SolverOptions(), unknown
        )
        x = model.layout.x0.copy()

        def once(model=model, x=x) -> None:
            x[0] += 1e-9  # a new point: no cached evaluation
            model.jacobian(x)

        once()
        t = best(once, repeats)
        base = base or t
        row(name, t, base)


def bench_solve(repeats: int) -> None:
    cam = camera(480, 360)
    truth = light()
    start = truth.replace(t_camera_light=truth.t_camera_light + np.array([0.03, -0.02, 0.02]))
    print(
        f"solve of 12 x 100 pixels (run_least_squares, best of {repeats}; the plastic problem"
        " has 2 more unknowns and may take more evaluations: per evaluation beside)"
    )
    base = base_eval = 0.0
    for name, wall in (("lambertian", None), ("plastic (2 wall parameters)", "plastic")):
        true_wall = WALLS["plastic"] if wall else LAMBERTIAN
        data = images(cam, 12, 100, true_wall)
        unknown = (
            WallUnknown(PlasticWall(0.4, 1.5, 1.0), ("roughness", "specular_weight"))
            if wall
            else None
        )

        def once(data=data, unknown=unknown) -> int:
            model = CalibrationModel(data, [LightUnknown(start)], SolverOptions(), unknown)
            return run_least_squares(model).nfev

        n_eval = once()
        t = best(once, repeats)
        base = base or t
        base_eval = base_eval or t / n_eval
        row(name, t, base)
        print(
            f"  {'  per evaluation (' + str(n_eval) + ' evaluations)':<34}"
            f" {t / n_eval * 1e3:10.2f} ms   {t / n_eval / base_eval:5.2f}x"
        )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes (seconds)")
    args = parser.parse_args(argv)
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    if args.quick:
        bench_full_frame(600, 400, 3)
        bench_pixels(600, 400, 20_000, 3)
        bench_jacobian(600, 400, 2_000, 3)
        bench_solve(2)
    else:
        bench_full_frame(3000, 2000, 5)
        bench_pixels(3000, 2000, 375_000, 5)
        bench_jacobian(3000, 2000, 100_000, 3)
        bench_solve(5)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
