"""The Solve tab's room light and fall-off (`sensor.estimate_ambient`,
`sensor.estimate_fall_off`): the page solves what `lightcal calibrate` solves on the
file with those keys, refuses an order the project does not take by its key, and keeps
them in the session file (files from before them: off)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
from lightcal_app.actions import Actions
from lightcal_app.session_file import apply_session, session_from_state
from lightcal_app.solve_service import SolveService
from lightcal_app.solve_settings import FALL_OFF_ORDERS, settings_of
from lightcal_app.state import AppState

from lightcal.cli.main import main
from lightcal.errors import InputError
from lightcal.io.project import load_project
from lightcal.pipeline import load_images
from tests.app_fixtures import run_requests
from tests.test_one_engine import _cli, _same


@pytest.fixture(scope="module")
def lit(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small synth dataset with room light and undeclared vignetting."""
    folder = tmp_path_factory.mktemp("lit") / "data"
    argv = ["synth", str(folder), "--views", "6", "--width", "160", "--height", "120"]
    flags = ["--ambient", "0.05", "--undeclared-vignetting", "-0.25", "0.05"]
    assert main([*argv, *flags, "--seed", "3", "--quiet"]) == 0
    return folder / "project.json"


def _quiet(*args: object, **kwargs: object) -> None:
    del args, kwargs


def test_the_solve_tab_settings_give_the_cli_answer_of_the_edited_file(lit: Path) -> None:
    data = json.loads(lit.read_text())
    data["sensor"] = {
        **data["sensor"],
        "estimate_ambient": True,
        "estimate_fall_off": {"order": 2},
    }
    edited = lit.with_name("edited.json")
    edited.write_text(json.dumps(data))
    project = load_project(lit)
    state = AppState(project, load_images(project))
    solve = SolveService(state, notify=_quiet, follow_iterations=False)
    settings = dataclasses.replace(settings_of(project), estimate_ambient=True, estimate_fall_off=2)
    assert FALL_OFF_ORDERS[settings.estimate_fall_off] == "r^2, r^4"
    Actions(state, planes=list, notify=_quiet).set_solve_settings(settings)
    assert state.solve_project.solver.estimate_ambient
    fall_off = state.solve_project.solver.fall_off
    assert fall_off is not None and fall_off.order == 2
    solve.setup_changed()
    solve.start("run")
    run_requests(solve, state, timeout=300.0)
    assert state.result is not None
    cli = _cli(edited)
    assert cli.ambient is not None and cli.fall_off is not None
    _same(state.result, cli)
    assert state.result.fall_off == cli.fall_off and state.result.ambient == cli.ambient


@pytest.mark.parametrize("order", [4, -1, True])
def test_an_order_the_project_does_not_take_is_refused_by_its_key(lit: Path, order) -> None:
    project = load_project(lit)
    state = AppState(project, load_images(project))
    before = state.solve_settings
    bad = dataclasses.replace(settings_of(project), estimate_fall_off=order)
    with pytest.raises(InputError) as refused:
        Actions(state, planes=list, notify=_quiet).set_solve_settings(bad)
    assert str(refused.value) == (
        f"sensor.estimate_fall_off.order: expected 0 (off) to 3, got {order!r}"
    )
    assert state.solve_settings == before and state.solve_project is project


def test_the_settings_travel_in_the_session_file(lit: Path) -> None:
    project = load_project(lit)
    loaded = load_images(project)
    state = AppState(project, loaded)
    chosen = dataclasses.replace(settings_of(project), estimate_ambient=True, estimate_fall_off=3)
    Actions(state, planes=list, notify=_quiet).set_solve_settings(chosen)
    saved = session_from_state(state)
    fresh = AppState(project, loaded)
    assert apply_session(fresh, type(saved).model_validate_json(saved.model_dump_json())) == []
    assert fresh.solve_settings == chosen
    assert fresh.solve_project.spec.sensor.estimate_ambient
    spec = fresh.solve_project.spec.sensor.estimate_fall_off
    assert spec is not None and spec.order == 3
    # A session file from before these settings: both off.
    old = json.loads(saved.model_dump_json())
    for key in ("estimate_ambient", "estimate_fall_off"):
        del old["solve_settings"][key]
    older = AppState(project, loaded)
    assert apply_session(older, type(saved).model_validate(old)) == []
    assert not older.solve_settings.estimate_ambient
    assert older.solve_settings.estimate_fall_off == 0


def test_the_overlays_render_the_estimated_room_light_and_fall_off(lit: Path) -> None:
    """After the page's solve with both terms, the rendered overlays carry them: their
    residuals are the fitted model's, well below those of the same estimate without
    (measured RMS: 45 with both, 120 without the room light, 170 without either)."""
    import numpy as np
    from lightcal_app.overlays import OverlayImages

    project = load_project(lit)
    loaded = load_images(project)
    state = AppState(project, loaded)
    solve = SolveService(state, notify=_quiet, follow_iterations=False)
    settings = dataclasses.replace(settings_of(project), estimate_ambient=True, estimate_fall_off=2)
    Actions(state, planes=list, notify=_quiet).set_solve_settings(settings)
    solve.setup_changed()
    solve.start("run")
    run_requests(solve, state, timeout=300.0)
    display = state.display
    assert display is not None and display.source == "estimate"
    assert len(display.fall_off_coeffs) == 2 and display.ambient > 0.0
    overlays = OverlayImages(project, loaded)

    def rms(shown) -> float:
        squares = [
            np.ma.mean(overlays.residual(i, overlays.render(i, shown)) ** 2)
            for i in range(len(project.names))
        ]
        return float(np.sqrt(np.mean(squares)))

    bare = dataclasses.replace(display, fall_off_coeffs=(), ambient=0.0)
    assert rms(display) < 0.5 * rms(bare)
