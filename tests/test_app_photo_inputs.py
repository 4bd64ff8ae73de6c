"""A new project from photos (`lightcal_app.photo_project`) takes what `lightcal init`
takes (issue 27): 8-bit photos with "8-bit photos are linear" (`--assume-linear`) or
the camera's response curve (`--response`), and several board files on one wall
(`--board A --board B`); a board file sharing a marker with a staged one replaces it.
"""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import cv2
import numpy as np
import pytest
from lightcal_app.photo_build import project_zip_bytes
from lightcal_app.photo_project import PhotoOptions, PhotoStaging, staged_markdown

from lightcal.capture.boards import ArucoGridBoard
from lightcal.errors import InputError
from lightcal.io.board_file import write_board
from lightcal.io.project import load_project
from lightcal.io.response import ResponseCurve
from lightcal.pipeline import load_images
from tests.photo_fixtures import BLANK_NAME, BOARD, Photos, write_photos

PITCH_M = BOARD.marker_length_m + BOARD.separation_m


@pytest.fixture(scope="module")
def photos(tmp_path_factory: pytest.TempPathFactory) -> Photos:
    return write_photos(tmp_path_factory.mktemp("photos"))


@pytest.fixture(scope="module")
def jpegs(photos: Photos, tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """The wall photos (but the blank) as 8-bit JPEGs of the same, linear, values."""
    folder = tmp_path_factory.mktemp("jpeg")
    out = []
    for path in photos.photos:
        if path.name == BLANK_NAME:
            continue
        values = cv2.imread(str(path), cv2.IMREAD_UNCHANGED).astype(np.float64)
        jpeg = folder / (path.stem + ".jpg")
        cv2.imwrite(str(jpeg), np.clip(np.rint(values / 257.0), 0, 255).astype(np.uint8))
        out.append(jpeg)
    return out


def _stage(staging: PhotoStaging, photos: Photos, walls: list[Path]) -> None:
    for path in walls:
        staging.receive("wall", path.name, path.read_bytes())
    staging.receive("camera", "camera.yaml", photos.camera.read_bytes())
    staging.receive("board", "board.yaml", photos.board.read_bytes())


def _centres(project_path: Path) -> np.ndarray:
    return np.array([v.center_world for v in load_project(project_path).views])


def test_8_bit_photos_need_linear_or_a_response_curve(
    photos: Photos, jpegs: list[Path], tmp_path: Path
) -> None:
    staging = PhotoStaging(tmp_path / "photos")
    _stage(staging, photos, jpegs)
    levels = staging.staged().levels
    assert levels is not None and levels.bits == 8
    assert "upload the camera's response curve" in levels.text()
    assert "tick '8-bit photos are linear'" in levels.text()
    with pytest.raises(InputError) as info:
        staging.build(options=PhotoOptions(half_angle_deg=30.0))
    assert str(info.value) == (
        "wall_0.jpg: 8-bit photos are gamma-encoded by the camera, not proportional to light: "
        "upload the camera's response curve (Response curve button; lightcal response makes "
        "it from an exposure bracket), or tick '8-bit photos are linear' if the camera wrote "
        "linear values"
    )
    built = staging.build(options=PhotoOptions(half_angle_deg=30.0, assume_linear=True))
    assert len(built.accepted) == len(jpegs)
    assert built.project.spec.sensor.assume_linear is True
    # The poses from the markers of 320 x 240 JPEGs (quality 95) at 0.8-1.35 m: measured
    # 4.7 mm at worst (the 16-bit PNGs: < 1 mm).
    for view, true in zip(built.project.views, photos.views, strict=True):
        assert np.linalg.norm(view.center_world - true.center_world) < 8e-3


def test_a_response_curve_linearises_8_bit_photos_and_travels_in_the_zip(
    photos: Photos, jpegs: list[Path], tmp_path: Path
) -> None:
    curve = ResponseCurve(((np.arange(256) + 0.5) / 256.0)[:, None])  # linear, > 0
    curve_path = tmp_path / "curve.json"
    curve.save(curve_path)
    staging = PhotoStaging(tmp_path / "photos")
    _stage(staging, photos, jpegs)
    received = staging.receive("response", "curve.json", curve_path.read_bytes())
    assert received.placed == (("response curve", "curve.json"),)
    staged = staging.staged()
    assert staged.response == "curve.json"
    assert "response curve: curve\\.json (linearises 8-bit photos)" in staged_markdown(staged)
    built = staging.build(options=PhotoOptions(half_angle_deg=30.0, assume_linear=True))
    sensor = built.project.spec.sensor
    assert sensor.response is not None and sensor.assume_linear is False  # the curve wins
    loaded = load_images(built.project)
    # The curve maps code c to (c + 0.5) / 256: the photos' values are below 1.
    assert 0.5 < max(float(im.values.max()) for im in loaded.images) < 1.0
    with zipfile.ZipFile(io.BytesIO(project_zip_bytes(built))) as zf:
        data = json.loads(zf.read("project.json"))
        assert data["sensor"]["response"] == "curve.json"
        assert "curve.json" in zf.namelist()
        zf.extractall(tmp_path / "unzipped")
    again = load_project(tmp_path / "unzipped" / "project.json")
    assert len(load_images(again).images) == len(jpegs)
    with pytest.raises(InputError) as info:
        staging.receive("response", "curve.txt", b"1 2 3")
    assert str(info.value) == (
        "curve.txt: unsupported response curve suffix '.txt': expected a .json curve written "
        "by lightcal response (or a (256, C) .npy array)"
    )


def _half(first_row: int, rows: int) -> ArucoGridBoard:
    """Rows `first_row ..` of the fixture's board, as a board of their own."""
    x0, y0 = BOARD.origin_world_m
    return ArucoGridBoard(
        BOARD.dictionary,
        BOARD.markers_x,
        rows,
        BOARD.marker_length_m,
        BOARD.separation_m,
        first_id=first_row * BOARD.markers_x,
        origin_world_m=(x0, y0 - first_row * PITCH_M),
    )


def test_two_board_files_of_one_wall_give_the_poses_of_the_whole_board(
    photos: Photos, tmp_path: Path
) -> None:
    walls = [p for p in photos.photos if p.name != BLANK_NAME]
    whole = PhotoStaging(tmp_path / "whole")
    _stage(whole, photos, walls)
    reference = whole.build(options=PhotoOptions(half_angle_deg=30.0)).project.path

    top, bottom = tmp_path / "top.yaml", tmp_path / "bottom.yaml"
    write_board(_half(0, 2), top)
    write_board(_half(2, 2), bottom)
    split = PhotoStaging(tmp_path / "split")
    for path in walls:
        split.receive("wall", path.name, path.read_bytes())
    split.receive("camera", "camera.yaml", photos.camera.read_bytes())
    for path in (top, bottom):
        split.receive("board", path.name, path.read_bytes())
    staged = split.staged()
    assert staged.wall_boards == (("aruco_grid", "bottom.yaml"), ("aruco_grid", "top.yaml"))
    text = staged_markdown(staged)
    assert "board file (aruco_grid) for the wall's markers: top\\.yaml" in text
    assert "board file (aruco_grid) for the wall's markers: bottom\\.yaml" in text
    built = split.build(options=PhotoOptions(half_angle_deg=30.0))
    assert len(built.accepted) == len(walls)
    assert sorted(p.name for p in built.boards) == ["bottom.yaml", "top.yaml"]
    # The same markers, the same poses (to the pose solver's tolerance: 5e-8 m measured).
    np.testing.assert_allclose(_centres(built.project.path), _centres(reference), atol=1e-6)
    # The whole board again shares the halves' markers: it replaces both.
    split.receive("board", "board.yaml", photos.board.read_bytes())
    assert split.staged().wall_boards == (("aruco_grid", "board.yaml"),)
