"""The wall's albedo map in a real headless Chromium: ticked in the Solve tab, Run solves
with it, the estimated map is drawn on the wall in the 3D view (blue and red patches
where the wall was grey), the View tab's toggle hides it, the Result tab says it, and
the Solve tab says when the selection is too sparse for it."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from lightcal_app.server import LightcalApp, build_app
from lightcal_app.state import SelectionSettings

from lightcal.io.albedo_map_spec import AlbedoMapSpec
from tests.test_app_albedo_map import textured  # noqa: F401  (a fixture)
from tests.test_app_browser import (  # noqa: F401  (the browser fixture is used by name)
    BROWSER_MARKS,
    SLOW_S,
    browser,
    open_page,
    shot,
    wait_for,
)

pytestmark = BROWSER_MARKS

SIZE = (1280, 800)
SCENE_WIDTH_PX = 900
"""The 3D view's part of a 1280 px wide page (the panel is on the right)."""


@pytest.fixture(scope="module")
def app(
    textured: tuple[Path, Path],  # noqa: F811  (the fixture imported above)
    tmp_path_factory: pytest.TempPathFactory,
) -> Iterator[LightcalApp]:
    state_dir = tmp_path_factory.mktemp("state")
    a = build_app(textured[1], port=0, session_path=False, state_dir=state_dir)
    assert a.wait_idle(SLOW_S)
    yield a
    a.close()


def _map_coloured_px(path: Path) -> int:
    """Pixels of the 3D view in the albedo map's saturated blues and reds (the wall, the
    frusta's grey pictures and the orange light have none)."""
    bgr = cv2.imread(str(path))[:, :SCENE_WIDTH_PX].astype(np.int32)
    b, g, r = bgr[..., 0], bgr[..., 1], bgr[..., 2]
    blue = (b - r > 60) & (b > g)
    red = (r - b > 60) & (g < 0.75 * r) & (r - g > 60) & (g < 130)
    return int(np.sum(blue | red))


def test_ticked_run_draws_the_map_on_the_wall(
    app: LightcalApp,
    browser: Any,  # noqa: F811  (the fixture imported above)
) -> None:
    page, _ = open_page(browser, app, size=SIZE)
    before = shot(page, "app_albedo_before.png")
    page.get_by_role("tab", name="Solve").click()
    page.get_by_label("estimate the wall's albedo map", exact=True).check()
    wait_for(lambda: app.state.solve_settings.albedo_map == AlbedoMapSpec(), "the map ticked")
    assert app.wait_idle(SLOW_S)
    app.controller.set_pace(0.0)
    page.get_by_role("button", name="Run").click()
    wait_for(lambda: app.state.solver_state == "converged", "the solve to converge")
    assert app.wait_idle(SLOW_S)
    result = app.state.result
    assert result is not None and result.albedo_map is not None
    drawn = app.controller.redrawer.albedo_wall
    assert drawn.handle is not None and drawn.handle.visible
    assert app.state.display is not None and drawn.shown is app.state.display.albedo
    drawn_px = _map_coloured_px(shot(page, "app_albedo_wall.png"))
    # (Before: only the gizmo's blue and red rings.)
    assert drawn_px > 5 * max(_map_coloured_px(before), 500)
    page.get_by_label("albedo map: smoothness", exact=True).scroll_into_view_if_needed()
    shot(page, "app_albedo_solve_tab.png")

    app.controller.set_overlay("residual")  # flat: the map is in the render
    assert app.wait_idle(SLOW_S)
    page.get_by_role("tab", name="View").click()
    page.get_by_text("Albedo map", exact=True).wait_for()
    toggle = page.get_by_label("show the albedo map on the wall", exact=True)
    shot(page, "app_albedo_view_tab.png")  # (shown: the toggle is on)
    toggle.uncheck()
    wait_for(lambda: not drawn.handle.visible, "the map hidden")
    hidden = shot(page, "app_albedo_hidden.png")
    assert _map_coloured_px(hidden) < 0.2 * drawn_px
    toggle.check()
    wait_for(lambda: drawn.handle.visible, "the map shown again")

    page.get_by_role("tab", name="Result").click()
    page.get_by_text("Wall albedo map:").first.wait_for()
    shot(page, "app_albedo_result_tab.png")

    # A sparse selection: the Solve tab says the map needs a dense one.
    app.controller.set_selection(SelectionSettings(strategy="random", n_per_image=100))
    assert app.wait_idle(SLOW_S)
    page.get_by_role("tab", name="Solve").click()
    note = page.get_by_text("The albedo map needs a dense selection", exact=False)
    note.scroll_into_view_if_needed()
    shot(page, "app_albedo_sparse_note.png")
