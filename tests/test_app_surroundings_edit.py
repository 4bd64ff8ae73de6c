"""The surroundings edited in the page (the Light tab's Surroundings folder): values
refused as the project file refuses them, with the file's words; an edit redraws the
surfaces in the 3D view, renders the overlays with their bounce light, goes into the
solve (page = CLI on the file with the same `surroundings:`) and the session file."""

from __future__ import annotations

import dataclasses
import json
import math
import re
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from lightcal_app.actions import Actions
from lightcal_app.overlays import OverlayImages
from lightcal_app.panels.surroundings import bounces_value, surroundings_text
from lightcal_app.server import LightcalApp, build_app
from lightcal_app.session_file import SessionFile, apply_session, read_session, session_from_state
from lightcal_app.solve_service import SolveService
from lightcal_app.state import AppState
from lightcal_app.surroundings_settings import (
    with_new_surface,
    with_surface_values,
    with_values,
    without_surface,
)

from lightcal.cli.main import main
from lightcal.core.bounce import BounceMap
from lightcal.core.bounce_image import BounceImages
from lightcal.core.problem import with_view
from lightcal.core.scene import Rig
from lightcal.errors import InputError
from lightcal.io.project import load_project
from lightcal.io.surroundings_spec import SurroundingsSpec, build_surroundings
from lightcal.pipeline import load_images
from tests.app_fixtures import run_requests
from tests.test_one_engine import _cli, _same

Edit = Callable[[SurroundingsSpec | None], SurroundingsSpec | None]


@pytest.fixture(scope="module")
def corner(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A ceiling and a side wall of albedo 0.8 meeting the wall 0.7 m from the views,
    declared in the project (3 views of 120 x 80: the bounce map builds in seconds)."""
    folder = tmp_path_factory.mktemp("corner") / "data"
    argv = ["synth", str(folder), "--views", "3", "--width", "120", "--height", "80"]
    argv += ["--corner", "0.7", "0.5", "0.8", "--declare-surroundings", "--seed", "1", "--quiet"]
    assert main(argv) == 0
    return folder / "project.json"


def _actions(path: Path) -> tuple[AppState, Actions]:
    project = load_project(path)
    state = AppState(project, load_images(project))
    return state, Actions(state, planes=list, notify=lambda *a, **k: None)


def _file_with(path: Path, name: str, change: Callable[[dict[str, Any]], None]) -> Path:
    """The project file with its `surroundings:` changed by `change`."""
    data = json.loads(path.read_text())
    change(data["surroundings"])
    edited = path.with_name(name)
    edited.write_text(json.dumps(data))
    return edited


def _set(*keys: Any, value: Any) -> Callable[[dict[str, Any]], None]:
    def change(section: dict[str, Any]) -> None:
        node = section
        for key in keys[:-1]:
            node = node[key]
        node[keys[-1]] = value

    return change


REFUSALS: list[tuple[str, Edit, Callable[[dict[str, Any]], None]]] = [
    (
        "albedo 1",
        lambda s: with_surface_values(s, 0, albedo=1.0),
        _set("surfaces", 0, "albedo", value=1.0),
    ),
    ("wall albedo 0", lambda s: with_values(s, wall_albedo=0.0), _set("wall_albedo", value=0.0)),
    ("patch 0.6 m", lambda s: with_values(s, patch_m=0.6), _set("patch_m", value=0.6)),
    (
        "2.5 bounces",
        lambda s: with_values(s, bounces=bounces_value(2.5)),
        _set("bounces", value=2.5),
    ),
    (
        "behind the wall",
        lambda s: with_surface_values(s, 1, corner_m=[0.75, -0.8, -0.2]),
        _set("surfaces", 1, "corner_m", value=[0.75, -0.8, -0.2]),
    ),
    (
        "parallel edges",
        lambda s: with_surface_values(s, 1, edge_u_m=[0.0, 0.0, 0.5]),
        _set("surfaces", 1, "edge_u_m", value=[0.0, 0.0, 0.5]),
    ),
    (
        "in the wall's plane",
        lambda s: with_surface_values(s, 0, edge_v_m=[0.0, 0.5, 0.0]),
        _set("surfaces", 0, "edge_v_m", value=[0.0, 0.5, 0.0]),
    ),
]


@pytest.mark.parametrize(("case", "edit", "change"), REFUSALS, ids=[r[0] for r in REFUSALS])
def test_a_value_is_refused_in_the_words_of_the_project_file(
    corner: Path, case: str, edit: Edit, change: Callable[[dict[str, Any]], None]
) -> None:
    state, actions = _actions(corner)
    before, project = state.solve_settings, state.solve_project
    with pytest.raises(InputError) as page:
        actions.edit_surroundings(edit)
    assert state.solve_settings is before and state.solve_project is project
    path = _file_with(corner, "refused.json", change)
    with pytest.raises(InputError) as file:
        load_project(path)
    assert str(file.value) == f"{path}: {page.value}"
    assert str(page.value).startswith("surroundings.")


def test_the_page_refuses_what_the_file_meets_only_when_its_model_is_built(corner: Path) -> None:
    """Beyond 16 surfaces the file is refused as it is read; a mesh beyond the core's
    limits only when its bounce map is built (a solve): the page refuses both as typed,
    in those words."""
    state, actions = _actions(corner)
    with pytest.raises(InputError) as refused:
        actions.edit_surroundings(lambda s: with_values(s, patch_m=0.03))
    expected = (
        "4216 patches of 0.03 m; expected at most 4000 (a larger patch_m, or smaller surfaces)"
    )
    assert str(refused.value) == f"surroundings.patch_m: {expected}"
    spec = state.solve_settings.surroundings
    assert spec is not None
    finer = build_surroundings(spec.model_copy(update={"patch_m": 0.03}), "file")
    assert finer is not None
    with pytest.raises(ValueError) as core:
        BounceMap(finer, (-1.0, 1.0, -1.0, 1.0))
    assert str(core.value) == f"surroundings: {expected}"
    for _ in range(14):
        actions.edit_surroundings(lambda s: with_new_surface(s, state.project))
    assert state.solve_settings.surroundings is not None
    assert len(state.solve_settings.surroundings.surfaces) == 16
    with pytest.raises(InputError) as many:
        actions.edit_surroundings(lambda s: with_new_surface(s, state.project))
    assert str(many.value) == (
        "surroundings.surfaces: List should have at most 16 items after validation, not 17"
    )
    with pytest.raises(InputError) as nan:
        actions.edit_surroundings(lambda s: with_surface_values(s, 0, albedo=math.nan))
    assert str(nan.value) == "surroundings.surfaces[0].albedo: Input should be a finite number"


def test_a_wall_grid_past_the_cores_limit_is_refused_as_typed(corner: Path) -> None:
    """A small surface with 1 cm patches: few patches, but the wall's grid over the wall
    the images see (as the overlays' bounce map covers it) would pass 40,000 nodes."""
    state, actions = _actions(corner)
    actions.edit_surroundings(lambda s: without_surface(s, 1))
    small = {"edge_u_m": [0.2, 0.0, 0.0], "edge_v_m": [0.0, 0.0, 0.2]}
    actions.edit_surroundings(lambda s: with_surface_values(s, 0, **small))
    spec = state.solve_settings.surroundings
    assert spec is not None
    with pytest.raises(InputError) as refused:
        actions.edit_surroundings(lambda s: with_values(s, patch_m=0.01))
    words = re.fullmatch(
        r"surroundings\.patch_m: the wall's grid would have about (\d+) nodes of 0\.005 m; "
        r"expected at most 40000 \(a larger patch_m\)",
        str(refused.value),
    )
    assert words is not None, str(refused.value)
    assert state.solve_settings.surroundings == spec
    # The overlays' bounce map of it: the core's count, within 1 % (measured 0.3 %).
    finer = build_surroundings(spec.model_copy(update={"patch_m": 0.01}), "file")
    assert finer is not None
    camera = OverlayImages(state.project, state.loaded).geo.render_camera
    images = BounceImages(camera, state.project.views, finer)
    rig = Rig(tuple(u.initial for u in state.project.lights))
    with pytest.raises(ValueError, match="the wall's grid would have") as core:
        images.image(0, state.project.views[0], rig)
    count = int(re.search(r"have (\d+) nodes", str(core.value)).group(1))  # type: ignore[union-attr]
    assert abs(int(words.group(1)) / count - 1.0) < 0.01


def test_removing_every_surface_leaves_none_and_the_project_comes_back(corner: Path) -> None:
    state, actions = _actions(corner)
    declared = state.project.spec.surroundings
    assert declared is not None and [s.name for s in declared.surfaces] == ["ceiling", "side wall"]
    actions.edit_surroundings(lambda s: without_surface(s, 0))
    spec = state.solve_settings.surroundings
    assert spec is not None and [s.name for s in spec.surfaces] == ["side wall"]
    assert state.solve_project.surroundings is not None
    assert len(state.solve_project.surroundings.surfaces) == 1
    actions.edit_surroundings(lambda s: without_surface(s, 0))
    assert state.solve_settings.surroundings is None and state.solve_project.surroundings is None
    assert surroundings_text(None, declared).startswith("**None**")
    # Added to none: a surface of its own section, the wall's albedo the default.
    actions.edit_surroundings(lambda s: with_new_surface(s, state.project))
    added = state.solve_settings.surroundings
    assert added is not None and [s.name for s in added.surfaces] == ["surface 1"]
    assert (added.wall_albedo, added.surfaces[0].albedo, added.surfaces[0].edge_v_m) == (
        0.8,
        0.8,
        [0.0, 0.0, 0.5],
    )
    actions.reset_surroundings()
    assert state.solve_settings.surroundings == declared
    assert state.solve_project is state.project  # the project's own settings: itself


def test_the_surroundings_travel_in_the_session_file(corner: Path) -> None:
    state, actions = _actions(corner)
    actions.edit_surroundings(lambda s: with_values(s, wall_albedo=0.6, bounces=2))
    actions.edit_surroundings(lambda s: with_surface_values(s, 1, albedo=0.4))
    edited = state.solve_settings.surroundings
    saved = session_from_state(state)
    text = saved.model_dump_json()
    fresh = AppState(state.project, state.loaded)
    assert apply_session(fresh, SessionFile.model_validate_json(text)) == []
    assert fresh.solve_settings == state.solve_settings
    restored = fresh.solve_project.surroundings
    assert restored is not None and edited is not None
    assert (restored.wall_albedo, restored.bounces) == (0.6, 2)
    assert [s.albedo for s in restored.surfaces] == [0.8, 0.4]
    # None taken off: none restored; a file from before the field: the project's.
    data = json.loads(text)
    data["solve_settings"]["surroundings"] = None
    fresh = AppState(state.project, state.loaded)
    assert apply_session(fresh, SessionFile.model_validate(data)) == []
    assert fresh.solve_settings.surroundings is None and fresh.solve_project.surroundings is None
    del data["solve_settings"]["surroundings"]
    fresh = AppState(state.project, state.loaded)
    assert apply_session(fresh, SessionFile.model_validate(data)) == []
    assert fresh.solve_settings.surroundings == state.project.spec.surroundings
    # A session's surroundings the project file would refuse: the project's, said.
    data["solve_settings"]["surroundings"] = edited.model_dump()
    data["solve_settings"]["surroundings"]["surfaces"][0]["corner_m"][2] = -1.0
    fresh = AppState(state.project, state.loaded)
    warnings = apply_session(fresh, SessionFile.model_validate(data))
    assert (
        len(warnings) == 1 and "surroundings.surfaces[0] (ceiling): reaches behind" in warnings[0]
    )
    assert fresh.solve_settings.surroundings == state.project.spec.surroundings


def test_the_page_solves_the_edited_surroundings_as_the_cli_solves_the_file(
    corner: Path,
) -> None:
    state, actions = _actions(corner)
    solve = SolveService(state, notify=lambda *a, **k: None, follow_iterations=False)
    actions.edit_surroundings(lambda s: with_values(s, wall_albedo=0.7, patch_m=0.15, bounces=3))
    actions.edit_surroundings(lambda s: with_surface_values(s, 0, albedo=0.6))
    actions.edit_surroundings(
        lambda s: with_surface_values(s, 1, corner_m=[0.8, -0.8, 0.0], edge_v_m=[0.0, 0.0, 0.4])
    )
    solve.setup_changed()
    solve.start("run")
    run_requests(solve, state, timeout=600.0)
    assert state.result is not None, state.solver_message

    def change(section: dict[str, Any]) -> None:
        section.update(wall_albedo=0.7, patch_m=0.15, bounces=3)
        section["surfaces"][0]["albedo"] = 0.6
        section["surfaces"][1].update(corner_m=[0.8, -0.8, 0.0], edge_v_m=[0.0, 0.0, 0.4])

    edited = _file_with(corner, "edited.json", change)
    cli = _cli(edited)
    _same(state.result, cli)
    # ... and not the answer of the surroundings as declared.
    declared = _cli(corner)
    assert np.abs(np.asarray(declared.x) - np.asarray(cli.x))[:3].max() > 0.01  # m (measured 45 mm)


def _build(corner: Path, tmp_path: Path) -> LightcalApp:
    autosave = tmp_path / "corner.session.json"
    a = build_app(corner, port=0, state_dir=tmp_path / "state", session_path=autosave)
    assert a.wait_idle(120.0)
    return a


def _type(a: LightcalApp, handle: Any, value: Any) -> None:
    """A value typed in the folder, as a browser's arrives (client None)."""
    handle.value = value
    assert a.wait_idle(120.0)


def _refusals(a: LightcalApp) -> list[str]:
    return [body for title, body in a.state.messages if title == "⚠ Value refused"]


def test_an_edit_redraws_the_surfaces_and_renders_their_bounce(
    corner: Path, tmp_path: Path
) -> None:
    app = _build(corner, tmp_path)
    try:
        kept = _edit_in_the_folder(app, tmp_path / "corner.session.json")
    finally:
        app.close()
    again = _build(corner, tmp_path)  # a new page on the project restores the autosave
    try:
        restored = again.panels.light.surroundings
        assert [w["albedo"].value for w in restored.surfaces] == [0.8]
        assert restored.bounces.value == 3
        assert again.state.solve_settings.surroundings == kept
        nodes = again.server.scene._handle_from_node_name
        assert "/surroundings/1" not in nodes
        np.testing.assert_allclose(nodes["/surroundings/0"].vertices[0], [0.8, -0.8, 0.0])
    finally:
        again.close()


def _edit_in_the_folder(app: LightcalApp, autosave: Path) -> SurroundingsSpec:
    """Edits typed in the folder, checked; returns the surroundings autosaved."""
    st, ctl = app.state, app.controller
    panel = app.panels.light.surroundings
    nodes = app.server.scene._handle_from_node_name
    assert [w["albedo"].value for w in panel.surfaces] == [0.8, 0.8]
    assert "as the project file declares them" in panel.text.content
    ctl.set_overlay("rendered")
    assert app.wait_idle(120.0)
    _type(app, panel.surfaces[0]["albedo"], 0.3)
    assert not _refusals(app)
    spec = st.solve_settings.surroundings
    assert spec is not None and spec.surfaces[0].albedo == 0.3
    assert "**edited** in the page" in panel.text.content
    surroundings = st.solve_project.surroundings
    display = st.display
    assert surroundings is not None and display is not None
    assert display.surroundings is surroundings  # the overlays render these
    assert nodes["/surroundings/0_label"].text.endswith("(albedo 0.3)")
    # The rendered overlay holds the core's bounce of the edited surroundings.
    i, ov = 1, ctl.overlays
    shown, rendered = ctl.redrawer._render_cache[i]
    assert shown is display
    without = ov.render(i, dataclasses.replace(display, surroundings=None))
    view = st.project.views[i]
    view = with_view(view, exposure=view.exposure * display.gains[i])
    bounce = BounceImages(
        ov.geo.render_camera, st.project.views, surroundings, sensor="radiance"
    ).image(i, view, display.rig, display.medium)
    lit = np.isfinite(np.ma.filled(without, np.nan))
    np.testing.assert_allclose(
        np.ma.filled(rendered - without, np.nan)[lit], bounce[lit], rtol=1e-9, atol=1e-12
    )
    declared = ov.render(i, dataclasses.replace(display, surroundings=st.project.surroundings))
    assert float(np.ma.max(declared - rendered)) > 0.0  # albedo 0.8: more bounce light
    assert len(ov._bounce) <= 3

    # A corner moved: the drawing's vertices follow.
    _type(app, panel.surfaces[1]["corner_m"], (0.8, -0.8, 0.0))
    spec = st.solve_settings.surroundings
    assert spec is not None
    s1 = spec.surfaces[1]
    c, u, v = (np.array(a) for a in (s1.corner_m, s1.edge_u_m, s1.edge_v_m))
    np.testing.assert_allclose(nodes["/surroundings/1"].vertices, [c, c + u, c + u + v, c + v])
    # A value refused: the page says why, the field shows the value kept.
    _type(app, panel.patch, 0.6)
    assert _refusals(app) == ["surroundings.patch_m: Input should be less than or equal to 0.5"]
    spec = st.solve_settings.surroundings
    assert panel.patch.value == 0.1 and spec is not None and spec.patch_m == 0.1
    _type(app, panel.bounces, 3)
    spec = st.solve_settings.surroundings
    assert spec is not None and spec.bounces == 3
    # Removed: one folder and one rectangle left.
    _type(app, panel.surfaces[0]["remove"], True)
    assert len(panel.surfaces) == 1 and panel.surfaces[0]["albedo"].value == 0.8
    assert "/surroundings/1" not in nodes
    np.testing.assert_allclose(nodes["/surroundings/0"].vertices[0], [0.8, -0.8, 0.0])

    # The autosave keeps them.
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline:
        saved = read_session(autosave) if autosave.is_file() else None
        kept = saved.solve_settings.surroundings if saved and saved.solve_settings else None
        if kept is not None and len(kept.surfaces) == 1 and kept.bounces == 3:
            return kept
        time.sleep(0.05)
    raise AssertionError("not autosaved")
