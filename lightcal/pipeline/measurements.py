"""What is known about each image beyond its selected pixels: its noise, its pose's
uncertainty and the camera intrinsics', and how to rebuild its pixels' footprints for
another pose or other intrinsics.

The fit diagnosis needs each value's noise: from the sensor's noise model when the project
has one, else estimated from the image itself (`lightcal.core.misfit.image_noise`). The
uncertainty needs each camera pose's covariance (`T_camera_world.covariance`, written by
`lightcal init` from the marker fit) and the pixels' footprints under perturbed poses;
the intrinsics' term needs the camera file's `intrinsics_covariance`, how each pose moves
with the intrinsics (`T_camera_world.d_pose_d_intrinsics`) and the footprints under
perturbed intrinsics.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from lightcal.core.footprint import Footprints
from lightcal.core.misfit import image_noise
from lightcal.core.scene import View
from lightcal.core.solver import CalibrationModel
from lightcal.core.wall_mesh import wall_footprints
from lightcal.io.project import Project
from lightcal.pipeline.load import LoadedImages, vignetting_for
from lightcal.pipeline.select import candidates, selection_binning

NoiseSource = str  # "model" | "image" | "none"


@dataclass(frozen=True, eq=False)
class Measurements:
    """Per image of a model (model order).

    Attributes:
        noise: (gain, read_variance) of each value (super-pixel means included) or None.
        noise_source: "model" (the project's sensor noise model), "image" (estimated from
            the images) or "none".
        pose_covariances: (6, 6) covariance of the image's pose (see `PoseSpec`) or None.
        footprints_at: (i, view, rows) -> `Footprints` of rows (k,) of image i's selected
            pixels seen from `view` (None: unknown).
        intrinsics_covariance: (p, p) covariance of the camera's intrinsic parameters
            (`Camera.intrinsic_params` of the project's camera file) or None.
        pose_intrinsics_jacobians: per image, (6, p) d (delta, c) / d intrinsics of its
            pose or None (a pose that does not move with the intrinsics).
        footprints_with: (i, dK, view, rows) -> `Footprints` of rows of image i's selected
            pixels seen from `view` by the camera whose intrinsic parameters are moved by
            dK (p,) (None: unknown).
        wall_flatness_m: the wall's declared flatness tolerance (`wall.flatness_mm`), m;
            0: flat (`lightcal.core.wall_flatness`).
        poses: per image, the photo it was read from (`Project.spec_image`: a photo's
            colour channels share its pose and its pose error), or None: each its own.
    """

    noise: list[tuple[float, float] | None]
    noise_source: NoiseSource
    pose_covariances: list[np.ndarray | None]
    footprints_at: Callable[[int, View, np.ndarray], Footprints] | None
    intrinsics_covariance: np.ndarray | None = None
    pose_intrinsics_jacobians: list[np.ndarray | None] | None = None
    footprints_with: Callable[[int, np.ndarray, View, np.ndarray], Footprints] | None = None
    wall_flatness_m: float = 0.0
    poses: list[int] | None = None


def model_only(model: CalibrationModel) -> Measurements:
    """What the model alone tells: the noise models its images carry, no pose terms."""
    noise = [im.noise for im in model.images]
    source = "model" if noise and all(n is not None for n in noise) else "none"
    return Measurements(
        noise if source == "model" else [None] * len(noise),
        source,
        [None] * len(noise),
        None,
    )


def measurements_for(
    project: Project, loaded: LoadedImages, model: CalibrationModel
) -> Measurements:
    """The noise, pose covariances and footprint rebuilder of a project's model."""
    index = {name: i for i, name in enumerate(project.names)}
    rows = [index[im.name] for im in model.images]
    b = selection_binning(project)
    if project.spec.sensor.noise is not None:
        noise: list[tuple[float, float] | None] = [im.noise for im in model.images]
        source = "model"
    else:
        noise = []
        for k in rows:
            est = image_noise(
                loaded.images[k].values,
                candidates(project, loaded, k),
                offset=project.spec.sensor.offset,
            )
            # A super-pixel value is the mean of b^2 pixels: 1 / b^2 of their variance.
            noise.append(None if est is None else (est[0] / (b * b), est[1] / (b * b)))
        source = "image" if all(n is not None for n in noise) else "none"
        if source == "none":
            noise = [None] * len(rows)
    covariances = [
        project.pose_covariances[k] if k < len(project.pose_covariances) else None for k in rows
    ]
    jacobians = [
        project.pose_intrinsics_jacobians[k] if k < len(project.pose_intrinsics_jacobians) else None
        for k in rows
    ]
    vignetting = vignetting_for(project, loaded.camera)
    # The images as read may be binned relative to the camera file (a raw reader's binning).
    read_binning = project.camera.width // loaded.camera.width
    base = project.camera.intrinsic_params

    def footprints_with(i: int, dK: np.ndarray, view: View, rows: np.ndarray) -> Footprints:
        camera = loaded.camera
        if np.any(dK != 0.0):
            camera = project.camera.with_intrinsic_params(base + dK)
            if read_binning > 1:
                camera = camera.binned(read_binning)
        return wall_footprints(
            camera,
            view,
            model.images[i].footprints.pixels[rows],
            mesh=project.wall_mesh,
            sensor=project.spec.sensor.model,
            vignetting=vignetting,
            binning=b,
            port=project.camera_port,
        )

    def footprints_at(i: int, view: View, rows: np.ndarray) -> Footprints:
        return footprints_with(i, np.zeros(base.size), view, rows)

    return Measurements(
        noise,
        source,
        covariances,
        footprints_at,
        project.camera.intrinsics_covariance,
        jacobians,
        footprints_with,
        project.spec.wall.flatness_mm / 1000.0,
        [project.spec_image(k) for k in rows] if project.channels else None,
    )
