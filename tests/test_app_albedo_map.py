"""The Solve tab's wall albedo map (`wall.albedo_map`) and the water's g in the page: the
page's solve with the map is `lightcal calibrate`'s on the file with the key, its
overlays render the map (the residuals are the pipeline's, flat), the map is drawn on
the wall, the setting travels in the session, and what the core refuses beside it (a
robust loss, backscatter) is refused in the page with the key."""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from lightcal_app.actions import Actions
from lightcal_app.albedo_scene import albedo_picture
from lightcal_app.overlays import OverlayImages
from lightcal_app.panels.solve import albedo_note
from lightcal_app.results import result_markdown
from lightcal_app.server import LightcalApp, build_app
from lightcal_app.session_file import apply_session, read_session, session_from_state
from lightcal_app.solve_service import SolveService
from lightcal_app.solve_settings import (
    MEDIUM_ESTIMATES,
    SolveSettings,
    albedo_map_spec,
    check_settings,
    project_for_solve,
    settings_of,
)
from lightcal_app.state import AppState, SelectionSettings

from lightcal.cli.main import main
from lightcal.colormap import diverging_rgb, robust_vmax, stepped
from lightcal.core.medium import Medium
from lightcal.errors import InputError
from lightcal.io.albedo_map_spec import AlbedoMapSpec
from lightcal.io.project import load_project
from lightcal.pipeline import load_images
from lightcal.pipeline.albedo_result import albedo_map_of, albedo_text
from tests.app_fixtures import run_requests
from tests.test_one_engine import _cli, _same

MAP = AlbedoMapSpec()
LOSS_REFUSED = (
    "wall.albedo_map: the albedo map needs the linear loss; the project's solver.loss is "
    "'huber' (set it to linear in the project file)"
)


def _quiet(*args: object, **kwargs: object) -> None:
    del args, kwargs


@pytest.fixture(scope="module")
def textured(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A wall with a +-10 % albedo texture, dense selection (binned 4): the project file
    with `wall.albedo_map` and the same file without it (an even wall)."""
    folder = tmp_path_factory.mktemp("albedo") / "data"
    argv = ["synth", str(folder), "--views", "8", "--width", "480", "--height", "320"]
    argv += ["--albedo-texture", "0.1", "--declare-albedo-map", "--seed", "3", "--quiet"]
    assert main(argv) == 0
    with_map = folder / "project.json"
    data = json.loads(with_map.read_text())
    assert data["wall"].pop("albedo_map") == MAP.model_dump()
    even = folder / "even.json"
    even.write_text(json.dumps(data))
    return with_map, even


@dataclasses.dataclass
class Solved:
    state: AppState
    solve: SolveService


@pytest.fixture(scope="module")
def solved(textured: tuple[Path, Path]) -> Solved:
    """The page's solve of the even wall's project with the map ticked."""
    project = load_project(textured[1])
    state = AppState(project, load_images(project))
    assert state.solve_settings.albedo_map is None  # the file has none: off
    solve = SolveService(state, notify=_quiet, follow_iterations=False)
    settings = dataclasses.replace(settings_of(project), albedo_map=MAP)
    Actions(state, planes=list, notify=_quiet).set_solve_settings(settings)
    assert state.solve_project.spec.wall.albedo_map == MAP
    assert state.solve_project.solver.albedo_map is not None
    solve.setup_changed()
    solve.start("run")
    run_requests(solve, state, timeout=300.0)
    assert state.result is not None, state.solver_message
    return Solved(state, solve)


def test_the_page_solve_with_the_map_is_the_cli_solve_of_the_file(
    solved: Solved, textured: tuple[Path, Path]
) -> None:
    page = solved.state.result
    assert page is not None and page.albedo_map is not None
    cli = _cli(textured[0])
    _same(page, cli)  # x and covariance to 1e-9
    assert cli.albedo_map is not None
    ours, theirs = albedo_map_of(page.albedo_map), albedo_map_of(cli.albedo_map)
    assert ours.grid.shape == theirs.grid.shape
    np.testing.assert_array_equal(ours.weight > 0, theirs.weight > 0)
    np.testing.assert_allclose(ours.delta, theirs.delta, rtol=1e-9, atol=1e-12)
    # The Result tab's line is the CLI's.
    words = albedo_text(cli.albedo_map).removeprefix("wall albedo map: ")
    shown = result_markdown(page, state="converged")
    assert f"Wall albedo map: {words}" in shown.replace("\\", "")


def test_the_overlays_render_the_map_their_residuals_are_the_pipelines(solved: Solved) -> None:
    """On the selection's grid (binning 4, `render_side` 120 for 480 px), the overlay's
    residual at each fitted super-pixel is the solved model's (measured: within 0.31 of
    residuals of RMS 9-18, i.e. 2 % of them and 5e-5 of the signal; the renderer's and
    the kernels' footprint sums differ that little); without the map they are 5-10x
    larger (the texture)."""
    st, solve = solved.state, solved.solve
    display, model = st.display, solve.model
    assert display is not None and display.source == "estimate" and model is not None
    assert display.albedo is not None
    assert st.result is not None
    x = np.asarray(st.result.x)
    np.testing.assert_array_equal(display.albedo.delta, model.albedo_map(x).delta)
    overlays = OverlayImages(st.project, st.loaded, render_side=120)
    assert overlays.geo.render_binning == st.selection.binning == 4
    r = model.residuals(x)
    for k, i in enumerate(solve._model_index):
        shown = overlays.residual(i, overlays.render(i, display))
        im = model.images[k]
        u, v = im.footprints.pixels.T
        fitted = r[model.bounds[k] : model.bounds[k + 1]] * model.sigmas[k]
        at = np.ma.filled(shown[v, u], np.nan)
        assert np.all(np.isfinite(at))
        rms = float(np.sqrt(np.mean(fitted**2)))
        assert np.max(np.abs(at - fitted)) < 0.05 * rms, i
        even = overlays.residual(i, overlays.render(i, dataclasses.replace(display, albedo=None)))
        assert float(np.sqrt(np.ma.mean(shown**2))) < 0.25 * float(np.sqrt(np.ma.mean(even**2)))


def test_the_map_is_drawn_on_the_wall_as_the_reports_figure_colours_it(solved: Solved) -> None:
    display = solved.state.display
    assert display is not None and display.albedo is not None
    albedo = display.albedo
    pic = albedo_picture(albedo, max_side_px=512)
    ny, nx = albedo.grid.shape
    k = 512 // max(ny, nx)
    assert pic.rgba.shape == (ny * k, nx * k, 4)
    s = albedo.grid.spacing_m
    assert (pic.width_m, pic.height_m) == (nx * s, ny * s)
    np.testing.assert_allclose(
        pic.center_xy_m, albedo.grid.origin_xy_m + s * (np.array([nx, ny]) - 1) / 2
    )
    values = albedo.image() - 1.0
    vmax = robust_vmax(values)
    assert pic.vmax == vmax
    colours = diverging_rgb(stepped(values, vmax), vmax)
    np.testing.assert_array_equal(pic.rgba[::k, ::k, :3], colours)  # row j: world y up
    np.testing.assert_array_equal(pic.rgba[::k, ::k, 3] == 255, np.isfinite(values))


def test_the_project_file_fills_the_setting_and_the_page_can_turn_it_off(
    textured: tuple[Path, Path],
) -> None:
    project = load_project(textured[0])
    settings = settings_of(project)
    assert settings.albedo_map == MAP
    assert project_for_solve(project, settings) is project
    off = project_for_solve(project, dataclasses.replace(settings, albedo_map=None))
    assert off.spec.wall.albedo_map is None and off.solver.albedo_map is None
    wide = AlbedoMapSpec(spacing_mm=50.0, variation=0.2, smoothness=0.1)
    other = project_for_solve(project, dataclasses.replace(settings, albedo_map=wide))
    options = other.solver.albedo_map
    assert options is not None and (options.spacing_m, options.variation) == (0.05, 0.2)


def test_the_setting_travels_in_the_session_file(textured: tuple[Path, Path]) -> None:
    project = load_project(textured[1])
    loaded = load_images(project)
    state = AppState(project, loaded)
    chosen = dataclasses.replace(
        settings_of(project), albedo_map=AlbedoMapSpec(spacing_mm=40.0, smoothness=0.1)
    )
    actions = Actions(state, planes=list, notify=_quiet)
    actions.set_solve_settings(chosen)
    actions.set_show_albedo(False)
    saved = session_from_state(state)
    fresh = AppState(project, loaded)
    assert apply_session(fresh, type(saved).model_validate_json(saved.model_dump_json())) == []
    assert fresh.solve_settings == chosen and not fresh.show_albedo
    assert fresh.solve_project.spec.wall.albedo_map == chosen.albedo_map
    # A session file from before the setting: off (and the map shown when there is one).
    old = json.loads(saved.model_dump_json())
    del old["solve_settings"]["albedo_map"], old["show_albedo"]
    older = AppState(project, loaded)
    assert apply_session(older, type(saved).model_validate(old)) == []
    assert older.solve_settings.albedo_map is None and older.show_albedo


def test_a_robust_loss_is_refused_by_its_key(textured: tuple[Path, Path]) -> None:
    data = json.loads(textured[1].read_text())
    data["solver"]["loss"] = "huber"
    huber = textured[1].with_name("huber.json")
    huber.write_text(json.dumps(data))
    project = load_project(huber)
    state = AppState(project, load_images(project))
    with pytest.raises(InputError) as refused:
        Actions(state, planes=list, notify=_quiet).set_solve_settings(
            dataclasses.replace(settings_of(project), albedo_map=MAP)
        )
    assert str(refused.value) == LOSS_REFUSED
    assert state.solve_settings.albedo_map is None and state.solve_project is project


@pytest.mark.parametrize(
    ("medium", "estimate"),
    [(Medium(0.1, 0.2), ()), (Medium(0.1, 0.0), MEDIUM_ESTIMATES["attenuation, backscatter"])],
    ids=["given", "estimated"],
)
def test_backscatter_goes_with_the_map(
    textured: tuple[Path, Path], medium: Medium, estimate: tuple[str, ...]
) -> None:
    """The map scales the wall's light and leaves the water's veil as it is
    (`lightcal.core.albedo_systems`): the page takes both, as the project file does."""
    project = load_project(textured[1])
    settings = dataclasses.replace(
        settings_of(project), albedo_map=MAP, medium=medium, medium_estimate=estimate
    )
    edited = project_for_solve(project, check_settings(project, settings))
    assert edited.solver.albedo_map is not None
    assert edited.medium.initial == medium and edited.medium.estimate == estimate


def test_values_out_of_the_files_range_are_refused_by_their_key() -> None:
    with pytest.raises(InputError) as refused:
        albedo_map_spec(0.5, 0.3, 0.05)
    assert str(refused.value) == (
        "wall.albedo_map.spacing_mm: expected a number greater than or equal to 1"
    )
    with pytest.raises(InputError) as refused:
        albedo_map_spec(25.0, 0.0, 0.05)
    assert str(refused.value) == "wall.albedo_map.variation: expected a number greater than 0"


def test_a_sparse_selection_is_said_to_be_too_sparse_for_the_map() -> None:
    settings = SolveSettings("lambertian", 0.0, False, "radiance", (), albedo_map=MAP)
    assert albedo_note(settings, ["all"]) == ""
    assert albedo_note(dataclasses.replace(settings, albedo_map=None), ["random"]) == ""
    assert albedo_note(settings, ["all", "random", "grid"]) == (
        "⚠ The albedo map needs a dense selection: the Pixels tab selects grid and random "
        "pixels, too few for each of its nodes. Choose the strategy *all* (binned, e.g. 4) "
        "there; with this one the map stays near its prior."
    )


def test_g_is_offered_beside_backscatter_and_refused_without(
    textured: tuple[Path, Path],
) -> None:
    project = load_project(textured[1])
    base = settings_of(project)
    with_g = dataclasses.replace(
        base, medium=Medium(0.1, 0.0), medium_estimate=MEDIUM_ESTIMATES["backscatter, g"]
    )
    estimated = project_for_solve(project, check_settings(project, with_g))
    assert estimated.medium.estimate == ("backscatter_per_m", "phase_g")
    given = dataclasses.replace(
        with_g, medium=Medium(0.1, 0.2), medium_estimate=MEDIUM_ESTIMATES["g"]
    )
    assert project_for_solve(project, check_settings(project, given)).medium.estimate == (
        "phase_g",
    )
    alone = dataclasses.replace(given, medium=Medium(0.1, 0.0))
    with pytest.raises(InputError) as refused:
        check_settings(project, alone)
    assert str(refused.value) == (
        "medium.estimate: g shapes the backscatter: expected a backscatter above 0 "
        "(Light tab, Water) or estimated with g"
    )


@pytest.fixture
def app(textured: tuple[Path, Path], tmp_path: Path) -> Iterator[LightcalApp]:
    a = build_app(textured[1], port=0, session_path=False, state_dir=tmp_path / "state")
    assert a.wait_idle(120.0)
    yield a
    a.close()


def test_the_solve_tabs_control_sets_the_map_and_says_what_it_needs(app: LightcalApp) -> None:
    panel, st = app.panels.solve, app.state
    assert panel.albedo_map.value is False
    panel.albedo_map.value = True  # ticked, as a browser's arrives (client None)
    assert app.wait_idle(120.0)
    assert st.solve_settings.albedo_map == MAP
    assert panel.albedo_note.content == ""  # the project's selection is dense
    panel.albedo_values[0].value = 40.0
    assert app.wait_idle(120.0)
    assert st.solve_settings.albedo_map == AlbedoMapSpec(spacing_mm=40.0)
    app.controller.set_selection(SelectionSettings(strategy="random", n_per_image=100))
    assert app.wait_idle(120.0)
    assert panel.albedo_note.content.startswith(
        "⚠ The albedo map needs a dense selection: the Pixels tab selects random pixels"
    )
    # Backscatter typed in the Light tab's Water folder: taken beside the map.
    app.panels.light.water.fields["backscatter_per_m"].value = 0.5
    assert app.wait_idle(120.0)
    assert [body for title, body in st.messages if title == "⚠ Value refused"] == []
    assert st.solve_settings.albedo_map == AlbedoMapSpec(spacing_mm=40.0)
    assert st.solve_settings.medium is not None
    assert st.solve_settings.medium.backscatter_per_m == 0.5


def test_the_setting_and_the_solved_map_come_back_from_the_autosave(
    textured: tuple[Path, Path], tmp_path: Path
) -> None:
    autosave = tmp_path / "even.session.json"
    a = build_app(textured[1], port=0, session_path=autosave, state_dir=tmp_path / "state")
    try:
        assert a.wait_idle(120.0)
        a.panels.solve.albedo_map.value = True
        a.panels.solve.albedo_values[0].value = 40.0
        assert a.wait_idle(120.0)
        a.controller.set_pace(0.0)
        a.controller.run()
        deadline = time.monotonic() + 300.0
        while not (a.state.solver_state == "converged" and autosave.is_file()):
            assert time.monotonic() < deadline, a.state.solver_message
            time.sleep(0.1)
        assert a.wait_idle(120.0)
        result = a.state.result
        assert result is not None and result.albedo_map is not None
        saved = read_session(autosave)
        while saved.solve is None or saved.solve.state != "converged":
            assert time.monotonic() < deadline, "the finished solve autosaved"
            time.sleep(0.1)
            saved = read_session(autosave)
        assert saved.solve_settings is not None
        assert saved.solve_settings.albedo_map == AlbedoMapSpec(spacing_mm=40.0)
    finally:
        a.close()
    b = build_app(textured[1], port=0, session_path=autosave, state_dir=tmp_path / "state")
    try:
        assert b.wait_idle(120.0)
        panel, st = b.panels.solve, b.state
        assert panel.albedo_map.value is True and panel.albedo_values[0].value == 40.0
        assert st.solve_settings.albedo_map == AlbedoMapSpec(spacing_mm=40.0)
        assert st.solver_state == "converged" and st.result is not None
        np.testing.assert_array_equal(st.result.x, result.x)
        # The result as it ended: its pixel weights (rendered where the solve's first pass
        # ended) come back with it, and so its map and covariance.
        again, before = albedo_map_of(st.result.albedo_map), albedo_map_of(result.albedo_map)
        np.testing.assert_array_equal(again.weight > 0, before.weight > 0)
        np.testing.assert_allclose(again.delta, before.delta, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(
            np.asarray(st.result.covariance, dtype=float),
            np.asarray(result.covariance, dtype=float),
            rtol=1e-9,
            atol=1e-18,
        )
        display = st.display
        assert display is not None and display.albedo is not None  # drawn on the wall again
        assert b.controller.redrawer.albedo_wall.shown is display.albedo
    finally:
        b.close()


def test_the_dense_binned_selection_the_map_needs_is_drawn_as_its_outline(
    textured: tuple[Path, Path],
) -> None:
    """All pixels binned 4 x 4 (the map's selection): an outline over the picture, not a
    lattice of dots covering half of it (measured before: 56 % of the picture; now 1 %)."""
    from lightcal_app.overlays import OUTLINE_FRACTION
    from lightcal_app.selection_service import SelectionService

    project = load_project(textured[0])
    state = AppState(project, load_images(project))
    SelectionService(state, notify=_quiet).compute()
    assert state.selected_binning[0] == 4 and len(state.selected[0]) == 9600
    overlays = OverlayImages(project, state.loaded)
    real = overlays.picture(0, "real")
    drawn = overlays.draw_selection(
        real.copy(), 0, selected=state.selected[0], binning=4, regions=(), points=()
    )
    changed = np.any(drawn != real, axis=-1)
    assert 0 < changed.mean() < OUTLINE_FRACTION
    h, w = changed.shape
    assert not changed[h // 4 : 3 * h // 4, w // 4 : 3 * w // 4].any()
