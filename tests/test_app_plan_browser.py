"""The Plan tab in a real browser: the live read-out, Suggest views, the ghost frusta;
screenshots at 1280 x 800 and 1920 x 1080 (in test-artifacts/ for a person to look at).

Same set-up as tests/test_app_browser.py (Debian's Chromium, software WebGL).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from lightcal_app.plan_scene import PLAN_RGB
from lightcal_app.server import LightcalApp
from PIL import Image

from tests.test_app_browser import (  # noqa: F401 - fixtures
    BROWSER_MARKS,
    SCREEN_SIZES,
    SIZE_IDS,
    SLOW_S,
    app,
    browser,
    open_page,
    shot,
    wait_for,
)

pytestmark = BROWSER_MARKS


def plan_blue_pixels(path: Path) -> int:
    """Pixels of the 3D view (left of the panel) in the ghost frusta's blue."""
    rgb = np.asarray(Image.open(path).convert("RGB"), dtype=np.int32)
    view = rgb[:, : rgb.shape[1] // 2]
    return int(np.sum(np.all(np.abs(view - np.array(PLAN_RGB)) < 45, axis=-1)))


@pytest.mark.parametrize("size", SCREEN_SIZES, ids=SIZE_IDS)
def test_plan_tab_suggests_views_drawn_as_ghost_frusta(
    app: LightcalApp,  # noqa: F811 - the fixture imported above
    browser: Any,  # noqa: F811 - the fixture imported above
    size: tuple[int, int],
) -> None:
    app.controller.reset()
    app.controller.reset_guess()
    with app.state.lock:
        app.state.plan = None
        app.state.mark("plan")
    assert app.wait_idle(SLOW_S)
    page, _ = open_page(browser, app, size=size)
    tag = f"{size[0]}x{size[1]}"
    page.get_by_role("tab", name="Plan").click()
    # The read-out of the guess is there before any plan.
    page.get_by_text("Uncertainty now at the initial guess").first.wait_for()
    before = shot(page, f"plan_before_{tag}.png")
    page.get_by_role("button", name="Suggest views").click()
    wait_for(lambda: app.state.plan is not None, "the suggested views")
    page.get_by_text("Suggested next views").first.wait_for()
    plan = app.state.plan
    assert plan is not None and len(plan.views) == 3
    # The table names the first view's place as the planner words it.
    first = plan.views[0].candidate.instruction().split(",")[0]
    page.get_by_text(first).first.wait_for()
    assert len(app.controller.redrawer.plan_scene.handles) == 2 * 3
    after = shot(page, f"plan_suggested_{tag}.png")
    # The ghost frusta are drawn: the 3D view gained their blue.
    gained = plan_blue_pixels(after) - plan_blue_pixels(before)
    assert gained > 200, gained
    # No photo hides a suggestion: the photos' frusta are outlines while it is shown.
    frusta = app.controller.redrawer.scene.frusta
    assert all(h.image is None for h in frusta)
    # Hidden on request, and the blue goes with them.
    page.get_by_label("show suggested views in 3D").uncheck()
    wait_for(lambda: not app.state.show_plan, "the plan hidden")
    assert app.wait_idle(SLOW_S)
    hidden = shot(page, f"plan_hidden_{tag}.png")
    assert plan_blue_pixels(hidden) < plan_blue_pixels(before) + 0.2 * gained
    assert all(h.image is not None for h in frusta)  # the pictures are back
    page.get_by_label("show suggested views in 3D").check()
    wait_for(lambda: app.state.show_plan, "the plan shown again")
    page.context.close()
