"""Tests of `lightcal init` (`lightcal.capture.project_init`) on synthetic images of a marker
wall."""

from __future__ import annotations

import dataclasses
import functools
import io
import json
import math
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
from PIL import Image

from lightcal.capture.boards import ArucoGridBoard, Chessboard
from lightcal.capture.marker_pose import solve_pose
from lightcal.capture.plane_texture import look_at_pose, render_plane_image
from lightcal.capture.project_init import POSE_FLOOR_DEG, POSE_FLOOR_M, init_project
from lightcal.cli.main import main
from lightcal.core.camera import Camera
from lightcal.core.rotations import rotvec_from_matrix
from lightcal.io.board_file import write_board
from lightcal.io.camera_file import write_camera
from lightcal.io.project import ExposureSpec, load_project

WIDTH, HEIGHT = 640, 480
CAMERA = Camera.from_params(
    fx=560.0, fy=560.0, cx=321.7, cy=238.4, width=WIDTH, height=HEIGHT, dist=(-0.1, 0.02, 0.0, 0.0)
)
BOARD = ArucoGridBoard("DICT_4X4_50", 7, 5, 0.07, 0.06, origin_world_m=(-0.42, 0.29))
BLACK_LEVEL, WHITE_LEVEL = 256.0, 4095.0
# (camera centre (m), target on the wall (m), roll (rad), exposure time (s))
VIEWS = [
    ((0.05, -0.04, 0.75), (0.02, 0.01, 0.0), 0.1, 1 / 60),
    ((-0.30, 0.15, 0.80), (0.0, 0.0, 0.0), -0.2, 1 / 30),
    ((0.25, 0.20, 0.95), (0.03, -0.02, 0.0), 0.3, 1 / 40),
]
IES = """IESNA:LM-63-2002
[TEST] test
TILT=NONE
1 -1 1 4 1 1 2 0 0 0
1 1 0
0 30 60 90
0
1000 700 200 0
"""


def _pose(k: int) -> tuple[np.ndarray, np.ndarray]:
    center, target, roll, _ = VIEWS[k]
    return look_at_pose(center, target, roll_rad=roll)


@functools.cache
def wall_image(k: int) -> np.ndarray:
    """(H, W) uint16 12-bit view k: albedo times a light spot, noise, black level."""
    R, t = _pose(k)
    rendering = BOARD.render(2000)
    albedo = render_plane_image(
        CAMERA,
        R,
        t,
        0.05 + 0.95 * rendering.image / 255.0,
        rendering.px_per_m,
        rendering.top_left_world_m,
        background=1.0,
    )
    rows, cols = np.mgrid[0:HEIGHT, 0:WIDTH]
    spot = 0.25 + np.exp(-((cols - 300.0) ** 2 + (rows - 260.0) ** 2) / (2 * 220.0**2))
    rng = np.random.default_rng(k)
    value = BLACK_LEVEL + 2800.0 * albedo * spot + rng.normal(0.0, 3.0, albedo.shape)
    return np.clip(np.rint(value), 0, WHITE_LEVEL).astype(np.uint16)


def _png(image: np.ndarray, exposure_time_s: float | None) -> bytes:
    buffer = io.BytesIO()
    kwargs = {}
    if exposure_time_s is not None:
        exif = Image.Exif()
        exif[0x8769] = {0x829A: exposure_time_s, 0x829D: 2.8, 0x8827: 200}
        kwargs["exif"] = exif
    Image.fromarray(image).save(buffer, format="PNG", **kwargs)
    return buffer.getvalue()


@pytest.fixture
def scene(tmp_path: Path) -> dict[str, Path]:
    """A folder with 3 good views (EXIF), a blank image and a corrupt file; camera, board,
    IES files."""
    images = tmp_path / "photos"
    images.mkdir()
    for k, (*_, exposure) in enumerate(VIEWS):
        (images / f"wall_{k}.png").write_bytes(_png(wall_image(k), exposure))
    blank = np.full((HEIGHT, WIDTH), 2000, np.uint16)
    (images / "wall_3_blank.png").write_bytes(_png(blank, 1 / 60))
    (images / "wall_4_corrupt.png").write_bytes(b"\x89PNG\r\n\x1a\nnot really")
    (images / "notes.txt").write_text("not an image")
    write_camera(CAMERA, tmp_path / "camera.yaml")
    write_board(BOARD, tmp_path / "board.yaml")
    (tmp_path / "led.ies").write_text(IES)
    return {"dir": tmp_path, "images": images}


def _angle_deg(R_a: np.ndarray, R_b: np.ndarray) -> float:
    return math.degrees(math.acos(np.clip((np.trace(R_a @ R_b.T) - 1.0) / 2.0, -1.0, 1.0)))


def test_init_writes_a_project_with_poses_masks_and_exposures(scene, capsys):
    root = scene["dir"]
    out = root / "project.json"
    argv = ["init", str(scene["images"]), "--camera", str(root / "camera.yaml")]
    argv += ["--board", str(root / "board.yaml"), "--light-ies", str(root / "led.ies")]
    argv += ["--initial-position", "0.1", "0", "0.01", "--initial-axis", "0", "0.1", "1"]
    argv += ["--black-level", "256", "--white-level", "4095", "--out", str(out)]
    assert main(argv) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 6
    for k in range(3):
        match = re.fullmatch(
            rf"wall_{k}\.png: (\d+) markers, rms (\d\.\d{{3}}) px, camera at \(.*\) m", lines[k]
        )
        assert match, lines[k]
        assert int(match[1]) >= 8 and float(match[2]) < 0.3
    assert lines[3] == "wall_3_blank.png: rejected: found 0 markers, need at least 4"
    assert lines[4] == "wall_4_corrupt.png: rejected: not a readable PNG image"
    assert lines[5] == (
        f"3 of 5 images accepted, 2 rejected; masks in {root / 'masks'}; project written to {out}"
    )

    data = json.loads(out.read_text())
    assert data["camera"] == {"path": "camera.yaml", "skew": 0.0, "dist": []}
    assert data["sensor"]["black_level"] == 256.0 and data["sensor"]["white_level"] == 4095.0
    assert data["lights"][0]["rid"] == {"type": "ies", "profile": "cos_power", "path": "led.ies"}
    assert data["lights"][0]["initial"]["position_m"] == [0.1, 0.0, 0.01]
    assert [im["path"] for im in data["images"]] == [f"photos/wall_{k}.png" for k in range(3)]
    assert [im["mask"] for im in data["images"]] == [f"masks/wall_{k}.png" for k in range(3)]

    project = load_project(out)
    assert project.names == ["wall_0", "wall_1", "wall_2"]
    np.testing.assert_allclose(
        project.lights[0].initial.axis_camera, [0, 0.1, 1] / np.hypot(0.1, 1)
    )
    for k, view in enumerate(project.views):
        R, t = _pose(k)
        assert _angle_deg(view.R_camera_world, R) < 0.05
        assert np.linalg.norm(view.center_world - (-R.T @ t)) < 1e-3
        # The marker fit's covariance of (delta, c) plus the systematic floor, as stored.
        covariance = np.array(data["images"][k]["T_camera_world"]["covariance"])
        assert covariance.shape == (6, 6)
        np.testing.assert_array_equal(project.pose_covariances[k], covariance)
        assert np.linalg.eigvalsh(covariance).min() > 0.0
        floor = np.array([np.radians(POSE_FLOOR_DEG)] * 3 + [POSE_FLOOR_M] * 3)
        fit_sigma = np.sqrt(np.diag(covariance) - floor**2)
        assert np.all(fit_sigma[:3] < np.radians(0.05)) and np.all(fit_sigma[3:] < 1e-3)
        # Exposure from EXIF, relative to the first image.
        assert view.exposure == pytest.approx(VIEWS[k][3] / VIEWS[0][3])
        spec = project.spec.images[k].exposure
        assert isinstance(spec, ExposureSpec)
        assert (spec.exposure_time_s, spec.iso, spec.f_number) == (VIEWS[k][3], 200.0, 2.8)

        # The mask covers every marker of the board in the image (detected or cut by the
        # border) and leaves the white wall between them.
        mask = cv2.imread(str(project.mask_paths[k]), cv2.IMREAD_UNCHANGED)
        assert mask is not None
        assert mask.shape == (HEIGHT, WIDTH) and mask.dtype == np.uint8
        assert set(np.unique(mask)) == {0, 255}
        corners = BOARD.corners_world(BOARD.ids)
        centers_px, _ = CAMERA.project(corners.mean(axis=1) @ R.T + t)
        inside = np.all((centers_px >= 0) & (centers_px <= [WIDTH - 1, HEIGHT - 1]), axis=1)
        assert inside.sum() >= 12
        u, v = np.rint(centers_px[inside]).astype(int).T
        assert np.all(mask[v, u] == 255)
        gaps_world = corners[:, 1] + np.array([BOARD.separation_m / 2, 0.0, 0.0])  # between
        gaps_px, _ = CAMERA.project(gaps_world @ R.T + t)
        ok = np.all((gaps_px >= 0) & (gaps_px <= [WIDTH - 1, HEIGHT - 1]), axis=1)
        u, v = np.rint(gaps_px[ok]).astype(int).T
        assert np.all(mask[v, u] == 0)
        # Masked: 20 - 50 % of the image (7 cm markers 13 cm apart, plus the margin).
        assert 0.1 < np.mean(mask > 0) < 0.5


def test_library_result_and_defaults(scene):
    root = scene["dir"]
    seen = []
    result = init_project(
        scene["images"],
        camera_path=root / "camera.yaml",
        board_path=root / "board.yaml",
        out_path=root / "sub.yaml",
        min_markers=32,
        mask_margin_px=0.0,
        on_image=lambda outcome: seen.append(outcome.name),
    )
    assert seen == ["wall_0", "wall_1", "wall_2", "wall_3_blank", "wall_4_corrupt"]
    accepted = [o.name for o in result.accepted]
    assert accepted == ["wall_2"]  # 35 markers; wall_0 and wall_1 show 30 and 31
    assert result.report().splitlines()[:4] == [
        "wall_0.png: rejected: found 30 markers, need at least 32",
        "wall_1.png: rejected: found 31 markers, need at least 32",
        result.accepted[0].report_line(),
        "wall_3_blank.png: rejected: found 0 markers, need at least 32",
    ]
    assert result.accepted[0].report_line().startswith("wall_2.png: 35 markers, rms 0.0")
    narrow = np.asarray(cv2.imread(str(result.accepted[0].mask_path), cv2.IMREAD_UNCHANGED)) > 0
    again = init_project(
        scene["images"],
        camera_path=root / "camera.yaml",
        board_path=root / "board.yaml",
        out_path=root / "wide.json",
        min_markers=32,
        mask_margin_px=6.0,
    )
    assert again.accepted[0].mask_path == root / "masks" / "wall_2.png"  # replaced
    wide = np.asarray(cv2.imread(str(root / "masks" / "wall_2.png"), cv2.IMREAD_UNCHANGED)) > 0
    assert np.all(wide[narrow]) and wide.sum() > 1.2 * narrow.sum()
    assert result.warnings == [
        "no light file nor half angle given: the light's profile is taken as cos^m, its "
        "exponent estimated from a start at a half angle of 30 degrees (give its IES/LDT file "
        "or half angle if known)"
    ]
    spec = result.spec
    assert spec.lights[0].rid.type == "half_angle" and spec.lights[0].rid.half_angle_deg == 30.0
    assert spec.lights[0].estimate_rid == "cos_power"
    assert spec.lights[0].initial == "auto"  # no guess given: from the beam
    assert spec.sensor.black_level is None
    assert spec.sensor.estimate_offset is False  # 16-bit photos: their black is known
    # Every pixel, binned to at most 300,000 super-pixels (3 images of 1200 x 800: 2 x 2).
    assert (spec.selection.strategy, spec.selection.binning) == ("all", 2)
    assert (root / "sub.yaml").read_text().startswith("version: 1\n")  # YAML by suffix
    assert load_project(root / "sub.yaml").names == accepted


def test_partial_exif_is_a_warning(scene, capsys):
    root = scene["dir"]
    (scene["images"] / "wall_1.png").write_bytes(_png(wall_image(1), None))
    argv = ["init", str(scene["images"]), "--camera", str(root / "camera.yaml")]
    argv += ["--board", str(root / "board.yaml"), "--half-angle-deg", "25"]
    assert main([*argv, "--out", str(root / "p.json")]) == 0
    out = capsys.readouterr().out
    assert (
        "warning: EXIF exposure found in 2 of 3 images (missing in wall_1.png): ignored, "
        "every image gets exposure 1; give the exposures in the project or estimate "
        "per-image gains (solver.estimate_gains)\n"
    ) in out
    project = load_project(root / "p.json")
    assert [v.exposure for v in project.views] == [1.0, 1.0, 1.0]
    assert project.spec.lights[0].rid.half_angle_deg == 25.0


def _init(root: Path, images: Path, *extra: str) -> list[str]:
    return [
        "init",
        str(images),
        "--camera",
        str(root / "camera.yaml"),
        "--board",
        str(root / "board.yaml"),
        "--out",
        str(root / "project.json"),
        "--force",  # the cases below run in one folder, one after another
        *extra,
    ]


def test_errors_are_one_line_naming_the_input(scene, capsys):
    root, images = scene["dir"], scene["images"]

    def error(argv: list[str]) -> str:
        assert main(argv) == 2
        captured = capsys.readouterr()
        assert captured.err.count("\n") == 1
        return captured.err.removeprefix("lightcal init: error: ").rstrip("\n")

    empty = root / "empty"
    empty.mkdir()
    assert error(_init(root, empty)) == (
        f"{empty}: no images found: expected image files (.png, .jpg, .tif, .tiff, .npy, "
        ".exr or camera raw such as .dng, .cr2, .nef, .arw) directly in the folder"
    )
    assert error(_init(root, root / "nope")) == f"{root / 'nope'}: image folder not found"

    only_bad = root / "bad"
    only_bad.mkdir()
    (only_bad / "blank.png").write_bytes(_png(np.full((HEIGHT, WIDTH), 9, np.uint16), None))
    (only_bad / "small.png").write_bytes(_png(wall_image(0)[:240, :320], None))
    assert error(_init(root, only_bad)) == (
        f"{only_bad}: no usable images: all 2 were rejected (blank.png: found 0 markers, need "
        "at least 4; small.png: image is 320x240 px, expected 640x480 px (the camera's size))"
    )

    (root / "camera.yaml").write_text("%YAML:1.0\n---\ncamera_matrix: [1, 2\n")
    message = error(_init(root, images))
    assert message.startswith(f"{root / 'camera.yaml'}")
    write_camera(CAMERA, root / "camera.yaml")

    (root / "board.yaml").write_bytes(b"\x00\xff\xfe binary junk")
    assert error(_init(root, images)) == (
        f"{root / 'board.yaml'}: the board file is not UTF-8 text (byte 1): save it as UTF-8"
    )
    write_board(Chessboard(9, 6, 0.03), root / "board.yaml")
    assert error(_init(root, images)) == (
        f"{root / 'board.yaml'}: a chessboard has no markers, so it gives no camera pose on "
        "the wall: expected an aruco_grid, charuco or markers board"
    )
    write_board(BOARD, root / "board.yaml")

    (root / "bad.ies").write_text("IESNA:LM-63-2002\nTILT=NONE\n1 -1 1 4\n")
    assert error(_init(root, images, "--light-ies", str(root / "bad.ies"))).startswith(
        f"{root / 'bad.ies'}:"
    )
    assert error(_init(root, images, "--light-ies", str(root / "led.csv"))) == (
        f"{root / 'led.csv'}: unsupported light file suffix '.csv': expected .ies or .ldt"
    )
    message = error(_init(root, images, "--initial-position", "0", "0", "5"))
    assert re.fullmatch(
        re.escape(f"{(root / 'project.json').resolve()}: lights[0].initial.position_m: ")
        + r"the light is on or behind the wall in image 'wall_0' \(world z = -4\.2\d m\); "
        + re.escape("expected it in front (z > 0)"),
        message,
    ), message
    assert error(_init(root, images, "--initial-axis", "0", "0", "0")) == (
        "--initial-axis: expected a non-zero direction, got 0 0 0"
    )
    assert not (root / "project.json").exists()


def test_init_writes_how_each_pose_moves_with_the_intrinsics(scene):
    root = scene["dir"]
    cov = np.diag([0.5, 0.5, 0.4, 0.4, 1e-4, 1e-4, 1e-6, 1e-6]) ** 2
    camera = dataclasses.replace(CAMERA, intrinsics_covariance=cov)
    write_camera(camera, root / "camera_cov.yaml")
    result = init_project(
        scene["images"],
        camera_path=root / "camera_cov.yaml",
        board_path=root / "board.yaml",
        out_path=root / "project.json",
    )
    project = load_project(root / "project.json")
    assert project.camera.intrinsics_covariance is not None
    for k, outcome in enumerate(result.accepted):
        D = project.pose_intrinsics_jacobians[k]
        assert D is not None and D.shape == (6, 8)
        assert outcome.pose is not None
        np.testing.assert_array_equal(D, outcome.d_pose_d_intrinsics)
        # Against re-solves with fx 1 px (2 sigma) larger and smaller.
        pose = outcome.pose
        moved = []
        for sign in (1.0, -1.0):
            params = camera.intrinsic_params + sign * np.eye(8)[0]
            R, t = solve_pose(
                pose.points_world, pose.points_image, camera.with_intrinsic_params(params)
            )
            moved.append(np.r_[rotvec_from_matrix(R @ pose.R_camera_world.T), -R.T @ t])
        np.testing.assert_allclose(
            (moved[0] - moved[1]) / 2.0, D[:, 0], rtol=1e-3, atol=1e-3 * np.abs(D[:, 0]).max()
        )
        # A longer focal length (fx and fy) puts the camera further back along its axis:
        # about distance / f per pixel.
        axis = pose.R_camera_world[2]
        distance = float(pose.camera_center_world[2] / -axis[2])
        assert (D[3:, 0] + D[3:, 1]) @ axis == pytest.approx(-distance / camera.fx, rel=0.2)
    # Without a covariance in the camera file there is nothing to propagate.
    plain = init_project(
        scene["images"],
        camera_path=root / "camera.yaml",
        board_path=root / "board.yaml",
        out_path=root / "plain.json",
    )
    assert all(o.d_pose_d_intrinsics is None for o in plain.accepted)
    assert load_project(root / "plain.json").pose_intrinsics_jacobians == [None] * 3


def test_init_never_replaces_a_project_or_masks_without_force(scene, capsys):
    root = scene["dir"]
    out = root / "project.json"
    argv = ["init", str(scene["images"]), "--camera", str(root / "camera.yaml")]
    argv += ["--board", str(root / "board.yaml"), "--half-angle-deg", "25", "--out", str(out)]
    assert main(argv) == 0
    capsys.readouterr()
    before = out.read_bytes()
    masks = sorted((root / "masks").iterdir())
    stamps = [m.stat().st_mtime_ns for m in masks]
    assert main(argv) == 2
    assert capsys.readouterr().err == (
        f"lightcal init: error: {out}: --out: exists; use --force to replace it\n"
    )
    out.unlink()
    assert main(argv) == 2
    assert capsys.readouterr().err == (
        f"lightcal init: error: {root / 'masks'}: the masks folder: the folder is not empty; "
        "use --force to write into it\n"
    )
    assert [m.stat().st_mtime_ns for m in masks] == stamps
    assert main([*argv, "--force"]) == 0
    assert out.read_bytes() == before
    image = sorted(scene["images"].iterdir())[0]
    assert main([*argv[:-1], str(image), "--force"]) == 2
    assert capsys.readouterr().err.endswith(
        f"{image}: --out: is input {image.name}, an input of the project; write elsewhere\n"
    )
