"""`lightcal init` with several boards on the wall (`--board A --board B`), on synthetic
photos of four official tag36h11 at the corners of a rectangle and an ArUco grid between
them (`lightcal.capture.board_set`, `marker_pose.estimate_pose` given several boards)."""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from lightcal.capture.boards import ArucoGridBoard, LayoutMarker, MarkerLayout
from lightcal.capture.marker_pose import estimate_pose
from lightcal.capture.plane_texture import look_at_pose, render_plane_image
from lightcal.capture.project_init import init_project
from lightcal.cli.main import main
from lightcal.core.camera import Camera
from lightcal.errors import InputError
from lightcal.io.board_file import write_board
from lightcal.io.camera_file import write_camera
from lightcal.io.project import load_project

WIDTH, HEIGHT = 800, 600
CAMERA = Camera.from_params(
    fx=640.0, fy=640.0, cx=401.2, cy=298.7, width=WIDTH, height=HEIGHT, dist=(-0.08, 0.01, 0, 0)
)
TAGS = MarkerLayout(
    tuple(
        LayoutMarker("DICT_APRILTAG_36h11", k, center, 0.1)
        for k, center in enumerate([(-0.4, 0.25), (0.4, 0.25), (0.4, -0.25), (-0.4, -0.25)])
    )
)
GRID = ArucoGridBoard("DICT_4X4_50", 3, 2, 0.06, 0.04, origin_world_m=(-0.14, 0.09))
VIEWS = [
    ((0.05, -0.04, 0.95), (0.02, 0.01, 0.0), 0.1),
    ((-0.25, 0.12, 1.05), (0.0, 0.0, 0.0), -0.2),
    ((0.2, 0.15, 1.1), (0.03, -0.02, 0.0), 0.25),
]


def _pose(k: int) -> tuple[np.ndarray, np.ndarray]:
    center, target, roll = VIEWS[k]
    return look_at_pose(center, target, roll_rad=roll)


def _albedo(board, R, t) -> np.ndarray:
    rendering = board.render(2000.0)
    return render_plane_image(
        CAMERA,
        R,
        t,
        0.05 + 0.95 * rendering.image / 255.0,
        rendering.px_per_m,
        rendering.top_left_world_m,
        background=1.0,
    )


@functools.cache
def wall_image(k: int) -> np.ndarray:
    """(H, W) uint16 view k of both boards under a light spot, with noise."""
    R, t = _pose(k)
    albedo = _albedo(TAGS, R, t) * _albedo(GRID, R, t)
    rows, cols = np.mgrid[0:HEIGHT, 0:WIDTH]
    spot = 0.3 + np.exp(-((cols - 380.0) ** 2 + (rows - 320.0) ** 2) / (2 * 260.0**2))
    value = 40000.0 * albedo * spot + np.random.default_rng(k).normal(0.0, 20.0, albedo.shape)
    return np.clip(np.rint(value), 0, 65535).astype(np.uint16)


@pytest.fixture
def wall(tmp_path: Path) -> Path:
    photos = tmp_path / "photos"
    photos.mkdir()
    for k in range(len(VIEWS)):
        cv2.imwrite(str(photos / f"view_{k}.png"), wall_image(k))
    write_camera(CAMERA, tmp_path / "camera.yaml")
    write_board(TAGS, tmp_path / "tags.yaml")
    write_board(GRID, tmp_path / "grid.json")
    return tmp_path


def _angle_deg(R_a: np.ndarray, R_b: np.ndarray) -> float:
    return math.degrees(math.acos(np.clip((np.trace(R_a @ R_b.T) - 1.0) / 2.0, -1.0, 1.0)))


def test_the_markers_of_both_boards_make_each_pose():
    R, t = _pose(0)
    image = wall_image(0)
    both = estimate_pose(image, CAMERA, [TAGS, GRID], min_markers=10)
    assert both.n_markers == 10
    assert both.ids.tolist() == [0, 1, 2, 3, 0, 1, 2, 3, 4, 5]  # the boards in order
    assert both.points_world.shape == (40, 3) and both.mask_polygons_world.shape == (10, 4, 3)
    assert _angle_deg(both.R_camera_world, R) < 0.02
    assert np.linalg.norm(both.camera_center_world - (-R.T @ t)) < 1e-3
    # Each board alone gives its own points; together they are the concatenation.
    tags = estimate_pose(image, CAMERA, TAGS)
    grid = estimate_pose(image, CAMERA, GRID)
    np.testing.assert_array_equal(
        both.points_image, np.concatenate([tags.points_image, grid.points_image])
    )
    # A list of one board is that board.
    one = estimate_pose(image, CAMERA, [GRID])
    np.testing.assert_array_equal(one.R_camera_world, grid.R_camera_world)
    with pytest.raises(InputError) as info:
        estimate_pose(image, CAMERA, [TAGS, GRID], min_markers=11)
    assert str(info.value) == "image: found 10 markers, need at least 11"


def test_init_with_two_boards(wall: Path, capsys):
    out = wall / "project.json"
    argv = ["init", str(wall / "photos"), "--camera", str(wall / "camera.yaml")]
    argv += ["--board", str(wall / "tags.yaml"), "--board", str(wall / "grid.json")]
    argv += ["--half-angle-deg", "20", "--out", str(out)]
    assert main(argv) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split(",")[0] for line in lines[:3]] == [
        f"view_{k}.png: 10 markers" for k in range(3)
    ]
    project = load_project(out)
    for k, view in enumerate(project.views):
        R, t = _pose(k)
        assert _angle_deg(view.R_camera_world, R) < 0.03
        assert np.linalg.norm(view.center_world - (-R.T @ t)) < 1.5e-3
        # The mask covers the markers of both boards.
        mask = cv2.imread(str(project.mask_paths[k]), cv2.IMREAD_UNCHANGED) > 0
        for board, corners in (
            (TAGS, TAGS.outline_world()),
            (GRID, GRID.corners_world(GRID.ids)),
        ):
            centers, _ = CAMERA.project(corners.mean(axis=1) @ R.T + t)
            u, v = np.rint(centers).astype(int).T
            assert np.all(mask[v, u]), board
        assert mask.mean() < 0.2
    assert json.loads(out.read_text())["images"][0]["mask"] == "masks/view_0.png"


def test_single_board_outputs_do_not_depend_on_how_the_board_is_given(wall: Path):
    """The path, a list of one path and the CLI write the same project and masks."""
    written = []
    for k, board_path in enumerate([wall / "grid.json", [wall / "grid.json"]]):
        folder = wall / f"run_{k}"
        folder.mkdir()
        init_project(
            wall / "photos", camera_path=wall / "camera.yaml", board_path=board_path,
            out_path=folder / "project.json",
        )  # fmt: skip
        written.append(folder)
    folder = wall / "run_cli"
    folder.mkdir()
    argv = ["init", str(wall / "photos"), "--camera", str(wall / "camera.yaml")]
    argv += ["--board", str(wall / "grid.json"), "--out", str(folder / "project.json")]
    assert main(argv) == 0
    written.append(folder)
    first = [(p.relative_to(written[0]), p.read_bytes()) for p in sorted(written[0].rglob("*.*"))]
    assert len(first) == 4  # the project and three masks
    for folder in written[1:]:
        assert [(p.relative_to(folder), p.read_bytes()) for p in sorted(folder.rglob("*.*"))] == (
            first
        )


def test_boards_sharing_a_marker_are_refused(wall: Path, capsys):
    clash = ArucoGridBoard("DICT_4X4_50", 2, 1, 0.06, 0.04, first_id=5, origin_world_m=(0.5, 0))
    write_board(clash, wall / "clash.yaml")
    argv = ["init", str(wall / "photos"), "--camera", str(wall / "camera.yaml")]
    argv += ["--board", str(wall / "grid.json"), "--board", str(wall / "clash.yaml")]
    argv += ["--out", str(wall / "project.json")]
    assert main(argv) == 2
    assert capsys.readouterr().err == (
        f"lightcal init: error: {wall / 'clash.yaml'}: DICT_4X4_50 id 5 is also on board "
        f"{wall / 'grid.json'}: expected boards with the same dictionary to use different ids\n"
    )
    # An AprilTag layout clashing with another layout's tag.
    write_board(
        MarkerLayout((LayoutMarker("DICT_APRILTAG_36h11", 2, (1, 1), 0.1),)), wall / "t.json"
    )
    argv[5] = str(wall / "tags.yaml")
    argv[7] = str(wall / "t.json")
    assert main(argv) == 2
    assert capsys.readouterr().err.endswith(
        ": DICT_APRILTAG_36h11 id 2 is also on board "
        f"{wall / 'tags.yaml'}: expected boards with the same dictionary to use different ids\n"
    )
    argv[7] = str(wall / "tags.yaml")
    assert main(argv) == 2
    assert capsys.readouterr().err == (
        f"lightcal init: error: {wall / 'tags.yaml'}: given twice as a board file (also as "
        f"{wall / 'tags.yaml'})\n"
    )
    argv[7] = str(wall / "grid.json")
    assert main([*argv, "--min-markers", "11"]) == 2
    assert capsys.readouterr().err == (
        "lightcal init: error: --min-markers: expected at most the 2 boards' 10 markers, got 11\n"
    )
    assert not (wall / "project.json").exists() and not (wall / "masks").exists()


def test_a_charuco_board_and_a_layout_together():
    """A ChArUco board's corners and a layout's marker corners make one pose; a ChArUco
    board not in the photo gives no points and no error when the other board has enough."""
    from lightcal.capture.boards import CharucoBoard

    charuco = CharucoBoard("DICT_5X5_100", 5, 4, 0.05, 0.035, origin_world_m=(-0.125, 0.1))
    R, t = _pose(1)
    both = estimate_pose(wall_image_of([TAGS, charuco], 1), CAMERA, [TAGS, charuco], min_markers=8)
    assert both.n_markers == 4 + charuco.n_markers
    assert both.points_world.shape == (16 + charuco.corner_ids.size, 3)
    assert _angle_deg(both.R_camera_world, R) < 0.03
    assert np.linalg.norm(both.camera_center_world - (-R.T @ t)) < 1e-3
    tags_only = estimate_pose(wall_image_of([TAGS], 1), CAMERA, [TAGS, charuco], min_markers=4)
    assert tags_only.n_markers == 4 and tags_only.points_world.shape == (16, 3)
    with pytest.raises(InputError) as info:
        estimate_pose(wall_image_of([TAGS], 1), CAMERA, charuco)
    assert str(info.value) == "image: found 0 markers, need at least 4"


def wall_image_of(boards, k: int) -> np.ndarray:
    """(H, W) float view k of these boards, lit unevenly, with a little noise."""
    R, t = _pose(k)
    albedo = np.prod([_albedo(board, R, t) for board in boards], axis=0)
    rows, cols = np.mgrid[0:HEIGHT, 0:WIDTH]
    spot = 0.3 + np.exp(-((cols - 380.0) ** 2 + (rows - 320.0) ** 2) / (2 * 260.0**2))
    return albedo * spot + np.random.default_rng(k).normal(0.0, 0.002, albedo.shape)
