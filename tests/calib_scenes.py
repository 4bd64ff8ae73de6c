"""Synthetic calibration problems in memory (and tiny project folders) for the solver tests.

Frames and units follow docs/model.md: the wall is z = 0 of the world frame, cameras sit at
z > 0 (OpenCV camera frame), a light's +z is its axis; metres and radians. Cameras are
small (320 x 240) and the solver sees ~100 pixels per image, as in the paper, so a solve
takes a few tens of milliseconds.

Randomness comes in as seeds or `numpy.random.Generator`s; the views come from
`lightcal.synthetic.scenes.sample_views` (stratified distances and tilts).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

# libgomp's default wait policy spins its worker threads for a while between parallel
# regions. On a loaded 2-core machine (two pytest workers and more) that made a 12 x 100
# pixel solve take 1-3 s instead of ~50 ms: the solver calls many small parallel kernels.
# Passive waiting keeps the solver tests fast under load; it must be set before the first
# parallel kernel runs (benchmarks/calibrate.py measures both policies).
os.environ.setdefault("OMP_WAIT_POLICY", "passive")

import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.footprint import pixel_footprints
from lightcal.core.medium import AIR, Medium
from lightcal.core.pose import axis_from_angles, rotation_from_axis
from lightcal.core.problem import ImageData, LightUnknown
from lightcal.core.render import render_image, shade
from lightcal.core.rid import CosPowerRID, IsotropicRID, Table2DRID
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.core.scene import Light, Rig, View
from lightcal.core.solver import CalibrationModel, SolverOptions
from lightcal.core.wall import LAMBERTIAN, WallReflectance
from lightcal.synthetic.scenes import SceneConfig, elliptical_beam_table, sample_views

WIDTH = 320
HEIGHT = 240

#: Expected value (pixel units) of the brightest pixels of the default lights.
SCALE = 1000.0


# ----------------------------------------------------------------------------- the scene


def small_camera(
    *, width: int = WIDTH, height: int = HEIGHT, dist: tuple[float, ...] = (-0.05, 0.01, 0, 0, 0)
) -> Camera:
    """A 320 x 240 camera with a ~56 x 44 degree field of view and mild distortion."""
    return Camera.from_params(
        fx=0.94 * width,
        fy=0.94 * width,
        cx=(width - 1) / 2 + 0.7,
        cy=(height - 1) / 2 - 0.4,
        width=width,
        height=height,
        dist=dist,
    )


def views(
    n: int = 12,
    *,
    distance_range_m: tuple[float, float] = (0.8, 2.5),
    tilt_range_deg: tuple[float, float] = (0.0, 35.0),
    target_spread_m: float = 0.3,
    seed: int = 0,
) -> list[View]:
    """`n` views of the wall (stratified distances and tilts, `synth.sample_views`)."""
    config = SceneConfig(
        n_views=n,
        distance_range_m=distance_range_m,
        tilt_range_deg=tilt_range_deg,
        target_spread_m=target_spread_m,
    )
    return sample_views(config, np.random.default_rng(seed))


def symmetric_light(
    *, half_angle_deg: float = 30.0, scale: float = SCALE, name: str = "light"
) -> Light:
    """A cos^m light 10 cm beside the camera, its axis tilted ~6 degrees."""
    return Light(
        CosPowerRID.from_half_angle(math.radians(half_angle_deg)),
        np.array([0.10, -0.03, 0.01]),
        rotation_from_axis(axis_from_angles(0.08, -0.06)),
        scale=scale,
        name=name,
    )


def isotropic_light(*, scale: float = SCALE) -> Light:
    """An isotropic point light (orientation unobservable) 8 cm beside the camera."""
    return Light(IsotropicRID(), np.array([-0.08, 0.02, 0.0]), np.eye(3), scale=scale)


def general_rid() -> Table2DRID:
    """A lopsided elliptical beam (2-D table, no rotational symmetry)."""
    theta_deg, phi_deg, values = elliptical_beam_table(30.0, aspect=0.6, skew=0.25)
    return Table2DRID(np.radians(theta_deg), np.radians(phi_deg), values)


def general_light(*, scale: float = SCALE) -> Light:
    """A light with the `general_rid` profile, rolled 40 degrees about its axis."""
    R = matrix_from_rotvec(np.array([0.05, -0.08, 0.0])) @ matrix_from_rotvec(
        np.array([0.0, 0.0, math.radians(40.0)])
    )
    return Light(general_rid(), np.array([0.09, 0.04, -0.01]), R, scale=scale)


def two_light_rig() -> Rig:
    """Two different cos^m lights on either side of the camera."""
    a = symmetric_light(half_angle_deg=30.0, name="left")
    b = Light(
        CosPowerRID.from_half_angle(math.radians(40.0)),
        np.array([-0.11, 0.02, 0.0]),
        rotation_from_axis(axis_from_angles(-0.10, 0.04)),
        scale=0.7 * SCALE,
        name="right",
    )
    return Rig((a, b))


# ---------------------------------------------------------------------- observed pixels


def observe(
    camera: Camera,
    true_views: list[View],
    rig: Rig,
    *,
    n_per_image: int = 100,
    rng: np.random.Generator,
    noise: tuple[float, float] | None = None,
    gains: np.ndarray | None = None,
    offset: float = 0.0,
    measured_views: list[View] | None = None,
    min_fraction: float = 0.02,
    noise_model: bool = False,
    wall: WallReflectance = LAMBERTIAN,
    measured_camera: Camera | None = None,
    medium: Medium = AIR,
) -> list[ImageData]:
    """Random lit pixels of each view, as the solver sees them.

    Args:
        camera: the intrinsics.
        true_views: (n_views) the poses the values are rendered from.
        rig: the true lights.
        n_per_image: pixels per image (fewer when the image has fewer lit valid pixels).
        rng: picks the pixels and the noise.
        noise: (gain, read_variance) of a Poisson-Gaussian sensor (variance =
            gain * signal + read_variance), drawn as a Gaussian; None: noise-free, sigma 1.
        gains: (n_views,) extra per-image gains on top of the exposure; default 1.
        offset: added to every value.
        measured_views: the poses the solver is told (pose error); default the true ones.
        min_fraction: pixels darker than this fraction of the image's brightest are skipped.
        noise_model: hand the solver the noise model (`ImageData.noise`: it re-weights).
        wall: the true wall's reflectance.
        measured_camera: the intrinsics the solver is told (intrinsics error); default
            `camera`.
        medium: the true medium between the rig and the wall.

    Returns:
        One `ImageData` per view with all-valid footprints built from `measured_views`
        and `measured_camera`.
    """
    told = true_views if measured_views is None else measured_views
    told_camera = camera if measured_camera is None else measured_camera
    out = []
    for i, (view, told_view) in enumerate(zip(true_views, told, strict=True)):
        n_draw = 6 * n_per_image
        pix = np.stack(
            [rng.integers(0, camera.width, n_draw), rng.integers(0, camera.height, n_draw)], 1
        )
        pix = np.unique(pix, axis=0)
        pix = pix[rng.permutation(len(pix))]
        fp_true = pixel_footprints(camera, view, pix)
        fp_told = pixel_footprints(told_camera, told_view, pix)
        values = shade(fp_true, view, rig, wall=wall, medium=medium).values.filled(np.nan)
        ok = fp_true.valid & fp_told.valid & np.isfinite(values)
        peak = float(np.nanmax(np.where(ok, values, np.nan))) if ok.any() else 0.0
        ok &= values > min_fraction * peak
        keep = np.nonzero(ok)[0][:n_per_image]
        keep.sort()
        pix = pix[keep]
        fp = pixel_footprints(told_camera, told_view, pix)
        signal = values[keep] * (1.0 if gains is None else float(gains[i]))
        if noise is None:
            observed = signal + offset
            sigma = np.ones(len(keep))
        else:
            gain, read_variance = noise
            variance = gain * signal + read_variance
            observed = signal + offset + rng.normal(size=signal.shape) * np.sqrt(variance)
            sigma = np.sqrt(gain * np.maximum(observed - offset, 0.0) + read_variance)
        known = noise if noise_model else None
        out.append(ImageData(f"view_{i:02d}", told_view, fp, observed, sigma, known))
    return out


def add_noise(
    clean: list[ImageData], noise: tuple[float, float], rng: np.random.Generator
) -> list[ImageData]:
    """Noisy copies of noise-free `clean` images (same pixels), sigma from the noise model.

    Args:
        clean: images whose `observed` are the expected values (offset 0).
        noise: (gain, read_variance): variance = gain * signal + read_variance.
        rng: the noise.
    """
    gain, read_variance = noise
    out = []
    for im in clean:
        std = np.sqrt(gain * im.observed + read_variance)
        observed = im.observed + rng.normal(size=im.observed.shape) * std
        sigma = np.sqrt(gain * np.maximum(observed, 0.0) + read_variance)
        out.append(ImageData(im.name, im.view, im.footprints, observed, sigma))
    return out


def moved(light: Light, *, position_m: np.ndarray, rotvec_rad: np.ndarray) -> Light:
    """`light` shifted by `position_m` (3,) and rotated by exp(`rotvec_rad`) (camera frame)."""
    return light.replace(
        t_camera_light=light.t_camera_light + np.asarray(position_m, dtype=np.float64),
        R_camera_light=matrix_from_rotvec(np.asarray(rotvec_rad, dtype=np.float64))
        @ light.R_camera_light,
    )


def start_near(light: Light, *, position_m: float = 0.05, angle_deg: float = 8.0) -> Light:
    """A fixed wrong initial guess: moved by `position_m` and turned by `angle_deg`, scale x 0.6."""
    direction = np.array([0.6, -0.48, 0.64])
    turn = np.array([0.0, 1.0, 0.0]) if light.rid.symmetric else np.array([0.6, 0.8, 0.0])
    out = moved(light, position_m=position_m * direction, rotvec_rad=math.radians(angle_deg) * turn)
    return out.replace(scale=0.6 * light.scale)


def model_of(
    images: list[ImageData], starts: list[Light] | list[LightUnknown], **options: object
) -> CalibrationModel:
    """The calibration model of `images` with lights started at `starts`."""
    unknowns = [s if isinstance(s, LightUnknown) else LightUnknown(s) for s in starts]
    return CalibrationModel(images, unknowns, SolverOptions(**options))  # type: ignore[arg-type]


def pose_errors(estimate: Light, truth: Light) -> tuple[float, float]:
    """(position error m, axis error deg) of an estimated light."""
    position = float(np.linalg.norm(estimate.t_camera_light - truth.t_camera_light))
    cos = float(np.clip(estimate.axis_camera @ truth.axis_camera, -1.0, 1.0))
    return position, math.degrees(math.acos(cos))


def calibrate_synth_folder(folder: Path) -> tuple[float, float, Medium]:
    """Calibrate the project of a `lightcal synth` folder: (position error m, axis error
    deg) of its first light against the folder's truth.json, and the estimated medium."""
    from lightcal.io.project import load_project
    from lightcal.pipeline import calibrate_project

    truth = json.loads((folder / "truth.json").read_text())["lights"][0]
    _, model, res = calibrate_project(load_project(folder / "project.json"))
    x = np.array(res.x)
    est = model.layout.rig(x).lights[0]
    position = float(np.linalg.norm(est.t_camera_light - np.array(truth["position_m"])))
    cos = float(np.clip(est.axis_camera @ np.array(truth["axis_camera"]), -1.0, 1.0))
    return position, math.degrees(math.acos(cos)), model.layout.medium_of(x)


def rotation_error_deg(estimate: Light, truth: Light) -> float:
    """Angle of R_est R_true^T, degrees (the full orientation, for general lights)."""
    D = estimate.R_camera_light @ truth.R_camera_light.T
    return math.degrees(math.acos(float(np.clip((np.trace(D) - 1.0) / 2.0, -1.0, 1.0))))


# ------------------------------------------------------------------ tiny project folders


def write_npy_project(
    folder: Path,
    camera: Camera,
    true_views: list[View],
    rig: Rig,
    *,
    initial: list[Light],
    rid_specs: list[dict],
    measured_views: list[View] | None = None,
    extra: dict | None = None,
) -> Path:
    """A project with noise-free float .npy images and inline intrinsics.

    Args:
        folder: created if needed; images go to folder/images/view_NN.npy.
        camera: the intrinsics (written inline).
        true_views: the poses the images are rendered from.
        rig: the true lights.
        initial: one initial guess per light (pose and scale written).
        rid_specs: one project RID spec per light.
        measured_views: the poses written to the project; default the true ones.
        extra: top-level project fields to set (e.g. "selection", "solver").

    Returns:
        The project.json path.
    """
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "images").mkdir(exist_ok=True)
    told = true_views if measured_views is None else measured_views
    images = []
    for i, (view, told_view) in enumerate(zip(true_views, told, strict=True)):
        img = render_image(camera, view, rig).filled(0.0)
        np.save(folder / "images" / f"view_{i:02d}.npy", img)
        images.append(
            {
                "path": f"images/view_{i:02d}.npy",
                "T_camera_world": {
                    "R": told_view.R_camera_world.tolist(),
                    "t": told_view.t_camera_world.tolist(),
                },
            }
        )
    K = camera.K
    doc: dict = {
        "version": 1,
        "camera": {
            "fx": float(K[0, 0]),
            "fy": float(K[1, 1]),
            "cx": float(K[0, 2]),
            "cy": float(K[1, 2]),
            "width": camera.width,
            "height": camera.height,
            "dist": camera.dist[: camera.n_dist_coeffs].tolist(),
        },
        "images": images,
        "lights": [
            {
                "name": light.name,
                "rid": spec,
                "initial": {
                    "position_m": light.t_camera_light.tolist(),
                    "R_camera_light": light.R_camera_light.tolist(),
                    "scale": light.scale,
                },
            }
            for light, spec in zip(initial, rid_specs, strict=True)
        ],
    }
    doc.update(extra or {})
    path = folder / "project.json"
    path.write_text(json.dumps(doc, indent=1))
    return path


def with_exposure(view: View, exposure: float) -> View:
    """A copy of `view` with another exposure."""
    return View(view.R_camera_world, view.t_camera_world, exposure)


__all__ = [
    "HEIGHT",
    "SCALE",
    "WIDTH",
    "add_noise",
    "general_light",
    "general_rid",
    "isotropic_light",
    "model_of",
    "moved",
    "observe",
    "pose_errors",
    "rotation_error_deg",
    "small_camera",
    "start_near",
    "symmetric_light",
    "two_light_rig",
    "views",
    "with_exposure",
    "write_npy_project",
]


def assert_columns_match_differences(
    model, x: np.ndarray, *, rtol: float = 1e-4, atol: float = 1e-5
) -> np.ndarray:
    """Every column of `model`'s Jacobian at x against central differences of its
    residuals (step 1e-6 max(1, |x_k|)), within rtol and atol times the column's largest
    difference; returns the Jacobian."""
    J = model.jacobian(x).copy()
    for k in range(model.layout.n):
        h = 1e-6 * max(1.0, abs(x[k]))
        hi, lo = x.copy(), x.copy()
        hi[k] += h
        lo[k] -= h
        fd = (model.residuals(hi).copy() - model.residuals(lo).copy()) / (2 * h)
        scale = np.abs(fd).max()
        np.testing.assert_allclose(
            J[:, k], fd, rtol=rtol, atol=atol * scale, err_msg=model.layout.names[k]
        )
    return J
