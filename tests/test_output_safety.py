"""An output is never one of the command's inputs, even with --force (issue 28).

`export` (the result, the --project file and the files it names), `camera calibrate` (the
board file and the photos), `camera import` (the camera file) and `render` (the result
file) are refused before any work, through `lightcal.io.outputs.check_output_file`; the
input is byte-identical afterwards. A small synth dataset (4 views, 160 x 120) calibrated
once per module gives the result.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from lightcal.capture.boards import Chessboard
from lightcal.cli.main import main
from lightcal.io.board_file import write_board

IES = """IESNA:LM-63-2002
TILT=NONE
1 1000 1 7 1 1 1 0 0 0
1 1 100
0 15 30 45 60 75 90
0
1000 950 850 700 500 250 0
"""


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The synth dataset with result.json, light.ies and p_ies.json (the light's RID from
    light.ies)."""
    folder = tmp_path_factory.mktemp("safety") / "data"
    argv = ["synth", str(folder), "--views", "4", "--width", "160", "--height", "120"]
    assert main([*argv, "--quiet"]) == 0
    project = folder / "project.json"
    result = folder / "result.json"
    assert main(["calibrate", str(project), "--out", str(result), "--quiet"]) == 0
    (folder / "light.ies").write_text(IES)
    doc = json.loads(project.read_text())
    doc["lights"][0]["rid"] = {"type": "ies", "path": "light.ies"}
    (folder / "p_ies.json").write_text(json.dumps(doc))
    return folder


def _refused(argv: list[str], kept: Path, capsys: pytest.CaptureFixture[str]) -> str:
    """Runs argv, expects exit 2 and `kept` unchanged; returns the one error line."""
    before = kept.read_bytes()
    capsys.readouterr()
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1, captured.err
    assert kept.read_bytes() == before
    return captured.err.rstrip("\n")


@pytest.mark.parametrize("force", [False, True])
def test_export_never_replaces_the_result_it_reads(data, capsys, force):
    result = data / "result.json"
    argv = ["export", str(result), "--format", "opencv", "--out", str(result)]
    assert _refused(argv + ["--force"] * force, result, capsys) == (
        f"lightcal export: error: {result}: --out: is the result file, an input of the "
        "export; write elsewhere"
    )


@pytest.mark.parametrize("force", [False, True])
def test_export_never_replaces_the_project_file(data, capsys, force):
    project = data / "p_ies.json"
    argv = ["export", str(data / "result.json"), "--format", "blender", "--out", str(project)]
    argv += ["--project", str(project)] + ["--force"] * force
    assert _refused(argv, project, capsys) == (
        f"lightcal export: error: {project}: --out: is the project file, an input of the "
        "export; write elsewhere"
    )


@pytest.mark.parametrize("force", [False, True])
def test_export_never_replaces_the_projects_ies_file(data, capsys, force):
    ies = data / "light.ies"
    argv = ["export", str(data / "result.json"), "--format", "ies", "--out", str(ies)]
    argv += ["--project", str(data / "p_ies.json")] + ["--force"] * force
    assert _refused(argv, ies, capsys) == (
        f"lightcal export: error: {ies}: --out: is the RID file of light light, an input of "
        "the export; write elsewhere"
    )


def test_export_knows_an_input_under_another_spelling(data, capsys):
    """A path through `..` or a symbolic link is the same file."""
    image = data / "images" / "view_01.png"
    other = data / "images" / ".." / "images" / "view_01.png"
    argv = ["export", str(data / "result.json"), "--format", "opencv", "--out", str(other)]
    argv += ["--project", str(data / "project.json"), "--force"]
    assert _refused(argv, image, capsys) == (
        f"lightcal export: error: {other}: --out: is image view_01, an input of the export; "
        "write elsewhere"
    )
    link = data / "linked_result.json"
    link.symlink_to(data / "result.json")
    try:
        argv = ["export", str(data / "result.json"), "--format", "opencv", "--out", str(link)]
        assert _refused([*argv, "--force"], data / "result.json", capsys) == (
            f"lightcal export: error: {link}: --out: is the result file, an input of the "
            "export; write elsewhere"
        )
    finally:
        link.unlink()


def test_export_still_replaces_its_own_output_with_force(data, tmp_path, capsys):
    out = tmp_path / "light.yaml"
    out.write_text("old")
    argv = ["export", str(data / "result.json"), "--format", "opencv", "--out", str(out)]
    assert main([*argv, "--force"]) == 0
    assert out.read_text().startswith("%YAML")


@pytest.fixture
def board_and_photos(tmp_path: Path) -> tuple[Path, Path]:
    """A chessboard file and a folder of two blank photos (no calibration could succeed:
    a refusal that names --out was made before any work)."""
    board = tmp_path / "board.yaml"
    write_board(Chessboard(9, 6, 0.03), board)
    photos = tmp_path / "photos"
    photos.mkdir()
    for k in range(2):
        cv2.imwrite(str(photos / f"chess_{k}.png"), np.full((120, 160), 128, np.uint8))
    return board, photos


def test_camera_calibrate_never_replaces_its_board_file(board_and_photos, capsys):
    board, photos = board_and_photos
    argv = ["camera", "calibrate", str(photos), "--board", str(board), "--out", str(board)]
    assert _refused(argv, board, capsys) == (
        f"lightcal camera: error: {board}: --out: is the board file, an input of the "
        "calibration; write elsewhere"
    )


def test_camera_calibrate_never_replaces_a_photo(board_and_photos, capsys):
    board, photos = board_and_photos
    photo = photos / "chess_1.png"
    argv = ["camera", "calibrate", str(photos), "--board", str(board), "--out", str(photo)]
    assert _refused(argv, photo, capsys) == (
        f"lightcal camera: error: {photo}: --out: is image chess_1.png, an input of the "
        "calibration; write elsewhere"
    )
    given = photos / "chess_0.png"
    argv = ["camera", "calibrate", str(given), "--board", str(board), "--out", str(given)]
    assert _refused(argv, given, capsys) == (
        f"lightcal camera: error: {given}: --out: is image chess_0.png, an input of the "
        "calibration; write elsewhere"
    )


def test_camera_import_never_replaces_its_file(data, tmp_path, capsys):
    camera = tmp_path / "camera.yaml"
    shutil.copy(data / "camera.yaml", camera)
    argv = ["camera", "import", str(camera), "--out", str(camera)]
    assert _refused(argv, camera, capsys) == (
        f"lightcal camera: error: {camera}: --out: is the camera file, an input of the "
        "import; write elsewhere"
    )


def test_render_never_replaces_the_result_even_with_force(data, tmp_path, capsys):
    """A result saved under a render's name in --out is not written over."""
    out = tmp_path / "renders"
    out.mkdir()
    result = out / "view_02_rendered.tif"
    shutil.copy(data / "result.json", result)
    argv = ["render", str(data / "project.json"), "--result", str(result), "--out", str(out)]
    assert _refused([*argv, "--force"], result, capsys) == (
        f"lightcal render: error: {result}: --out: is the result file, an input of the "
        "render; write elsewhere"
    )
    assert sorted(p.name for p in out.iterdir()) == ["view_02_rendered.tif"]


def test_export_never_replaces_an_input_with_a_mitsuba_texture(data, tmp_path, capsys):
    """The texture written beside --out (`<stem>_rid_0.png`) is checked as --out is."""
    result = tmp_path / "scene_rid_0.png"
    shutil.copy(data / "result.json", result)
    out = tmp_path / "scene.xml"
    argv = ["export", str(result), "--format", "mitsuba", "--out", str(out), "--force"]
    argv += ["--project", str(data / "project.json")]
    assert _refused(argv, result, capsys) == (
        f"lightcal export: error: {result}: --out: is the result file, an input of the "
        "export; write elsewhere"
    )
    assert not out.exists()


def test_calibrate_replaces_an_earlier_result_and_only_that(
    tiny_dataset: Path, tmp_path: Path
) -> None:
    """Run again, calibrate replaces its earlier result; any other existing file needs
    --force (and an input of the project is never replaced)."""
    out = tmp_path / "result.json"
    argv = ["calibrate", str(tiny_dataset / "project.json"), "--quiet", "--out", str(out)]
    assert main(argv) in (0, 3)
    first = out.read_bytes()
    assert main(argv) in (0, 3)  # an earlier result: replaced without --force
    assert out.read_bytes() != first  # (the time taken differs)
    notes = tmp_path / "notes.json"
    notes.write_text('{"mine": true}')
    argv[-1] = str(notes)
    assert main(argv) == 2
    assert notes.read_text() == '{"mine": true}'
    assert main([*argv, "--force"]) in (0, 3)
    assert "lightcal_version" in notes.read_text()
