"""Capture planning on synthetic data: do planned views beat random ones, and is the
predicted sigma the one a new solve gets? Prints; asserts nothing.

Run `python benchmarks/plan.py` (about a minute on 2 cores) or `--seeds 3` for a smoke
run. Per seed: 12 random views (`lightcal.synthetic.views.sample_views`), a cos^m light
(30 deg half angle) 10 cm beside a 320 x 240 camera, ~200 pixels per image at a peak of
1000 DN with Poisson-Gaussian noise (gain 1, read variance 4) whose sigma the solver is
given (s^2 = 1). From the first 3 views (solved from a start 3 cm / 5 deg off), 3 views
are planned (`lightcal.pipeline.plan.plan_views`, default grid, 3 m wall) at the 3-view
estimate; each is then actually photographed (rendered at the truth, exposed to the same
peak, noise drawn) and the problem solved again. Compared: the position sigma (m, root of
the trace) and axis sigma (deg) of 3 views, 3 + 3 planned, 3 + 3 random (views 4-6) and
all 12 random views, averaged over the seeds, and predicted / obtained sigma after each
added planned view.
"""

from __future__ import annotations

import argparse
import math
import os
import time

os.environ.setdefault("OMP_WAIT_POLICY", "passive")

import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.footprint import pixel_footprints
from lightcal.core.pose import axis_from_angles, rotation_from_axis
from lightcal.core.problem import ImageData, LightUnknown
from lightcal.core.rid import CosPowerRID
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.core.scene import Light, View
from lightcal.core.solver import CalibrationModel, SolverOptions, run_least_squares
from lightcal.pipeline.plan import (
    InformationState,
    PlanGrid,
    candidate_image,
    plan_views,
)
from lightcal.synthetic.views import SceneConfig, sample_views

NOISE = (1.0, 4.0)
PEAK = 1000.0
GRID = PlanGrid()


def camera() -> Camera:
    return Camera.from_params(
        fx=300.0, fy=300.0, cx=159.5, cy=119.5, width=320, height=240, dist=(0, 0, 0, 0, 0)
    )


def truth() -> Light:
    return Light(
        CosPowerRID.from_half_angle(math.radians(30.0)),
        np.array([0.10, -0.03, 0.01]),
        rotation_from_axis(axis_from_angles(0.08, -0.06)),
        scale=1.0,
    )


def truth_model(cam: Camera, light: Light, view: View) -> tuple[CalibrationModel, np.ndarray]:
    """A one-image model at the truth, to render observations with `candidate_image`."""
    pix = np.array([[cam.width // 2, cam.height // 2]])
    fp = pixel_footprints(cam, view, pix)
    seed_image = ImageData("seed", view, fp, np.ones(1), np.ones(1), NOISE)
    model = CalibrationModel([seed_image], [LightUnknown(light)], SolverOptions())
    return model, model.layout.x0.copy()


def photograph(tm, cam: Camera, view: View, rng: np.random.Generator, name: str) -> ImageData:
    """The view's grid pixels at the truth, exposed to PEAK, with noise of known sigma."""
    model, x = tm
    clean = candidate_image(model, x, cam, view, GRID, name, peak=PEAK)
    assert clean is not None, "a benchmark view sees no light"
    observed = clean.observed + rng.normal(size=clean.observed.shape) * clean.sigma
    return ImageData(name, clean.view, clean.footprints, observed, clean.sigma)


def solve(images: list[ImageData], start: Light) -> tuple[CalibrationModel, np.ndarray]:
    model = CalibrationModel(images, [LightUnknown(start)], SolverOptions())
    return model, run_least_squares(model).x


def sigmas(model: CalibrationModel, x: np.ndarray) -> tuple[float, float]:
    s = InformationState(model, x).sigmas()
    axis = s.axis_deg[0]
    assert axis is not None
    return s.position_m[0], axis


def run_seed(seed: int) -> dict[str, object]:
    rng = np.random.default_rng(seed)
    cam, light = camera(), truth()
    views = sample_views(SceneConfig(n_views=12), rng)
    tm = truth_model(cam, light, views[0])
    photos = [photograph(tm, cam, v, rng, f"view_{i:02d}") for i, v in enumerate(views)]
    start = light.replace(
        t_camera_light=light.t_camera_light + np.array([0.018, -0.014, 0.019]),
        R_camera_light=matrix_from_rotvec(np.array([0.0, math.radians(5.0), 0.0]))
        @ light.R_camera_light,
        scale=0.6,
    )
    m3, x3 = solve(photos[:3], start)
    _, planned = plan_views(m3, x3, cam, n=3, grid=GRID, noise_scale2=1.0)
    images = list(photos[:3])
    predicted, obtained = [], []
    for k, pv in enumerate(planned):
        images.append(photograph(tm, cam, pv.image.view, rng, f"plan_{k}"))
        m, x = solve(images, light.replace(scale=1.0))
        predicted.append((pv.after.position_m[0], pv.after.axis_deg[0]))
        obtained.append(sigmas(m, x))
    return {
        "3": sigmas(m3, x3),
        "3+planned": obtained[-1],
        "3+random": sigmas(*solve(photos[:6], light.replace(scale=1.0))),
        "12": sigmas(*solve(photos, light.replace(scale=1.0))),
        "ratios": [(p[0] / o[0], p[1] / o[1]) for p, o in zip(predicted, obtained, strict=True)],
        "steps": obtained,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    args = parser.parse_args()
    t0 = time.perf_counter()
    rows = [run_seed(s) for s in range(args.seeds)]
    print(f"{args.seeds} seeds, {time.perf_counter() - t0:.0f} s, load {os.getloadavg()[0]:.1f}")
    print(f"{'views':<24}{'position sigma mm':>20}{'axis sigma deg':>16}")
    for key, label in (
        ("3", "3 random"),
        ("3+random", "3 + 3 random (6)"),
        ("3+planned", "3 + 3 planned (6)"),
        ("12", "12 random"),
    ):
        a = np.array([r[key] for r in rows])
        print(f"{label:<24}{1000 * a[:, 0].mean():>20.3f}{a[:, 1].mean():>16.4f}")
    steps = np.array([r["steps"] for r in rows])  # (seeds, 3, 2)
    twelve = np.array([r["12"] for r in rows])
    for k in range(steps.shape[1]):
        reached = np.mean(np.all(steps[:, k] <= twelve, axis=1))
        print(
            f"3 + {k + 1} planned ({4 + k}): position {1000 * steps[:, k, 0].mean():.3f} mm, "
            f"axis {steps[:, k, 1].mean():.4f} deg; seeds at or below 12 random: "
            f"{100 * reached:.0f} %"
        )
    ratios = np.array([r["ratios"] for r in rows]).reshape(-1, 2)
    dev = np.abs(ratios - 1.0)
    print(
        "predicted / obtained sigma after each planned view "
        f"({len(ratios)} additions): position mean {ratios[:, 0].mean():.3f} "
        f"(max |dev| {dev[:, 0].max():.3f}), axis mean {ratios[:, 1].mean():.3f} "
        f"(max |dev| {dev[:, 1].max():.3f}); within 20 %: "
        f"{100 * np.mean(np.all(dev <= 0.2, axis=1)):.0f} %"
    )


if __name__ == "__main__":
    main()
