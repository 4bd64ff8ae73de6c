"""Issue 25's acceptance from the page: a camera's JPEGs (`lightcal synth --real-world`)
built into a project by "New project from photos" with the page's defaults (the light
guessed from the beam, its cos^m exponent estimated) and the camera's response curve,
then solved by the page's Run (`SolveService`, the engine of `lightcal calibrate`),
land within 2 mm and 0.1 degrees of the truth, as the CLI's path does
(tests/test_real_world_acceptance.py)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from lightcal_app.photo_service import PhotoFields
from lightcal_app.requests import BuildPhotoProject

from lightcal.cli.main import main
from tests.test_app_photo_project import make_service
from tests.test_one_engine import _page_state


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
    truth = json.loads((dataset / "truth.json").read_text())["lights"][0]
    light = page.result.lights[0]
    error_mm = 1e3 * float(np.linalg.norm(light.pose.t_camera_light - truth["position_m"]))
    cos = float(np.dot(light.pose.axis_camera, truth["axis_camera"]))
    error_deg = math.degrees(math.acos(min(1.0, cos)))
    print(f"the page: {error_mm:.2f} mm, {error_deg:.3f} deg from the truth")
    assert error_mm < 2.0 and error_deg < 0.1
