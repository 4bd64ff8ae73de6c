"""Issue 25's acceptance from the page: a camera's JPEGs (`lightcal synth --real-world`)
built into a project by "New project from photos" with the page's defaults (the light
guessed from the beam, its cos^m exponent estimated) and the camera's response curve,
then solved by the page's Run (`SolveService`, the engine of `lightcal calibrate`),
land within 2 mm and 0.1 degrees of the truth, as the CLI's path does
(tests/test_real_world_acceptance.py); and the same in a headless Chromium through the
upload buttons (measured: 0.18 mm, 0.003 degrees both ways)."""

from __future__ import annotations

import json
import math
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from lightcal_app.photo_service import PhotoFields
from lightcal_app.requests import BuildPhotoProject
from lightcal_app.server import LightcalApp

from lightcal.cli.main import main
from lightcal.pipeline.results import PoseSummary
from tests.test_app_browser import (  # noqa: F401 - fixtures
    BROWSER_MARKS,
    SLOW_S,
    app,
    browser,
    open_page,
    shot,
    wait_for,
)
from tests.test_app_photo_project import make_service
from tests.test_app_photo_sample_browser import _holds, _upload
from tests.test_one_engine import _page_state


def _errors(dataset: Path, pose: PoseSummary) -> tuple[float, float]:
    """(mm, deg) of a solved light from truth.json's."""
    truth = json.loads((dataset / "truth.json").read_text())["lights"][0]
    error_mm = 1e3 * float(np.linalg.norm(pose.t_camera_light - truth["position_m"]))
    cos = float(np.dot(pose.axis_camera, truth["axis_camera"]))
    return error_mm, math.degrees(math.acos(min(1.0, cos)))


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("real_page") / "rw"
    assert main(["synth", str(out), "--real-world", "--quiet"]) == 0
    bracket = sorted(str(p) for p in (out / "bracket").glob("*.jpg"))
    assert main(["response", *bracket, "--out", str(out / "curve.json")]) == 0
    return out


def test_the_page_builds_and_solves_a_cameras_jpegs(dataset: Path, tmp_path: Path) -> None:
    service, state, messages, _, _ = make_service(tmp_path)
    for path in sorted((dataset / "images").glob("*.jpg")):
        service.upload("wall", path.name, path.read_bytes(), client="page")
    for kind, name in (("camera", "camera.yaml"), ("board", "markers.yaml")):
        service.upload(kind, name, (dataset / name).read_bytes(), client="page")  # type: ignore[arg-type]
    service.upload("response", "curve.json", (dataset / "curve.json").read_bytes(), client="page")
    staged = service.staged()
    assert staged.ready and staged.wall_boards == (("markers", "markers.yaml"),)
    service.request_build(PhotoFields(), client="page")  # the page's defaults
    (req,) = list(state.requests)
    state.requests.clear()
    assert isinstance(req, BuildPhotoProject)
    service.build(req)
    built = service.last_build
    assert built is not None, messages.items
    assert len(built.accepted) == 8  # every photo, the ones whose tag the beam clips too
    spec = built.project.spec
    assert spec.lights[0].initial == "auto" and spec.lights[0].estimate_rid == "cos_power"
    assert spec.sensor.response is not None
    page = _page_state(built.project.path)
    assert page.result is not None and page.result.converged, page.solver_message
    error_mm, error_deg = _errors(dataset, page.result.lights[0].pose)
    print(f"the page: {error_mm:.2f} mm, {error_deg:.3f} deg from the truth")
    assert error_mm < 2.0 and error_deg < 0.1


@BROWSER_MARKS[0]
@BROWSER_MARKS[1]
def test_the_same_from_the_browser(
    dataset: Path,
    app: LightcalApp,  # noqa: F811 - the fixture imported above
    browser: Any,  # noqa: F811 - the fixture imported above
    tmp_path: Path,
) -> None:
    """What a user does in a headless Chromium: the JPEGs as a zip, the camera, the
    markers' board file and the response curve through the upload buttons, Build with the
    page's defaults, Run."""
    service = app.controller.photos
    service.clear()
    page, _ = open_page(browser, app, size=(1280, 800))
    page.get_by_role("tab", name="Files").click()
    photos = tmp_path / "jpegs.zip"
    with zipfile.ZipFile(photos, "w") as zf:
        for path in sorted((dataset / "images").glob("*.jpg")):
            zf.write(path, f"images/{path.name}")
    _upload(page, app, "wall", photos)
    wait_for(_holds(service, "wall_photos", 8), "the JPEGs")
    for kind, name in (("camera", "camera.yaml"), ("board", "markers.yaml")):
        _upload(page, app, kind, dataset / name)  # type: ignore[arg-type]
        page.get_by_text(name).first.wait_for()
    _upload(page, app, "response", dataset / "curve.json")
    page.get_by_text("linearises 8-bit photos").first.wait_for()
    page.get_by_text("Ready: press Build project.").wait_for()
    old = app.state.project
    page.get_by_role("button", name="Build project").click()
    wait_for(lambda: app.state.project is not old, "the new project", timeout=4 * SLOW_S)
    assert app.wait_idle(SLOW_S)
    page.get_by_text("Built: 8 of 8 photos accepted, 0 rejected").wait_for()
    page.get_by_role("tab", name="Solve").click()
    app.controller.set_pace(0.0)
    page.get_by_role("button", name="Run").click()
    wait_for(lambda: app.state.solver_state == "converged", "convergence", timeout=8 * SLOW_S)
    assert app.wait_idle(SLOW_S)
    shot(page, "real_world_converged_1280x800.png")
    result = app.state.result
    assert result is not None
    error_mm, error_deg = _errors(dataset, result.lights[0].pose)
    print(f"the browser: {error_mm:.2f} mm, {error_deg:.3f} deg from the truth")
    assert error_mm < 2.0 and error_deg < 0.1
    page.context.close()
