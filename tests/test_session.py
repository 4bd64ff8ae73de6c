"""SolverSession: step / run / pause / stop / reset of a solve in a worker thread."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from lightcal.core.scene import Rig
from lightcal.core.session import SolverSession
from lightcal.core.solver import CalibrationModel, IterationReport, SolveOutcome
from tests import calib_scenes as cs

TIMEOUT_S = 60.0


@pytest.fixture(scope="module")
def problem():
    light = cs.symmetric_light()
    images = cs.observe(
        cs.small_camera(),
        cs.views(8, seed=1),
        Rig.single(light),
        n_per_image=60,
        rng=np.random.default_rng(2),
        noise=(0.5, 4.0),
    )
    return light, images


@pytest.fixture
def model(problem) -> CalibrationModel:
    light, images = problem
    return cs.model_of(images, [cs.start_near(light, position_m=0.12, angle_deg=20.0)])


class Recorder:
    """Collects the session's callbacks."""

    def __init__(self) -> None:
        self.reports: list[IterationReport] = []
        self.finished: list[SolveOutcome] = []

    def on_iteration(self, rep: IterationReport) -> None:
        self.reports.append(rep)

    def on_finish(self, out: SolveOutcome) -> None:
        self.finished.append(out)


def _solver_threads() -> set[threading.Thread]:
    """The live worker threads of every session."""
    return {t for t in threading.enumerate() if t.name == "lightcal-solver" and t.is_alive()}


def _session(model, rec: Recorder) -> SolverSession:
    return SolverSession(model, on_iteration=rec.on_iteration, on_finish=rec.on_finish)


def test_a_new_session_is_idle(model):
    s = SolverSession(model)
    assert s.state == "idle"
    assert s.latest is None and s.outcome is None and s.error is None
    np.testing.assert_array_equal(s.x, model.layout.x0)


def test_step_lets_one_iteration_through(model):
    rec = Recorder()
    s = _session(model, rec)
    s.step()
    assert s.wait(TIMEOUT_S)
    assert s.state == "paused"
    assert [r.iteration for r in s.history] == [0, 1]
    s.step()
    assert s.wait(TIMEOUT_S)
    assert [r.iteration for r in s.history] == [0, 1, 2]
    assert rec.reports == s.history
    assert s.latest is s.history[-1]
    np.testing.assert_array_equal(s.x, s.history[-1].x)
    assert rec.finished == []
    # Each report carries the state the app shows.
    rep = s.history[-1]
    assert rep.x.shape == (model.layout.n,)
    assert rep.per_image_rms.shape == (len(model.images),)
    assert rep.cost < s.history[0].cost
    assert rep.gradient_norm > 0.0
    s.stop()
    assert s.state == "stopped"


def test_run_to_convergence(model):
    rec = Recorder()
    s = _session(model, rec)
    s.run()
    assert s.wait(TIMEOUT_S)
    assert s.state == "finished"
    assert s.outcome is not None and s.outcome.success
    assert rec.finished == [s.outcome]
    assert rec.reports == s.history
    assert [r.iteration for r in s.history] == list(range(len(s.history)))
    assert len(s.history) >= 5
    np.testing.assert_array_equal(s.outcome.x, s.history[-1].x)
    # Controls after the end change nothing.
    s.step()
    s.run()
    assert s.state == "finished"
    assert len(rec.finished) == 1


def test_pause_from_the_callback_holds_after_that_iteration(model):
    holder: list[SolverSession] = []

    def on_iteration(rep: IterationReport) -> None:
        if rep.iteration == 2:
            holder[0].pause()

    s = SolverSession(model, on_iteration=on_iteration)
    holder.append(s)
    s.run()
    assert s.wait(TIMEOUT_S)
    assert s.state == "paused"
    assert s.latest is not None and s.latest.iteration == 2
    time.sleep(0.2)
    assert s.latest.iteration == 2  # really held
    s.run()
    assert s.wait(TIMEOUT_S)
    assert s.state == "finished"
    assert s.outcome is not None and s.outcome.success


def test_stop_keeps_the_estimate_so_far(model):
    before = _solver_threads()
    rec = Recorder()
    s = _session(model, rec)
    s.step()
    s.wait(TIMEOUT_S)
    s.step()
    s.wait(TIMEOUT_S)
    s.stop()
    assert s.state == "stopped"
    assert s.outcome is not None
    assert s.outcome.status == -2 and not s.outcome.success
    np.testing.assert_array_equal(s.outcome.x, s.history[-1].x)
    assert s.history[-1].iteration == 2
    assert rec.finished == [s.outcome]
    s.run()
    s.step()
    assert s.state == "stopped"
    assert _solver_threads() <= before  # stop() joined the worker


def test_reset_returns_to_the_initial_guess(model):
    rec = Recorder()
    s = _session(model, rec)
    s.step()
    s.wait(TIMEOUT_S)
    s.reset()
    assert s.state == "idle"
    assert s.history == [] and s.outcome is None and s.error is None
    np.testing.assert_array_equal(s.x, model.layout.x0)
    s.run()
    assert s.wait(TIMEOUT_S)
    assert s.state == "finished"
    np.testing.assert_array_equal(s.history[0].x, model.layout.x0)


def test_reset_to_another_start(model, problem):
    light, _ = problem
    s = SolverSession(model)
    x_new = model.layout.x0.copy()
    x_new[:3] = light.t_camera_light + 0.01
    s.reset(x_new)
    np.testing.assert_array_equal(s.x, x_new)
    s.run()
    assert s.wait(TIMEOUT_S)
    np.testing.assert_array_equal(s.history[0].x, x_new)
    assert s.state == "finished"


def test_reset_while_running(model):
    before = _solver_threads()
    s = SolverSession(model)
    s.run()
    s.reset()
    assert s.state == "idle" and s.history == []
    assert _solver_threads() <= before


def test_one_worker_at_a_time(model):
    before = _solver_threads()
    s = SolverSession(model)
    s.step()
    s.step()
    s.run()
    assert len(_solver_threads() - before) <= 1
    assert s.wait(TIMEOUT_S)
    assert s.state == "finished"


def test_a_failing_callback_fails_the_session(model):
    def boom(rep: IterationReport) -> None:
        if rep.iteration == 1:
            raise RuntimeError("viewer went away")

    s = SolverSession(model, on_iteration=boom)
    s.run()
    assert s.wait(TIMEOUT_S)
    assert s.state == "failed"
    assert isinstance(s.error, RuntimeError)
    assert str(s.error) == "viewer went away"


def test_max_iterations_finishes_the_session(problem):
    light, images = problem
    model = cs.model_of(images, [cs.start_near(light, position_m=0.12)], max_iterations=2)
    s = SolverSession(model)
    s.run()
    assert s.wait(TIMEOUT_S)
    assert s.state == "finished"
    assert s.outcome is not None
    assert s.outcome.status == 0 and s.outcome.iterations == 2


def test_wait_after_pause_returns_when_the_worker_holds(model):
    entered = threading.Event()
    release = threading.Event()
    calls = [0]
    jacobian = model.solver_jacobian

    def slow_jacobian(x: np.ndarray) -> np.ndarray:
        calls[0] += 1
        if calls[0] == 3:  # the first new point after the start: inside iteration 1
            entered.set()
            release.wait(TIMEOUT_S)
        return jacobian(x)

    model.solver_jacobian = slow_jacobian
    s = SolverSession(model)
    try:
        s.run()
        assert entered.wait(TIMEOUT_S)
        s.pause()
        threading.Timer(0.3, release.set).start()
        assert s.wait(TIMEOUT_S)
        seen = len(s.history)
        release.set()
        time.sleep(0.5)
        assert len(s.history) == seen
    finally:
        release.set()
        s.stop()


def test_time_counts_the_solver_not_its_callbacks(model, monkeypatch) -> None:
    """A clock that the callback moves by 100 s per iteration (as a paused app waits in
    it): time_s stays the solver's own."""
    import lightcal.core.solver as solver_module
    from lightcal.core.solver import run_least_squares

    now = [0.0]

    def fake_clock() -> float:
        now[0] += 1e-3  # every reading: 1 ms of solver work
        return now[0]

    monkeypatch.setattr(solver_module.time, "perf_counter", fake_clock)
    calls = []

    def waiting(rep: IterationReport) -> None:
        calls.append(rep.iteration)
        now[0] += 100.0

    out = run_least_squares(model, on_iteration=waiting)
    assert len(calls) >= 2
    # Without the callbacks' 100 s each (a few ms of clock readings remain).
    assert out.time_s < 1.0
