"""Capture planning: which camera poses would shrink the light's uncertainty most.

The criterion (docs/model.md, "Planning the next views"). With the solver's weighted
Jacobian J (the `CalibrationModel`'s, the same rows trf sees) the pixel-noise covariance of
the estimate is s^2 N^-1, N = J^T J. A new view v adds the expected information
J_v^T J_v, J_v its weighted Jacobian on a synthetic selection of its pixels rendered at the
current estimate, weighted by the noise model (Poisson-Gaussian when the images have one,
else the images' median sigma), its rows scaled to the pixel count the project's own
selection gives an image (k rows stand for N_typ pixels: J_v^T J_v N_typ / k). When the
per-image gains are estimated, the view brings a gain of its own: one more column
(d r / d log g = -(m - offset) / sigma), marginalised with the rest. So

    Cov_after(v) = s^2 (N (+) 0 + J_v^T J_v)^-1,

and the view chosen minimises the D-optimal criterion on the pose block P (every light's
position and axis / rotation parameters):

    log det Cov_after(v)[P, P],

the volume of the pose's confidence ellipsoid; scale, gains, offset and wall parameters
are nuisance parameters, marginalised (not conditioned on). N best views are chosen
greedily: each chosen view's information is added before the next is chosen.

Candidates are a grid in front of the wall: each camera looks at the wall's centre (the
mean point where the project's optical axes meet the wall) from a distance d along its
axis, tilted by `tilt` from the wall normal towards `azimuth`, rolled about its axis. A
candidate is kept when its four image corners see the wall inside its extent (the wall's
size, centred on that point) and at least `min_lit_pixels` of its grid pixels are lit.

Before any solve the estimate is the initial guess (scales fitted) and s^2 = 1 (the
residuals there are the guess's misfit, not noise; `lightcal plan` without --result):
s^2 is the mean noise variance of the pixels (`noise_variance`: the sensor's noise model
when the project gives one, else each image's estimated from the image itself, as the
fit test does), what a solve's residuals estimate when the model fits: the sigmas are
in metres and degrees before the solve as after it. Only when no noise model exists
are they for a pixel noise of 1, and `lightcal plan` says so. After a solve s^2 comes
from its residuals.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.flat_port import FlatPort
from lightcal.core.light_axis import axis_jacobian
from lightcal.core.model_rebuild import rebuilt
from lightcal.core.problem import ImageData, poisson_gaussian_sigma
from lightcal.core.solver import CalibrationModel, SolverOptions
from lightcal.core.uncertainty import noise_inflation
from lightcal.core.wall_mesh import WallMesh
from lightcal.errors import InputError
from lightcal.pipeline.plan_candidates import (
    AZIMUTHS_DEG,
    DISTANCES_M,
    ROLLS_DEG,
    TILTS_DEG,
    WALL_SIZE_M,
    Candidate,
    PlanGrid,
    candidate_image,
    candidate_view,
    candidates,
    wall_centre,
)

__all__ = [
    "AZIMUTHS_DEG",
    "DISTANCES_M",
    "ROLLS_DEG",
    "TILTS_DEG",
    "WALL_SIZE_M",
    "Candidate",
    "InformationState",
    "PlanGrid",
    "PlannedView",
    "Sigmas",
    "candidate_image",
    "candidate_view",
    "candidates",
    "greedy_plan",
    "noise_variance",
    "plan_to_dict",
    "plan_views",
    "residual_noise_scale2",
    "start_vector",
    "typical_peak",
    "wall_centre",
]


def noise_variance(
    model: CalibrationModel, noise: list[tuple[float, float] | None]
) -> float | None:
    """s^2 before any solve: the mean noise variance of the model's pixels (image units^2).

    Each image's noise model (gain, read_variance) (model order) gives its pixels the
    variance gain * (observed - offset) + read_variance; their mean is what the residuals
    of a solve estimate s^2 to be when the model fits (the solver weighs the pixels
    alike), so the sigmas come out in metres and degrees before the solve as after it.
    None when an image has no noise model.
    """
    if not noise or any(n is None for n in noise):
        return None
    offset = model.layout.offset(model.layout.x0)
    total, count = 0.0, 0
    for im, sigma_im, n in zip(model.images, model.sigmas, noise, strict=True):
        assert n is not None
        variance = poisson_gaussian_sigma(im.observed - offset, n) ** 2 / sigma_im**2
        total += float(np.sum(variance))
        count += variance.size
    return total / count if count else None


def residual_noise_scale2(model: CalibrationModel, x: np.ndarray) -> float:
    """s^2 from the residuals at x (`noise_inflation`, as a solve's uncertainty takes it):
    after a solve the pixel noise the fit left; before it, the guess's misfit."""
    r = model.residuals(np.asarray(x, dtype=np.float64))
    sigma_is_noise = any(im.noise is not None for im in model.images)
    dof = model.m - model.layout.n
    return noise_inflation(float(r @ r), dof, 0.0, sigma_is_noise=sigma_is_noise)


def typical_peak(model: CalibrationModel, x: np.ndarray) -> float:
    """The median over the images of their brightest selected value above the offset."""
    offset = model.layout.offset(x)
    return float(np.median([np.max(im.observed) - offset for im in model.images]))


@dataclass(frozen=True)
class Sigmas:
    """Per light: 1-sigma position (m, root of the trace) and axis (deg) uncertainty, and
    the D-optimal criterion log det Cov[P, P] of the pose block."""

    position_m: tuple[float, ...]
    axis_deg: tuple[float | None, ...]
    log_det: float


def camera_pixel_options(options: SolverOptions) -> SolverOptions:
    """The solver options of a planned view, whose pixels are the camera's (binning 1):
    an estimated fall-off then maps them, not the selection's super-pixels."""
    f = options.fall_off
    if f is None or f.binning == 1:
        return options
    return replace(options, fall_off=replace(f, binning=1))


def camera_pixel_model(model: CalibrationModel) -> CalibrationModel:
    """`model` with `camera_pixel_options` (itself when they are its own)."""
    options = camera_pixel_options(model.options)
    if options is model.options:
        return model
    return rebuilt(model, options=options, surroundings=None)


class InformationState:
    """The normal matrix N of the views so far (grown by one gain column per added view
    when gains are estimated) and the map from a candidate's columns into it.

    Args:
        model: the project's calibration model.
        x: (n,) the estimate (or the initial vector).
        noise_scale2: s^2 of the pixel-noise covariance.
        rows_per_view: the pixel count a real view's selection gives (the candidate's rows
            are scaled to it); None: each candidate counts as its own rows.
    """

    def __init__(
        self,
        model: CalibrationModel,
        x: np.ndarray,
        noise_scale2: float = 1.0,
        rows_per_view: float | None = None,
    ) -> None:
        self.model = model
        self.x = np.asarray(x, dtype=np.float64)
        self.noise_scale2 = noise_scale2
        self.rows_per_view = rows_per_view
        self.N = model.normal_matrix(self.x)
        lay = model.layout
        self.gains = lay.gains.stop > lay.gains.start
        self.pose = np.concatenate([np.arange(b.pose.start, b.pose.stop) for b in lay.blocks])

    def view_information(self, image: ImageData, N: np.ndarray | None = None) -> np.ndarray:
        """N (+) 0 + J_v^T J_v for the candidate `image` (rows scaled, see the class)."""
        N = self.N if N is None else N
        lay = self.model.layout
        # A planned view's pixels, on a wall taken as even: an albedo map is known only
        # where the photos saw the wall, and N has its uncertainty marginalised already.
        options = replace(camera_pixel_options(self.model.options), albedo_map=None)
        single = rebuilt(self.model, images=[image], options=options, surroundings=None)
        index = [lay.names.index(nm) for nm in single.layout.names]
        J = single.jacobian(self.x[index])
        scale = 1.0 if self.rows_per_view is None else self.rows_per_view / len(image.observed)
        cols = list(index)
        if self.gains:
            # d r / d log g of the view's own gain: -(m - offset) / sigma.
            gain_col = -(image.observed - lay.offset(self.x)) / image.sigma
            J = np.c_[J, gain_col]
            cols.append(N.shape[0])
            out = np.zeros((N.shape[0] + 1, N.shape[0] + 1))
            out[:-1, :-1] = N
        else:
            out = N.copy()
        out[np.ix_(cols, cols)] += scale * (J.T @ J)
        return out

    def sigmas(self, N: np.ndarray | None = None) -> Sigmas:
        """The pose-block sigmas and criterion of s^2 N^-1."""
        N = self.N if N is None else N
        cov = self.noise_scale2 * _inverse(N)
        lay = self.model.layout
        pos: list[float] = []
        ax: list[float | None] = []
        for b in lay.blocks:
            i = b.pose.start
            pos.append(float(math.sqrt(max(np.trace(cov[i : i + 3, i : i + 3]), 0.0))))
            k = b.pose.stop - b.pose.start
            if k == 5:
                A = axis_jacobian(float(self.x[i + 3]), float(self.x[i + 4]))
                c = A @ cov[i + 3 : i + 5, i + 3 : i + 5] @ A.T
                ax.append(math.degrees(math.sqrt(max(np.trace(c), 0.0))))
            elif k == 6:
                c = cov[i + 3 : i + 6, i + 3 : i + 6]
                ax.append(math.degrees(math.sqrt(max(np.trace(c), 0.0))))
            else:
                ax.append(None)
        P = cov[np.ix_(self.pose, self.pose)]
        sign, log_det = np.linalg.slogdet(P)
        return Sigmas(tuple(pos), tuple(ax), float(log_det) if sign > 0 else math.inf)


def _inverse(N: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.inv(N)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(N)


@dataclass(frozen=True)
class PlannedView:
    """One chosen view: the candidate, and the sigmas before and after adding it."""

    candidate: Candidate
    before: Sigmas
    after: Sigmas
    image: ImageData = field(repr=False)


def greedy_plan(
    state: InformationState, images: list[ImageData | None], pool: list[Candidate], n: int
) -> list[PlannedView]:
    """The `n` best of `pool` (their synthetic `images`, None: unusable) chosen greedily
    by the D-optimal criterion, each added to the information before the next."""
    N = state.N
    chosen: list[PlannedView] = []
    used: set[int] = set()
    for _ in range(n):
        before = state.sigmas(N)
        best: tuple[float, int, np.ndarray] | None = None
        for k, image in enumerate(images):
            if image is None or k in used:
                continue
            N_k = state.view_information(image, N)
            crit = state.sigmas(N_k).log_det
            if best is None or crit < best[0]:
                best = (crit, k, N_k)
        if best is None:
            break
        _, k, N = best
        used.add(k)
        image = images[k]
        assert image is not None
        chosen.append(PlannedView(pool[k], before, state.sigmas(N), image))
    return chosen


def plan_views(
    model: CalibrationModel,
    x: np.ndarray,
    camera: Camera,
    *,
    n: int = 3,
    grid: PlanGrid | None = None,
    noise_scale2: float | None = None,
    progress: Callable[[str, int, int], None] | None = None,
    mesh: WallMesh | None = None,
    port: FlatPort | None = None,
) -> tuple[Sigmas, list[PlannedView]]:
    """The current sigmas and the `n` best next views of a calibration model at x.

    Args:
        model: the views so far (`lightcal.pipeline.build_model`).
        x: (n,) the estimate, or the initial vector before any solve.
        camera: the intrinsics of the images.
        n: how many views to plan.
        grid: the candidates' grid (default `PlanGrid()`).
        noise_scale2: s^2 (default: from the residuals at x, `noise_inflation`).
        progress: progress("rendering candidates", done, total) as the candidate views
            are rendered (the long part).
        mesh: the wall's shape (`wall.mesh`): the candidates' footprints on it (a
            candidate whose image corners miss it is dropped); None: the plane z = 0.
        port: the camera's flat port (`camera.port`): the candidates seen through it.
    """
    grid = PlanGrid() if grid is None else grid
    if noise_scale2 is None:
        noise_scale2 = residual_noise_scale2(model, x)
    rows = float(np.median(model.sizes))
    state = InformationState(model, x, noise_scale2, rows)
    exposure = float(np.median([im.view.exposure for im in model.images]))
    centre = wall_centre([im.view for im in model.images])
    pool = candidates(camera, grid, centre, exposure, mesh=mesh, port=port)
    peak = typical_peak(model, state.x)
    at_camera_pixels = camera_pixel_model(model)
    images = []
    for k, c in enumerate(pool):
        if progress is not None:
            progress("rendering candidates", k, len(pool))
        images.append(
            candidate_image(
                at_camera_pixels,
                state.x,
                camera,
                c.view,
                grid,
                f"plan_{k:03d}",
                peak=peak,
                mesh=mesh,
                port=port,
            )
        )
    if progress is not None:
        progress("rendering candidates", len(pool), len(pool))
    if not any(im is not None for im in images):
        raise InputError(
            "plan", "no candidate view sees the lit wall within the wall's size; widen the grid"
        )
    return state.sigmas(), greedy_plan(state, images, pool, n)


def start_vector(
    model: CalibrationModel,
    names: list[str] | None,
    x: list[float] | None,
    source: object = "result",
) -> np.ndarray:
    """(n,) the model's x: a result's parameters matched by name (its `parameters.names`
    and `x`), or the model's initial vector when no result is given.

    Raises:
        InputError: the result lacks one of the model's parameters.
    """
    if names is None or x is None:
        return model.layout.x0.copy()
    values = dict(zip(names, x, strict=True))
    missing = [nm for nm in model.layout.names if nm not in values]
    if missing:
        raise InputError(
            str(source),
            f"parameters {', '.join(missing)} are not in the result: solve this project",
        )
    return np.array([values[nm] for nm in model.layout.names], dtype=np.float64)


def _sigmas_dict(s: Sigmas, light_names: list[str]) -> list[dict[str, object]]:
    return [
        {"light": nm, "position_sigma_m": p, "axis_sigma_deg": a}
        for nm, p, a in zip(light_names, s.position_m, s.axis_deg, strict=True)
    ]


def plan_to_dict(
    current: Sigmas, planned: list[PlannedView], light_names: list[str]
) -> dict[str, object]:
    """The plan as JSON-ready data (what `lightcal plan --out` writes)."""
    views = []
    for k, pv in enumerate(planned):
        c = pv.candidate
        views.append(
            {
                "rank": k + 1,
                "instruction": c.instruction(),
                "distance_m": c.distance_m,
                "tilt_deg": c.tilt_deg,
                "azimuth_deg": c.azimuth_deg,
                "roll_deg": c.roll_deg,
                "target_world_m": [float(v) for v in c.target_world],
                "R_camera_world": c.view.R_camera_world.tolist(),
                "t_camera_world": c.view.t_camera_world.tolist(),
                "center_world_m": c.view.center_world.tolist(),
                "before": _sigmas_dict(pv.before, light_names),
                "after": _sigmas_dict(pv.after, light_names),
                "log_det_pose_covariance_after": pv.after.log_det,
            }
        )
    return {
        "criterion": "D-optimal: minimise log det of the pose block's covariance (greedy)",
        "frame": "world: wall z = 0, +z towards the cameras; T_camera_world maps world to "
        "OpenCV camera",
        "current": _sigmas_dict(current, light_names),
        "log_det_pose_covariance": current.log_det,
        "views": views,
    }
