"""The Solve tab's "estimate water" (`medium.estimate`, issue 26): in the page, a project
of water that its file does not declare is solved as `lightcal calibrate` solves the file
with the key, and the water's attenuation is recovered."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
from lightcal_app.actions import Actions
from lightcal_app.session_file import apply_session, session_from_state
from lightcal_app.solve_service import SolveService
from lightcal_app.solve_settings import MEDIUM_ESTIMATES, check_settings, settings_of
from lightcal_app.state import AppState

from lightcal.cli.main import main
from lightcal.errors import InputError
from lightcal.io.project import load_project
from lightcal.pipeline import load_images
from tests.app_fixtures import run_requests
from tests.test_one_engine import _cli, _same

ATTENUATION_PER_M = 0.3


@pytest.fixture(scope="module")
def water(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Clear water (c = 0.3 /m) that the project does not declare (air, as a first
    project from a vehicle would)."""
    folder = tmp_path_factory.mktemp("water") / "data"
    argv = ["synth", str(folder), "--views", "6", "--width", "200", "--height", "150"]
    argv += ["--attenuation", str(ATTENUATION_PER_M), "--seed", "3", "--quiet"]
    assert main(argv) == 0
    return folder / "project.json"


def test_estimate_water_in_the_page_gives_the_cli_answer_of_the_edited_file(
    water: Path,
) -> None:
    data = json.loads(water.read_text())
    data["medium"] = {"estimate": ["attenuation_per_m"]}
    edited = water.parent / "edited.json"
    edited.write_text(json.dumps(data))

    project = load_project(water)
    state = AppState(project, load_images(project))
    solve = SolveService(state, notify=lambda *a, **k: None, follow_iterations=False)
    actions = Actions(state, planes=list, notify=lambda *a, **k: None)
    settings = dataclasses.replace(
        settings_of(project), medium_estimate=MEDIUM_ESTIMATES["attenuation"]
    )
    actions.set_solve_settings(settings)
    assert state.solve_project.spec.medium.estimate == ["attenuation_per_m"]
    solve.setup_changed()
    solve.start("run")
    run_requests(solve, state, timeout=300.0)
    assert state.result is not None
    cli = _cli(edited)
    _same(state.result, cli)
    c = state.result.medium["attenuation_per_m"]
    assert abs(c / ATTENUATION_PER_M - 1.0) < 0.05, c
    # The choice travels in the session file.
    fresh = AppState(project, state.loaded)
    saved = session_from_state(state)
    assert apply_session(fresh, type(saved).model_validate_json(saved.model_dump_json())) == []
    assert fresh.solve_settings.medium_estimate == ("attenuation_per_m",)


def test_a_medium_estimate_the_page_does_not_offer_is_refused(water: Path) -> None:
    project = load_project(water)
    # (Each set of c, beta and g is offered, in that order: a file's other order is
    # read in it.)
    wrong = dataclasses.replace(
        settings_of(project), medium_estimate=("phase_g", "backscatter_per_m")
    )
    with pytest.raises(InputError) as info:
        check_settings(project, wrong)
    assert str(info.value) == (
        "medium.estimate: expected one of 'none', 'attenuation', 'backscatter', "
        "'attenuation, backscatter', 'backscatter, g', 'attenuation, backscatter, g', 'g', "
        "'attenuation, g', got ('phase_g', 'backscatter_per_m')"
    )
