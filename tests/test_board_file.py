"""Tests of lightcal.io.board_file: board descriptions on disk."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from lightcal.capture.boards import ArucoGridBoard, CharucoBoard, Chessboard
from lightcal.errors import InputError
from lightcal.io.board_file import (
    ArucoGridSpec,
    board_from_spec,
    board_to_spec,
    parse_board,
    read_board,
    write_board,
)

BOARDS: list[ArucoGridBoard | CharucoBoard | Chessboard] = [
    ArucoGridBoard("DICT_4X4_50", 8, 6, 0.12, 0.18, first_id=1, origin_world_m=(-1.11, 0.81)),
    CharucoBoard("DICT_5X5_100", 11, 8, 0.07, 0.05, origin_world_m=(-0.385, 0.28)),
    Chessboard(9, 6, 0.03),
]

GRID_YAML = """\
type: aruco_grid
dictionary: DICT_4X4_50
markers_x: 8
markers_y: 6
marker_length_m: 0.12
separation_m: 0.18
origin_world_m: [-1.11, 0.81]
"""


def _raises(path_or_source, message: str, *, line: int | None = None):
    where = f"{path_or_source}:{line}" if line is not None else str(path_or_source)
    return pytest.raises(InputError, match=f"^{re.escape(f'{where}: {message}')}$")


@pytest.mark.parametrize("suffix", [".json", ".yaml", ".yml"])
@pytest.mark.parametrize("board", BOARDS, ids=["aruco_grid", "charuco", "chessboard"])
def test_round_trip(tmp_path: Path, board, suffix: str):
    path = tmp_path / f"board{suffix}"
    write_board(board, path)
    assert read_board(path) == board
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary file left


def test_hand_written_yaml_with_defaults(tmp_path: Path):
    path = tmp_path / "wall.yaml"
    path.write_text(GRID_YAML)
    board = read_board(path)
    assert board == ArucoGridBoard(
        "DICT_4X4_50", 8, 6, 0.12, 0.18, first_id=0, origin_world_m=(-1.11, 0.81)
    )
    assert board.corners_world([0])[0, 0].tolist() == [-1.11, 0.81, 0.0]
    chess = tmp_path / "chess.json"
    chess.write_text('{"type": "chessboard", "inner_x": 9, "inner_y": 6, "square_length_m": 0.06}')
    assert read_board(chess) == Chessboard(9, 6, 0.06)


def test_written_yaml_is_readable_text(tmp_path: Path):
    path = tmp_path / "board.yaml"
    write_board(BOARDS[0], path)
    text = path.read_text()
    assert text.startswith("version: 1\ntype: aruco_grid\ndictionary: DICT_4X4_50\n")
    write_board(BOARDS[2], path)  # replaces the file
    assert read_board(path) == BOARDS[2]


def test_spec_conversion_round_trip():
    for board in BOARDS:
        assert board_from_spec(board_to_spec(board)) == board
    spec = board_to_spec(BOARDS[0])
    assert isinstance(spec, ArucoGridSpec) and spec.first_id == 1


def test_file_errors(tmp_path: Path):
    missing = tmp_path / "missing.yaml"
    with _raises(missing, "board file not found"):
        read_board(missing)
    wrong = tmp_path / "board.txt"
    wrong.write_text(GRID_YAML)
    with _raises(wrong, "unsupported board file suffix '.txt': expected .json, .yaml or .yml"):
        read_board(wrong)
    empty = tmp_path / "empty.yaml"
    empty.write_text("  \n")
    with _raises(
        empty,
        "empty file: expected a board description with a 'type' "
        "(aruco_grid, charuco, chessboard or markers)",
    ):
        read_board(empty)
    folder = tmp_path / "folder.yaml"
    folder.mkdir()
    with _raises(folder, "is a folder; expected a board file"):
        read_board(folder)


def test_corrupt_files(tmp_path: Path):
    binary = tmp_path / "binary.yaml"
    binary.write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe\x00garbage")
    with _raises(binary, "a PNG image; expected a board file (a text file)"):
        read_board(binary)  # named for what it is (lightcal.io.text_files)
    bad_json = tmp_path / "bad.json"
    bad_json.write_text('{"type": "chessboard",\n "inner_x": 9,,\n}')
    with _raises(
        bad_json, "not valid JSON: Expecting property name enclosed in double quotes", line=2
    ):
        read_board(bad_json)
    bad_yaml = tmp_path / "bad.yaml"
    bad_yaml.write_text("type: chessboard\ninner_x: [9\ninner_y: 6\n")
    with pytest.raises(InputError, match=rf"^{re.escape(str(bad_yaml))}:\d+: not valid YAML: "):
        read_board(bad_yaml)
    truncated = tmp_path / "truncated.yaml"
    truncated.write_text("".join(GRID_YAML.splitlines(keepends=True)[:3]))  # cut short
    with _raises(truncated, "markers_y: Field required (and 2 more problems)"):
        read_board(truncated)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            {"type": "checkerboard"},
            "type: expected aruco_grid, charuco, chessboard or markers, got 'checkerboard'",
        ),
        ({"version": 2}, "version: this lightcal reads board file version 1, got 2"),
        ({"markers_x": 0}, "markers_x: Input should be greater than or equal to 1"),
        ({"markers_x": True}, "markers_x: expected a number, got True"),
        (
            {"markers_x": 2.5},
            "markers_x: Input should be a valid integer, got a number with a fractional part",
        ),
        ({"marker_length_m": -0.1}, "marker_length_m: Input should be greater than 0"),
        (
            {"separation_m": "wide"},
            "separation_m: Input should be a valid number, unable to parse string as a number",
        ),
        (
            {"origin_world_m": [0.0]},
            "origin_world_m: List should have at least 2 items after validation, not 1",
        ),
        ({"colour": "red"}, "colour: Extra inputs are not permitted"),
        (
            {"dictionary": "DICT_9X9_1"},
            "dictionary: unknown ArUco dictionary 'DICT_9X9_1': expected a cv2.aruco name "
            "such as DICT_4X4_50, DICT_5X5_100, DICT_6X6_250, DICT_7X7_1000 or DICT_APRILTAG_36h11",
        ),
        (
            {"markers_y": 7},
            "first_id: the board needs marker ids 0..55 but DICT_4X4_50 has ids 0..49",
        ),
    ],
)
def test_invalid_fields(change, message):
    import yaml

    data = {**yaml.safe_load(GRID_YAML), **change}
    with _raises("wall.yaml", message):
        board_from_spec(parse_board(data, "wall.yaml"), "wall.yaml")


def test_not_a_mapping_and_charuco_checks():
    with _raises(
        "b.yaml",
        "expected a mapping with a 'type' (aruco_grid, charuco, chessboard or markers) at the "
        "top level",
    ):
        parse_board([1, 2], "b.yaml")
    data = {
        "type": "charuco",
        "dictionary": "DICT_4X4_50",
        "squares_x": 5,
        "squares_y": 4,
        "square_length_m": 0.04,
        "marker_length_m": 0.05,
    }
    with _raises(
        "b.yaml", "marker_length_m: expected a marker smaller than the square (0.04 m), got 0.05 m"
    ):
        board_from_spec(parse_board(data, "b.yaml"), "b.yaml")


def test_write_errors(tmp_path: Path):
    with _raises(
        tmp_path / "b.txt", "unsupported board file suffix '.txt': expected .json, .yaml or .yml"
    ):
        write_board(BOARDS[0], tmp_path / "b.txt")
    target = tmp_path / "nowhere" / "b.yaml"
    with _raises(target, f"cannot write: folder {str(target.parent)!r} does not exist"):
        write_board(BOARDS[0], target)
