"""The Solve tab's "What the solve fits" in a real headless Chromium (issue 27): a user
sets `wall: auto` in the page on a painted wall and gets the CLI's answer on the project
file with that key."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from lightcal_app.server import LightcalApp, build_app

from lightcal.cli.main import main
from lightcal.io.project import load_project
from lightcal.pipeline import build_model, calibrate, load_images
from tests.test_app_browser import (  # noqa: F401  (the browser fixture is used by name)
    BROWSER_MARKS,
    SLOW_S,
    browser,
    open_page,
    shot,
    wait_for,
)

pytestmark = BROWSER_MARKS


@pytest.fixture(scope="module")
def painted(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A plastic wall; the project file says lambertian, as a first guess would."""
    folder = tmp_path_factory.mktemp("painted_page") / "data"
    argv = ["synth", str(folder), "--views", "6", "--width", "200", "--height", "150"]
    argv += ["--wall", "plastic", "--roughness", "0.15", "--seed", "4", "--quiet"]
    assert main(argv) == 0
    return folder / "project.json"


@pytest.fixture(scope="module")
def app(painted: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[LightcalApp]:
    state_dir = tmp_path_factory.mktemp("state")
    a = build_app(painted, port=0, session_path=False, state_dir=state_dir)
    assert a.wait_idle()
    yield a
    a.close()


def test_wall_auto_chosen_in_the_page_gives_the_cli_answer(
    app: LightcalApp,
    browser: Any,  # noqa: F811  (the fixture imported above)
    painted: Path,
) -> None:
    page, _ = open_page(browser, app, size=(1280, 800))
    page.get_by_role("tab", name="Solve").click()
    page.get_by_label("wall", exact=True).click()
    page.get_by_role("option", name="auto", exact=True).click()
    wait_for(lambda: app.state.solve_settings.wall_model == "auto", "the page's wall: auto")
    assert app.wait_idle(SLOW_S)
    app.controller.set_pace(0.0)
    page.get_by_role("button", name="Run").click()
    wait_for(lambda: app.state.solver_state == "converged", "the solve to converge")
    assert app.wait_idle(SLOW_S)
    page.get_by_text("converged").first.wait_for()
    shot(page, "app_wall_auto.png")

    data = json.loads(painted.read_text())
    data["wall"] = {"model": "auto"}
    edited = painted.parent / "auto.json"
    edited.write_text(json.dumps(data))
    project = load_project(edited)
    loaded = load_images(project)
    cli = calibrate(project, loaded, build_model(project, loaded)).result
    page_result = app.state.result
    assert page_result is not None
    assert cli.wall["model"] == page_result.wall["model"] == "plastic"
    np.testing.assert_allclose(page_result.x, cli.x, rtol=1e-9, atol=1e-12)
    # The overlays render the plastic wall the solve chose.
    display = app.state.display
    assert display is not None and display.wall.name == "plastic"
    # The plots, for a person to look at: the axis as roll and pitch, labels unclipped.
    # One page at a time: each new page is sent the converged scene and its overlays,
    # and under a loaded CI a new page's tab did not settle while the first was open
    # (a click timed out after 120 s once).
    page.context.close()
    for size in ((1280, 800), (1920, 1080)):
        view, _ = open_page(browser, app, size=size)
        assert app.wait_idle(SLOW_S)
        view.get_by_role("tab", name="Solve").click()
        view.get_by_text("light axis: roll and pitch (deg)").wait_for()
        view.mouse.move(size[0] - 150, size[1] // 2)  # over the panel
        view.mouse.wheel(0, 3000)
        shot(view, f"app_solve_plots_{size[0]}x{size[1]}.png")
        view.context.close()
