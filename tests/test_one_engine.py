"""The page solves as the CLI does (issue 27): the app's Run drives
`lightcal.pipeline.calibrate`, the engine of `lightcal calibrate`, so the same project
gives the same result in both: multi-start, mirror exclusion, `wall: auto`, the fit test
and the uncertainty included."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from lightcal_app.solve_service import SolveService
from lightcal_app.state import AppState, Display

from lightcal.cli.main import main
from lightcal.io.project import load_project
from lightcal.pipeline import CalibrationResult, calibrate_project, load_images
from tests.app_fixtures import run_requests

SAMPLE = Path(__file__).resolve().parent.parent / "sample_data" / "project.json"


def _cli(path: Path) -> CalibrationResult:
    """What `lightcal calibrate` computes (`calibrate_project`: load, `initial: auto`,
    select, solve)."""
    return calibrate_project(load_project(path))[2]


def _page(path: Path, *, steps: int = 0) -> tuple[CalibrationResult, list[int]]:
    """The result and the iteration numbers the page drew (`_page_state`)."""
    state = _page_state(path, steps=steps)
    assert state.result is not None, state.solver_message
    return state.result, [rep.iteration for rep in state.history]


def _page_state(path: Path, *, steps: int = 0) -> AppState:
    """Run (after `steps` Steps) in the app's solve service, without a browser."""
    project = load_project(path)
    state = AppState(project, load_images(project))
    solve = SolveService(state, notify=lambda *a, **k: None, follow_iterations=False)
    solve.setup_changed()
    for _ in range(steps):
        solve.start("step")
        assert solve.session is not None and solve.session.wait(60)
        solve.poll()
    solve.start("run")
    run_requests(solve, state, timeout=300.0)
    return state


def _same(page: CalibrationResult, cli: CalibrationResult) -> None:
    assert page.parameter_names == cli.parameter_names
    np.testing.assert_allclose(page.x, cli.x, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(
        np.asarray(page.covariance, dtype=float),
        np.asarray(cli.covariance, dtype=float),
        rtol=1e-9,
        atol=1e-18,
    )
    assert page.wall == cli.wall
    assert page.converged == cli.converged
    assert page.fit_adequate == cli.fit_adequate
    assert page.warnings == cli.warnings
    assert page.uncertainty_terms == cli.uncertainty_terms


def test_the_sample_gives_the_same_result_in_page_and_cli() -> None:
    page, iterations = _page(SAMPLE)
    _same(page, _cli(SAMPLE))
    assert iterations == sorted(iterations) and len(set(iterations)) == len(iterations)


@pytest.fixture(scope="module")
def painted(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A plastic (painted) wall, the project asking for `wall: auto`, two random starts
    and mirror exclusion: every stage of the pipeline runs."""
    folder = tmp_path_factory.mktemp("painted") / "data"
    argv = ["synth", str(folder), "--views", "6", "--width", "200", "--height", "150"]
    argv += ["--wall", "plastic", "--roughness", "0.15", "--seed", "4", "--quiet"]
    assert main(argv) == 0
    path = folder / "project.json"
    data = json.loads(path.read_text())
    data["wall"] = {"model": "auto"}
    data["solver"] = {**data.get("solver", {}), "multistart": 2}
    data["selection"] = {**data.get("selection", {}), "exclude_mirror_deg": 3.0}
    path.write_text(json.dumps(data))
    return path


def test_a_painted_wall_on_auto_gives_the_cli_answer_stepping_first(painted: Path) -> None:
    cli = _cli(painted)
    assert cli.wall["model"] == "plastic"  # auto found the paint: the stages all ran
    page, iterations = _page(painted, steps=3)
    _same(page, cli)
    # Every stage drew its iterations, numbered on: starts, the trimmed and the walls'.
    assert iterations == sorted(iterations) and len(set(iterations)) == len(iterations)
    assert iterations[:4] == [0, 1, 2, 3]


VARIANTS: list[tuple[str, list[str], dict[str, object]]] = [
    ("two lights", ["--lights", "2"], {}),
    ("an isotropic light", ["--light", "isotropic"], {}),
    ("a light without symmetry", ["--light", "table2d"], {}),
    ("an IES light", ["--light", "ies"], {}),
    ("its RID estimated", [], {"lights.0.estimate_rid": "curve"}),
    ("a robust loss", ["--ambient", "0.05"], {"solver.loss": "huber"}),
    ("room light estimated", ["--ambient", "0.05"], {"sensor.estimate_offset": True}),
    ("cos4 fall-off", ["--sensor", "cos4"], {}),
    ("two random starts", [], {"solver.multistart": 2}),
    ("initial: auto", ["--half-angle-deg", "12"], {"lights.0.initial": "auto"}),
]


@pytest.mark.parametrize(("case", "flags", "keys"), VARIANTS, ids=[v[0] for v in VARIANTS])
def test_every_kind_of_project_gives_the_same_result_in_page_and_cli(
    tmp_path_factory: pytest.TempPathFactory, case: str, flags: list[str], keys: dict[str, object]
) -> None:
    folder = tmp_path_factory.mktemp("variant") / "data"
    argv = ["synth", str(folder), "--views", "5", "--width", "160", "--height", "120"]
    assert main([*argv, *flags, "--seed", "2", "--quiet"]) == 0
    path = folder / "project.json"
    data = json.loads(path.read_text())
    for key, value in keys.items():
        *parents, last = key.split(".")
        node = data
        for part in parents:
            node = node[int(part)] if part.isdigit() else node.setdefault(part, {})
        node[last] = value
    path.write_text(json.dumps(data))
    _same(_page(path)[0], _cli(path))


def test_the_overlays_render_the_wall_auto_chose(painted: Path) -> None:
    """The guess renders the project's (matte) wall; after the page's solve picks
    plastic, the overlays render its highlight: their residuals are the fitted wall's."""
    from lightcal_app.overlays import OverlayImages

    from lightcal.core.wall import LAMBERTIAN

    project = load_project(painted)
    loaded = load_images(project)
    guess = AppState(project, loaded)
    SolveService(guess, notify=lambda *a, **k: None, follow_iterations=False).setup_changed()
    assert guess.display is not None and guess.display.wall is LAMBERTIAN
    display = _page_state(painted).display
    assert display is not None and display.source == "estimate"
    assert display.wall.name == "plastic"
    overlays = OverlayImages(project, loaded)

    def rms(shown: Display) -> float:
        squares = [
            np.ma.mean(overlays.residual(i, overlays.render(i, shown)) ** 2)
            for i in range(len(project.names))
        ]
        return float(np.sqrt(np.mean(squares)))

    fitted, matte = rms(display), rms(dataclasses.replace(display, wall=LAMBERTIAN))
    assert fitted < 0.3 * matte  # measured: 48 against 430


def test_the_solve_tab_settings_give_the_cli_answer_of_the_edited_file(painted: Path) -> None:
    """The painted project with `wall: lambertian` in its file: choosing `auto`, mirror
    exclusion and the offset in the page solves what `lightcal calibrate` solves on the
    file with those keys."""
    from lightcal_app.actions import Actions
    from lightcal_app.solve_settings import SolveSettings

    data = json.loads(painted.read_text())
    data["wall"] = {"model": "lambertian"}
    data["selection"]["exclude_mirror_deg"] = None
    matte = painted.parent / "matte.json"
    matte.write_text(json.dumps(data))
    data["wall"] = {"model": "auto"}
    data["selection"]["exclude_mirror_deg"] = 2.5
    data["sensor"] = {**data.get("sensor", {}), "estimate_offset": True}
    edited = painted.parent / "edited.json"
    edited.write_text(json.dumps(data))

    project = load_project(matte)
    state = AppState(project, load_images(project))
    solve = SolveService(state, notify=lambda *a, **k: None, follow_iterations=False)
    actions = Actions(state, planes=list, notify=lambda *a, **k: None)
    settings = SolveSettings("auto", 2.5, True, project.spec.sensor.model, ("none",))
    actions.set_solve_settings(settings)
    assert state.solve_settings == settings and state.solve_project is not project
    solve.setup_changed()
    solve.start("run")
    run_requests(solve, state, timeout=300.0)
    assert state.result is not None
    cli = _cli(edited)
    assert cli.wall["model"] == "plastic"
    _same(state.result, cli)


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (
            {"wall_model": "glass"},
            "wall.model: expected one of lambertian, plastic, oren_nayar, auto",
        ),
        (
            {"exclude_mirror_deg": 95.0},
            "selection.exclude_mirror_deg: expected an angle in degrees from 0 (off) to below "
            "90, got 95.0",
        ),
        (
            {"fall_off": "map"},
            "sensor.model: 'map' needs the project's vignetting file (sensor.vignetting)",
        ),
        (
            {"estimate_rid": ("curve", "none")},
            "lights.estimate_rid: expected one per light (1), got 2",
        ),
        (
            {"estimate_rid": ("spline",)},
            "lights.0.estimate_rid: expected one of none, cos_power, curve",
        ),
    ],
)
def test_settings_the_project_does_not_take_are_refused_by_their_key(
    painted: Path, change: dict[str, object], expected: str
) -> None:
    from lightcal_app.actions import Actions
    from lightcal_app.solve_settings import settings_of

    from lightcal.errors import InputError

    project = load_project(painted)
    state = AppState(project, load_images(project))
    actions = Actions(state, planes=list, notify=lambda *a, **k: None)
    before = state.solve_settings
    with pytest.raises(InputError) as refused:
        actions.set_solve_settings(dataclasses.replace(settings_of(project), **change))
    assert str(refused.value) == expected
    assert state.solve_settings == before and state.solve_project is project


def test_the_settings_travel_in_the_session_file(painted: Path) -> None:
    from lightcal_app.session_file import apply_session, session_from_state
    from lightcal_app.solve_settings import SolveSettings

    project = load_project(painted)
    loaded = load_images(project)
    state = AppState(project, loaded)
    chosen = SolveSettings("oren_nayar", 4.0, True, "cos4", ("cos_power",))
    from lightcal_app.actions import Actions

    Actions(state, planes=list, notify=lambda *a, **k: None).set_solve_settings(chosen)
    saved = session_from_state(state)
    fresh = AppState(project, loaded)
    assert apply_session(fresh, type(saved).model_validate_json(saved.model_dump_json())) == []
    assert fresh.solve_settings == chosen
    assert fresh.solve_project.spec.wall.model == "oren_nayar"
    assert fresh.solve_project.spec.sensor.model == "cos4"
    assert fresh.solve_project.lights[0].estimate_rid == "cos_power"


def test_the_solve_tab_plots_the_axis_as_roll_and_pitch(painted: Path) -> None:
    """One convention: the angle plot's last point is the result's roll and pitch."""
    from lightcal_app.solve_display import light_angles_deg

    state = _page_state(painted)
    assert state.result is not None
    project = load_project(painted)
    solve = SolveService(
        AppState(project, load_images(project)),
        notify=lambda *a, **k: None,
        follow_iterations=False,
    )
    assert light_angles_deg(solve.first_model, [h.x for h in state.history]) is None
    solve.setup_changed()
    assert solve.ensure_session()
    angles = light_angles_deg(solve.first_model, [h.x for h in state.history])
    assert angles is not None and [name for name, _ in angles] == ["light"]
    last = angles[0][1][-1]
    pose = state.result.lights[0].pose
    np.testing.assert_allclose(last, [pose.roll_deg, pose.pitch_deg], atol=1e-9)


def test_one_status_in_both_tabs_when_the_fit_test_finds_a_misfit(painted: Path) -> None:
    """A painted wall solved as matte: converged, and both tabs say the misfit matters."""
    from lightcal_app.results import MISFIT_WORDS, result_markdown

    data = json.loads(painted.read_text())
    data["wall"] = {"model": "lambertian"}
    matte = painted.parent / "matte_status.json"
    matte.write_text(json.dumps(data))
    state = _page_state(matte)
    assert state.result is not None and state.result.converged
    assert not state.result.fit_adequate
    assert state.solver_state == "converged"
    assert state.solver_message.endswith(f"; {MISFIT_WORDS}")
    head = result_markdown(state.result, state=state.solver_state).splitlines()[0]
    assert head.startswith(f"**converged, {MISFIT_WORDS}**: ")


def test_a_restored_wall_auto_solve_shows_the_wall_it_chose(painted: Path) -> None:
    """A session saved after `wall: auto` chose plastic restores to that estimate (its
    parameters are the plastic model's, which the project's first, matte, model lacks),
    not to the guess."""
    from lightcal_app.session_file import apply_session, session_from_state

    solved = _page_state(painted)
    assert solved.result is not None and solved.result.wall["model"] == "plastic"
    saved = session_from_state(solved)
    fresh = AppState(solved.project, solved.loaded)
    service = SolveService(fresh, notify=lambda *a, **k: None, follow_iterations=False)
    assert apply_session(fresh, type(saved).model_validate_json(saved.model_dump_json())) == []
    fresh.resume_x = fresh.history[-1].x.copy()
    service.selection.compute()
    service.show_guess()
    service.restore_estimate()
    assert fresh.display is not None and fresh.display.source == "estimate"
    assert fresh.display.wall.name == "plastic"
    assert fresh.result is not None and fresh.solver_state == "converged"
    assert fresh.result.parameter_names == solved.result.parameter_names
    np.testing.assert_allclose(fresh.result.x, solved.result.x, rtol=0, atol=0)
