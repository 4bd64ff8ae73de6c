"""Hardening of `lightcal init` and `lightcal camera` (issue 28): every argument checked
before any work (the initial light within the project file's bounds, `--min-markers` within
the board's markers), nothing left behind by a run that fails or is interrupted part-way, a
non-finite marker fit refused, capture sets that cannot determine the intrinsics (copies of
one photo, the board at one angle) refused or warned about, a camera, project or result
file given as the board named for what it is, and `camera --out` replacing a file only
with `--force` (never an input).

Each case asserts the exact line on stderr and the exit code of `lightcal.cli.main.main`.
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

import lightcal.capture.init_image as init_image
import lightcal.capture.marker_pose as marker_pose
import lightcal.capture.project_init as project_init
from lightcal.capture.boards import ArucoGridBoard
from lightcal.capture.intrinsics import calibrate_intrinsics
from lightcal.capture.plane_texture import look_at_pose, render_plane_image
from lightcal.cli.main import main
from lightcal.errors import InputError
from lightcal.io.board_file import read_board, write_board
from lightcal.io.camera_file import read_camera, write_camera
from lightcal.io.project import load_project
from tests.test_cli_camera import CAMERA as CHESS_CAMERA
from tests.test_cli_camera import CHESSBOARD, chessboard_views
from tests.test_cli_init import BOARD, CAMERA, VIEWS, _png, wall_image

EXPECTED_VIEWS = (
    "expected photos of the board from at least 3 different angles, tilted by 10-45 degrees"
)


AXIS_NOT_MINUS_Z = (
    "expected an axis other than -z (straight back, away from the wall: there the light's "
    "initial orientation is not defined)"
)
"""The refusal of an initial axis along -z (the project cannot orient the light there)."""


def _listing(folder: Path) -> list[str]:
    """Every path under `folder`, hidden ones included, relative."""
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*"))


@pytest.fixture
def wall(tmp_path: Path) -> Path:
    """A folder with `photos/` (3 views of the marker wall), camera.yaml and board.yaml."""
    photos = tmp_path / "photos"
    photos.mkdir()
    for k in range(len(VIEWS)):
        (photos / f"wall_{k}.png").write_bytes(_png(wall_image(k), None))
    write_camera(CAMERA, tmp_path / "camera.yaml")
    write_board(BOARD, tmp_path / "board.yaml")
    return tmp_path


def _init(root: Path, *extra: str) -> list[str]:
    return [
        "init",
        str(root / "photos"),
        "--camera",
        str(root / "camera.yaml"),
        "--board",
        str(root / "board.yaml"),
        "--half-angle-deg",
        "25",
        "--out",
        str(root / "project.json"),
        *extra,
    ]


# --- init: every option before any work ------------------------------------------------

INIT_OPTION_CASES = [
    (["--pose-floor-mm", "-1"], "--pose-floor-mm: expected a finite value >= 0 mm, got -1"),
    (["--pose-floor-mm", "nan"], "--pose-floor-mm: expected a finite value >= 0 mm, got nan"),
    (["--pose-floor-mm", "inf"], "--pose-floor-mm: expected a finite value >= 0 mm, got inf"),
    (
        ["--pose-floor-deg", "-0.5"],
        "--pose-floor-deg: expected a finite value >= 0 degrees, got -0.5",
    ),
    (
        ["--pose-floor-deg", "nan"],
        "--pose-floor-deg: expected a finite value >= 0 degrees, got nan",
    ),
    (
        ["--pose-floor-deg", "inf"],
        "--pose-floor-deg: expected a finite value >= 0 degrees, got inf",
    ),
    (["--min-markers", "0"], "--min-markers: expected an integer >= 1, got 0"),
    (["--mask-margin-px", "-1"], "--mask-margin-px: expected a padding of 0 to 100 pixels, got -1"),
    (
        ["--mask-margin-px", "1e9"],
        "--mask-margin-px: expected a padding of 0 to 100 pixels, got 1e+09",
    ),
    (
        ["--mask-margin-px", "nan"],
        "--mask-margin-px: expected a padding of 0 to 100 pixels, got nan",
    ),
    (["--max-rms-px", "0"], "--max-rms-px: expected a finite value > 0 pixels, got 0"),
    (["--max-rms-px", "nan"], "--max-rms-px: expected a finite value > 0 pixels, got nan"),
    (["--max-rms-px", "inf"], "--max-rms-px: expected a finite value > 0 pixels, got inf"),
    (["--half-angle-deg", "90"], "--half-angle-deg: expected a value in (0, 90) degrees, got 90"),
    (["--half-angle-deg", "nan"], "--half-angle-deg: expected a value in (0, 90) degrees, got nan"),
    (
        ["--initial-position", "nan", "0", "0.1"],
        "--initial-position: expected three finite numbers (metres), got nan 0 0.1",
    ),
    (
        ["--initial-axis", "0", "inf", "1"],
        "--initial-axis: expected three finite numbers, got 0 inf 1",
    ),
    # The initial light within the project file's bounds (InitialSpec.position_m: ±10 m),
    # and an axis the project can turn into an orientation: checked before the images.
    (
        ["--initial-position", "1e9", "0", "0"],
        "--initial-position: expected each coordinate within ±10 m of the camera, got 1e+09 0 0",
    ),
    (
        ["--initial-position", "0", "-10.5", "0.2"],
        "--initial-position: expected each coordinate within ±10 m of the camera, got 0 -10.5 0.2",
    ),
    (["--initial-axis", "0", "0", "0"], "--initial-axis: expected a non-zero direction, got 0 0 0"),
    (["--initial-axis", "0", "0", "-1"], f"--initial-axis: {AXIS_NOT_MINUS_Z}, got 0 0 -1"),
    (["--initial-axis", "0", "-0", "-3"], f"--initial-axis: {AXIS_NOT_MINUS_Z}, got 0 -0 -3"),
    (
        ["--initial-axis", "1e200", "0", "1"],
        "--initial-axis: expected a direction of length 1e-100 to 1e+100, got 1e+200 0 1",
    ),
    # More markers than the board has (35: 7 x 5) can never be found in an image.
    (["--min-markers", "36"], "--min-markers: expected at most the board's 35 markers, got 36"),
    (
        ["--min-markers", "100000"],
        "--min-markers: expected at most the board's 35 markers, got 100000",
    ),
    (["--black-level", "-1"], "--black-level: expected a finite value >= 0, got -1"),
    (["--black-level", "nan"], "--black-level: expected a finite value >= 0, got nan"),
    (["--white-level", "0"], "--white-level: expected a finite value > 0, got 0"),
    (["--white-level", "inf"], "--white-level: expected a finite value > 0, got inf"),
    (
        ["--black-level", "300", "--white-level", "200"],
        "--white-level: expected a value above --black-level (300), got 200",
    ),
    (
        ["--out", "{root}/project.txt"],
        "{root}/project.txt: --out: unsupported project file suffix '.txt': expected .json, "
        ".yaml or .yml",
    ),
]


@pytest.mark.parametrize(
    ("extra", "expected"), INIT_OPTION_CASES, ids=[" ".join(c[0]) for c in INIT_OPTION_CASES]
)
def test_init_checks_every_option_before_any_work(
    wall: Path, capsys: pytest.CaptureFixture[str], extra: list[str], expected: str
) -> None:
    before = _listing(wall)
    argv = _init(wall, *(e.format(root=wall) for e in extra))
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.err == f"lightcal init: error: {expected.format(root=wall)}\n"
    assert captured.out == ""  # no image was read: each prints its line as it is done
    assert _listing(wall) == before  # no masks, no project, no staging folder


def test_a_refused_pose_floor_leaves_nothing_that_blocks_the_corrected_run(
    wall: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(_init(wall, "--pose-floor-mm", "-1")) == 2
    assert capsys.readouterr().err == (
        "lightcal init: error: --pose-floor-mm: expected a finite value >= 0 mm, got -1\n"
    )
    assert not (wall / "masks").exists()
    assert main(_init(wall, "--pose-floor-mm", "1")) == 0  # no --force needed
    assert sorted(p.name for p in (wall / "masks").iterdir()) == [f"wall_{k}.png" for k in range(3)]
    covariance = np.array(load_project(wall / "project.json").pose_covariances[0])
    assert np.all(np.diag(covariance)[3:] >= 1e-3**2)  # the floor of 1 mm


def test_the_library_checks_the_pose_floor_before_any_image(wall: Path) -> None:
    with pytest.raises(
        InputError, match=r"^pose_floor_deg: expected a finite value >= 0, got nan$"
    ):
        project_init.init_project(
            wall / "photos",
            camera_path=wall / "camera.yaml",
            board_path=wall / "board.yaml",
            out_path=wall / "project.json",
            pose_floor_deg=math.nan,
            on_image=lambda outcome: pytest.fail("an image was read"),
        )


# --- init: nothing left behind by a run that stops part-way -----------------------------


def test_init_failing_after_the_images_leaves_no_masks(
    wall: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The initial light behind the wall is found only once the poses are known."""
    before = _listing(wall)
    assert main(_init(wall, "--initial-position", "0", "0", "5")) == 2
    captured = capsys.readouterr()
    assert len(captured.out.splitlines()) == 3  # every image was detected
    assert captured.err.startswith(
        f"lightcal init: error: {(wall / 'project.json').resolve()}: "
        "lights[0].initial.position_m: the light is on or behind the wall"
    )
    assert _listing(wall) == before
    assert main(_init(wall)) == 0  # the corrected run, without --force


def test_ctrl_c_during_init_leaves_nothing(
    wall: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    real = init_image.estimate_pose
    calls = []

    def interrupted(*args, **kwargs):
        calls.append(kwargs["source"])
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(init_image, "estimate_pose", interrupted)
    before = _listing(wall)
    assert main(_init(wall)) == 130
    captured = capsys.readouterr()
    assert captured.err == "lightcal init: interrupted\n"
    assert len(captured.out.splitlines()) == 2  # two masks were written (to the staging)
    assert _listing(wall) == before


def test_a_failure_after_the_masks_are_moved_in_restores_the_old_masks(
    wall: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """With --force over an earlier run: a project that cannot be written puts back the
    masks it replaced and removes the ones it added; other files are never touched."""
    masks = wall / "masks"
    masks.mkdir()
    (masks / "wall_0.png").write_bytes(b"an earlier mask")
    (masks / "notes.txt").write_text("mine")
    out = wall / "project.json"

    def full_disk(spec, path):
        raise OSError(28, "No space left on device", str(path))

    monkeypatch.setattr(project_init, "save_project", full_disk)
    before = _listing(wall)
    assert main(_init(wall, "--force")) == 2
    assert capsys.readouterr().err == f"lightcal init: error: {out}: No space left on device\n"
    assert _listing(wall) == before
    assert (masks / "wall_0.png").read_bytes() == b"an earlier mask"
    assert (masks / "notes.txt").read_text() == "mine"

    masks.joinpath("wall_0.png").unlink()
    masks.joinpath("notes.txt").unlink()
    masks.rmdir()
    before = _listing(wall)
    assert main(_init(wall)) == 2
    capsys.readouterr()
    assert _listing(wall) == before  # the masks folder this run created is gone


# --- init: a non-finite marker fit is a rejection -------------------------------------

NAN_REASON = (
    "marker reprojection RMS nan px: expected a finite RMS of at most 1 px (check that the "
    "board file describes the printed board and the camera file this camera)"
)
NOT_FINITE_REASON = (
    "the marker fit gave a non-finite pose or covariance: expected markers that fit one "
    "camera pose (check that the board file describes the printed board and the camera "
    "file this camera)"
)


def _spoil(monkeypatch: pytest.MonkeyPatch, spoiled: set[str], **changes: Any) -> None:
    """`estimate_pose` gives the images named in `spoiled` the fields in `changes`."""
    real = init_image.estimate_pose

    def estimate(*args, **kwargs):
        pose = real(*args, **kwargs)
        return dataclasses.replace(pose, **changes) if kwargs["source"] in spoiled else pose

    monkeypatch.setattr(init_image, "estimate_pose", estimate)


@pytest.mark.parametrize(
    ("changes", "reason"),
    [
        ({"reprojection_rms_px": math.nan}, NAN_REASON),
        ({"reprojection_rms_px": math.inf}, NAN_REASON.replace("nan px", "inf px")),
        ({"covariance": np.full((6, 6), math.nan)}, NOT_FINITE_REASON),
        ({"t_camera_world": np.array([0.0, math.inf, 1.0])}, NOT_FINITE_REASON),
    ],
    ids=["nan rms", "inf rms", "nan covariance", "inf translation"],
)
def test_a_non_finite_marker_fit_rejects_the_image(
    wall: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    changes: dict[str, object],
    reason: str,
) -> None:
    _spoil(monkeypatch, {"wall_1"}, **changes)
    assert main(_init(wall)) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1] == f"wall_1.png: rejected: {reason}"
    assert lines[-1].startswith("2 of 3 images accepted, 1 rejected")
    assert load_project(wall / "project.json").names == ["wall_0", "wall_2"]
    assert sorted(p.name for p in (wall / "masks").iterdir()) == ["wall_0.png", "wall_2.png"]


def test_a_camera_behind_the_wall_is_rejected(
    wall: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A marker pose that puts the camera at world z = -0.5 m (behind the wall's plane)."""
    real = marker_pose.solve_pose

    def solve(*args, **kwargs):
        R, t = real(*args, **kwargs)
        if kwargs["source"] == "wall_1":
            z_m = float((-R.T @ t)[2])
            t = t + R @ np.array([0.0, 0.0, z_m + 0.5])  # the centre moves to z = -0.5
        return R, t

    monkeypatch.setattr(marker_pose, "solve_pose", solve)
    assert main(_init(wall)) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1] == (
        "wall_1.png: rejected: the pose puts the camera at world z = -0.5 m, expected z > 0 "
        "(in front of the wall)"
    )
    assert load_project(wall / "project.json").names == ["wall_0", "wall_2"]


def test_only_non_finite_fits_is_an_input_error_not_a_crash(
    wall: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    _spoil(monkeypatch, {"wall_0", "wall_1", "wall_2"}, reprojection_rms_px=math.nan)
    before = _listing(wall)
    assert main(_init(wall)) == 2
    reasons = "; ".join(f"wall_{k}.png: {NAN_REASON}" for k in range(3))
    assert capsys.readouterr().err == (
        f"lightcal init: error: {wall / 'photos'}: no usable images: all 3 were rejected "
        f"({reasons})\n"
    )
    assert _listing(wall) == before


def _degenerate_refusal(line: str, name: str) -> bool:
    """Whether `line` refuses `name`'s pose from a wrong board file: a NaN RMS (markers
    behind the camera), or the camera on the wall (z within 1e-4 m of 0, on the far side)."""
    if line == f"{name}.png: rejected: {NAN_REASON}":
        return True
    on_wall = re.fullmatch(
        rf"{name}\.png: rejected: the pose puts the camera at world z = (\S+) m, expected "
        r"z > 0 \(in front of the wall\)",
        line,
    )
    return on_wall is not None and -1e-4 < float(on_wall[1]) <= 0.0


def test_a_wrong_board_file_gives_nan_fits_that_are_refused(
    wall: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A real construction: the printed 7 x 5 grid described as 12 x 3 (same dictionary,
    marker size and gap) puts the markers' ids at the wrong places; the pose then sends
    some of them behind the camera, where the projection is NaN: the RMS is NaN. Or the
    degenerate pose puts the camera on the wall, z within 1e-4 m of 0: which side of it,
    hence which refusal, depends on the corners' last 0.01 px, which move with OpenCV's
    build and the CPU's SIMD (wall_1 gave NaN on one machine, z = -2.5e-6 m on another).
    The two refusals are each tested exactly on their own (`test_a_non_finite_marker_fit_
    rejects_the_image`, `test_a_camera_behind_the_wall_is_rejected`)."""
    write_board(
        ArucoGridBoard("DICT_4X4_50", 12, 3, 0.07, 0.06, origin_world_m=(-0.42, 0.29)),
        wall / "board.yaml",
    )
    before = _listing(wall)
    assert main(_init(wall)) == 2
    captured = capsys.readouterr()
    lines = captured.out.splitlines()[1:]
    assert len(lines) == 2
    assert _degenerate_refusal(lines[0], "wall_1"), lines[0]
    assert _degenerate_refusal(lines[1], "wall_2"), lines[1]
    assert captured.err.startswith(
        f"lightcal init: error: {wall / 'photos'}: no usable images: all 3 were rejected ("
    )
    assert "; wall_1.png: " in captured.err and "; wall_2.png: " in captured.err
    assert "internal error" not in captured.err
    assert _listing(wall) == before


# --- camera calibrate: capture sets that cannot determine the intrinsics ---------------


def _write(folder: Path, images: list[np.ndarray]) -> Path:
    folder.mkdir(exist_ok=True)
    for i, image in enumerate(images):
        cv2.imwrite(str(folder / f"chess_{i:02d}.png"), image)
    write_board(CHESSBOARD, folder.parent / "chessboard.yaml")
    return folder


def _calibrate(folder: Path, out: Path, *extra: str) -> list[str]:
    board = folder.parent / "chessboard.yaml"
    return ["camera", "calibrate", str(folder), "--board", str(board), "--out", str(out), *extra]


def _render(center_m: np.ndarray, target_m: np.ndarray, roll_rad: float, seed: int) -> np.ndarray:
    """A uint8 photo of the chessboard from `center_m`, looking at `target_m`."""
    rng = np.random.default_rng(seed)
    rendering = CHESSBOARD.render(2000)
    texture = 0.05 + 0.85 * rendering.image / 255.0
    R, t = look_at_pose(center_m, target_m, roll_rad=roll_rad)
    image = render_plane_image(
        CHESS_CAMERA, R, t, texture, rendering.px_per_m, rendering.top_left_world_m
    )
    image += rng.normal(0.0, 0.005, image.shape)
    return np.clip(np.rint(image * 255.0), 0, 255).astype(np.uint8)


_S = CHESSBOARD.square_length_m
BOARD_CENTER = np.array([(CHESSBOARD.inner_x - 1) * _S / 2, -(CHESSBOARD.inner_y - 1) * _S / 2, 0])
SHIFTS = [(0.0, 0.0), (0.05, 0.0), (-0.05, 0.03), (0.02, -0.04), (0.0, 0.05)]


def test_ten_copies_of_one_photo_are_refused(tmp_path: Path, capsys) -> None:
    folder = _write(tmp_path / "chess", [chessboard_views()[0]] * 10)
    out = tmp_path / "camera.yaml"
    assert main(_calibrate(folder, out)) == 2
    captured = capsys.readouterr()
    assert captured.err == (
        "lightcal camera: error: images: 10 views of the board but only 1 distinct "
        "(chess_01.png, chess_02.png, chess_03.png and 6 more are the same view as an earlier "
        f"one): {EXPECTED_VIEWS}\n"
    )
    assert captured.out == ""
    assert not out.exists()


def test_near_identical_photos_count_once(tmp_path: Path, capsys) -> None:
    """Re-noised copies (a tripod burst): the corners move by far less than 0.5 px."""
    rng = np.random.default_rng(5)
    views = chessboard_views()
    images = []
    for k in (0, 0, 0, 1, 1):
        noisy = views[k].astype(np.float64) + rng.normal(0.0, 1.5, views[k].shape)
        images.append(np.clip(np.rint(noisy), 0, 255).astype(np.uint8))
    folder = _write(tmp_path / "chess", images)
    assert main(_calibrate(folder, tmp_path / "camera.yaml")) == 2
    assert capsys.readouterr().err == (
        "lightcal camera: error: images: 5 views of the board but only 2 distinct "
        "(chess_01.png, chess_02.png, chess_04.png are the same view as an earlier one): "
        f"{EXPECTED_VIEWS}\n"
    )


def test_a_copy_among_good_photos_is_rejected_and_named(tmp_path: Path, capsys) -> None:
    views = list(chessboard_views()[:6])
    folder = _write(tmp_path / "chess", [*views, views[2]])
    out = tmp_path / "camera.yaml"
    assert main(_calibrate(folder, out)) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[6] == (
        "chess_06.png: rejected: the same view as chess_02.png (every corner within 0.00 px): "
        "a copy adds no information; expected each photo from another angle"
    )
    assert lines[-1].startswith("6 views used, 1 rejected, ")
    assert not any(line.startswith("warning:") for line in lines)
    assert abs(read_camera(out).fx / CHESS_CAMERA.fx - 1.0) < 2e-3


@pytest.mark.parametrize("tilt_deg", [0.0, 25.0], ids=["square-on", "tilted"])
def test_one_board_angle_is_refused(tmp_path: Path, capsys, tilt_deg: float) -> None:
    """The board moved in its plane and turned about its normal: one angle, however
    many photos (the focal length trades with the distance)."""
    tilt = math.radians(tilt_deg)
    direction = 0.45 * np.array([math.sin(tilt), 0.0, math.cos(tilt)])
    images = []
    for k, (dx, dy) in enumerate(SHIFTS):
        target = BOARD_CENTER + np.array([dx, dy, 0.0])
        images.append(_render(target + direction, target, 0.3 * k if tilt == 0 else 0.0, k))
    folder = _write(tmp_path / "chess", images)
    out = tmp_path / "camera.yaml"
    assert main(_calibrate(folder, out)) == 2
    assert capsys.readouterr().err == (
        "lightcal camera: error: images: the 5 views show the board at only 1 angle (board "
        "normals within 5 degrees of each other: chess_00.png, chess_01.png, chess_02.png and "
        f"2 more): {EXPECTED_VIEWS}\n"
    )
    assert not out.exists()


def test_two_board_angles_are_refused(tmp_path: Path, capsys) -> None:
    images = []
    for k, (dx, dy) in enumerate(SHIFTS[:4]):
        side = 1.0 if k < 2 else -1.0
        direction = 0.45 * np.array([side * math.sin(0.4), 0.0, math.cos(0.4)])
        target = BOARD_CENTER + np.array([dx, dy, 0.0])
        images.append(_render(target + direction, target, 0.0, k))
    folder = _write(tmp_path / "chess", images)
    assert main(_calibrate(folder, tmp_path / "camera.yaml")) == 2
    assert capsys.readouterr().err == (
        "lightcal camera: error: images: the 4 views show the board at only 2 different angles "
        "(board normals within 5 degrees of each other: chess_00.png, chess_01.png; "
        f"chess_02.png, chess_03.png): {EXPECTED_VIEWS}\n"
    )


def test_a_board_nearly_square_on_in_every_view_is_a_warning(tmp_path: Path, capsys) -> None:
    tilt = math.radians(5.7)
    images = []
    for k, azimuth in enumerate(np.linspace(0.0, 2 * np.pi, 6, endpoint=False)):
        direction = 0.45 * np.array(
            [math.sin(tilt) * math.cos(azimuth), math.sin(tilt) * math.sin(azimuth), math.cos(tilt)]
        )
        images.append(_render(BOARD_CENTER + direction, BOARD_CENTER, 0.0, k))
    folder = _write(tmp_path / "chess", images)
    out = tmp_path / "camera.yaml"
    assert main(_calibrate(folder, out)) == 0
    lines = capsys.readouterr().out.splitlines()
    warnings = [line for line in lines if line.startswith("warning:")]
    assert len(warnings) == 1
    assert re.fullmatch(
        r"warning: the board is tilted at most 5\.\d degrees from square-on in every view: "
        r"the focal length is poorly determined; take photos of the board from at least 3 "
        r"different angles, tilted by 10-45 degrees",
        warnings[0],
    ), warnings[0]
    assert out.exists()


def test_the_library_reports_the_warning_and_the_copies() -> None:
    views = list(chessboard_views()[:5])
    result = calibrate_intrinsics([*views, views[0]], CHESSBOARD, sources=list("abcdef"))
    assert result.warnings == ()
    assert result.used == ("a", "b", "c", "d", "e")
    assert [name for name, _ in result.rejected] == ["f"]


# --- camera: every option before any work ---------------------------------------------


@pytest.fixture
def blank_photos(tmp_path: Path) -> Path:
    """Two blank photos and a chessboard file: a calibration could only fail with "0
    usable views", so any other refusal was made before the work."""
    folder = _write(
        tmp_path / "chess", [np.full((120, 160), 128, np.uint8), np.zeros((120, 160), np.uint8)]
    )
    return folder


@pytest.mark.parametrize(
    ("out_name", "extra", "expected"),
    [
        (
            "camera.txt",
            [],
            "{t}/camera.txt: unsupported file suffix '.txt': expected .yaml, .yml, .xml or .json",
        ),
        (
            "camera",
            [],
            "{t}/camera: unsupported file suffix '': expected .yaml, .yml, .xml or .json",
        ),
        (
            "camera.yaml",
            ["--max-rms-px", "0"],
            "--max-rms-px: expected a finite value > 0 pixels, got 0",
        ),
        (
            "camera.yaml",
            ["--max-rms-px", "nan"],
            "--max-rms-px: expected a finite value > 0 pixels, got nan",
        ),
        (
            "camera.yaml",
            ["--max-rms-px", "inf"],
            "--max-rms-px: expected a finite value > 0 pixels, got inf",
        ),
    ],
    ids=["suffix .txt", "no suffix", "rms 0", "rms nan", "rms inf"],
)
def test_camera_calibrate_checks_every_option_before_any_work(
    tmp_path: Path, blank_photos: Path, capsys, out_name: str, extra: list[str], expected: str
) -> None:
    out = tmp_path / out_name
    argv = _calibrate(blank_photos, out, *(e.format(t=tmp_path) for e in extra))
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.err == f"lightcal camera: error: {expected.format(t=tmp_path)}\n"
    assert captured.out == ""
    assert not out.exists()


def test_camera_calibrate_refuses_a_photo_given_twice(
    tmp_path: Path, blank_photos: Path, capsys
) -> None:
    """Named and in a folder named: it would count as two views."""
    photo = blank_photos / "chess_00.png"
    argv = _calibrate(blank_photos, tmp_path / "camera.yaml")
    assert main([*argv[:3], str(photo), *argv[3:]]) == 2
    assert capsys.readouterr().err == (
        f"lightcal camera: error: {photo}: given twice: expected each photo once (a copy adds "
        "no information)\n"
    )


def test_camera_import_checks_its_options_before_reading(tmp_path: Path, capsys) -> None:
    corrupt = tmp_path / "camera.yaml"
    corrupt.write_text("%YAML:1.0\n---\ncamera_matrix: [1, 2\n")
    out = tmp_path / "camera.txt"
    assert main(["camera", "import", str(corrupt), "--out", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"lightcal camera: error: {out}: unsupported file suffix '.txt': expected .yaml, .yml, "
        ".xml or .json\n"
    )
    argv = ["camera", "import", str(corrupt), "--out", str(tmp_path / "c.json")]
    assert main([*argv, "--camera-id", "2"]) == 2
    assert capsys.readouterr().err == (
        "lightcal camera: error: --camera-id: applies only to a COLMAP cameras.txt, got "
        "camera.yaml (it holds one camera)\n"
    )
    assert not (tmp_path / "c.json").exists()


def test_camera_import_names_the_camera_id_option(tmp_path: Path, capsys) -> None:
    colmap = tmp_path / "cameras.txt"
    colmap.write_text("1 PINHOLE 640 480 560 561 322.9 238.6\n2 PINHOLE 640 480 500 500 320 240\n")
    out = tmp_path / "camera.yaml"
    assert main(["camera", "import", str(colmap), "--out", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"lightcal camera: error: {colmap}: found 2 cameras (ids 1, 2): pass --camera-id to "
        "choose one\n"
    )
    assert main(["camera", "import", str(colmap), "--out", str(out), "--camera-id", "7"]) == 2
    assert capsys.readouterr().err == (
        f"lightcal camera: error: {colmap}: --camera-id 7 not found: the file has ids 1, 2\n"
    )
    assert main(["camera", "import", str(colmap), "--out", str(out), "--camera-id", "2"]) == 0
    assert read_camera(out).fx == 500.0


# --- init: the initial light and --min-markers in the library, before any image ----------


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (
            {"initial_position_m": (0.0, 0.0, 11.0)},
            "initial_position_m: expected each coordinate within ±10 m of the camera, got "
            "(0, 0, 11)",
        ),
        (
            {"initial_axis_camera": (0, 0, 0)},
            "initial_axis_camera: expected a non-zero direction, got (0, 0, 0)",
        ),
        (
            {"initial_axis_camera": (1e-170, 0.0, -1.0)},  # x^2 underflows: -z to the project
            f"initial_axis_camera: {AXIS_NOT_MINUS_Z}, got (1e-170, 0, -1)",
        ),
        ({"min_markers": 36}, "min_markers: expected at most the board's 35 markers, got 36"),
    ],
    ids=["position", "zero axis", "-z axis", "min markers"],
)
def test_the_library_checks_the_initial_light_and_markers_before_any_image(
    wall: Path, change: dict[str, Any], expected: str
) -> None:
    before = _listing(wall)
    with pytest.raises(InputError, match=f"^{re.escape(expected)}$"):
        project_init.init_project(
            wall / "photos",
            camera_path=wall / "camera.yaml",
            board_path=wall / "board.yaml",
            out_path=wall / "project.json",
            on_image=lambda outcome: pytest.fail("an image was read"),
            **change,
        )
    assert _listing(wall) == before


def test_the_largest_initial_guess_the_checks_take_makes_a_project(
    wall: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The bounds are the project file's: what passes them loads (here: every marker of
    the board required, an axis just off -z, the light 10 m to the side)."""
    argv = _init(wall, "--min-markers", "35", "--initial-axis", "0.01", "0", "-1")
    assert main([*argv, "--initial-position", "-10", "0", "0"]) == 0
    project = load_project(wall / "project.json")
    assert project.spec.lights[0].initial.axis_camera == [0.01, 0.0, -1.0]
    lines = capsys.readouterr().out.splitlines()
    assert lines[:2] == [
        "wall_0.png: rejected: found 30 markers, need at least 35",
        "wall_1.png: rejected: found 31 markers, need at least 35",
    ]
    assert lines[2].startswith("wall_2.png: 35 markers, rms ")
    assert lines[3].startswith("1 of 3 images accepted, 2 rejected")
    assert project.spec.lights[0].initial.position_m == [-10.0, 0.0, 0.0]


# --- a camera, project or result file given as the board file --------------------------

NOT_A_BOARD = (
    ", not a board file: expected a board file (type aruco_grid, charuco, chessboard or markers)"
)


@pytest.mark.parametrize("command", ["init", "camera calibrate"])
def test_a_camera_file_given_as_the_board_is_named(
    wall: Path, capsys: pytest.CaptureFixture[str], command: str
) -> None:
    camera = wall / "camera.yaml"  # written by OpenCV: tags !!opencv-matrix
    if command == "init":
        argv = _init(wall, "--board", str(camera))
    else:
        out = wall / "new_camera.yaml"
        argv = ["camera", "calibrate", str(wall / "photos"), "--board", str(camera)]
        argv += ["--out", str(out)]
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.err == (
        f"lightcal {command.split()[0]}: error: {camera}: an OpenCV camera file{NOT_A_BOARD}\n"
    )
    assert captured.out == ""


@pytest.mark.parametrize(
    ("name", "content", "what"),
    [
        ("camera.json", None, "an OpenCV camera file"),
        (
            "camera.yaml",
            "image_width: 640\nimage_height: 480\ncamera_matrix: [[500, 0, 320], [0, 500, "
            "240], [0, 0, 1]]\n",
            "an OpenCV camera file",
        ),
        (
            "camera.yml",
            "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n",
            "an OpenCV camera file",
        ),
        (
            "project.json",
            '{"camera": {"path": "camera.yaml"}, "images": [{"path": "a.png"}], '
            '"lights": [{"rid": {"type": "half_angle", "half_angle_deg": 30}}]}',
            "a project file",
        ),
        (
            "result.json",
            '{"version": 3, "lightcal_version": "1.0", "parameters": {}, "lights": []}',
            "a result file of lightcal calibrate",
        ),
    ],
    ids=["camera json", "camera plain yaml", "camera size only", "project", "result"],
)
def test_another_lightcal_file_given_as_the_board_is_named(
    tmp_path: Path, name: str, content: str | None, what: str
) -> None:
    path = tmp_path / name
    if content is None:
        write_camera(CAMERA, path)
    else:
        path.write_text(content)
    with pytest.raises(InputError, match=f"^{re.escape(f'{path}: {what}{NOT_A_BOARD}')}$"):
        read_board(path)


# --- camera: --out never replaces a file without --force --------------------------------


def test_camera_import_replaces_an_existing_out_only_with_force(tmp_path: Path, capsys) -> None:
    colmap = tmp_path / "cameras.txt"
    colmap.write_text("1 PINHOLE 640 480 560 561 322.9 238.6\n")
    out = tmp_path / "project.json"  # the file the issue saw replaced
    out.write_text('{"version": 1}\n')
    assert main(["camera", "import", str(colmap), "--out", str(out)]) == 2
    captured = capsys.readouterr()
    assert captured.err == (
        f"lightcal camera: error: {out}: --out: exists; use --force to replace it\n"
    )
    assert captured.out == "" and out.read_text() == '{"version": 1}\n'
    assert main(["camera", "import", str(colmap), "--out", str(out), "--force"]) == 0
    assert read_camera(out).fx == 560.0
    assert main(["camera", "import", str(out), "--out", str(out), "--force"]) == 2
    assert capsys.readouterr().err == (
        f"lightcal camera: error: {out}: --out: is the camera file, an input of the import; "
        "write elsewhere\n"
    )
    assert read_camera(out).fx == 560.0
    assert _listing(tmp_path) == ["cameras.txt", "project.json"]  # no temporary file left


def test_camera_import_never_replaces_a_file_that_appears_while_it_works(
    tmp_path: Path, capsys, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Checked first, then created atomically without replacing: a file another program
    wrote in between is kept."""
    import lightcal.io.outputs as outputs

    colmap = tmp_path / "cameras.txt"
    colmap.write_text("1 PINHOLE 640 480 560 561 322.9 238.6\n")
    out = tmp_path / "camera.yaml"
    check = outputs.check_output_file

    def check_then_appear(path: Path, **kwargs: Any) -> Path:
        checked = check(path, **kwargs)
        out.write_text("theirs\n")
        return checked

    monkeypatch.setattr(outputs, "check_output_file", check_then_appear)
    assert main(["camera", "import", str(colmap), "--out", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"lightcal camera: error: {out}: --out: exists; use --force to replace it\n"
    )
    assert out.read_text() == "theirs\n"
    assert _listing(tmp_path) == ["camera.yaml", "cameras.txt"]


def test_write_camera_without_replace_keeps_an_existing_file(tmp_path: Path) -> None:
    out = tmp_path / "camera.json"
    out.write_text("mine\n")
    with pytest.raises(FileExistsError):
        write_camera(CAMERA, out, replace=False)
    assert out.read_text() == "mine\n" and _listing(tmp_path) == ["camera.json"]
    write_camera(CAMERA, tmp_path / "new.json", replace=False)
    assert read_camera(tmp_path / "new.json") == CAMERA


def test_camera_calibrate_replaces_an_existing_out_only_with_force(tmp_path: Path, capsys) -> None:
    folder = _write(tmp_path / "chess", list(chessboard_views()))
    out = tmp_path / "camera.yaml"
    out.write_text("keep\n")
    assert main(_calibrate(folder, out)) == 2
    captured = capsys.readouterr()
    assert captured.err == (
        f"lightcal camera: error: {out}: --out: exists; use --force to replace it\n"
    )
    assert captured.out == ""  # before any photo was read
    assert out.read_text() == "keep\n"
    assert main(_calibrate(folder, out, "--force")) == 0
    assert read_camera(out).width == CHESS_CAMERA.width
    board = tmp_path / "chessboard.yaml"
    assert main(_calibrate(folder, board, "--force")) == 2  # an input, even with --force
    assert capsys.readouterr().err == (
        f"lightcal camera: error: {board}: --out: is the board file, an input of the "
        "calibration; write elsewhere\n"
    )
