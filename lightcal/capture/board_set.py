"""Several boards on one wall (`lightcal init --board A.yaml --board B.yaml`).

Each photo's pose uses the markers of every board (`marker_pose.estimate_pose` given a
sequence of boards), so the boards must share the world frame (their `origin_world_m` or
`center_world_m` place them on the one wall) and no marker may be on two boards: boards
with the same dictionary must use different ids, or a marker found in a photo could not
be told apart (`read_marker_boards` refuses them, naming both files).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from lightcal.capture.boards import ArucoGridBoard, CharucoBoard, MarkerLayout
from lightcal.capture.marker_pose import MarkerBoard
from lightcal.errors import InputError
from lightcal.io.board_file import read_board

__all__ = ["marker_keys", "read_marker_boards"]


def marker_keys(board: MarkerBoard) -> list[tuple[str, int]]:
    """The (dictionary, id) of every marker of a board, in the board's order."""
    if isinstance(board, MarkerLayout):
        return [(m.dictionary, m.id) for m in board.markers]
    if isinstance(board, ArucoGridBoard):
        return [(board.dictionary, int(i)) for i in board.ids]
    return [(board.dictionary, int(i)) for i in board.marker_ids]


def read_marker_boards(paths: Sequence[str | Path]) -> list[MarkerBoard]:
    """Read the board files of a wall: each must carry markers, no marker on two boards.

    Args:
        paths: The board files (`lightcal.io.board_file`), at least one.

    Returns:
        The boards, in the order of `paths`.

    Raises:
        InputError: No board file; a file that cannot be read or describes no board; a
            chessboard (no markers); a file given twice; a marker (dictionary, id) on two
            boards (named on the later file).
    """
    if not paths:
        raise InputError("board", "expected at least one board file")
    boards: list[MarkerBoard] = []
    owner: dict[tuple[str, int], Path] = {}
    seen: dict[Path, Path] = {}
    for given in paths:
        path = Path(given)
        resolved = path.resolve()
        if resolved in seen:
            raise InputError(path, f"given twice as a board file (also as {seen[resolved]})")
        seen[resolved] = path
        board = read_board(path)
        if not isinstance(board, ArucoGridBoard | CharucoBoard | MarkerLayout):
            raise InputError(
                path,
                "a chessboard has no markers, so it gives no camera pose on the wall: "
                "expected an aruco_grid, charuco or markers board",
            )
        for key in marker_keys(board):
            other = owner.get(key)
            if other is not None:
                raise InputError(
                    path,
                    f"{key[0]} id {key[1]} is also on board {other}: expected boards with "
                    "the same dictionary to use different ids",
                )
        owner.update(dict.fromkeys(marker_keys(board), path))
        boards.append(board)
    return boards
