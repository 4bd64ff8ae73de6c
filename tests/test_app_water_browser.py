"""The Light tab's Water folder in a real headless Chromium (issue 26): c typed in the
page renders the overlays through the water and goes into Run's solve; with the Solve
tab's "estimate water" the field shows the estimate after Run."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from lightcal_app.server import LightcalApp, build_app

from tests.test_app_browser import (  # noqa: F401  (the browser fixture is used by name)
    BROWSER_MARKS,
    SLOW_S,
    browser,
    open_page,
    shot,
    wait_for,
)
from tests.test_app_water import ATTENUATION_PER_M, water  # noqa: F401  (a fixture)

pytestmark = BROWSER_MARKS

C_LABEL = "attenuation c (m⁻¹)"


@pytest.fixture(scope="module")
def app(
    water: Path,  # noqa: F811  (the fixture imported above)
    tmp_path_factory: pytest.TempPathFactory,
) -> Iterator[LightcalApp]:
    state_dir = tmp_path_factory.mktemp("state")
    a = build_app(water, port=0, session_path=False, state_dir=state_dir)
    assert a.wait_idle(SLOW_S)
    yield a
    a.close()


def _attenuation(app: LightcalApp) -> float | None:
    medium = app.state.solve_settings.medium
    return None if medium is None else medium.attenuation_per_m


def _run(app: LightcalApp, page: Any) -> None:
    app.controller.set_pace(0.0)
    page.get_by_role("tab", name="Solve").click()
    page.get_by_role("button", name="Run").click()
    wait_for(lambda: app.state.solver_state == "converged", "the solve to converge")
    assert app.wait_idle(SLOW_S)
    page.get_by_role("tab", name="Light").click()


def test_c_typed_in_the_page_renders_the_overlays_and_goes_into_the_solve(
    app: LightcalApp,
    browser: Any,  # noqa: F811  (the fixture imported above)
) -> None:
    page, _ = open_page(browser, app, size=(1280, 800))
    app.controller.set_overlay("residual")
    assert app.wait_idle(SLOW_S)
    field = page.get_by_label(C_LABEL, exact=True)
    assert field.input_value() == "0"  # the project's: air
    page.get_by_text("Air", exact=True).wait_for()
    before = app.controller.redrawer._render_cache[0][1].copy()

    field.fill(str(ATTENUATION_PER_M))
    field.press("Enter")
    wait_for(lambda: _attenuation(app) == ATTENUATION_PER_M, "the page's c")
    assert app.wait_idle(SLOW_S)
    display = app.state.display
    assert display is not None and display.medium.attenuation_per_m == ATTENUATION_PER_M
    shown, after = app.controller.redrawer._render_cache[0]
    assert shown is display  # the overlay the page shows now renders through the water
    lit = np.ma.filled(before, 0.0) > 0.05 * float(before.max())
    assert float(np.ma.median((after / before)[lit])) < 0.9  # metres of water: darker
    page.get_by_text("Given", exact=True).wait_for()
    shot(page, "app_water_light_tab.png")
    # Out of the core's range: said in the page, and the field goes back to 0.3.
    field.fill("20")
    field.press("Enter")
    page.get_by_text(f"{C_LABEL}: expected a number from 0 to 10, got 20").first.wait_for()
    assert app.wait_idle(SLOW_S)
    wait_for(lambda: field.input_value() == "0.3", "the field back at 0.3")
    assert _attenuation(app) == ATTENUATION_PER_M

    # Run: the solve keeps c as typed.
    _run(app, page)
    result = app.state.result
    assert result is not None and result.medium["attenuation_per_m"] == ATTENUATION_PER_M
    assert result.medium["estimated"] == []

    # From c = 0.1 with "estimate water: attenuation": the field shows the estimate.
    field.fill("0.1")
    field.press("Enter")
    wait_for(lambda: _attenuation(app) == 0.1, "the page's new c")
    page.get_by_role("tab", name="Solve").click()
    page.get_by_label("estimate water", exact=True).click()
    page.get_by_role("option", name="attenuation", exact=True).click()
    wait_for(
        lambda: app.state.solve_settings.medium_estimate == ("attenuation_per_m",),
        "the page's estimate water",
    )
    assert app.wait_idle(SLOW_S)
    _run(app, page)
    result = app.state.result
    assert result is not None and result.medium["estimated"] == ["attenuation_per_m"]
    c = result.medium["attenuation_per_m"]
    assert abs(c / ATTENUATION_PER_M - 1.0) < 0.05, c
    wait_for(lambda: field.input_value() == f"{round(c, 3):g}", f"the field to show c = {c}")
    page.get_by_text("estimate", exact=True).first.wait_for()
    shot(page, "app_water_estimated.png")
