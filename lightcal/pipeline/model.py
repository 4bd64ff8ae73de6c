"""The calibration model of a project: selected pixels of every image, the lights to
solve for (with fitted starting scales) and the solver options."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from lightcal.core.medium import AIR, Medium
from lightcal.core.problem import ImageData, LightUnknown
from lightcal.core.qr_factors import economic_r, stack_r_factors
from lightcal.core.render import shade
from lightcal.core.scene import Rig
from lightcal.core.solver import CalibrationModel, SolverOptions
from lightcal.core.wall import LAMBERTIAN, WallReflectance
from lightcal.errors import InputError
from lightcal.io.project import Project
from lightcal.pipeline.load import LoadedImages, ProgressFn
from lightcal.pipeline.select import image_data

#: At most this many pixels per image enter the starting scales' fit (a regular
#: subsample beyond): a start for the solver, which fits the scales with every pixel.
SCALE_FIT_PIXELS = 1 << 16


def fit_scales(
    images: list[ImageData],
    unknowns: list[LightUnknown],
    offset: float,
    wall: WallReflectance = LAMBERTIAN,
    medium: Medium = AIR,
) -> list[float]:
    """Linear least-squares scales of the lights at their initial poses (positive).

    The weighted system [A y] (one row a pixel, one column a light, then the values) is
    reduced image by image to its R factor (`stack_r_factors`), so no (m, L) matrix is
    held; the non-negative least squares then runs on that (L + 1, L + 1) system, whose
    solutions are those of the full one. Images with more than `SCALE_FIT_PIXELS` pixels
    enter by a regular subsample of them.
    """
    rig = Rig(tuple(u.initial.replace(scale=1.0) for u in unknowns))
    n_l = len(unknowns)
    tops: list[np.ndarray | None] = []
    sum_abs_y = 0.0
    sum_rows = 0.0
    m = 0
    for im in images:
        step = -(-len(im.observed) // SCALE_FIT_PIXELS)
        if step > 1:  # indices, not a strided slice: the kernels take contiguous arrays
            im = im.subset(np.arange(0, len(im.observed), step))
        sh = shade(im.footprints, im.view, rig, wall=wall, medium=medium)
        Ay = np.empty((len(im.observed), n_l + 1), order="F")
        Ay[:, :n_l] = (sh.flux / im.sigma).T
        Ay[:, n_l] = (im.observed - offset) / im.sigma
        del sh
        sum_abs_y += float(np.abs(Ay[:, n_l]).sum())
        sum_rows += float(Ay[:, :n_l].sum())
        m += Ay.shape[0]
        if Ay.shape[0]:
            tops.append(economic_r(Ay) if np.all(np.isfinite(Ay)) else None)
    R = stack_r_factors(tops, n_l + 1)
    s = np.zeros(n_l)
    if np.all(np.isfinite(R)):
        from scipy.optimize import nnls  # see lightcal.core.solver on SciPy's optimize

        s, _ = nnls(R[:n_l, :n_l], R[:n_l, n_l])
    largest = float(s.max())
    if not largest > 0.0:
        # The start explains none of the light (aimed away, or data below the offset):
        # the ratio of mean magnitudes gives the solver a scale to start from.
        mean_row = sum_rows / max(m, 1)
        largest = float((sum_abs_y / max(m, 1)) / max(mean_row, 1e-300)) or 1.0
        s = np.full(n_l, largest)
    # A light the start leaves dark keeps a scale it can grow from.
    return [float(max(v, 1e-3 * largest)) for v in s]


def solver_options(project: Project, loaded: LoadedImages) -> SolverOptions:
    """The project's solver options for its images as read: an estimated fall-off's
    r is measured on the grid the images have (`loaded.camera`: a raw reader's binned
    grid when it binned), whose centre and half diagonal are the sensor's."""
    f = project.solver.fall_off
    cam = loaded.camera
    if f is None or (f.width, f.height) == (cam.width, cam.height):
        return project.solver
    return replace(project.solver, fall_off=replace(f, width=cam.width, height=cam.height))


def build_model(
    project: Project,
    loaded: LoadedImages,
    *,
    pixels: list[np.ndarray | None] | None = None,
    lights: list[LightUnknown] | None = None,
    progress: ProgressFn | None = None,
) -> CalibrationModel:
    """The calibration model of a project: selected pixels, lights, options.

    Args:
        project: the project.
        loaded: its images.
        pixels: per image an explicit (N, 2) pixel choice or None (strategy).
        lights: lights to use instead of the project's (e.g. a dragged initial guess).
        progress: progress callback.
    """
    data = []
    n = len(project.views)
    for i in range(n):
        if progress is not None:
            progress("selecting pixels", i, n)
        d = image_data(project, loaded, i, pixels=None if pixels is None else pixels[i])
        if len(d.observed) > 0:
            data.append(d)
    if not data and project.wall_mesh is not None:
        raise InputError(
            project.path,
            f"wall.mesh: no selected pixel of any image meets the wall mesh "
            f"{project.spec.wall.mesh!r}; expected a mesh in the world frame of the images' "
            "poses, in metres, under the views",
        )
    if not data:
        raise InputError(
            project.path,
            "no usable pixels in any image (all saturated, masked, below the noise floor "
            "or off the wall); check the selection and sensor settings",
        )
    unknowns = list(lights) if lights is not None else starting_lights(project, data)
    options = solver_options(project, loaded)
    model = CalibrationModel(
        data,
        unknowns,
        options,
        project.wall,
        project.medium,
        project.surroundings,
        project.channels,
        project.media or None,
    )
    if model.m <= model.layout.n:
        raise InputError(
            project.path,
            f"selection: {model.m} usable pixels for {model.layout.n} parameters; expected "
            "more pixels than parameters (more images or pixels per image, a lower binning, "
            "or fewer parameters to estimate)",
        )
    return model


def starting_lights(
    project: Project, images: list[ImageData], lights: list[LightUnknown] | None = None
) -> list[LightUnknown]:
    """The lights a solve starts from: `lights` (default: the project's), with the
    scales the project leaves to be fitted (`scale` not given) fitted to `images`.

    Args:
        project: the project (which scales are fitted, the offset, the wall, the medium).
        images: the selected pixels; none: the scales are left as they are.
        lights: lights to start from instead of the project's (e.g. the app's guess).
    """
    unknowns = list(lights) if lights is not None else list(project.lights)
    auto = [
        j
        for j, ls in enumerate(project.spec.lights)
        if ls.initial == "auto" or ls.initial.scale is None
    ]
    if auto and images:
        scales = fit_scales(
            images, unknowns, project.solver.offset, project.wall.initial, project.medium.initial
        )
        for j in auto:
            u = unknowns[j]
            unknowns[j] = replace(u, initial=u.initial.replace(scale=scales[j]))
    return unknowns
