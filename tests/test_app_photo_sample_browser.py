"""The sample's own photos built into a project in the page, solved within 1 mm of the truth.

What a user of the bundled sample does without its project file: the 12 wall photos
(16-bit PNG of 14-bit data, black level 512) and the 16 chessboard photos go in through
the page's upload buttons with the board files and the light's IES; the level fields,
prefilled from the photos' files (0 and 65535: a PNG does not say its sensor's levels),
get the sample's 512 and 16383 (sample_data/README.md), the initial light its
"ruler" guess (90, 0, 0) mm; Build, then Run. The light lands within 1 mm of
sample_data/truth.json (the sample's own project: 0.11 mm), where a build
without the black level landed 10 cm off (issue 27). The built project's zip, downloaded
from the page, unpacks into a project `lightcal calibrate` solves as well.

`test_the_sample_photos_build_a_project_whose_zip_solves_within_1_mm` is the same build
without a browser (through `PhotoService`), in this file for the 500-line bound of
tests/test_app_photo_project.py; it carries no browser mark. It also holds the page's
project equal to the one `lightcal init` writes with the same options (but the paths).
"""

from __future__ import annotations

import io
import json
import zipfile
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from lightcal_app.photo_project import PhotoKind, outcomes_markdown
from lightcal_app.photo_service import PhotoFields, PhotoService
from lightcal_app.requests import BuildPhotoProject
from lightcal_app.server import LightcalApp

from lightcal.cli.main import main
from lightcal.io.camera_file import read_camera
from lightcal.resources import sample_project_dir
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

POSITION_TOLERANCE_M = 1e-3
"""The issue's acceptance: within 1 mm of the truth (the sample's project gives 0.11 mm;
its 1-sigma is 0.25 - 0.43 mm per axis)."""

SAMPLE_FIELDS = PhotoFields(
    initial_position_mm=(90, 0, 0), initial_auto=False, black_level=512, white_level=16383
)
ZIP_MEMBERS = sorted(
    ["project.json", "camera.yaml", "light.ies", "board.yaml", "chessboard.yaml"]
    + [f"{f}/view_{k:02d}.png" for f in ("images", "masks") for k in range(12)]
)


def _truth_m() -> np.ndarray:
    truth = json.loads((sample_project_dir() / "truth.json").read_text(encoding="utf-8"))
    return np.array(truth["light"]["position_m"])


def _solved_in(folder: Path, content: bytes) -> np.ndarray:
    """The light position `lightcal calibrate` gives the project of a zip, m."""
    with zipfile.ZipFile(io.BytesIO(content)) as zf:
        assert sorted(zf.namelist()) == ZIP_MEMBERS
        zf.extractall(folder / "unzipped")
    out = folder / "result.json"
    assert main(["calibrate", str(folder / "unzipped" / "project.json"), "--out", str(out)]) == 0
    return np.array(json.loads(out.read_text(encoding="utf-8"))["lights"][0]["position_m"])


def test_the_sample_photos_build_a_project_whose_zip_solves_within_1_mm(tmp_path: Path) -> None:
    sample = sample_project_dir()
    service, state, messages, _, _ = make_service(tmp_path)
    uploads = [("chessboard", p) for p in sorted((sample / "chessboard").iterdir())]
    uploads += [("wall", p) for p in sorted((sample / "images").iterdir())]
    uploads += [("board", sample / "chessboard.yaml"), ("board", sample / "board.yaml")]
    for kind, path in [*uploads, ("light", sample / "light.ies")]:
        service.upload(kind, path.name, path.read_bytes())  # type: ignore[arg-type]
    levels = service.staged().levels
    assert levels is not None and levels.fields() == (0.0, 65535.0)
    assert "A 14-bit sensor stored in 16 bits has white level 16383" in levels.text()
    service.request_build(SAMPLE_FIELDS, client="page")
    (req,) = list(state.requests)
    assert isinstance(req, BuildPhotoProject)
    service.build(req)
    built = service.last_build
    assert built is not None and messages.titles()[-1] == "Project updated", messages.items
    assert built.camera.file is None and len(built.camera.used) == 16
    assert built.loaded.camera.fx == pytest.approx(read_camera(sample / "camera.yaml").fx)
    assert built.camera.warnings == ()  # the sample's chessboard views are tilted enough
    assert built.warnings == ()  # the black level given, every photo's EXIF exposure read
    warned = replace(built, camera=replace(built.camera, warnings=("the board is tilted",)))
    assert "Note (chessboard photos): the board is tilted" in outcomes_markdown(warned)
    sensor = built.project.spec.sensor
    assert (sensor.black_level, sensor.white_level) == (512.0, 16383.0)
    name, content = service.project_zip()
    assert name == "project-from-photos.zip"
    error_m = float(np.linalg.norm(_solved_in(tmp_path, content) - _truth_m()))
    print(f"lightcal calibrate on the zip: {1e3 * error_m:.3f} mm from the truth")
    assert error_m < POSITION_TOLERANCE_M
    # `lightcal init` with the same options on the zip's files writes the same project.
    unzipped, cli = tmp_path / "unzipped", tmp_path / "cli"
    cli.mkdir()
    argv = ["init", str(unzipped / "images"), "--camera", str(unzipped / "camera.yaml")]
    argv += ["--board", str(unzipped / "board.yaml"), "--light-ies", str(unzipped / "light.ies")]
    argv += ["--initial-position", "0.09", "0", "0", "--black-level", "512"]
    assert main([*argv, "--white-level", "16383", "--out", str(cli / "project.json")]) == 0
    page_spec = json.loads((unzipped / "project.json").read_text(encoding="utf-8"))
    cli_spec = json.loads((cli / "project.json").read_text(encoding="utf-8"))
    for spec in (page_spec, cli_spec):
        for image in spec["images"]:
            del image["path"], image["mask"]
        del spec["camera"]["path"], spec["lights"][0]["rid"]["path"]
    assert page_spec == cli_spec


def _holds(service: PhotoService, what: str, n: int) -> Callable[[], bool]:
    """Whether the staging area holds `n` photos of `what` ("wall_photos", ...)."""
    return lambda: len(getattr(service.staged(), what)) == n


def _upload(page: Any, lightcal_app: LightcalApp, kind: PhotoKind, path: Path) -> None:
    """Choose `path` in the hidden file input of the photo panel's `kind` button."""
    handle = lightcal_app.panels.files.photos.uploads[kind]
    page.locator(f"#file_upload_{handle._impl.uuid}").set_input_files(str(path))


@BROWSER_MARKS[0]
@BROWSER_MARKS[1]
def test_the_sample_photos_built_in_the_page_solve_within_1_mm(
    app: LightcalApp,  # noqa: F811 - the fixture imported above
    browser: Any,  # noqa: F811 - the fixture imported above
    tmp_path: Path,
) -> None:
    sample = sample_project_dir()
    service = app.controller.photos
    panel = app.panels.files.photos
    page, _ = open_page(browser, app, size=(1280, 800))
    page.get_by_role("tab", name="Files").click()
    page.get_by_text("Received: nothing yet.").wait_for()

    # The wall photos one per press, as a user would; the chessboard photos as a zip.
    walls = sorted((sample / "images").iterdir())
    for k, path in enumerate(walls):
        _upload(page, app, "wall", path)
        wait_for(_holds(service, "wall_photos", k + 1), f"photo {k + 1}")
        page.get_by_text(f"wall photos ({k + 1})").wait_for()
    # The level fields: what the PNG files say (they do not know the sensor's black).
    page.get_by_text("levels of view_00.png (16-bit PNG): black 0, white 65535").wait_for()
    assert page.get_by_label("black level", exact=True).input_value() == "0"
    assert page.get_by_label("white level", exact=True).input_value() == "65535"
    chess = tmp_path / "chessboard photos.zip"
    with zipfile.ZipFile(chess, "w") as zf:
        for path in sorted((sample / "chessboard").iterdir()):
            zf.write(path, f"chessboard/{path.name}")
    _upload(page, app, "chessboard", chess)
    wait_for(_holds(service, "chessboard_photos", 16), "the chessboard photos")
    # Each listed in the page (after viser's acknowledgement of the upload: a next upload
    # on the same button before that leaves viser's progress notification spinning).
    for name, shown in (
        ("chessboard.yaml", "board file (chessboard) for the chessboard photos"),
        ("board.yaml", "board file (aruco_grid) for the wall's markers"),
        ("light.ies", "light file: light.ies"),
    ):
        _upload(page, app, "light" if name.endswith(".ies") else "board", sample / name)
        page.get_by_text(shown).first.wait_for()
    page.get_by_text("Ready: press Build project.").wait_for()

    # A black level above the white level is refused at Build, naming the field.
    page.get_by_label("black level", exact=True).fill("70000")
    page.get_by_label("black level", exact=True).press("Enter")
    wait_for(lambda: panel.fields().black_level == 70000, "the black level")
    old = app.state.project
    page.get_by_role("button", name="Build project").click()
    page.get_by_text(
        "white level: expected a value above black level (70000), got 65535"
    ).first.wait_for()
    assert app.state.project is old and not app.state.requests

    # What lightcal init is told in the README: the levels and the initial guess.
    for label, value in (("black level", "512"), ("white level", "16383")):
        page.get_by_label(label, exact=True).fill(value)
        page.get_by_label(label, exact=True).press("Enter")
    wait_for(lambda: panel.fields().black_level == 512, "the black level")
    wait_for(lambda: panel.fields().white_level == 16383, "the white level")
    page.get_by_label("guess the light from the beam").uncheck()  # the README's ruler guess
    x = page.get_by_label("initial light (mm)")
    x.fill("90")
    x.press("Enter")
    wait_for(lambda: panel.fields() == SAMPLE_FIELDS, "the initial light")
    # A later upload prefills again: the fields the user typed into keep the user's values.
    _upload(page, app, "light", sample / "light.ies")
    page.get_by_text("Ready: press Build project.").wait_for()
    app.wait_idle(SLOW_S)
    assert panel.fields() == SAMPLE_FIELDS
    assert page.get_by_label("black level", exact=True).input_value() == "512"
    shot(page, "photos_sample_staged_1280x800.png")

    page.get_by_role("button", name="Build project").click()
    wait_for(lambda: app.state.project is not old, "the new project", timeout=4 * SLOW_S)
    assert app.wait_idle(SLOW_S)
    page.get_by_text("Built: 12 of 12 photos accepted, 0 rejected").wait_for()
    page.get_by_text("calibrated from 16 of 16 chessboard photos").first.wait_for()
    sensor = app.state.project.spec.sensor
    assert (sensor.black_level, sensor.white_level) == (512.0, 16383.0)
    shot(page, "photos_sample_built_1280x800.png")
    page.get_by_role("button", name="Download the project (zip)").scroll_into_view_if_needed()
    shot(page, "photos_sample_download_1280x800.png")

    with page.expect_download(timeout=SLOW_S * 1000) as download:
        page.get_by_role("button", name="Download the project (zip)").click()
    assert download.value.suggested_filename == "project-from-photos.zip"
    content = Path(download.value.path()).read_bytes()

    page.get_by_role("tab", name="Solve").click()
    page.get_by_role("button", name="Run").click()
    wait_for(lambda: app.state.solver_state == "converged", "convergence", timeout=8 * SLOW_S)
    assert app.wait_idle(SLOW_S)
    shot(page, "photos_sample_converged_1280x800.png")
    result = app.state.result
    assert result is not None
    solved = np.asarray(result.lights[0].pose.t_camera_light)
    error_m = float(np.linalg.norm(solved - _truth_m()))
    sigma_mm = 1e3 * np.asarray(result.lights[0].sigma.t_camera_light)
    print(f"page: {1e3 * error_m:.3f} mm from the truth; 1-sigma {np.round(sigma_mm, 3)} mm")
    assert error_m < POSITION_TOLERANCE_M
    # The downloaded zip: lightcal calibrate gives the page's answer.
    assert np.linalg.norm(_solved_in(tmp_path, content) - solved) < 1e-6
    page.context.close()

    # A second browser at 1920 x 1080 sees the fields and the photos' table.
    page, _ = open_page(browser, app, size=(1920, 1080))
    page.get_by_role("tab", name="Files").click()
    page.get_by_text("Built: 12 of 12 photos accepted, 0 rejected").wait_for()
    assert page.get_by_label("black level", exact=True).input_value() == "512"
    page.get_by_text("Built: 12 of 12 photos accepted").scroll_into_view_if_needed()
    shot(page, "photos_sample_built_1920x1080.png")
    page.context.close()
