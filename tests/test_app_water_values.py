"""The Light tab's Water folder (issue 26): the medium's values typed in the page render
the overlays through the water, go into the solve (given, or its start when estimated),
the result file and the autosaved session, show the solve's estimate afterwards, and
bad values are refused with a message naming the key."""

from __future__ import annotations

import dataclasses
import json
import math
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from lightcal_app.panels.water import water_text
from lightcal_app.server import LightcalApp, build_app
from lightcal_app.session_file import SessionFile, apply_session, read_session
from lightcal_app.solve_settings import MEDIUM_ESTIMATES
from lightcal_app.state import AppState

from lightcal.core.footprint import pixel_footprints
from lightcal.core.medium import (
    AIR,
    MAX_ATTENUATION_PER_M,
    MAX_BACKSCATTER_PER_M,
    MAX_PHASE_G,
    Medium,
)
from lightcal.core.problem import with_view
from lightcal.core.render import render_image
from lightcal.errors import InputError
from tests.test_app_water import ATTENUATION_PER_M, water  # noqa: F401  (a fixture)
from tests.test_one_engine import _cli, _same

FIELD = {"c": "attenuation_per_m", "beta": "backscatter_per_m", "g": "phase_g"}


def _build(project: Path, tmp: Path, **kw: Any) -> LightcalApp:
    kw.setdefault("session_path", False)
    a = build_app(project, port=0, state_dir=tmp / "state", **kw)
    assert a.wait_idle(120.0)
    return a


@pytest.fixture
def app(water: Path, tmp_path: Path) -> Iterator[LightcalApp]:  # noqa: F811  (imported)
    a = _build(water, tmp_path)
    yield a
    a.close()


def _type(a: LightcalApp, which: str, value: float) -> None:
    """A value typed in the Water folder, as a browser's arrives (client None)."""
    a.panels.light.water.fields[FIELD[which]].value = value
    assert a.wait_idle(120.0)


def _shown(a: LightcalApp) -> dict[str, float]:
    return {k: a.panels.light.water.fields[name].value for k, name in FIELD.items()}


def _refusals(a: LightcalApp) -> list[str]:
    return [body for title, body in a.state.messages if title == "⚠ Value refused"]


def _run(a: LightcalApp) -> None:
    a.controller.set_pace(0.0)
    a.controller.run()
    deadline = time.monotonic() + 300.0
    while a.state.solver_state not in ("converged", "not converged"):
        assert time.monotonic() < deadline, "the solve did not end"
        time.sleep(0.05)
    assert a.wait_idle(120.0)


def test_the_fields_take_the_cores_ranges_and_the_projects_values(app: LightcalApp) -> None:
    fields = app.panels.light.water.fields
    assert (fields["attenuation_per_m"].min, fields["attenuation_per_m"].max) == (
        0.0,
        MAX_ATTENUATION_PER_M,
    )
    assert fields["backscatter_per_m"].max == MAX_BACKSCATTER_PER_M
    assert (fields["phase_g"].min, fields["phase_g"].max) == (-MAX_PHASE_G, MAX_PHASE_G)
    assert _shown(app) == {"c": 0.0, "beta": 0.0, "g": AIR.phase_g}  # air: the file has none
    assert "**Air**" in app.panels.light.water.text.content


def test_typed_attenuation_renders_the_overlays_through_the_water(app: LightcalApp) -> None:
    """The rendered overlay after typing c is the core's render of the same lights in
    air times exp(-c (d_light + d_camera)) at each footprint's centre."""
    st, ctl = app.state, app.controller
    ctl.set_overlay("residual")
    assert app.wait_idle(120.0)
    i = 2
    before = ctl.redrawer._render_cache[i][1].copy()
    residual_before = ctl.overlays.residual(i, before)
    _type(app, "c", ATTENUATION_PER_M)
    assert _shown(app)["c"] == ATTENUATION_PER_M and not _refusals(app)
    assert st.solve_settings.medium is not None
    assert st.solve_settings.medium.attenuation_per_m == ATTENUATION_PER_M
    display = st.display
    assert display is not None and display.source == "guess"
    assert display.medium.attenuation_per_m == ATTENUATION_PER_M
    cached_display, rendered = ctl.redrawer._render_cache[i]
    assert cached_display is display  # what the page shows now

    geo, view = ctl.overlays.geo, st.project.views[i]
    view = with_view(view, exposure=view.exposure * display.gains[i])
    air = render_image(
        geo.render_camera,
        view,
        display.rig,
        sensor=display.fall_off or "radiance",
        rid_subsamples=st.project.solver.rid_subsamples,
        wall=display.wall,
        medium=AIR,
    )
    values = np.ma.filled(rendered - display.offset, np.nan)
    lit = np.ma.filled(air, 0.0) > 0.05 * float(air.max())
    rows, cols = np.nonzero(lit & np.isfinite(values))
    pick = np.linspace(0, len(rows) - 1, 7).astype(int)
    pixels = np.stack([cols[pick], rows[pick]], axis=1)
    centers = pixel_footprints(geo.render_camera, view, pixels).centers_world
    light = display.rig.lights[0]
    d_light = np.linalg.norm(centers - light.position_world(view), axis=1)
    d_camera = np.linalg.norm(centers - view.center_world, axis=1)
    expected = np.exp(-ATTENUATION_PER_M * (d_light + d_camera))
    at = (pixels[:, 1], pixels[:, 0])
    ratio = values[at] / np.ma.filled(air, np.nan)[at]
    np.testing.assert_allclose(ratio, expected, rtol=1e-9)
    assert expected.min() < 0.7  # metres of water: a change no rounding hides
    # The residual overlay changed with it (real minus the new render).
    residual_after = ctl.overlays.residual(i, rendered)
    assert not np.ma.allclose(residual_after, residual_before)


def test_the_solve_uses_the_typed_values_as_given_and_as_the_start(
    app: LightcalApp,
    water: Path,  # noqa: F811  (the fixture imported above)
) -> None:
    st, ctl = app.state, app.controller
    _type(app, "c", ATTENUATION_PER_M)
    _run(app)
    assert st.result is not None
    assert st.result.medium["attenuation_per_m"] == ATTENUATION_PER_M
    assert st.result.medium["estimated"] == []
    assert "Water: attenuation 0.3 /m (given)" in app.panels.result.result_md.content
    # What `lightcal calibrate` gives on the file with the value typed.
    data = json.loads(water.read_text())
    data["medium"] = {"attenuation_per_m": ATTENUATION_PER_M}
    given = water.with_name("given.json")
    given.write_text(json.dumps(data))
    _same(st.result, _cli(given))
    # ... and the result file the page hands out says it.
    ctl.request_download("result")
    assert app.wait_idle(120.0)
    download = st.downloads[-1]
    assert download.name.endswith(".result.json")
    assert json.loads(download.content)["medium"]["attenuation_per_m"] == ATTENUATION_PER_M

    # Estimated: the typed value is the start, and the fields show the estimate.
    start = 0.1
    _type(app, "c", start)
    estimate = dataclasses.replace(
        st.solve_settings, medium_estimate=MEDIUM_ESTIMATES["attenuation"]
    )
    ctl.set_solve_settings(estimate)
    assert app.wait_idle(120.0)
    assert _shown(app)["c"] == start
    assert "**estimates** c" in app.panels.light.water.text.content
    _run(app)
    assert st.result is not None
    k = st.result.parameter_names.index("medium.attenuation_per_m")
    assert st.history[0].x[k] == start
    c = st.result.medium["attenuation_per_m"]
    assert st.result.medium["estimated"] == ["attenuation_per_m"]
    assert abs(c / ATTENUATION_PER_M - 1.0) < 0.05, c
    assert _shown(app)["c"] == round(c, 3) != start
    assert "Showing the solve's **estimate** of c" in app.panels.light.water.text.content
    assert f"Water: attenuation {c:.4g} ± " in app.panels.result.result_md.content
    assert st.display is not None and st.display.medium.attenuation_per_m == c
    # The CLI on the file with that start and estimate.
    data["medium"] = {"attenuation_per_m": start, "estimate": ["attenuation_per_m"]}
    given.write_text(json.dumps(data))
    _same(st.result, _cli(given))
    # Typing g after the solve keeps c as shown (the estimate), as the pose fields do.
    _type(app, "g", 0.5)
    medium = st.solve_settings.medium
    assert medium is not None and (medium.attenuation_per_m, medium.phase_g) == (c, 0.5)


def test_the_values_travel_in_the_autosaved_session(
    water: Path,  # noqa: F811  (the fixture imported above)
    tmp_path: Path,
) -> None:
    autosave = tmp_path / "water.session.json"
    a = _build(water, tmp_path, session_path=autosave)
    try:
        for which, value in (("c", 0.25), ("beta", 0.4), ("g", 0.75)):
            _type(a, which, value)
        deadline = time.monotonic() + 30.0  # written by the worker after the changes
        saved: SessionFile | None = None
        while time.monotonic() < deadline:
            saved = read_session(autosave) if autosave.is_file() else None
            settings = saved.solve_settings if saved is not None else None
            if settings is not None and settings.medium and settings.medium.phase_g == 0.75:
                break
            time.sleep(0.05)
        assert saved is not None and saved.solve_settings is not None
        assert saved.solve_settings.medium is not None
        assert saved.solve_settings.medium.model_dump() == {
            "attenuation_per_m": 0.25,
            "backscatter_per_m": 0.4,
            "phase_g": 0.75,
        }
    finally:
        a.close()
    b = _build(water, tmp_path, session_path=autosave)
    try:
        assert _shown(b) == {"c": 0.25, "beta": 0.4, "g": 0.75}
        medium = b.state.solve_project.medium.initial
        assert (medium.attenuation_per_m, medium.backscatter_per_m, medium.phase_g) == (
            0.25,
            0.4,
            0.75,
        )
        display = b.state.display
        assert display is not None and display.medium == medium  # the overlays' too
        # A session file from before the field: the project's values (air).
        old = json.loads(autosave.read_text())
        del old["solve_settings"]["medium"]
        fresh = AppState(b.state.project, b.state.loaded)
        assert apply_session(fresh, SessionFile.model_validate(old)) == []
        assert fresh.solve_settings.medium is None and fresh.solve_project.medium.initial == AIR
    finally:
        b.close()


@pytest.mark.parametrize(
    ("which", "value", "message"),
    [
        ("c", math.nan, "medium.attenuation_per_m: expected a number from 0 to 10 (1/m), got nan"),
        ("c", 12.0, "medium.attenuation_per_m: expected a number from 0 to 10 (1/m), got 12"),
        ("c", -0.1, "medium.attenuation_per_m: expected a number from 0 to 10 (1/m), got -0.1"),
        (
            "beta",
            1500.0,
            "medium.backscatter_per_m: expected a number from 0 to 1000 (1/m), got 1500",
        ),
        ("g", 1.0, "medium.phase_g: expected a number from -0.99 to 0.99, got 1"),
    ],
)
def test_a_bad_value_is_refused_and_the_previous_one_stays(
    app: LightcalApp, which: str, value: float, message: str
) -> None:
    _type(app, "c", 0.2)
    settings, display = app.state.solve_settings, app.state.display
    _type(app, which, value)
    assert _refusals(app) == [message]
    assert app.state.solve_settings is settings and app.state.display is display
    assert _shown(app) == {"c": 0.2, "beta": 0.0, "g": AIR.phase_g}


def test_backscatter_needs_the_radiance_fall_off(app: LightcalApp) -> None:
    st, ctl = app.state, app.controller
    ctl.set_solve_settings(dataclasses.replace(st.solve_settings, fall_off="cos4"))
    assert app.wait_idle(120.0)
    settings = st.solve_settings
    _type(app, "beta", 0.5)
    refused = (
        "medium.backscatter_per_m: the backscatter is modelled with the camera fall-off "
        "radiance (sensor.model) only, not 'cos4': set backscatter to 0 or the fall-off to "
        "radiance"
    )
    assert _refusals(app) == [refused]
    assert st.solve_settings is settings and _shown(app)["beta"] == 0.0
    # With radiance it is taken, and the veil brightens the render; back to cos4: refused.
    ctl.set_solve_settings(dataclasses.replace(settings, fall_off="radiance"))
    assert app.wait_idle(120.0)
    before = st.display
    _type(app, "beta", 0.5)
    assert _shown(app)["beta"] == 0.5
    after = st.display
    assert before is not None and after is not None and after.medium.backscatter_per_m == 0.5
    overlays = ctl.overlays
    veil = overlays.render(0, after) - overlays.render(0, dataclasses.replace(after, medium=AIR))
    assert float(np.ma.min(veil)) >= 0.0 and float(np.ma.max(veil)) > 0.0
    with pytest.raises(InputError, match=r"^medium\.backscatter_per_m: the backscatter"):
        ctl.set_solve_settings(dataclasses.replace(st.solve_settings, fall_off="cos4"))
    assert st.solve_settings.fall_off == "radiance"


def test_the_folder_says_what_its_values_are() -> None:
    start, fitted = Medium(0.1, 0.2), Medium(0.31, 0.5)
    both = ("attenuation_per_m", "backscatter_per_m")
    assert water_text(fitted, start, both, estimate_shown=True) == (
        "Showing the solve's **estimate** of c and β; it started from c\u00a0=\u00a00.1, "
        "β\u00a0=\u00a00.2."
    )
    assert water_text(start, start, both[:1], estimate_shown=False) == (
        "The solve **estimates** c, starting from the value typed here."
    )
    assert water_text(start, start, (), estimate_shown=False).startswith("**Given**")
    assert water_text(AIR, AIR, (), estimate_shown=False).startswith("**Air**")
