"""Capture planning behind the Plan tab, without a browser: the next views, a live read-out.

`PlanService` answers the Plan tab with `lightcal.pipeline.plan`, the criterion and the
candidate grid of `lightcal plan` (docs/model.md, "Planning the next views"):

- `plan` (a `PlanViews` request, worker thread): the n best next camera poses for the
  estimate shown (the solve's last iteration, else the guess with its scales fitted), with
  the sigmas before and after each; the candidates' rendering reports to the busy line.
- `refresh` (worker thread, after every round): the read-out, the light's 1-sigma
  position and axis uncertainty at the estimate shown, from the solver's Jacobian there,
  recomputed whenever the guess, the selection or the iteration changes.

s^2, the pixel noise that scales N^-1: the images' noise model (the sensor's, else
estimated from each image) while no solve has ended, as `lightcal plan` before a solve;
once a solve has ended, from its residuals, as `lightcal plan --result`; without a noise
model, from the residuals at the estimate (before a solve, the guess's misfit: said so).
These sigmas count the pixel noise only; the Result tab's uncertainty adds the camera
poses' own.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

import numpy as np

from lightcal.core.solver import CalibrationModel
from lightcal.errors import InputError
from lightcal.pipeline import measurements_for
from lightcal.pipeline.plan import (
    InformationState,
    PlanGrid,
    noise_variance,
    plan_views,
    residual_noise_scale2,
)
from lightcal_app.requests import PlanViews
from lightcal_app.solve_service import SolveService
from lightcal_app.state import AppState, EstimateKey, PlanShown, Readout

log = logging.getLogger("lightcal.app")

READOUT_MAX_ROWS = 200_000
"""Above this many selected pixels the read-out waits for the solve (building a model
of a dense selection only for it would cost seconds at every change)."""
PROGRESS_EVERY_S = 0.25
"""The busy line's refresh while the candidates render."""

Notify = Callable[..., None]
"""`notify(client, title, body, *, error=False)`: a message in the page."""

_NOISE_WORDS = {
    "model": "pixel noise from the sensor's noise model",
    "image": "pixel noise estimated from each image",
    "residuals": "pixel noise from the solve's residuals",
    "misfit": "no noise model: scaled by the residuals at the estimate (before a solve, "
    "the guess's misfit, not noise)",
}


class PlanService:
    """The Plan tab's computations on the state's project.

    Args:
        state: the shared state.
        solve: the solve (its model and selection).
        notify: shows a message in the page.
        say: shows a line in the page's busy line (progress of the plan).
    """

    def __init__(
        self,
        state: AppState,
        solve: SolveService,
        *,
        notify: Notify,
        say: Callable[[str], None] = lambda text: None,
    ) -> None:
        self.state = state
        self.solve = solve
        self.notify = notify
        self.say = say
        self._readout_key: tuple[object, EstimateKey] | None = None
        self._noise_key: tuple[object, int] | None = None
        self._noise: tuple[list[tuple[float, float] | None], str] = ([], "none")

    # ------------------------------------------------------------------ the estimate

    def _estimate(self, *, build: bool) -> tuple[CalibrationModel, np.ndarray, str] | None:
        """The model, the estimate shown and its name in words; None when there is no
        model (and `build` is False, or no image has pixels)."""
        st = self.state
        with st.lock:
            model = self.solve.model
            history = list(st.history)
            state = st.solver_state
        if model is not None and history and len(history[-1].x) == model.layout.n:
            x = np.asarray(history[-1].x, dtype=np.float64)
            if state in ("converged", "not converged"):
                return model, x, f"the {state} result"
            return model, x, f"iteration {history[-1].iteration}"
        if model is None:
            if not build:
                return None
            built = self.solve.build_model()
            if built is None:
                return None
            model = built[0]
        return model, model.layout.x0.copy(), "the initial guess (scales fitted)"

    def _noise_scale2(self, model: CalibrationModel, x: np.ndarray) -> tuple[float, str]:
        """s^2 and its source in words (see the module docstring)."""
        st = self.state
        with st.lock:
            project, loaded = st.project, st.loaded
            ended = st.solver_state in ("converged", "not converged")
            key = (project, st.selection_rev)
        if ended:
            return residual_noise_scale2(model, x), _NOISE_WORDS["residuals"]
        if self._noise_key != key or len(self._noise[0]) != len(model.images):
            meas = measurements_for(project, loaded, model)
            self._noise = (list(meas.noise), meas.noise_source)
            self._noise_key = key
        noise, source = self._noise
        s2 = noise_variance(model, noise)
        if s2 is None:
            return residual_noise_scale2(model, x), _NOISE_WORDS["misfit"]
        return s2, _NOISE_WORDS[source]

    def _readout(
        self, model: CalibrationModel, x: np.ndarray, where: str, key: EstimateKey
    ) -> tuple[Readout, float]:
        """The read-out at x, and the s^2 it used."""
        s2, noise = self._noise_scale2(model, x)
        sigmas = InformationState(model, x, s2).sigmas()
        names = tuple(u.initial.name for u in model.unknowns)
        return Readout(sigmas, names, where, noise, key), s2

    # ------------------------------------------------------------------ requests

    def refresh(self) -> None:
        """Recompute the read-out when the estimate shown changed (after every round)."""
        st = self.state
        with st.lock:
            key = st.estimate_key()
            project = st.project
            running = st.solver_state == "running"
            rows = sum(len(s) for s in st.selected)
        if (project, key) == self._readout_key:
            return
        if rows > READOUT_MAX_ROWS and (running or self.solve.model is None):
            readout = None  # waits for the solve to pause or end
        else:
            est = self._estimate(build=True)
            if est is None:
                readout = None
            else:
                model, x, where = est
                readout = self._readout(model, x, where, key)[0]
        with st.lock:
            if st.project is not project or st.estimate_key() != key:
                return  # moved on meanwhile: the next round computes it
            self._readout_key = (project, key)
            st.readout = readout
            st.mark("plan")

    def plan(self, request: PlanViews) -> None:
        """The `request.n` best next views for the estimate shown."""
        st = self.state
        with st.lock:
            key = st.estimate_key()
            project, camera = st.project, st.loaded.camera
        est = self._estimate(build=True)
        if est is None:
            raise InputError("plan", "no image has usable pixels: check the Pixels tab")
        model, x, where = est
        now, s2 = self._readout(model, x, where, key)
        last = [0.0]

        def progress(what: str, done: int, total: int) -> None:
            t = time.monotonic()
            if done == total or t - last[0] >= PROGRESS_EVERY_S:
                last[0] = t
                self.say(f"planning the next views: {what} {done} of {total}")

        grid = PlanGrid(wall_size_m=request.wall_size_m)
        t0 = time.perf_counter()
        _, planned = plan_views(
            model,
            x,
            camera,
            n=request.n,
            grid=grid,
            noise_scale2=s2,
            progress=progress,
            mesh=project.wall_mesh,
            port=project.camera_port,
        )
        log.info("planned %d views in %.2f s", len(planned), time.perf_counter() - t0)
        with st.lock:
            if st.project is not project:
                return
            st.plan = PlanShown(now, tuple(planned))
            st.show_plan = True
            st.mark("plan")
        if len(planned) < request.n:
            self.notify(
                request.client,
                "Fewer views than asked",
                f"only {len(planned)} candidate views see the lit wall within "
                f"{request.wall_size_m:g} m; a larger wall size allows more",
            )
