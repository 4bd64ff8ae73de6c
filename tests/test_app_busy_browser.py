"""Busy and focus states in a real browser: a widget whose numbers the worker is still
computing says so until they arrive; one image highlighted, the others faded.
Screenshots at 1280 x 800 and 1920 x 1080 in test-artifacts/.

Same set-up as tests/test_app_browser.py (Debian's Chromium, software WebGL).
"""

from __future__ import annotations

import threading
from typing import Any

import numpy as np
import pytest
from lightcal_app import requests as rq
from lightcal_app.overlays import DIM_KEEP, DIM_RGB
from lightcal_app.scene3d import CAMERA_RGB, FOCUS_CAMERA_RGB
from lightcal_app.server import LightcalApp

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
def test_the_selection_count_says_it_is_updating_until_the_worker_is_done(
    app: LightcalApp,  # noqa: F811 - the fixture imported above
    browser: Any,  # noqa: F811 - the fixture imported above
    size: tuple[int, int],
) -> None:
    app.controller.reset()
    assert app.wait_idle(SLOW_S)
    page, _ = open_page(browser, app, size=size)
    tag = f"{size[0]}x{size[1]}"
    page.get_by_role("tab", name="Pixels").click()
    worker = app.controller.worker
    original = worker.handlers[rq.SetupChanged]
    release = threading.Event()

    def held(request: rq.Request) -> None:  # a slow selection: held until released
        release.wait(SLOW_S)
        original(request)

    worker.handlers[rq.SetupChanged] = held
    n_before = app.state.selection.n_per_image
    try:
        field = page.get_by_label("pixels per image (random)")
        field.fill(str(n_before + 20))
        field.press("Enter")
        page.get_by_text("updating (selecting the pixels)").first.wait_for()
        total_before = sum(len(s) for s in app.state.selected)
        page.get_by_text(f"{total_before} pixels").first.wait_for()  # the old count, below
        shot(page, f"busy_selection_updating_{tag}.png", settle_s=0.3)
    finally:
        release.set()
        worker.handlers[rq.SetupChanged] = original
    assert app.wait_idle(SLOW_S)
    total_after = sum(len(s) for s in app.state.selected)
    assert total_after == total_before + 20 * len(app.state.project.names)
    page.get_by_text(f"{total_after} pixels").first.wait_for()
    page.get_by_text("updating (selecting the pixels)").wait_for(state="detached")
    shot(page, f"busy_selection_done_{tag}.png", settle_s=0.3)
    # Back to the project's count for the other tests.
    field.fill(str(n_before))
    field.press("Enter")
    wait_for(lambda: app.state.selection.n_per_image == n_before, "the count restored")
    assert app.wait_idle(SLOW_S)
    page.context.close()


@pytest.mark.parametrize("size", SCREEN_SIZES, ids=SIZE_IDS)
def test_a_highlighted_image_is_framed_and_the_others_fade(
    app: LightcalApp,  # noqa: F811 - the fixture imported above
    browser: Any,  # noqa: F811 - the fixture imported above
    size: tuple[int, int],
) -> None:
    assert app.wait_idle(SLOW_S)
    page, _ = open_page(browser, app, size=size)
    tag = f"{size[0]}x{size[1]}"
    frusta = app.controller.scene.frusta
    before = [np.asarray(h.image).copy() for h in frusta]
    page.get_by_role("tab", name="View").click()
    page.get_by_label("highlight this image").check()
    names = app.state.project.names
    wait_for(lambda: app.state.focus_image == names[0], "the first image highlighted")
    assert app.wait_idle(SLOW_S)
    assert tuple(frusta[0].color) == FOCUS_CAMERA_RGB
    assert all(tuple(h.color) == CAMERA_RGB for h in frusta[1:])  # 0 also carries the gizmo
    after = [np.asarray(h.image) for h in frusta]
    np.testing.assert_array_equal(after[0], before[0])
    for i in range(1, len(frusta)):
        # Faded towards the wall's grey, DIM_KEEP of the picture kept (the lower half: the
        # name is written at the top, after the fading).
        h = before[i].shape[0] // 2
        expected = DIM_KEEP * before[i][h:].astype(np.float64) + (1.0 - DIM_KEEP) * DIM_RGB
        np.testing.assert_allclose(after[i][h:], expected, atol=0.5 + 1e-9)
    shot(page, f"focus_highlighted_{tag}.png")
    page.get_by_label("highlight this image").uncheck()
    wait_for(lambda: app.state.focus_image is None, "no image highlighted")
    assert app.wait_idle(SLOW_S)
    np.testing.assert_array_equal(np.asarray(frusta[1].image), before[1])
    page.context.close()
