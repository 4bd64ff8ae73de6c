"""The files of a new project's staging area (`lightcal_app.photo_project`): the suffixes
each kind of upload takes, the board type a board file is kept as, and reading an upload
with its checks, its errors naming the upload as the page knows it. No viser."""

from __future__ import annotations

from collections.abc import Callable, Collection
from pathlib import Path
from typing import TypeVar

from lightcal.capture.board_set import marker_keys
from lightcal.capture.boards import ArucoGridBoard, Board, CharucoBoard, Chessboard
from lightcal.capture.marker_layout import MarkerLayout
from lightcal.errors import InputError
from lightcal.io.board_file import read_board
from lightcal_app.uploads import relative_message, safe_file_name

CAMERA_SUFFIXES = (".yaml", ".yml", ".xml", ".json", ".txt")
BOARD_SUFFIXES = (".yaml", ".yml", ".json")
IMAGE_SUFFIXES_TEXT = (
    ".png, .tif, .tiff, .npy, .exr, .jpg or camera raw such as .dng, .cr2, .nef, .arw"
)


def board_type(board: Board) -> str:
    """The staging area's name of a board's type (its folder: `photo_build.BOARD_DIRS`)."""
    if isinstance(board, ArucoGridBoard):
        return "aruco_grid"
    if isinstance(board, CharucoBoard):
        return "charuco"
    if isinstance(board, MarkerLayout):
        return "markers"
    return "chessboard"


def folder_size(folder: Path) -> int:
    """Bytes of the files under `folder`."""
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file() and not p.is_symlink())


def files_in(folder: Path) -> list[Path]:
    """The files of `folder` (not hidden ones), sorted; none for a missing folder."""
    if not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir() if p.is_file() and not p.name.startswith("."))


def reader_error(exc: InputError, path: Path, name: str) -> InputError:
    """A reader's error on the stored `path`, named by the upload's `name`."""
    if exc.source in (str(path), str(path.resolve())):
        where = f"line {exc.line}: " if exc.line is not None else ""
        return InputError(name, where + exc.detail)
    return InputError(name, relative_message(exc, path.parent, name))


T = TypeVar("T")


def read_checked(
    path: Path,
    shown: str,
    suffixes: Collection[str],
    what: str,
    expected: str,
    reader: Callable[[Path], T],
) -> T:
    """`reader(path)` after checking the suffix; errors name the upload `shown`."""
    if path.suffix.lower() not in suffixes:
        raise InputError(shown, f"unsupported {what} suffix {path.suffix!r}: expected {expected}")
    try:
        return reader(path)
    except InputError as exc:
        raise reader_error(exc, path, shown) from exc


def add_wall_board(walls: list[Path], folder: Path, path: Path, board: Board) -> str:
    """Move the board file `path` into `folder`, one of the wall boards' `walls`: a wall
    has any number of boards, but no marker on two, so a staged wall board that shares
    a marker with `board` (an earlier version of it, most likely) is replaced.

    Returns:
        the stored name.
    """
    keys = set() if isinstance(board, Chessboard) else set(marker_keys(board))
    for staged in (f for wall in walls for f in files_in(wall)):
        try:
            old = read_board(staged)
        except InputError:
            old = None  # unreadable now: replaced as well
        if old is None or isinstance(old, Chessboard) or keys & set(marker_keys(old)):
            staged.unlink()
    folder.mkdir(exist_ok=True)
    stored = safe_file_name(path.name)
    path.replace(folder / stored)
    return stored
