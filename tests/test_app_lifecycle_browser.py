"""The solve's life in a real browser: a watchable Run, a result kept through an edit
and restored, one angle convention; screenshots at 1280 x 800 and 1920 x 1080.

Same set-up as tests/test_app_browser.py (Debian's Chromium, software WebGL); the
screenshots land in test-artifacts/ for a person to look at.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from lightcal_app.server import LightcalApp

# The app (a 4-view synthetic project, demo mode) and the browser, one of each for this
# module: the fixtures of tests/test_app_browser.py.
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


@pytest.mark.parametrize("size", SCREEN_SIZES, ids=SIZE_IDS)
def test_run_is_watchable_and_an_edit_keeps_the_result(
    app: LightcalApp,  # noqa: F811 - the fixture imported above
    browser: Any,  # noqa: F811 - the fixture imported above
    size: tuple[int, int],
) -> None:
    app.controller.reset()
    app.controller.reset_guess()
    assert app.wait_idle(SLOW_S)
    with app.state.lock:
        app.state.previous = None
    page, _ = open_page(browser, app, size=size)
    tag = f"{size[0]}x{size[1]}"
    page.get_by_role("tab", name="Solve").click()
    # The pace slider is the state's: 0.5 s per iteration unless the user moves it.
    assert app.panels.solve.pace.value == pytest.approx(app.state.min_iteration_s)
    page.get_by_role("button", name="Run").click()
    # Paced: the page shows "running" with some iterations before the end.
    wait_for(
        lambda: app.state.solver_state == "running" and len(app.state.history) >= 2,
        "a running solve with two iterations shown",
    )
    page.get_by_text("running").first.wait_for()
    shot(page, f"lifecycle_running_{tag}.png", settle_s=0.2)
    wait_for(lambda: app.state.solver_state == "converged", "convergence")
    page.get_by_text("iteration", exact=False).first.wait_for()
    solved = app.state.result
    assert solved is not None
    shot(page, f"lifecycle_converged_{tag}.png")
    # The Light tab gives the estimate in the result's roll and pitch.
    page.get_by_role("tab", name="Light").click()
    page.get_by_text("axis roll, pitch (deg)").first.wait_for()
    roll, pitch = app.panels.light.light_widgets[0]["axis"].value
    light = solved.lights[0]
    assert roll == pytest.approx(light.pose.roll_deg, abs=2e-3)
    assert pitch == pytest.approx(light.pose.pitch_deg, abs=2e-3)
    shot(page, f"lifecycle_light_tab_{tag}.png")
    # An edit starts a draft; the result is kept and shown, and comes back on Restore.
    app.controller.set_guess(0, t_camera_light=np.array([0.07, 0.0, 0.0]))
    wait_for(lambda: app.state.solver_state == "idle", "the new draft")
    page.get_by_role("tab", name="Result").click()
    page.get_by_text("Previous result").first.wait_for()
    shot(page, f"lifecycle_previous_result_{tag}.png")
    page.get_by_role("button", name="Restore previous result").click()
    wait_for(lambda: app.state.solver_state == "converged", "the restored result")
    assert app.state.result is not None
    np.testing.assert_array_equal(app.state.result.x, solved.x)
    page.get_by_text("Previous result restored").first.wait_for()
    shot(page, f"lifecycle_restored_{tag}.png")
    page.context.close()
