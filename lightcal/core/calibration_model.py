"""The calibration model: weighted residuals and their analytic Jacobian.

`CalibrationModel` maps the parameter vector x (`ParameterLayout`) to the weighted
residuals r = (m_obs - m_render(x)) / sigma of the selected pixels and to d r / d x: pose
and scale from the renderer's gradients, RID parameters (when estimated) by central
differences of the renderer. With many pixels and the linear loss it hands the solver the
QR-compressed problem (`reduced`). `lightcal.core.solver.run_least_squares` minimises it.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from collections.abc import Callable, Iterator

import numpy as np

from lightcal.core import solver_kernels as sk
from lightcal.core.albedo_map import AlbedoMap, AlbedoProjection
from lightcal.core.albedo_systems import projected_systems
from lightcal.core.blas_threads import single_threaded_blas
from lightcal.core.bounce_term import BounceTerm
from lightcal.core.channels import check_channels
from lightcal.core.fall_off import ambient_estimated
from lightcal.core.light_bounds import parameter_bounds
from lightcal.core.medium import MediumUnknown
from lightcal.core.pose import pose_column_map
from lightcal.core.problem import (
    LOG_CLIP,
    ImageData,
    LightUnknown,
    ParameterLayout,
    WallUnknown,
    poisson_gaussian_sigma,
    with_curve_range,
)
from lightcal.core.qr_factors import economic_r, stack_r_factors
from lightcal.core.render import light_flux
from lightcal.core.rendered_signal import rendered_signal
from lightcal.core.rid_columns import rid_columns
from lightcal.core.solver_options import IterationReport, SolverOptions, robust_cost
from lightcal.core.surroundings import Surroundings
from lightcal.core.system_buffers import StateAtX, SystemBuffers

ImageVisitor = Callable[[int, np.ndarray, np.ndarray], None]
"""visit(i, A (N_i, n + 1), fluxes (L, N_i)): see `CalibrationModel.evaluate_visiting`."""

# Pixels from which the QR-compressed problem pays (SolverOptions.compress None); measured:
# 12 x 100 px solve 27 ms compressed vs 21.5 ms full; 12 x 375,000 px 5 s vs 18 s.
COMPRESS_MIN_PIXELS = 20_000


class CalibrationModel:
    """Residuals and Jacobian of a calibration problem.

    Args:
        images: the selected pixels of each image.
        unknowns: the lights to calibrate.
        options: solver options.
        wall: the wall's reflectance and what to estimate of it (default: Lambertian).
        medium: the medium between rig and wall, what to estimate of it (default: air).
        surroundings: surfaces whose bounce light the lights' flux gains (default: none).
        channels: the colour channels solved jointly (`ParameterLayout`), each image's
            its `ImageData.channel`; `media` then one medium per channel.
    """

    def __init__(
        self,
        images: list[ImageData],
        unknowns: list[LightUnknown],
        options: SolverOptions,
        wall: WallUnknown | None = None,
        medium: MediumUnknown | None = None,
        surroundings: Surroundings | None = None,
        channels: tuple[str, ...] = (),
        media: tuple[MediumUnknown, ...] | None = None,
    ) -> None:
        if not images:
            raise ValueError("calibration: expected at least one image with selected pixels")
        if not unknowns:
            raise ValueError("calibration: expected at least one light")
        check_channels(images, channels, options, surroundings)
        self.images = images
        self.unknowns = [with_curve_range(u, images) for u in unknowns]
        unknowns = self.unknowns
        self.options = options
        self.layout = ParameterLayout.build(
            unknowns,
            len(images),
            estimate_gains=options.estimate_gains,
            estimate_offset=options.estimate_offset,
            offset0=options.offset,
            wall=wall,
            medium=medium,
            fall_off=options.fall_off,
            estimate_ambient=ambient_estimated(images, options),
            channels=channels,
            media=media,
            surroundings=surroundings,
        )
        self.sizes = np.array([len(im.observed) for im in images])
        self.bounds = np.cumsum(np.concatenate([[0], self.sizes]))
        self.m = int(self.bounds[-1])
        self._cache_x: np.ndarray | None = None
        self._cache_r: np.ndarray | None = None
        self._cache_J_x: np.ndarray | None = None
        self._cache_J: np.ndarray | None = None
        self._cache_R: np.ndarray | None = None
        # The last two compressed evaluations' (x, R factor, per-image RMS): what an
        # iteration's report needs (trf may have tried a point after the one it reports).
        self._recent: deque[tuple[np.ndarray, np.ndarray, np.ndarray]] = deque(maxlen=2)
        self.sigmas: list[np.ndarray] = [im.sigma for im in images]
        self._buffers = SystemBuffers()
        self._evaluating = threading.Lock()
        self.weights_at: np.ndarray | None = None
        self.nfev = 0
        self.albedo = None
        if options.albedo_map is not None:
            centers = [im.footprints.centers_world[:, :2] for im in images]
            self.albedo = AlbedoProjection.over(centers, options.albedo_map)
        self._albedo_at: tuple[np.ndarray, AlbedoMap, np.ndarray] | None = None
        self.surroundings = surroundings
        self.bounce = BounceTerm.of(surroundings, [im.footprints for im in images])

    # -- evaluation -------------------------------------------------------------------

    @property
    def compressed(self) -> bool:
        """trf works on the QR-compressed problem (`reduced`): linear loss only; always
        with an albedo map (its prior rows are in the compressed problem only)."""
        if self.albedo is not None:
            return True
        if self.options.loss != "linear" or self.options.compress is False:
            return False
        return self.options.compress is True or self.m >= COMPRESS_MIN_PIXELS

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """(m,) weighted residuals (m_obs - m_render) / sigma.

        Computed together with the Jacobian (one render with gradients): trf asks for
        the Jacobian at every point whose residuals it accepts, so this renders once
        per accepted step instead of twice.
        """
        if self._cache_x is None or not np.array_equal(x, self._cache_x):
            self.nfev += 1
            self._evaluate(x, full_jacobian=not self.compressed)
        assert self._cache_r is not None
        return self._cache_r

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """(m, n) d residuals / d x."""
        if self._cache_J_x is None or not np.array_equal(x, self._cache_J_x):
            self._evaluate(x, full_jacobian=True)
        assert self._cache_J is not None
        return self._cache_J

    def reduced(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The QR-compressed problem at x: (r~ (n+1,), J~ (n+1, n)).

        With [J r] = Q [[R, Q^T r], [0, rho]] (thin QR of the (m, n+1) matrix),
        r~ = (Q^T r, rho) and J~ = (R; 0) satisfy |r~| = |r|, J~^T r~ = J^T r,
        J~^T J~ = J^T J and |J~ p + r~| = |J p + r| for every step p: trf's quadratic
        model, gradient, Jacobian scaling and cost are those of the full problem, so
        its iterates are the same (to rounding) while every iteration costs O(n^3)
        instead of an SVD of the (m, n) Jacobian, and no (m, n) matrix is kept.
        """
        self.residuals(x)
        assert self._cache_R is not None
        return self._cache_R[:, -1], self._cache_R[:, :-1]

    def solver_residuals(self, x: np.ndarray) -> np.ndarray:
        """The residuals handed to least_squares: `reduced` when compressed, else full."""
        return self.reduced(x)[0] if self.compressed else self.residuals(x)

    def solver_jacobian(self, x: np.ndarray) -> np.ndarray:
        """The Jacobian handed to least_squares, matching `solver_residuals`."""
        return self.reduced(x)[1] if self.compressed else self.jacobian(x)

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """(n,) J^T r at x."""
        r_s, J_s = self.solver_residuals(x), self.solver_jacobian(x)
        return J_s.T @ r_s

    def normal_matrix(self, x: np.ndarray) -> np.ndarray:
        """(n, n) J^T J at x (Gauss-Newton approximation of the cost's Hessian)."""
        J_s = self.solver_jacobian(x)
        return J_s.T @ J_s

    def gauss_newton_decrease(self, x: np.ndarray) -> float | None:
        """How much the Gauss-Newton step from x lowers the cost in trf's quadratic model:
        0.5 |Q^T r|^2, Q^T r the first n entries of the last column of [J r]'s R factor
        (the step p = -R_J^-1 Q^T r leaves the model cost 0.5 rho^2). From the evaluation
        at x when it is cached; None otherwise, and for a robust loss (trf's model then
        works on re-scaled residuals)."""
        if self.options.loss != "linear":
            return None
        n = self.layout.n
        recent = self._recent_at(x)
        at_x = all(c is not None and np.array_equal(c, x) for c in (self._cache_J_x, self._cache_x))
        if recent is not None:
            R = recent[1]
        elif at_x and self._cache_J is not None and self._cache_r is not None:
            Jr = np.column_stack([self._cache_J, self._cache_r])
            if not np.all(np.isfinite(Jr)):
                return None
            R = stack_r_factors([economic_r(np.asfortranarray(Jr))], n + 1)
        else:
            return None
        q = R[:n, n]
        decrease = 0.5 * float(q @ q)
        return decrease if math.isfinite(decrease) else None

    def _recent_at(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The kept compressed evaluation (x, R factor, per-image RMS) at x, if any."""
        return next((e for e in self._recent if np.array_equal(e[0], x)), None)

    def evaluate_visiting(self, x: np.ndarray, visit: ImageVisitor) -> None:
        """Evaluate at x as the solver does (residuals and J^T J then cached at x) and call
        visit(i, A, fluxes) per image on the way: A (N_i, n + 1) its [J_i r_i] (a shared
        buffer: copy what is kept), fluxes (L, N_i) each light's flux per unit scale. The
        checks after a solve take what they need of every pixel from this one pass."""
        with self._evaluating, single_threaded_blas():  # one at a time: shared buffers
            self._evaluate_blas_limited(x, full_jacobian=not self.compressed, visit=visit)

    def release_buffers(self) -> None:
        """Free the image systems' work arrays (the next evaluation makes them again)."""
        with self._evaluating:
            self._buffers = SystemBuffers()

    def _evaluate(self, x: np.ndarray, *, full_jacobian: bool) -> None:
        """Residuals, the QR-compressed problem and optionally the full Jacobian at x."""
        with self._evaluating, single_threaded_blas():  # one at a time: shared buffers
            self._evaluate_blas_limited(x, full_jacobian=full_jacobian)

    def _evaluate_blas_limited(
        self, x: np.ndarray, *, full_jacobian: bool, visit: ImageVisitor | None = None
    ) -> None:
        n = self.layout.n
        # The previous residuals dropped first: beside the new ones they set the peak.
        self._cache_x = None
        self._cache_r = None
        r = np.empty(self.m)
        J = np.empty((self.m, n)) if full_jacobian else None
        tops = []
        rms = np.full(len(self.images), np.nan)
        lay = self.layout
        channels = range(lay.n_channels) if lay.channels else range(0)
        at_x = StateAtX(
            lay.rig(x),
            lay.gain_factors(x),
            lay.offset(x),
            self._pose_maps(x),
            lay.wall_of(x),
            lay.medium_of(x),
            tuple(lay.rig(x, ch) for ch in channels),
            tuple(lay.medium_of(x, ch) for ch in channels),
            lay.surface_albedos(x),
        )
        for i, A, (squares, finite), fluxes in self._image_systems(x, at_x, visit is not None):
            rows = slice(self.bounds[i], self.bounds[i + 1])
            r[rows] = A[:, n]
            if J is not None:
                J[rows] = A[:, :n]
            if visit is not None:
                assert fluxes is not None
                visit(i, A, fluxes[0][None] if len(fluxes) == 1 else np.stack(fluxes))
            if self.compressed and A.shape[0]:
                rms[i] = math.sqrt(squares / A.shape[0])
                tops.append(economic_r(A) if finite else None)
        if self._albedo_at is not None and np.array_equal(self._albedo_at[0], x):
            prior = self._albedo_at[2]
            tops.append(economic_r(prior) if np.all(np.isfinite(prior)) else None)
        if self.compressed:
            self._cache_R = stack_r_factors(tops, n + 1)
            self._recent.append((x.copy(), self._cache_R, rms))
        self._cache_x = x.copy()
        self._cache_r = r
        if J is not None:
            self._cache_J_x = x.copy()
            self._cache_J = J

    def _image_systems(
        self, x: np.ndarray, at_x: StateAtX, want_fluxes: bool
    ) -> Iterator[tuple[int, np.ndarray, tuple[float, bool], list[np.ndarray] | None]]:
        """Per image (i, [J_i r_i], (sum of squares in value units, all finite), fluxes
        or None) of `_image_system`, or with an albedo map of its variable projection
        (`lightcal.core.albedo_map`: all systems kept, N x (n + 1) doubles)."""
        if self.albedo is None:
            for i in range(len(self.images)):
                fluxes: list[np.ndarray] | None = [] if want_fluxes else None
                A, stats = self._image_system(x, i, at_x, fluxes)
                yield i, A, stats, fluxes
            return
        systems, all_fluxes, albedo, prior = projected_systems(
            self.albedo,
            self.layout,
            [(im.observed, sigma) for im, sigma in zip(self.images, self.sigmas, strict=True)],
            at_x,
            lambda i, at, fluxes: self._image_system(x, i, at, fluxes)[0],
            want_fluxes,
        )
        self._albedo_at = (x.copy(), albedo, prior)
        n = self.layout.n
        for i, A in enumerate(systems):
            d = A[:, n] * self.sigmas[i]
            yield i, A, (float(d @ d), bool(np.all(np.isfinite(A)))), all_fluxes[i]

    def albedo_map(self, x: np.ndarray) -> AlbedoMap | None:
        """The albedo map at x (None without one), the projection's minimiser."""
        if self.albedo is None:
            return None
        if self._albedo_at is None or not np.array_equal(self._albedo_at[0], x):
            self._evaluate(x, full_jacobian=False)
        assert self._albedo_at is not None
        return self._albedo_at[1]

    def _pose_maps(self, x: np.ndarray) -> list[np.ndarray]:
        """Per light: (6, k) map from (d/dt, d/d delta) (camera frame) to its k pose columns."""
        return [pose_column_map(b.param.kind, x[b.pose]) for b in self.layout.blocks]

    def _image_system(
        self, x: np.ndarray, i: int, at_x: StateAtX, fluxes: list[np.ndarray] | None = None
    ) -> tuple[np.ndarray, tuple[float, bool]]:
        """[J_i r_i] (N_i, n + 1), Fortran order: image i's Jacobian and residuals, and
        (sum of the squared residuals in value units, whether all are finite).

        One render with gradients per light; the world-frame gradients go to the pose
        columns through one (N, 6) x (6, k) product per light. `fluxes`, when given,
        receives each light's flux (N_i,) per unit scale.
        """
        lay = self.layout
        im = self.images[i]
        view = im.view
        n = lay.n
        rig, offset, pose_maps = at_x.rig_of(im.channel), at_x.offset, at_x.pose_maps
        medium, medium_columns = at_x.medium_of(im.channel), lay.medium_columns(im.channel)
        g = at_x.gains[i]
        N = len(im.observed)
        gain_column = lay.gains.start + i - 1 if lay.gains.stop > lay.gains.start and i > 0 else -1
        offset_column = -1 if lay.offset_index is None else lay.offset_index
        A, grad_buffer = self._buffers.system(
            N, n + 1, self._unwritten_columns(gain_column, offset_column, im.channel)
        )
        total = np.zeros(N)
        # d L_world / d t = R^T and delta_world = R^T delta_camera: rows (world) -> camera.
        R_t = view.R_camera_world.T
        to_camera = np.zeros((6, 6))
        to_camera[:3, :3] = R_t
        to_camera[3:, 3:] = R_t
        wall = at_x.wall
        wall_cols = lay.wall
        wall_idx = lay.wall_unknown.indices
        wall_grad = None
        if not wall.is_lambertian:
            wall_grad = np.empty((N, len(wall.parameter_names)))
        medium_idx = lay.medium_unknown.indices
        medium_grad = np.empty((N, max(medium_idx) + 1)) if medium_idx else None
        albedo_cols = lay.surface_albedo  # the surroundings' estimated albedos
        albedo_grad = np.empty((N, albedo_cols.stop - albedo_cols.start))
        c_grad = None  # the bounce's d/dc joins the medium's column of c when c is estimated
        if medium_grad is not None and "attenuation_per_m" in lay.medium_unknown.estimate:
            c_grad = medium_grad[:, 0]  # d flux / dc (`Medium.parameter_names`)
        for j, block in enumerate(lay.blocks):
            light = rig.lights[j]
            flux, grad_world = light_flux(
                im.footprints,
                view,
                light,
                rid_subsamples=self.options.rid_subsamples,
                want_grad=True,
                grad_out=grad_buffer,
                wall=wall,
                wall_grad_out=wall_grad,
                medium=medium,
                medium_grad_out=medium_grad,
            )
            assert grad_world is not None
            if self.bounce is not None:
                albedo_grad[:] = 0.0
                albedos = at_x.surface_albedos
                self.bounce.add(
                    i, view, light, flux, grad_world, medium, c_grad, albedos, albedo_grad
                )
                A[:, albedo_cols] += g * light.scale * albedo_grad
            if fluxes is not None:
                fluxes.append(flux)
            value_per_flux = g * light.scale
            sk.add_light_columns(
                A,
                total,
                grad_world,
                flux,
                value_per_flux * (to_camera @ pose_maps[j]),
                block.pose.start,
                block.log_scale_of(im.channel),
                value_per_flux if abs(x[block.log_scale_of(im.channel)]) < LOG_CLIP else 0.0,
                light.scale,
            )
            if block.rid.stop > block.rid.start:
                A[:, block.rid] = rid_columns(lay, im, x, j, g, self.options.rid_subsamples)
            if wall_grad is not None and wall_idx:
                A[:, wall_cols] += value_per_flux * wall_grad[:, wall_idx]
            if medium_grad is not None:
                A[:, medium_columns] += value_per_flux * medium_grad[:, medium_idx]
        lay.apply_sensor_terms(A, total, im, x, g, fluxes)  # room light, V: when estimated
        stats = sk.finish_rows(
            A,
            total,
            im.footprints.valid,
            im.observed,
            self.sigmas[i],
            g,
            offset,
            gain_column,
            offset_column,
        )
        return A, stats

    def _unwritten_columns(
        self, gain_column: int, offset_column: int, channel: int = 0
    ) -> list[int]:
        """The columns of an image's [J r] that `_image_system` does not assign (zeroed
        first): other images' gains, other channels' scales, the wall's and the medium's
        (which it adds to)."""
        lay = self.layout
        written = {lay.n, gain_column, offset_column}
        for block in lay.blocks:
            written.update(range(block.pose.start, block.pose.stop))
            written.update(range(block.rid.start, block.rid.stop))
            written.add(block.log_scale_of(channel))
        return [c for c in range(lay.n + 1) if c not in written]

    @property
    def reweights(self) -> bool:
        """Whether `run_least_squares` re-weights from the rendered values and solves again."""
        return self.options.reweight and any(im.noise is not None for im in self.images)

    def set_weights_at(self, x: np.ndarray | None) -> None:
        """Pixel sigmas from the data (None) or from the values rendered at x: an image
        with a noise model (gain, read_variance) gets sigma = sqrt(gain * max(v - offset,
        0) + read_variance) of its rendered values v (room light, fall-off, albedo in);
        images without one keep their sigmas."""
        sigmas = [im.sigma for im in self.images]
        if x is not None:
            lay = self.layout
            gains = lay.gain_factors(x)
            albedo_map = self.albedo_map(x)
            for i, im in enumerate(self.images):
                if im.noise is None:
                    continue
                signal = rendered_signal(self, x, i, gains[i], albedo_map)
                sigma = poisson_gaussian_sigma(signal, im.noise)
                sigmas[i] = np.where(np.isfinite(sigma), sigma, im.sigma)
        self.sigmas = sigmas
        self.weights_at = None if x is None else np.array(x, dtype=np.float64)
        self._cache_x = self._cache_J_x = None
        self._recent.clear()

    def per_image_rms(self, x: np.ndarray) -> np.ndarray:
        """(n_images,) RMS of m_obs - m_render per image (pixel value units)."""
        r = self.residuals(x)
        out = np.empty(len(self.images))
        for i in range(len(self.images)):
            d = r[self.bounds[i] : self.bounds[i + 1]] * self.sigmas[i]
            out[i] = float(np.sqrt(np.mean(d * d))) if d.size else float("nan")
        return out

    def report(self, x: np.ndarray, iteration: int) -> IterationReport:
        """The iteration's numbers at x; from a recent compressed evaluation when there is
        one (|r~| = |r|, J~^T r~ = J^T r), else from the residuals and gradient at x."""
        recent = self._recent_at(x)
        if recent is None and self.compressed:
            # The start (iteration 0) is reported before trf evaluates it: evaluate it
            # now (trf then reuses it), and read the numbers off its compressed system.
            self.residuals(x)
            recent = self._recent_at(x)
        if recent is None:
            r = self.residuals(x)
            cost = robust_cost(r, self.options.loss, self.options.f_scale)
            gradient, rms = self.gradient(x), self.per_image_rms(x)
        else:  # compressed: the linear loss
            _, R, rms = recent
            cost, gradient = 0.5 * float(R[:, -1] @ R[:, -1]), R[:, :-1].T @ R[:, -1]
        return IterationReport(
            iteration,
            x.copy(),
            cost,
            float(np.abs(gradient).max()),
            rms.copy(),
            self.nfev,
            self.weights_at is not None,
        )

    # -- bounds -------------------------------------------------------------------------

    def parameter_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Box bounds that keep every light in front of the wall in every view
        (`lightcal.core.light_bounds`)."""
        return parameter_bounds(self.layout, self.images, self.options.position_bound_m)
