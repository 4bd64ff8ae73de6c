"""A project from photos in a real browser: the photos, camera file and board file go in
through the page's upload buttons, Build makes the project, Run solves it, and the result
JSON downloaded from the Result tab holds the light the photos were rendered with.

Same set-up as tests/test_app_browser.py (Debian's Chromium, software WebGL); the
screenshots (1280 x 800 and 1920 x 1080) land in test-artifacts/ for a person to look at.
"""

from __future__ import annotations

import json
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from lightcal_app.photo_project import PhotoKind
from lightcal_app.photo_service import PhotoService
from lightcal_app.server import LightcalApp

from tests.photo_fixtures import BLANK_NAME, BLANK_REASON, Photos, angle_deg, write_photos

# The app (a 4-view synthetic project, demo mode) and the browser, one of each for this
# module: the fixtures of tests/test_app_browser.py.
from tests.test_app_browser import (  # noqa: F401 - fixtures
    CHROMIUM,
    SLOW_S,
    app,
    browser,
    open_page,
    shot,
    wait_for,
)

pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(
        not CHROMIUM.exists(),
        reason="needs Debian's chromium at /usr/bin/chromium (scripts/setup.sh --browser)",
    ),
]

POSITION_TOLERANCE_M = 3e-3
"""How close the solved light must be to the one the photos were rendered with. The photos
leave two errors: the marker poses (0.1 - 0.25 mm off on these 320 x 240 photos; each is
given 0.5 mm and 0.05 degrees of systematic error, `lightcal init`'s floor) and the noise.
The solve's own 1-sigma of the position is 0.7 - 0.9 mm per axis, so 3 mm is over 3 sigma
of its length; it is 1/35 of the initial guess's error (105 mm), so a solve that did not
move or stopped half-way fails."""

AXIS_TOLERANCE_DEG = 0.5
"""The same for the axis (the solve's 1-sigma is about 0.1 degrees)."""


@pytest.fixture(scope="module")
def photos(tmp_path_factory: pytest.TempPathFactory) -> Photos:
    return write_photos(tmp_path_factory.mktemp("photos"))


def _photos_are(service: PhotoService, n: int) -> bool:
    return len(service.staged().wall_photos) == n


def _upload(page: Any, lightcal_app: LightcalApp, kind: PhotoKind, path: Path) -> None:
    """Choose `path` in the hidden file input of the photo panel's `kind` button."""
    handle = lightcal_app.panels.files.photos.uploads[kind]
    page.locator(f"#file_upload_{handle._impl.uuid}").set_input_files(str(path))


def test_a_project_from_photos_uploaded_in_the_page(
    app: LightcalApp,  # noqa: F811 - the fixture imported above
    browser: Any,  # noqa: F811 - the fixture imported above
    photos: Photos,
) -> None:
    service = app.controller.photos
    busy: list[str] = []
    show = service.show_work

    def record(text: str) -> None:
        busy.append(text)
        show(text)

    service.show_work = record
    page, _ = open_page(browser, app, size=(1280, 800))
    page.get_by_role("tab", name="Files").click()
    page.get_by_text("New project from photos").first.wait_for()
    page.get_by_text("Received: nothing yet.").wait_for()

    # One photo per press, as a user would; each is listed in the page as it arrives (the
    # list comes after viser's last acknowledgement of the upload: a next upload on the
    # same button before that would leave viser's progress notification spinning).
    for k, path in enumerate(photos.photos):
        _upload(page, app, "wall", path)
        wait_for(partial(_photos_are, service, k + 1), f"photo {k + 1} to arrive")
        page.get_by_text(f"wall photos ({k + 1})").wait_for()
    page.get_by_text("Missing:").first.wait_for()
    _upload(page, app, "camera", photos.camera)
    wait_for(lambda: service.staged().camera == "camera.yaml", "the camera file")
    _upload(page, app, "board", photos.board)
    wait_for(lambda: service.staged().ready, "the board file")
    page.get_by_text("Ready: press Build project.").wait_for()
    shot(page, "photos_staged_1280x800.png")

    old = app.state.project
    page.get_by_role("button", name="Build project").click()
    wait_for(lambda: app.state.project is not old, "the new project to be shown")
    assert app.wait_idle(SLOW_S)
    n = len(photos.photos)
    assert busy[:n] == [f"building the project: image {k} of {n}" for k in range(1, n + 1)]
    project = app.state.project
    assert project.names == [f"wall_{k}" for k in range(n - 1)]
    # The table of the photos, and the message naming the rejected one with its reason.
    page.get_by_text(f"Built: {n - 1} of {n} photos accepted, 1 rejected").wait_for()
    page.get_by_text(f"rejected: {BLANK_REASON}").first.wait_for()
    page.get_by_text(f"1 of {n} photos rejected").first.wait_for()
    page.get_by_text(f"{BLANK_NAME}: {BLANK_REASON}").first.wait_for()
    page.get_by_text(f"rejected: {BLANK_REASON}").first.scroll_into_view_if_needed()
    shot(page, "photos_built_1280x800.png")

    # Solve the new project, as it is, from lightcal init's initial guess (the camera).
    page.get_by_role("tab", name="Solve").click()
    page.get_by_role("button", name="Run").click()
    wait_for(lambda: app.state.solver_state == "converged", "convergence", timeout=4 * SLOW_S)
    assert app.wait_idle(SLOW_S)
    shot(page, "photos_converged_1280x800.png")

    page.get_by_role("tab", name="Result").click()
    with page.expect_download(timeout=SLOW_S * 1000) as download:
        page.get_by_role("button", name="Download result (JSON)").click()
    assert download.value.suggested_filename == "project.result.json"
    data = json.loads(Path(download.value.path()).read_text(encoding="utf-8"))
    (light,) = data["lights"]
    truth = photos.light
    error_m = float(np.linalg.norm(np.array(light["position_m"]) - truth.t_camera_light))
    sigma_m = np.array(light["sigma"]["position_m"])
    print(f"light position {1e3 * error_m:.3f} mm off; 1-sigma {np.round(1e3 * sigma_m, 3)} mm")
    assert error_m < POSITION_TOLERANCE_M, (light["position_m"], sigma_m)
    assert angle_deg(np.array(light["axis_camera"]), truth.R_camera_light[:, 2]) < (
        AXIS_TOLERANCE_DEG
    )
    assert data["converged"] and [im["name"] for im in data["images"]] == project.names
    shot(page, "photos_result_1280x800.png")
    page.context.close()

    # A second browser at 1920 x 1080 sees the same: the photos' table and the result.
    page, _ = open_page(browser, app, size=(1920, 1080))
    page.get_by_role("tab", name="Files").click()
    page.get_by_text(f"rejected: {BLANK_REASON}").first.wait_for()
    page.get_by_text(f"rejected: {BLANK_REASON}").first.scroll_into_view_if_needed()
    shot(page, "photos_built_1920x1080.png")
    page.get_by_role("tab", name="Result").click()
    page.get_by_text("converged").first.wait_for()
    shot(page, "photos_result_1920x1080.png")
    page.context.close()
