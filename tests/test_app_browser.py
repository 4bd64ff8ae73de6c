"""End-to-end tests of the calibration app in a real headless Chromium.

Debian's /usr/bin/chromium (installed by `scripts/setup.sh --browser`) is driven with
Playwright's Python package, software WebGL (SwiftShader). Screenshots land in
`test-artifacts/` for a person to look at. The tests share one app and one browser and
run in file order; each starts from a reset solve.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from lightcal_app.server import LightcalApp, build_app

from lightcal.core.rotations import matrix_from_quaternion_wxyz
from tests.app_fixtures import make_project

CHROMIUM = Path("/usr/bin/chromium")
ARTIFACTS = Path(__file__).resolve().parents[1] / "test-artifacts"
FLAGS = [
    "--no-sandbox",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--disable-quic",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
]
WIDTH, HEIGHT = 960, 600
SLOW_S = 120.0  # software WebGL on a busy machine is slow

BROWSER_MARKS = [
    pytest.mark.browser,
    pytest.mark.skipif(
        not CHROMIUM.exists(),
        reason="needs Debian's chromium at /usr/bin/chromium (scripts/setup.sh --browser)",
    ),
]
"""The marks of every browser test module (`pytestmark = BROWSER_MARKS`)."""
pytestmark = BROWSER_MARKS

SCREEN_SIZES = [(1280, 800), (1920, 1080)]
"""The page sizes whose screenshots a person looks at."""
SIZE_IDS = [f"{w}x{h}" for w, h in SCREEN_SIZES]


def wait_for(condition: Callable[[], Any], what: str, timeout: float = SLOW_S) -> Any:
    """Poll until `condition()` is truthy; fail naming `what` otherwise."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = condition()
        if value:
            return value
        time.sleep(0.1)
    pytest.fail(f"timed out after {timeout:.0f} s waiting for {what}")


def shot(page: Any, name: str, *, settle_s: float = 1.5) -> Path:
    ARTIFACTS.mkdir(exist_ok=True)
    path = ARTIFACTS / name
    time.sleep(settle_s)  # let the pictures arrive and software WebGL draw a frame
    page.screenshot(path=str(path), timeout=SLOW_S * 1000)
    return path


@pytest.fixture(scope="module")
def app(tmp_path_factory: pytest.TempPathFactory) -> Iterator[LightcalApp]:
    folder = tmp_path_factory.mktemp("browser")
    project = make_project(folder / "proj", n_views=4, width=320, height=240)
    a = build_app(project.path, port=0, demo=True, session_path=False, state_dir=folder / "state")
    assert a.wait_idle()
    yield a
    a.close()


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=str(CHROMIUM), args=FLAGS)
        yield b
        b.close()


def open_page(
    browser: Any, app: LightcalApp, *, size: tuple[int, int] = (WIDTH, HEIGHT)
) -> tuple[Any, Any]:
    """A new browser page on the app, connected; returns (page, its viser client)."""
    before = set(app.server.get_clients())
    context = browser.new_context(viewport={"width": size[0], "height": size[1]})
    page = context.new_page()
    page.set_default_timeout(SLOW_S * 1000)
    page.goto(app.url)
    page.get_by_text("Connecting...").wait_for(state="hidden")
    page.get_by_role("tab", name="Explain").wait_for(timeout=2 * SLOW_S * 1000)  # panel built
    clients = wait_for(
        lambda: [c for k, c in app.server.get_clients().items() if k not in before],
        "the page to connect",
    )
    return page, clients[0]


@pytest.fixture(scope="module")
def page_and_client(browser: Any, app: LightcalApp) -> tuple[Any, Any]:
    return open_page(browser, app)


@pytest.fixture
def fresh(app: LightcalApp) -> LightcalApp:
    app.controller.clear_regions()
    app.controller.reset()
    app.controller.reset_guess()
    assert app.wait_idle(SLOW_S)
    return app


def uplot_data(page: Any, uuid: str) -> list[list[float]] | None:
    """The data of one uPlot chart in the page (viser's e2e test point)."""
    return page.evaluate(
        """(uuid) => {
            const tp = window.__viserTestpoints?.uplots?.[uuid];
            return tp ? tp.chart.data.map(a => Array.from(a)) : null;
        }""",
        uuid,
    )


def project_to_screen(client: Any, points_world: np.ndarray) -> np.ndarray:
    """(N, 2) page coordinates of world points seen by a browser's camera."""
    cam = client.camera
    R = matrix_from_quaternion_wxyz(np.asarray(cam.wxyz))
    q = (np.atleast_2d(points_world) - np.asarray(cam.position)) @ R
    t = math.tan(cam.fov / 2)
    sx = (q[:, 0] / q[:, 2] / (t * cam.aspect) + 1) / 2 * WIDTH
    sy = (q[:, 1] / q[:, 2] / t + 1) / 2 * HEIGHT
    return np.stack([sx, sy], axis=1)


def set_camera(client: Any, position: np.ndarray, look_at: np.ndarray, up: np.ndarray) -> None:
    with client.atomic():
        client.camera.up_direction = up
        client.camera.position = position
        client.camera.look_at = look_at
    time.sleep(2.0)  # the browser applies and reports it back


def overview(app: LightcalApp, client: Any) -> None:
    """Back to the initial view (close-ups of big translucent meshes are slow to render
    in software, and the GPU process is shared by every page)."""
    cam = app.server.initial_camera
    set_camera(client, cam.position, cam.look_at, np.array([0.0, -1.0, 0.0]))


def test_page_loads_without_share_button(
    app: LightcalApp, page_and_client: tuple[Any, Any]
) -> None:
    page, _ = page_and_client
    tabs = [t.inner_text().strip() for t in page.get_by_role("tab").all()]
    for name in ("Light", "Pixels", "View", "Solve", "Result", "Files", "Explain"):
        assert name in tabs
    assert page.get_by_text("Share", exact=True).count() == 0
    assert page.get_by_role("button", name="Back to the project's initial guess").is_visible()
    shot(page, "app_loaded.png")


def test_step_updates_the_cost_plot(fresh: LightcalApp, page_and_client: tuple[Any, Any]) -> None:
    app = fresh
    page, _ = page_and_client
    page.get_by_role("tab", name="Solve").click()
    page.get_by_role("button", name="Step").click()
    wait_for(lambda: len(app.state.history) == 2 and app.state.solver_state == "paused", "a step")
    uuid = app.panels.solve.cost_plot._impl.uuid
    data = wait_for(
        lambda: (d := uplot_data(page, uuid)) is not None and len(d[0]) == 2 and d,
        "the cost plot to show two iterations",
    )
    assert data[0] == [0.0, 1.0]
    np.testing.assert_allclose(data[1], np.log10([h.cost for h in app.state.history]))
    page.get_by_text("iteration 1, cost").wait_for()
    shot(page, "app_after_step.png")


def test_gizmo_drag_changes_the_rendered_overlay(
    fresh: LightcalApp, page_and_client: tuple[Any, Any]
) -> None:
    app = fresh
    page, client = page_and_client
    app.controller.set_overlay("rendered")
    assert app.wait_idle(SLOW_S)
    before = app.controller.scene.frusta[0].image.copy()
    # Look at the gizmo on image 0's camera along that camera's axis, from 0.5 m behind.
    view = app.state.project.views[0]
    R_wc = view.R_camera_world.T
    light = view.center_world + R_wc @ app.state.guess[0].t_camera_light
    set_camera(client, light - 0.5 * R_wc[:, 2], light, -R_wc[:, 1])
    size = 10 * app.controller.scene.light_size_m  # the gizmo's scale
    center, tip_y = project_to_screen(client, np.array([light, light + size * R_wc[:, 1]]))
    assert np.allclose(center, [WIDTH / 2, HEIGHT / 2], atol=2)
    start = center + 0.75 * (tip_y - center)  # on the gizmo's y arrow (camera y: down)
    page.mouse.move(*start)
    page.mouse.down()
    for k in range(1, 11):
        page.mouse.move(start[0], start[1] + 6 * k, steps=2)
        time.sleep(0.05)
    page.mouse.up()
    wait_for(lambda: app.state.guess[0].t_camera_light[1] > 0.02, "the drag to move the light")
    assert app.wait_idle(SLOW_S)
    y_mm = app.state.guess[0].t_camera_light[1] * 1e3
    assert app.state.guess[0].t_camera_light[[0, 2]] == pytest.approx([0.05, 0.0], abs=1e-9)
    after = app.controller.scene.frusta[0].image
    assert np.abs(after.astype(int) - before.astype(int)).mean() > 1.0
    # The typed numbers follow the gizmo in the page.
    page.get_by_role("tab", name="Light").click()
    wait_for(
        lambda: any(
            abs(float(v) - y_mm) < 0.1  # the field shows its step's precision
            for v in page.locator("input").evaluate_all("els => els.map(e => e.value)")
            if v.replace(".", "", 1).replace("-", "", 1).isdigit()
        ),
        "the position field to show the dragged y",
    )
    shot(page, "app_after_gizmo_drag.png", settle_s=4.0)
    overview(app, client)


def test_region_drawn_on_an_image_changes_its_selection(
    fresh: LightcalApp, page_and_client: tuple[Any, Any]
) -> None:
    app = fresh
    page, client = page_and_client
    st = app.state
    before = [s.copy() for s in st.selected]
    app.controller.set_overlay("real")
    page.get_by_role("tab", name="View").click()
    # "Look through image" for image v01 (the dropdown's value is set server-side).
    app.panels.view.overlay_image.value = st.project.names[1]
    page.get_by_role("button", name="Look through image").click()
    view = st.project.views[1]
    wait_for(
        lambda: np.allclose(
            client.camera.look_at,
            view.center_world + view.center_world[2] * view.R_camera_world[2],
            atol=1e-3,
        ),
        "the camera to look through image v01",
    )
    time.sleep(2.0)
    x0, y0, x1, y1 = 0.42 * WIDTH, 0.42 * HEIGHT, 0.58 * WIDTH, 0.58 * HEIGHT
    page.keyboard.down("Shift")
    page.mouse.move(x0, y0)
    page.mouse.down()
    for k in range(1, 11):
        page.mouse.move(x0 + (x1 - x0) * k / 10, y0 + (y1 - y0) * k / 10)
        time.sleep(0.05)
    page.mouse.up()
    page.keyboard.up("Shift")
    wait_for(lambda: len(st.regions) == 1, "the rectangle to become a region")
    assert app.wait_idle(SLOW_S)
    region = st.regions[0]
    assert region.image == st.project.names[1] and region.include
    poly = np.array(region.points)
    # The middle of the screen is the middle of the image.
    assert np.allclose(poly.mean(axis=0), [159.5, 119.5], atol=12)
    sel = st.selected[1]
    assert 0 < len(sel) <= 60
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    assert np.all((sel >= lo - 0.5) & (sel <= hi + 0.5))
    assert not np.array_equal(sel, before[1])
    for i in (0, 2, 3):
        np.testing.assert_array_equal(st.selected[i], before[i])
    shot(page, "app_after_region.png", settle_s=5.0)
    overview(app, client)


def test_two_browsers_see_the_same_state(
    fresh: LightcalApp, browser: Any, page_and_client: tuple[Any, Any]
) -> None:
    app = fresh
    page1, _ = page_and_client
    page1.get_by_role("tab", name="Solve").click()
    page1.get_by_role("button", name="Step").click()
    wait_for(lambda: len(app.state.history) == 2 and app.state.solver_state == "paused", "a step")
    page2, _ = open_page(browser, app, size=(800, 560))  # a late joiner
    try:
        page2.get_by_role("tab", name="Solve").click()
        page2.get_by_text("iteration 1, cost").wait_for()  # sees the current state
        # Both click Step at once: one solve, two more iterations, none twice.
        page1.get_by_role("button", name="Step").click()
        page2.get_by_role("button", name="Step").click()
        wait_for(
            lambda: len(app.state.history) == 4 and app.state.solver_state == "paused",
            "two more steps",
        )
        assert [h.iteration for h in app.state.history] == [0, 1, 2, 3]
        for page in (page1, page2):
            page.get_by_text("iteration 3, cost").wait_for()
        uuid = app.panels.solve.cost_plot._impl.uuid
        for page in (page1, page2):

            def four_points(page: Any = page) -> bool:
                d = uplot_data(page, uuid)
                return d is not None and len(d[0]) == 4

            wait_for(four_points, "both cost plots to show four iterations")
        # A change in one browser shows in the other.
        page2.get_by_role("button", name="Reset").click()
        wait_for(lambda: app.state.solver_state == "idle" and not app.state.history, "the reset")
        page1.get_by_text("idle: press Step or Run").wait_for()
        shot(page1, "app_browser1.png")
        shot(page2, "app_browser2.png")
    finally:
        page2.context.close()
