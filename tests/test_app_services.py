"""The app's services and worker without a browser or a viser server.

`SolveService` and `FilesService` are driven directly on an `AppState`, with a list for
the page's messages; the worker thread with a redraw that only records frames. Nothing
here imports viser.
"""

from __future__ import annotations

import math
import sys
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from lightcal_app import requests as rq
from lightcal_app.files_service import FilesService
from lightcal_app.solve_service import SolveService
from lightcal_app.state import AppState, Frame, LightGuess, SelectionSettings, UserRegion
from lightcal_app.worker import Worker

from lightcal.core.pose import axis_roll_from_rotation, rotation_from_axis, rotation_from_axis_roll
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.io.project import load_project
from lightcal.pipeline import build_model, image_data, load_images
from tests.app_fixtures import TRUE_POSITION_M, SyntheticProject, make_project, run_requests


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory: pytest.TempPathFactory) -> SyntheticProject:
    return make_project(tmp_path_factory.mktemp("svc"), n_views=4, width=96, height=72)


class Messages:
    """A `notify` that keeps what the page would show."""

    def __init__(self) -> None:
        self.items: list[tuple[Any, str, str, bool]] = []

    def __call__(self, client: Any, title: str, body: str, *, error: bool = False) -> None:
        self.items.append((client, title, body, error))

    def titles(self) -> list[str]:
        return [t for _, t, _, _ in self.items]


def _state(synthetic: SyntheticProject) -> AppState:
    project = load_project(synthetic.path)
    return AppState(project, load_images(project))


def _service(synthetic: SyntheticProject) -> tuple[AppState, SolveService, Messages]:
    state = _state(synthetic)
    messages = Messages()
    # Nobody draws here: the solver must not wait for a redraw.
    solve = SolveService(state, notify=messages, follow_iterations=False)
    solve.setup_changed()
    return state, solve, messages


def test_the_services_import_no_viser() -> None:
    code = (
        "import sys; import lightcal_app.solve_service, lightcal_app.files_service, "
        "lightcal_app.worker, lightcal_app.actions, lightcal_app.requests, "
        "lightcal_app.plan_service; "
        "print('viser' in sys.modules)"
    )
    import subprocess

    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, env=None
    )
    assert out.stdout.strip() == "False"


def test_selection_matches_the_pipeline_and_the_model_uses_its_lights(
    synthetic: SyntheticProject,
) -> None:
    state, solve, messages = _service(synthetic)
    for i in range(len(state.project.names)):
        expected = image_data(state.project, state.loaded, i).footprints.pixels
        np.testing.assert_array_equal(state.selected[i], expected)
    assert state.display is not None and state.display.source == "guess"
    assert solve.ensure_session()
    assert solve.model is not None
    # With the project's guess, the model starts where `build_model` starts.
    reference = build_model(state.project, state.loaded)
    np.testing.assert_allclose(solve.model.layout.x0, reference.layout.x0)
    assert messages.items == []


def test_step_records_an_iteration_and_an_interim_result(synthetic: SyntheticProject) -> None:
    state, solve, _ = _service(synthetic)
    solve.start("step")
    run_requests(solve, state)
    assert [h.iteration for h in state.history] == [0, 1]
    assert state.solver_state == "paused"
    assert state.result is not None and "paused after iteration 1" in state.result.message
    assert state.display is not None and state.display.source == "estimate"


def test_run_finds_the_true_light_then_reset_returns_to_the_guess(
    synthetic: SyntheticProject,
) -> None:
    state, solve, messages = _service(synthetic)
    solve.start("run")
    run_requests(solve, state, timeout=120.0)
    assert state.solver_state == "converged"
    assert state.result is not None and state.result.converged
    np.testing.assert_allclose(
        state.result.lights[0].pose.t_camera_light, TRUE_POSITION_M, atol=5e-4
    )
    solve.start("step")  # after the end: a message, no second solve
    assert messages.titles()[-1] == "The solve has ended"
    solve.reset()
    assert state.history == [] and state.result is None and state.solver_state == "idle"
    assert state.display is not None and state.display.source == "guess"


def test_the_guess_and_the_selection_reach_the_model(synthetic: SyntheticProject) -> None:
    state, solve, _ = _service(synthetic)
    with state.lock:
        state.guess = [LightGuess(np.array([0.08, 0.0, 0.0]), np.eye(3))]
        state.selection = SelectionSettings("grid", 60, 24, 1, 0)
        state.regions = [
            UserRegion("rect", ((0.0, 0.0), (40.0, 30.0)), False, state.project.names[0])
        ]
        state.selection_rev += 1
    solve.setup_changed()
    assert len(state.selected[0]) < len(state.selected[1])
    assert solve.ensure_session()
    assert solve.model is not None
    np.testing.assert_allclose(solve.model.layout.x0[:3], [0.08, 0.0, 0.0])


def test_no_pixels_is_a_message_not_a_solve(synthetic: SyntheticProject) -> None:
    state, solve, messages = _service(synthetic)
    with state.lock:
        state.regions = [UserRegion("rect", ((-1.0, -1.0), (200.0, 200.0)), False, None)]
        state.selection_rev += 1
    solve.setup_changed()
    solve.start("run")
    assert solve.session is None
    assert messages.items[-1][1:] == (
        "No pixels to fit",
        "No image has usable pixels: check the selection (Pixels tab) and the regions.",
        True,
    )


def _files(state: AppState, solve: SolveService, messages: Messages, tmp: Path) -> FilesService:
    """The files service of `state`, its session beside `tmp`, downloads dropped."""
    return FilesService(
        state,
        solve,
        notify=messages,
        deliver=lambda c, n, b: None,
        on_switch=lambda p, loaded, t: None,
        truth=None,
        session_path=tmp / "s.session.json",
        state_dir=tmp / "state",
    )


def test_session_restore_continues_the_solve(synthetic: SyntheticProject, tmp_path: Path) -> None:
    state, solve, messages = _service(synthetic)
    files = _files(state, solve, messages, tmp_path)
    solve.start("step")
    run_requests(solve, state)
    files.save_session(rq.SaveSession())
    assert state.downloads[-1].name == "project.saved-session.json"
    solve.reset()
    files.load_saved_session(rq.LoadSavedSession())
    assert [h.iteration for h in state.history] == [0, 1]
    assert state.solver_state == "paused"
    assert messages.titles()[-1] == "Session restored"
    solve.start("step")
    run_requests(solve, state)
    assert [h.iteration for h in state.history] == [0, 1, 2]


def _converged(synthetic: SyntheticProject, tmp: Path):
    """A service solved to convergence, with its files service."""
    state, solve, messages = _service(synthetic)
    files = _files(state, solve, messages, tmp)
    solve.start("run")
    run_requests(solve, state, timeout=120.0)
    assert state.solver_state == "converged" and state.result is not None
    return state, solve, messages, files


def test_a_reloaded_converged_session_is_still_converged(
    synthetic: SyntheticProject, tmp_path: Path
) -> None:
    """Saved after convergence and reloaded in a fresh app: the same status, reason,
    solver time and estimate with its uncertainties, not "paused"; Step says it ended."""
    state, _, _, files = _converged(synthetic, tmp_path)
    before = state.result
    message = state.solver_message
    files.save_session(rq.SaveSession())

    state2, solve2, messages2 = _service(synthetic)
    files2 = _files(state2, solve2, messages2, tmp_path)
    files2.load_saved_session(rq.LoadSavedSession())
    assert state2.solver_state == "converged"
    assert state2.solver_message == message
    after = state2.result
    assert after is not None and after.converged
    assert after.status == before.status and after.message == before.message
    assert after.time_s == before.time_s  # the solver's time, not the reload's
    assert after.iterations == before.iterations
    np.testing.assert_allclose(after.x, before.x, rtol=0, atol=0)
    np.testing.assert_allclose(
        after.lights[0].sigma.t_camera_light, before.lights[0].sigma.t_camera_light, rtol=1e-9
    )
    solve2.start("step")
    assert messages2.titles()[-1] == "The solve has ended"


def test_an_edit_after_a_solve_keeps_the_result_and_undo_brings_it_back(
    synthetic: SyntheticProject, tmp_path: Path
) -> None:
    """A converged result is not lost when the user edits the guess: it becomes the
    previous result (shown, with its settings), and Restore brings back result, status,
    guess and selection; the draft that had not finished is not kept in turn."""
    state, solve, messages, files = _converged(synthetic, tmp_path)
    solved = state.result
    guess_before = state.guess[0].t_camera_light.copy()
    selection_before = state.selection
    # The user types a new position: a new draft starts from it.
    with state.lock:
        state.guess = [LightGuess(np.array([0.05, 0.01, 0.0]), state.guess[0].R_camera_light)]
        state.selection = SelectionSettings("grid", 60, 16, 1, 0)
        state.selection_rev += 1
    solve.setup_changed()
    assert state.solver_state == "idle" and state.result is None
    assert state.previous is not None and state.previous.result is solved
    assert state.previous.state == "converged"
    # Undo.
    files.restore_previous(rq.RestorePrevious())
    assert messages.titles()[-1] == "Previous result restored"
    assert state.solver_state == "converged"
    assert state.result is not None
    np.testing.assert_array_equal(state.result.x, solved.x)
    np.testing.assert_array_equal(state.guess[0].t_camera_light, guess_before)
    assert state.selection == selection_before  # the settings it was solved with
    assert state.previous is None  # the unfinished draft is not kept
    # A reset keeps a finished result too; nothing left after a second undo.
    solve.reset()
    assert state.previous is not None and state.previous.state == "converged"
    files.restore_previous(rq.RestorePrevious())
    files.restore_previous(rq.RestorePrevious())
    assert messages.titles()[-1] == "Nothing to restore"


def test_run_keeps_each_iteration_on_the_page_for_the_chosen_pace(
    synthetic: SyntheticProject,
) -> None:
    """With a page following (a stand-in drawer here), Run leaves at least
    `min_iteration_s` between iterations; the solver's time excludes those waits."""
    import time

    state = _state(synthetic)
    solve = SolveService(state, notify=Messages(), follow_iterations=True)
    solve.setup_changed()
    state.min_iteration_s = 0.3
    shown: dict[int, float] = {}
    stop = threading.Event()

    def drawer() -> None:  # what the redraw does: mark the newest iteration drawn
        while not stop.is_set():
            with state.cond:
                if state.history:
                    it = state.history[-1].iteration
                    shown.setdefault(it, time.monotonic())
                    state.drawn = (state.session_gen, it)
                    state.cond.notify_all()
            stop.wait(0.005)

    thread = threading.Thread(target=drawer, daemon=True)
    thread.start()
    start = time.monotonic()
    try:
        solve.start("run")
        run_requests(solve, state, timeout=120.0)
    finally:
        stop.set()
        thread.join()
    wall = time.monotonic() - start
    assert state.solver_state == "converged" and state.result is not None
    iterations = sorted(shown)
    assert len(iterations) >= 3
    gaps = np.diff([shown[i] for i in iterations])
    assert gaps.min() >= 0.3 - 0.01  # never faster than the pace (slower is allowed)
    assert state.result.time_s <= wall - 0.3 * (len(iterations) - 2)


def test_the_pace_is_bounded_and_must_be_a_number(synthetic: SyntheticProject) -> None:
    from lightcal_app.actions import Actions

    from lightcal.errors import InputError

    state = _state(synthetic)
    actions = Actions(state, planes=lambda: [], notify=Messages())
    actions.set_pace(99.0)
    assert state.min_iteration_s == 5.0
    actions.set_pace(-1.0)
    assert state.min_iteration_s == 0.0
    with pytest.raises(InputError, match="seconds per iteration: expected a number, got nan"):
        actions.set_pace(float("nan"))


def test_only_run_is_paced_a_step_shows_at_once(synthetic: SyntheticProject) -> None:
    from lightcal_app.solve_display import pace_wait_s

    assert pace_wait_s(True, 0.5, 0.2) == pytest.approx(0.3)
    assert pace_wait_s(True, 0.5, 0.7) == 0.0
    assert pace_wait_s(True, 99.0, 0.0) == 5.0  # at most MAX_ITERATION_S
    assert pace_wait_s(False, 0.5, 0.0) == 0.0  # Step: no wait
    # The session says which: steps are a budget, Run is unlimited.
    state, solve, _ = _service(synthetic)
    solve.start("step")
    assert solve.session is not None and not solve.session.unlimited
    run_requests(solve, state)
    solve.start("run")
    assert solve.session.unlimited
    run_requests(solve, state, timeout=120.0)


def test_worker_dispatches_by_type_and_merges_setup_changes(synthetic: SyntheticProject) -> None:
    state = _state(synthetic)
    handled: list[rq.Request] = []
    frames: list[Frame] = []
    messages = Messages()
    worker = Worker(
        state,
        handlers={rq.SetupChanged: handled.append, rq.Solve: handled.append},
        redraw=frames.append,
        notify=messages,
    )
    with state.lock:
        state.request(rq.SetupChanged())
        state.request(rq.Solve(client="browser-1"))
        state.request(rq.SetupChanged())
    worker.start()
    try:
        assert worker.wait_idle(10)
        assert [type(r) for r in handled] == [rq.SetupChanged, rq.Solve]
        assert frames and frames[0].dirty  # the first round draws everything
        state.request(rq.Pause())  # no handler: an internal error, shown once
        assert worker.wait_idle(10)
        assert messages.titles() == ["Internal error"]
    finally:
        worker.stop()


def test_worker_says_what_it_does_while_it_does_it(synthetic: SyntheticProject) -> None:
    """The busy line names the work before it runs (a slow report, a reselection, the
    pictures) and is cleared when the worker is idle."""
    state = _state(synthetic)
    shown: list[str] = []
    seen_during: list[str] = []

    def slow(request: rq.Request) -> None:
        seen_during.append(shown[-1])  # what the page said while this ran

    worker = Worker(
        state,
        handlers={rq.SetupChanged: slow, rq.PrepareDownload: slow},
        redraw=lambda frame: None,
        notify=Messages(),
        show_work=shown.append,
    )
    worker.start()
    try:
        assert worker.wait_idle(10)
        assert shown == ["drawing the pictures", ""]  # the first round draws everything
        state.request(rq.PrepareDownload("report"))
        assert worker.wait_idle(10)
        assert seen_during == ["building the report (every image rendered)"]
        with state.lock:
            state.request(rq.SetupChanged())
            state.mark("overlays")
        assert worker.wait_idle(10)
        assert seen_during[-1] == "selecting the pixels for the new setup; drawing the pictures"
        assert shown[-1] == ""
    finally:
        worker.stop()
    assert rq.work_of(rq.PrepareDownload("result")) == "preparing the result download"


def test_worker_shows_a_repeated_error_once(synthetic: SyntheticProject) -> None:
    state = _state(synthetic)
    messages = Messages()

    def broken_redraw(frame: Frame) -> None:
        raise RuntimeError("cannot draw")

    def notify(client: Any, title: str, body: str, *, error: bool = False) -> None:
        messages(client, title, body, error=error)
        state.mark("status")  # as the page's notify does: this asks for a redraw

    worker = Worker(state, handlers={}, redraw=broken_redraw, notify=notify)
    worker.start()
    try:
        threading.Event().wait(0.5)
    finally:
        worker.stop()
    assert messages.titles() == ["Internal error"]


def test_pose_angles_in_core_round_trip() -> None:
    R = matrix_from_rotvec(np.array([0.3, -0.2, 0.4]))
    np.testing.assert_allclose(rotation_from_axis_roll(*axis_roll_from_rotation(R)), R, atol=1e-12)
    R = rotation_from_axis(np.array([0.0, math.sin(0.2), math.cos(0.2)]))
    assert axis_roll_from_rotation(R) == pytest.approx((0.0, 0.2, 0.0), abs=1e-12)
    with pytest.raises(ValueError, match="roll_rad"):
        rotation_from_axis_roll(0.0, 0.0, math.nan)
