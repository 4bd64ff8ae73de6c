"""The Light tab's Surroundings folder in a real headless Chromium: an albedo typed in
the page and a surface removed reach the state and the 3D view."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

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
from tests.test_app_surroundings_edit import corner  # noqa: F401  (a fixture)

pytestmark = BROWSER_MARKS


@pytest.fixture(scope="module")
def app(
    corner: Path,  # noqa: F811  (the fixture imported above)
    tmp_path_factory: pytest.TempPathFactory,
) -> Iterator[LightcalApp]:
    state_dir = tmp_path_factory.mktemp("state")
    a = build_app(corner, port=0, session_path=False, state_dir=state_dir)
    assert a.wait_idle(SLOW_S)
    yield a
    a.close()


def _albedos(app: LightcalApp) -> list[float]:
    spec = app.state.solve_settings.surroundings
    return [] if spec is None else [s.albedo for s in spec.surfaces]


def test_an_albedo_typed_and_a_surface_removed_in_the_page(
    app: LightcalApp,
    browser: Any,  # noqa: F811  (the fixture imported above)
) -> None:
    page, _ = open_page(browser, app, size=(1280, 800))
    nodes = app.server.scene._handle_from_node_name
    field = page.get_by_label("albedo", exact=True).first  # the ceiling's
    assert field.input_value() == "0.8"
    field.fill("0.5")
    field.press("Enter")
    wait_for(lambda: _albedos(app) == [0.5, 0.8], "the ceiling's albedo")
    assert app.wait_idle(SLOW_S)
    assert nodes["/surroundings/0_label"].text.endswith("(albedo 0.5)")
    page.get_by_text("edited", exact=True).wait_for()
    page.get_by_role("button", name="Remove side wall").click()
    wait_for(lambda: _albedos(app) == [0.5], "the side wall removed")
    assert app.wait_idle(SLOW_S)
    assert "/surroundings/1" not in nodes
    shot(page, "app_surroundings_light_tab.png")
