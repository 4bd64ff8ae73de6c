"""The Plan tab's service without a browser: the live read-out and the suggested views are
`lightcal plan`'s numbers for the estimate the page shows, and say when they are stale."""

from __future__ import annotations

import math

import numpy as np
import pytest
from lightcal_app.limits import check_plan
from lightcal_app.panels.plan import plan_markdown, readout_markdown
from lightcal_app.plan_service import PlanService
from lightcal_app.requests import PlanViews
from lightcal_app.state import AppState

from lightcal.errors import InputError
from lightcal.pipeline import build_model, measurements_for
from lightcal.pipeline.plan import (
    InformationState,
    PlanGrid,
    noise_variance,
    plan_views,
    residual_noise_scale2,
)
from tests.app_fixtures import SyntheticProject, run_requests
from tests.test_app_services import (  # noqa: F401  (the fixture is used by name)
    Messages,
    _service,
    synthetic,
)


def _plan_service(project: SyntheticProject) -> tuple[AppState, PlanService, list[str]]:
    state, solve, messages = _service(project)
    said: list[str] = []
    return state, PlanService(state, solve, notify=messages, say=said.append), said


def _expected_before_a_solve(state: AppState) -> tuple[object, np.ndarray, float]:
    """The pipeline's model, start and s^2 (what `lightcal plan` without --result uses)."""
    model = build_model(state.project, state.loaded)
    s2 = noise_variance(model, measurements_for(state.project, state.loaded, model).noise)
    if s2 is None:
        s2 = residual_noise_scale2(model, model.layout.x0)
    return model, model.layout.x0, s2


def test_readout_before_a_solve_is_lightcal_plans_sigmas(
    synthetic: SyntheticProject,  # noqa: F811
) -> None:
    state, plan, _ = _plan_service(synthetic)
    plan.refresh()
    readout = state.readout
    assert readout is not None
    assert readout.where == "the initial guess (scales fitted)"
    assert readout.key == state.estimate_key()
    model, x0, s2 = _expected_before_a_solve(state)
    expected = InformationState(model, x0, s2).sigmas()  # type: ignore[arg-type]
    np.testing.assert_allclose(readout.sigmas.position_m, expected.position_m, rtol=1e-9)
    np.testing.assert_allclose(readout.sigmas.axis_deg, expected.axis_deg, rtol=1e-9)
    assert 0 < readout.sigmas.position_m[0] < 0.05  # metres: a fraction of the distances
    text = readout_markdown(readout, state.estimate_key())
    assert f"position ± {1e3 * expected.position_m[0]:.3g} mm" in text
    assert "updating" not in text


def test_suggested_views_shrink_the_uncertainty_and_go_stale_on_an_edit(
    synthetic: SyntheticProject,  # noqa: F811
) -> None:
    state, plan, said = _plan_service(synthetic)
    plan.plan(PlanViews(2))
    shown = state.plan
    assert shown is not None and len(shown.views) == 2
    first, second = shown.views
    assert first.after.log_det < first.before.log_det
    assert second.before == first.after  # greedy: each added before the next
    assert second.after.position_m[0] < first.before.position_m[0]
    # The same views as the pipeline's planner on the same model, start and noise.
    model, x0, s2 = _expected_before_a_solve(state)
    _, expected = plan_views(model, x0, state.loaded.camera, n=2, grid=PlanGrid(), noise_scale2=s2)  # type: ignore[arg-type]
    assert [pv.candidate.instruction() for pv in shown.views] == [
        pv.candidate.instruction() for pv in expected
    ]
    np.testing.assert_allclose(
        [pv.after.position_m[0] for pv in shown.views],
        [pv.after.position_m[0] for pv in expected],
        rtol=1e-9,
    )
    assert any(line.startswith("planning the next views: rendering candidates") for line in said)
    key = state.estimate_key()
    text = plan_markdown(shown, key)
    assert "Stale" not in text and expected[0].candidate.instruction().split(",")[0] in text
    # An edit of the guess: the plan is kept but marked stale; the read-out follows.
    plan.solve.state.setup_changed(selection=False)
    plan.solve.setup_changed()
    assert state.estimate_key() != key
    assert "**Stale**" in plan_markdown(state.plan, state.estimate_key())
    plan.refresh()
    assert state.readout is not None and state.readout.key == state.estimate_key()


def test_readout_follows_the_solve_to_its_result(synthetic: SyntheticProject) -> None:  # noqa: F811
    state, plan, _ = _plan_service(synthetic)
    plan.refresh()
    assert state.readout is not None
    guess_sigma = state.readout.sigmas.position_m[0]
    plan.solve.start("step")
    run_requests(plan.solve, state)
    plan.refresh()
    assert state.readout is not None and state.readout.where == "iteration 1"
    plan.solve.start("run")
    run_requests(plan.solve, state, timeout=120.0)
    assert state.solver_state == "converged"
    plan.refresh()
    readout = state.readout
    assert readout is not None and readout.where == "the converged result"
    assert readout.noise == "pixel noise from the solve's residuals"
    model = plan.solve.model
    assert model is not None
    x = state.history[-1].x
    expected = InformationState(model, x, residual_noise_scale2(model, x)).sigmas()
    assert readout.sigmas.position_m == pytest.approx(expected.position_m, rel=1e-9)
    assert math.isfinite(guess_sigma)


@pytest.mark.parametrize(
    ("n", "size", "message"),
    [
        (0, 3.0, "views to suggest: expected 1 to 6, got 0"),
        (7, 3.0, "views to suggest: expected 1 to 6, got 7"),
        (2.5, 3.0, "views to suggest: expected a whole number, got 2.5"),
        (True, 3.0, "views to suggest: expected a whole number, got True"),
        (3, float("nan"), "wall size (m): expected 0.2 to 100 m, got nan"),
        (3, 0.1, "wall size (m): expected 0.2 to 100 m, got 0.1"),
    ],
)
def test_plan_values_from_a_page_are_checked(n: object, size: float, message: str) -> None:
    with pytest.raises(InputError) as err:
        check_plan(n, size)
    assert str(err.value) == message
    assert check_plan(4.0, 2.5) == (4, 2.5)
