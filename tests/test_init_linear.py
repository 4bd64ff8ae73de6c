"""`lightcal init` on 8-bit photos (JPEG): `--assume-linear`, `--response FILE`, and the
refusal of 8-bit photos with neither, naming the options the user types."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from lightcal.capture.project_init import GammaEncodedImage, init_project
from lightcal.cli.main import main
from lightcal.io.board_file import write_board
from lightcal.io.camera_file import write_camera
from lightcal.io.images import read_image
from lightcal.io.project import load_project
from lightcal.io.response import ResponseCurve
from lightcal.pipeline.load import load_images
from tests.test_cli_init import BLACK_LEVEL, BOARD, CAMERA, VIEWS, WHITE_LEVEL, wall_image

CODES = np.arange(256) / 255.0
SRGB_TO_LINEAR = np.where(CODES <= 0.04045, CODES / 12.92, ((CODES + 0.055) / 1.055) ** 2.4)


def _srgb_8bit(k: int) -> np.ndarray:
    """View k of the marker wall as an sRGB-encoded 8-bit colour image (B = G = R)."""
    linear = (wall_image(k).astype(np.float64) - BLACK_LEVEL) / (WHITE_LEVEL - BLACK_LEVEL)
    x = np.clip(linear, 0.0, 1.0)
    encoded = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
    grey = np.rint(255.0 * encoded).astype(np.uint8)
    return np.repeat(grey[..., None], 3, axis=2)


@pytest.fixture
def jpegs(tmp_path: Path) -> Path:
    photos = tmp_path / "photos"
    photos.mkdir()
    for k in range(len(VIEWS)):
        cv2.imwrite(str(photos / f"wall_{k}.jpg"), _srgb_8bit(k), [cv2.IMWRITE_JPEG_QUALITY, 95])
    write_camera(CAMERA, tmp_path / "camera.yaml")
    write_board(BOARD, tmp_path / "board.yaml")
    ResponseCurve(np.maximum(SRGB_TO_LINEAR, 1e-6)).save(tmp_path / "response.json")
    return tmp_path


def _argv(root: Path, *extra: str) -> list[str]:
    return [
        "init", str(root / "photos"), "--camera", str(root / "camera.yaml"),
        "--board", str(root / "board.yaml"), "--out", str(root / "project.json"), *extra,
    ]  # fmt: skip


def test_8bit_photos_without_a_flag_are_refused_naming_the_flags(jpegs: Path, capsys):
    assert main(_argv(jpegs)) == 2
    assert capsys.readouterr().err == (
        f"lightcal init: error: {jpegs / 'photos' / 'wall_0.jpg'}: 8-bit image values are "
        "gamma-encoded by the camera, not proportional to light: give the camera's response "
        "curve with --response FILE (fitted from an exposure bracket by lightcal response), "
        "or --assume-linear if the camera wrote linear values\n"
    )
    assert sorted(p.name for p in jpegs.iterdir()) == [
        "board.yaml", "camera.yaml", "photos", "response.json"
    ]  # fmt: skip
    # The library names its own arguments.
    with pytest.raises(GammaEncodedImage) as info:
        init_project(
            jpegs / "photos", camera_path=jpegs / "camera.yaml",
            board_path=jpegs / "board.yaml", out_path=jpegs / "p.json",
        )  # fmt: skip
    assert info.value.detail.endswith(
        "give init_project the camera's response curve (response_path=..., a file of lightcal "
        "response) or assume_linear=True if the camera wrote linear values"
    )
    assert not (jpegs / "p.json").exists() and not (jpegs / "masks").exists()


@pytest.mark.parametrize("flag", ["--assume-linear", "--response"])
def test_jpegs_go_through_init_and_calibrate_reads_them_alike(jpegs: Path, capsys, flag):
    extra = [flag] if flag == "--assume-linear" else [flag, str(jpegs / "response.json")]
    assert main(_argv(jpegs, *extra)) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[-1].startswith("3 of 3 images accepted, 0 rejected")
    sensor = json.loads((jpegs / "project.json").read_text())["sensor"]
    if flag == "--assume-linear":
        assert (sensor["assume_linear"], sensor.get("response")) == (True, None)
    else:
        assert (sensor["assume_linear"], sensor["response"]) == (False, "response.json")
    project = load_project(jpegs / "project.json")
    assert project.names == ["wall_0", "wall_1", "wall_2"]
    for k, view in enumerate(project.views):
        center, *_ = VIEWS[k]
        assert np.linalg.norm(view.center_world - np.asarray(center)) < 2e-3
    # What calibrate reads is what init read: the same linear values.
    loaded = load_images(project)
    curve = None if flag == "--assume-linear" else ResponseCurve.load(jpegs / "response.json")
    first = read_image(jpegs / "photos" / "wall_0.jpg", assume_linear=curve is None, response=curve)
    np.testing.assert_array_equal(loaded.images[0].values, first.values)
    if curve is not None:  # linearised: the wall's bright white is near 1, not near 255
        assert 0.3 < np.percentile(first.values, 99) <= 1.0


def test_linear_flag_refusals(jpegs: Path, capsys):
    with pytest.raises(SystemExit) as usage:
        main(_argv(jpegs, "--assume-linear", "--response", str(jpegs / "response.json")))
    assert usage.value.code == 2
    assert capsys.readouterr().err.splitlines()[-1] == (
        "lightcal init: error: argument --response: not allowed with argument --assume-linear"
    )
    assert main(_argv(jpegs, "--response", str(jpegs / "r.json"), "--white-level", "200")) == 2
    assert capsys.readouterr().err == (
        "lightcal init: error: --white-level: with --response the white level is code 255; do "
        "not give one\n"
    )
    assert main(_argv(jpegs, "--response", str(jpegs / "missing.json"))) == 2
    assert capsys.readouterr().err == (
        f"lightcal init: error: {jpegs / 'missing.json'}: file not found\n"
    )
    # A response curve for 16-bit photos: each is rejected, saying why.
    for k in range(len(VIEWS)):
        (jpegs / "photos" / f"wall_{k}.jpg").unlink()
        cv2.imwrite(str(jpegs / "photos" / f"wall_{k}.png"), wall_image(k))
    assert main(_argv(jpegs, "--response", str(jpegs / "response.json"))) == 2
    assert capsys.readouterr().err == (
        f"lightcal init: error: {jpegs / 'photos'}: no usable images: all 3 were rejected "
        "(wall_0.png: a response curve applies only to 8-bit images; this image has 16 bits; "
        "wall_1.png: a response curve applies only to 8-bit images; this image has 16 bits; "
        "wall_2.png: a response curve applies only to 8-bit images; this image has 16 bits)\n"
    )
    assert not (jpegs / "project.json").exists() and not (jpegs / "masks").exists()


def test_jpegs_of_four_official_tags_at_the_corners_of_a_rectangle(tmp_path: Path, capsys):
    """The issue's wall: four tag36h11 (official images) at the corners of 1.2 m x 0.7 m,
    photographed as 8-bit sRGB JPEGs under an uneven light: init --assume-linear with a
    `markers` board gives every pose."""
    from lightcal.capture.boards import LayoutMarker, MarkerLayout
    from lightcal.capture.plane_texture import look_at_pose, render_plane_image
    from lightcal.core.camera import Camera

    camera = Camera.from_params(
        fx=700.0, fy=700.0, cx=479.6, cy=359.2, width=960, height=720, dist=(-0.06, 0.01, 0, 0)
    )
    corners = [(-0.6, 0.35), (0.6, 0.35), (0.6, -0.35), (-0.6, -0.35)]
    layout = MarkerLayout(
        tuple(LayoutMarker("DICT_APRILTAG_36h11", k, c, 0.15) for k, c in enumerate(corners))
    )
    rendering = layout.render(2000.0)
    views = [((0.1, -0.05, 1.6), 0.05), ((-0.3, 0.2, 1.7), -0.1), ((0.35, 0.1, 1.55), 3.0)]
    photos = tmp_path / "photos"
    photos.mkdir()
    rows, cols = np.mgrid[0:720, 0:960]
    for k, (center, roll) in enumerate(views):
        R, t = look_at_pose(center, (0.0, 0.0, 0.0), roll_rad=roll)
        albedo = render_plane_image(
            camera, R, t, 0.05 + 0.9 * rendering.image / 255.0, rendering.px_per_m,
            rendering.top_left_world_m, background=0.9,
        )  # fmt: skip
        light = 0.25 + 0.7 * np.exp(-((cols - 400.0) ** 2 + (rows - 380.0) ** 2) / (2 * 300.0**2))
        linear = albedo * light + np.random.default_rng(k).normal(0.0, 0.003, albedo.shape)
        x = np.clip(linear, 0.0, 1.0)
        encoded = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
        cv2.imwrite(
            str(photos / f"view_{k}.jpg"), np.rint(255.0 * encoded).astype(np.uint8),
            [cv2.IMWRITE_JPEG_QUALITY, 92],
        )  # fmt: skip
    write_camera(camera, tmp_path / "camera.yaml")
    write_board(layout, tmp_path / "tags.yaml")
    argv = ["init", str(photos), "--camera", str(tmp_path / "camera.yaml")]
    argv += ["--board", str(tmp_path / "tags.yaml"), "--assume-linear"]
    assert main([*argv, "--out", str(tmp_path / "project.json")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split(",")[0] for line in lines[:3]] == [
        f"view_{k}.jpg: 4 markers" for k in range(3)
    ]
    project = load_project(tmp_path / "project.json")
    for k, view in enumerate(project.views):
        center, roll = views[k]
        R, _ = look_at_pose(center, (0.0, 0.0, 0.0), roll_rad=roll)
        cos = np.clip((np.trace(view.R_camera_world @ R.T) - 1.0) / 2.0, -1.0, 1.0)
        assert np.degrees(np.arccos(cos)) < 0.05
        assert np.linalg.norm(view.center_world - np.asarray(center)) < 2e-3
