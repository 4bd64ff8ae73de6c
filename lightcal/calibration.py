"""From a project file to a calibrated light: load, select, solve, summarise.

This is the layer the CLI and the app share: it reads the images a project names,
selects pixels, builds the `CalibrationModel`, runs the solver (optionally from several
starts) and turns the outcome into a `CalibrationResult` with 1-sigma uncertainties and
warnings. It knows files (through `lightcal.io`) but nothing of terminals or browsers.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import nnls

from lightcal.core.camera import Camera
from lightcal.core.footprint import pixel_footprints
from lightcal.core.pose import describe_pose
from lightcal.core.problem import ImageData, LightUnknown, poisson_gaussian_sigma
from lightcal.core.render import shade
from lightcal.core.rid import CosPowerRID
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.core.scene import Rig
from lightcal.core.selection import (
    Region,
    bin_values,
    binned_candidates,
    candidate_mask,
    select_pixels,
)
from lightcal.core.solver import CalibrationModel, IterationReport, SolveOutcome, run_least_squares
from lightcal.errors import InputError
from lightcal.io.images import LinearImage, read_image
from lightcal.io.project import Project

ProgressFn = Callable[[str, int, int], None]


@dataclass(frozen=True, eq=False)
class LoadedImages:
    """The project's images read as linear values.

    Attributes:
        images: one `LinearImage` per project image.
        excluded: (H, W) bool per image: user mask pixels.
        camera: the intrinsics matching the images as read (binned when the reader binned).
    """

    images: list[LinearImage]
    excluded: list[np.ndarray | None]
    camera: Camera


def load_images(project: Project, *, progress: ProgressFn | None = None) -> LoadedImages:
    """Read every image of a project (and its mask) and check sizes against the camera."""
    sensor = project.spec.sensor
    response = None
    if sensor.response:
        from lightcal.io.response import ResponseCurve

        response = ResponseCurve.load(project.folder / sensor.response)
    images: list[LinearImage] = []
    excluded: list[np.ndarray | None] = []
    camera = project.camera
    for i, path in enumerate(project.image_paths):
        if progress is not None:
            progress("reading images", i, len(project.image_paths))
        img = read_image(
            path,
            channel=sensor.channel,
            black_level=sensor.black_level,
            white_level=sensor.white_level,
            response=response,
            assume_linear=sensor.assume_linear,
        )
        h, w = img.values.shape
        if (w, h) != (camera.width, camera.height):
            b = img.binning
            if b > 1 and (w, h) == (camera.width // b, camera.height // b):
                camera = project.camera.binned(b)
            else:
                raise InputError(
                    path,
                    f"image is {w}x{h} pixels but the camera intrinsics are for "
                    f"{camera.width}x{camera.height}; expected the same size",
                )
        images.append(img)
        mask_path = project.mask_paths[i]
        excluded.append(_read_mask(mask_path, (h, w)) if mask_path is not None else None)
    if progress is not None:
        progress("reading images", len(project.image_paths), len(project.image_paths))
    return LoadedImages(images, excluded, camera)


def _read_mask(path, shape: tuple[int, int]) -> np.ndarray:
    img = read_image(path, assume_linear=True)
    if img.values.shape != shape:
        raise InputError(
            path,
            f"mask is {img.values.shape[1]}x{img.values.shape[0]} pixels, "
            f"expected {shape[1]}x{shape[0]} like its image",
        )
    return np.asarray(img.values > 0)


def regions_for(project: Project, image_index: int) -> list[Region]:
    """The project's selection regions that apply to one image."""
    name = project.names[image_index]
    out = []
    for r in project.spec.selection.regions:
        if r.images is None or name in r.images:
            out.append(Region(r.kind, np.array(r.points, dtype=np.float64), r.include))
    return out


def noise_floor(project: Project, image: LinearImage) -> float:
    """Values at or below are too dark to use: the project's min_signal, else the offset
    plus 5 read-noise sigmas, else 1 % of the image's 99th percentile."""
    sel = project.selection
    if sel.min_signal is not None:
        return sel.min_signal
    sensor = project.spec.sensor
    if sensor.noise is not None:
        return sensor.offset + 5.0 * math.sqrt(sensor.noise.read_variance)
    finite = image.values[np.isfinite(image.values)]
    return sensor.offset + 0.01 * float(np.percentile(finite, 99)) if finite.size else 0.0


def image_data(
    project: Project,
    loaded: LoadedImages,
    index: int,
    *,
    pixels: np.ndarray | None = None,
    extra_pixels: np.ndarray | None = None,
) -> ImageData:
    """The selected pixels of one image as solver input.

    Args:
        project: the project.
        loaded: its images.
        index: which image.
        pixels: (N, 2) explicit pixel choice (in the binned grid); default: the project's
            selection strategy.
        extra_pixels: (K, 2) pixels (in the binned grid, e.g. clicked by a user) added to
            the selection when they are candidates (valid, unsaturated, above the noise
            floor, inside the regions and masks); the random strategy's cut to N never
            drops them. Others are ignored.
    """
    img = loaded.images[index]
    view = project.views[index]
    sel = project.selection
    b = sel.binning if sel.strategy == "all" else 1
    cand = candidate_mask(
        img.values,
        saturated=img.saturated,
        excluded=loaded.excluded[index],
        regions=regions_for(project, index),
        min_signal=noise_floor(project, img),
    )
    values = img.values
    if b > 1:
        cand = binned_candidates(cand, b)
        values = bin_values(values, b)
    if pixels is None:
        pixels = select_pixels(cand, sel, image_index=index, oversample=1.5)
    extra = _candidates_among(cand, extra_pixels)
    if extra.size:
        pixels = np.unique(np.concatenate([np.asarray(pixels, np.int64), extra]), axis=0)
    vignetting = _vignetting(project, loaded.camera)
    fp = pixel_footprints(
        loaded.camera,
        view,
        pixels,
        sensor=project.spec.sensor.model,
        vignetting=vignetting,
        binning=b,
    )
    keep = np.nonzero(fp.valid)[0]
    if sel.strategy == "random" and keep.size > sel.n_per_image:
        # A random N of the valid ones (not the first N: pixels are sorted by row),
        # plus the extra pixels.
        is_extra = _rows_in(fp.pixels[keep], extra)
        rng = np.random.default_rng([sel.seed, index, 1])
        chosen = rng.permutation(keep[~is_extra])[: sel.n_per_image]
        keep = np.sort(np.concatenate([chosen, keep[is_extra]]))
    fp = _subset(fp, keep)
    px = fp.pixels
    observed = values[px[:, 1], px[:, 0]]
    noise = project.spec.sensor.noise
    if noise is None:
        return ImageData(project.names[index], view, fp, observed, np.ones(len(observed)))
    # A super-pixel value is the mean of b^2 pixels: its variance is 1 / b^2 of theirs.
    per_value = (noise.gain / (b * b), noise.read_variance / (b * b))
    sigma = poisson_gaussian_sigma(observed - project.spec.sensor.offset, per_value)
    return ImageData(project.names[index], view, fp, observed, sigma, per_value)


def _candidates_among(cand: np.ndarray, pixels: np.ndarray | None) -> np.ndarray:
    """(M, 2) unique int64 rows of `pixels` (K, 2) inside the (H, W) mask `cand` and True."""
    if pixels is None:
        return np.zeros((0, 2), np.int64)
    p = np.asarray(pixels, dtype=np.int64).reshape(-1, 2)
    h, w = cand.shape
    p = p[(p[:, 0] >= 0) & (p[:, 0] < w) & (p[:, 1] >= 0) & (p[:, 1] < h)]
    p = p[cand[p[:, 1], p[:, 0]]]
    return np.unique(p, axis=0) if p.size else np.zeros((0, 2), np.int64)


def _rows_in(rows: np.ndarray, table: np.ndarray) -> np.ndarray:
    """(N,) which rows of `rows` (N, 2) appear in `table` (M, 2) (int64 pixel indices)."""
    if table.size == 0:
        return np.zeros(len(rows), dtype=bool)
    return np.isin(_pixel_keys(rows), _pixel_keys(table))


def _pixel_keys(pixels: np.ndarray) -> np.ndarray:
    """(N,) one int64 per (u, v) row of `pixels` (N, 2), u, v < 2^31."""
    p = np.asarray(pixels, dtype=np.int64)
    return (p[:, 1] << 32) + p[:, 0]


def _subset(fp, keep: np.ndarray):
    return replace(
        fp,
        pixels=fp.pixels[keep],
        corners_world=fp.corners_world[keep],
        weights=fp.weights[keep],
        valid=fp.valid[keep],
        area_m2=fp.area_m2[keep],
    )


_VIGNETTING_CACHE: dict[str, np.ndarray] = {}


def _vignetting(project: Project, camera: Camera) -> np.ndarray | None:
    if project.spec.sensor.model != "map" or project.vignetting_path is None:
        return None
    from lightcal.io.vignetting_file import load_vignetting

    key = f"{project.vignetting_path}:{camera.width}x{camera.height}"
    if key not in _VIGNETTING_CACHE:
        _VIGNETTING_CACHE[key] = load_vignetting(
            project.vignetting_path, width=camera.width, height=camera.height
        )
    return _VIGNETTING_CACHE[key]


def fit_scales(images: list[ImageData], unknowns: list[LightUnknown], offset: float) -> list[float]:
    """Linear least-squares scales of the lights at their initial poses (positive)."""
    rig = Rig(tuple(u.initial.replace(scale=1.0) for u in unknowns))
    cols = []
    rhs = []
    for im in images:
        sh = shade(im.footprints, im.view, rig)
        cols.append((sh.flux / im.sigma).T)
        rhs.append((im.observed - offset) / im.sigma)
    A = np.concatenate(cols)
    y = np.concatenate(rhs)
    s, _ = nnls(A, y)
    largest = float(s.max())
    if not largest > 0.0:
        # The start explains none of the light (aimed away, or data below the offset):
        # the ratio of mean magnitudes gives the solver a scale to start from.
        largest = float(np.abs(y).mean() / max(float(A.sum(axis=1).mean()), 1e-300)) or 1.0
        s = np.full(A.shape[1], largest)
    # A light the start leaves dark keeps a scale it can grow from.
    return [float(max(v, 1e-3 * largest)) for v in s]


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
    if not data:
        raise InputError(
            project.path,
            "no usable pixels in any image (all saturated, masked, below the noise floor "
            "or off the wall); check the selection and sensor settings",
        )
    unknowns = list(lights) if lights is not None else list(project.lights)
    auto = [j for j, ls in enumerate(project.spec.lights) if ls.initial.scale is None]
    if auto and lights is None:
        scales = fit_scales(data, unknowns, project.solver.offset)
        for j in auto:
            u = unknowns[j]
            unknowns[j] = replace(u, initial=u.initial.replace(scale=scales[j]))
    return CalibrationModel(data, unknowns, project.solver)


# -- results -------------------------------------------------------------------------------


@dataclass(frozen=True)
class LightResult:
    """One calibrated light.

    Attributes:
        name: the light's name.
        pose: `describe_pose` output (position_m, R_camera_light, quaternion_wxyz,
            axis_camera, roll_deg, pitch_deg, axis_angle_from_optical_axis_deg).
        sigma: 1-sigma of the same quantities (same keys; position and vectors per component).
        scale, scale_sigma: the fitted scale.
        pose_kind: isotropic, symmetric or general.
        rid: estimated RID description (None when the RID was given).
    """

    name: str
    pose: dict
    sigma: dict
    scale: float
    scale_sigma: float
    pose_kind: str
    rid: dict | None


@dataclass(frozen=True)
class CalibrationResult:
    """Everything a calibration produced (written as result JSON)."""

    lights: list[LightResult]
    offset: float
    offset_sigma: float | None
    gains: list[float]
    image_names: list[str]
    per_image_rms: list[float]
    pixels_used: list[int]
    iterations: int
    nfev: int
    status: int
    message: str
    converged: bool
    cost: float
    time_s: float
    warnings: list[str]
    parameter_names: list[str]
    x: list[float]
    covariance: list[list[float]]
    history: list[IterationReport] = field(default_factory=list, repr=False)


def _numeric_jacobian(fn: Callable[[np.ndarray], np.ndarray], x: np.ndarray) -> np.ndarray:
    y0 = np.asarray(fn(x), dtype=np.float64)
    J = np.zeros((y0.size, x.size))
    for k in range(x.size):
        h = 1e-7 * max(1.0, abs(x[k]))
        xp = x.copy()
        xm = x.copy()
        xp[k] += h
        xm[k] -= h
        J[:, k] = (np.asarray(fn(xp)) - np.asarray(fn(xm))).ravel() / (2 * h)
    return J


def covariance(model: CalibrationModel, x: np.ndarray) -> np.ndarray:
    """Parameter covariance s^2 (J^T J)^-1, s^2 the residual variance (reduced chi^2)."""
    r = model.residuals(x)
    JtJ = model.normal_matrix(x)
    dof = max(model.m - model.layout.n, 1)
    s2 = float(r @ r) / dof
    try:
        return s2 * np.linalg.inv(JtJ)
    except np.linalg.LinAlgError:
        return s2 * np.linalg.pinv(JtJ)


def _pose_vector(model: CalibrationModel, j: int, x: np.ndarray) -> np.ndarray:
    block = model.layout.blocks[j]
    R, t = block.param.to_pose(x[block.pose])
    d = describe_pose(R, t)
    return np.concatenate(
        [
            d["position_m"],
            np.ravel(d["R_camera_light"]),
            d["quaternion_wxyz"],
            d["axis_camera"],
            [d["roll_deg"], d["pitch_deg"], d["axis_angle_from_optical_axis_deg"]],
        ]
    )


def _split_pose_vector(v: np.ndarray) -> dict:
    return {
        "position_m": v[0:3].tolist(),
        "R_camera_light": v[3:12].reshape(3, 3).tolist(),
        "quaternion_wxyz": v[12:16].tolist(),
        "axis_camera": v[16:19].tolist(),
        "roll_deg": float(v[19]),
        "pitch_deg": float(v[20]),
        "axis_angle_from_optical_axis_deg": float(v[21]),
    }


def variety_warnings(model: CalibrationModel, cov: np.ndarray) -> list[str]:
    """Warnings when the views lack the distance/angle variety that constrains the pose."""
    warnings = []
    views = [im.view for im in model.images]
    dist = []
    axes = []
    for v in views:
        axis_world = v.R_camera_world[2]  # camera z in world coordinates
        dist.append(v.center_world[2] / max(-axis_world[2], 1e-9))
        axes.append(axis_world)
    dist_arr = np.array(dist)
    if len(views) < 3:
        warnings.append(
            f"only {len(views)} image(s): the paper used 12; use several views at "
            "different distances and angles"
        )
    if dist_arr.max() / dist_arr.min() < 1.25:
        warnings.append(
            f"camera-to-wall distances span only {dist_arr.min():.2f}-{dist_arr.max():.2f} m: "
            "the light's position along the view direction and its scale are poorly "
            "separated; add views nearer and farther from the wall"
        )
    A = np.array(axes)
    spread = max(math.degrees(math.acos(float(np.clip(a @ b, -1, 1)))) for a in A for b in A)
    if spread < 10.0:
        warnings.append(
            f"the views' directions differ by at most {spread:.1f} degrees: the light's "
            "orientation and lateral position are poorly separated; tilt the camera more"
        )
    sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    names = model.layout.names
    for b in model.layout.blocks:
        idx = [*range(b.pose.start, b.pose.stop), b.log_scale]
        sub = corr[np.ix_(idx, idx)]
        np.fill_diagonal(sub, 0.0)
        if np.nanmax(np.abs(sub)) > 0.995:
            a, c = np.unravel_index(np.nanargmax(np.abs(sub)), sub.shape)
            warnings.append(
                f"parameters {names[idx[a]]} and {names[idx[c]]} are correlated "
                f"({sub[a, c]:+.4f}): the views do not separate them; add views with more "
                "variety of distance and angle"
            )
    return warnings


def dark_light_warnings(model: CalibrationModel, x: np.ndarray) -> list[str]:
    """Warnings for lights that light (almost) none of the selected pixels at x.

    Such a light's pose is not determined by the data: the solver may have parked it
    pointing away or behind the wall while another light explains the images (two
    similar beams close together invite this).
    """
    rig = model.layout.rig(x)
    gains = model.layout.gain_factors(x)
    share = np.zeros(len(rig.lights))
    for i, im in enumerate(model.images):
        sh = shade(im.footprints, im.view, rig, rid_subsamples=model.options.rid_subsamples)
        share += gains[i] * np.array([light.scale for light in rig.lights]) * sh.flux.sum(axis=1)
    total = float(share.sum())
    out = []
    for light, s in zip(rig.lights, share, strict=True):
        if not (total > 0.0 and s > 1e-6 * total):
            out.append(
                f"light '{light.name}' lights none of the selected pixels at the solution "
                "(it points away or sits behind the wall): its pose is not determined; "
                "start it nearer its true pose, or calibrate the lights one at a time"
            )
    return out


def summarise(model: CalibrationModel, outcome: SolveOutcome) -> CalibrationResult:
    """Turn a solve into a `CalibrationResult` with uncertainties and warnings."""
    x = outcome.x
    cov = covariance(model, x)
    lay = model.layout
    lights = []
    for j, block in enumerate(lay.blocks):
        v = _pose_vector(model, j, x)
        G = _numeric_jacobian(functools.partial(_pose_vector, model, j), x)
        sig = np.sqrt(np.clip(np.diag(G @ cov @ G.T), 0, None))
        scale = lay.light_of(block, x).scale  # exp(log-scale), clipped as the model
        rid_desc = None
        if block.unknown.estimate_rid != "none":
            rid = lay.rid_of(block, x)
            theta = np.linspace(0, math.radians(89), 90)
            rid_desc = {
                "model": block.unknown.estimate_rid,
                "parameters": x[block.rid].tolist(),
                "half_angle_deg": math.degrees(rid.half_angle_rad),
                "theta_deg": np.degrees(theta).tolist(),
                "values": np.asarray(rid(theta)).tolist(),
            }
            if block.unknown.estimate_rid == "cos_power":
                assert isinstance(rid, CosPowerRID)
                rid_desc["m"] = rid.m
        lights.append(
            LightResult(
                block.unknown.initial.name,
                _split_pose_vector(v),
                _split_pose_vector(sig),
                scale,
                scale * math.sqrt(max(cov[block.log_scale, block.log_scale], 0.0)),
                block.param.kind,
                rid_desc,
            )
        )
    offset_sigma = None
    if lay.offset_index is not None:
        offset_sigma = math.sqrt(max(cov[lay.offset_index, lay.offset_index], 0.0))
    return CalibrationResult(
        lights=lights,
        offset=lay.offset(x),
        offset_sigma=offset_sigma,
        gains=lay.gain_factors(x).tolist(),
        image_names=[im.name for im in model.images],
        per_image_rms=model.per_image_rms(x).tolist(),
        pixels_used=[len(im.observed) for im in model.images],
        iterations=outcome.iterations,
        nfev=outcome.nfev,
        status=outcome.status,
        message=outcome.message,
        converged=outcome.success,
        cost=outcome.cost,
        time_s=outcome.time_s,
        warnings=dark_light_warnings(model, x) + variety_warnings(model, cov),
        parameter_names=list(lay.names),
        x=x.tolist(),
        covariance=cov.tolist(),
        history=outcome.history,
    )


def perturbed_start(
    model: CalibrationModel, rng: np.random.Generator, *, position_m: float, angle_deg: float
) -> np.ndarray:
    """A random start near the initial guess: positions moved by up to `position_m`,
    light axes/orientations rotated by up to `angle_deg`."""
    x = model.layout.x0.copy()
    for block in model.layout.blocks:
        p = x[block.pose].copy()
        d = rng.normal(size=3)
        p[:3] += d / np.linalg.norm(d) * rng.uniform(0, position_m)
        R, t = block.param.to_pose(p)
        if block.param.n_rot:
            w = rng.normal(size=3)
            w *= math.radians(rng.uniform(0, angle_deg)) / np.linalg.norm(w)
            R = matrix_from_rotvec(w) @ R
        x[block.pose] = block.param.from_pose(R, t)
    return x


def solve(
    model: CalibrationModel,
    *,
    multistart: int = 0,
    multistart_position_m: float = 0.3,
    multistart_angle_deg: float = 30.0,
    seed: int = 0,
    on_iteration: Callable[[IterationReport], None] | None = None,
    on_start: Callable[[int, int], None] | None = None,
) -> SolveOutcome:
    """Solve from the initial guess and `multistart` random starts; keep the best.

    `on_iteration` sees every start's iterations (each numbered from 0); `on_start(k, n)`
    is called before start k of n (0: the initial guess).
    """
    n_starts = 1 + multistart
    if on_start is not None:
        on_start(0, n_starts)
    best = run_least_squares(model, on_iteration=on_iteration)
    rng = np.random.default_rng(seed)
    for k in range(1, n_starts):
        x0 = perturbed_start(
            model, rng, position_m=multistart_position_m, angle_deg=multistart_angle_deg
        )
        if on_start is not None:
            on_start(k, n_starts)
        try:
            out = run_least_squares(model, x0, on_iteration=on_iteration)
        except ValueError:
            continue
        if out.cost < best.cost:
            best = out
    if multistart:
        model.set_weights_at(best.weights_at)  # the weights the best solve ended with
    return best


def solve_project(
    project: Project,
    model: CalibrationModel,
    *,
    on_iteration: Callable[[IterationReport], None] | None = None,
    on_start: Callable[[int, int], None] | None = None,
) -> SolveOutcome:
    """`solve` with the project's multi-start settings."""
    so = project.spec.solver
    return solve(
        model,
        multistart=so.multistart,
        multistart_position_m=so.multistart_position_m,
        multistart_angle_deg=so.multistart_angle_deg,
        seed=project.selection.seed,
        on_iteration=on_iteration,
        on_start=on_start,
    )


def calibrate_project(
    project: Project,
    *,
    progress: ProgressFn | None = None,
    on_iteration: Callable[[IterationReport], None] | None = None,
) -> tuple[LoadedImages, CalibrationModel, CalibrationResult]:
    """Load, select, solve and summarise a project."""
    loaded = load_images(project, progress=progress)
    model = build_model(project, loaded, progress=progress)
    outcome = solve_project(project, model, on_iteration=on_iteration)
    return loaded, model, summarise(model, outcome)
