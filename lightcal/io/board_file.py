"""The board file: a small JSON or YAML description of one calibration board.

`lightcal init --board` (marker poses) and `lightcal camera calibrate --board`
(intrinsics) read it. One mapping with a `type` and the fields of the matching
`lightcal.capture.boards` class (lengths in metres, the world placement of the board as that
module defines it):

```yaml
version: 1                 # optional
type: aruco_grid           # aruco_grid | charuco | chessboard
dictionary: DICT_4X4_50
markers_x: 8
markers_y: 6
marker_length_m: 0.10
separation_m: 0.20
first_id: 0                # optional
origin_world_m: [-1.1, 0.8] # optional: the board's top-left corner on the wall
```

`charuco` takes `dictionary`, `squares_x`, `squares_y`, `square_length_m`,
`marker_length_m` and `origin_world_m`; `chessboard` takes `inner_x`, `inner_y` and
`square_length_m`. `markers` lists markers one by one
(`lightcal.capture.marker_layout`), each with its own dictionary or the file's:

```yaml
type: markers
dictionary: DICT_APRILTAG_36h11  # optional: the default of the markers
markers:
  - {id: 0, center_world_m: [-0.6, 0.35], size_m: 0.15}
  - {id: 1, center_world_m: [0.6, 0.35], size_m: 0.15, rotation_deg: 90}
  - {dictionary: DICT_4X4_50, id: 7, center_world_m: [0.0, -0.35], size_m: 0.1}
```

JSON for `.json`, YAML for `.yaml` / `.yml`. Every problem is an
`InputError` naming the file and the field; an OpenCV camera file, a project or a result
file given as a board file is named for what it is.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, TypeAdapter, ValidationError

from lightcal.capture.boards import (
    ArucoGridBoard,
    Board,
    CharucoBoard,
    Chessboard,
    LayoutMarker,
    MarkerLayout,
    aruco_dictionary,
)
from lightcal.errors import InputError
from lightcal.io.atomic import atomic_write_text
from lightcal.io.document import read_document

__all__ = [
    "BOARD_FILE_VERSION",
    "ArucoGridSpec",
    "BoardSpec",
    "CharucoSpec",
    "ChessboardSpec",
    "LayoutMarkerSpec",
    "MarkersSpec",
    "board_from_spec",
    "board_to_spec",
    "parse_board",
    "read_board",
    "write_board",
]

BOARD_FILE_VERSION: Literal[1] = 1

_SUFFIXES = (".json", ".yaml", ".yml")


def _not_bool(value: Any) -> Any:
    """YAML `yes` / JSON `true` are not numbers (pydantic would take them as 1)."""
    if isinstance(value, bool):
        raise ValueError(f"expected a number, got {value!r}")
    return value


Count = Annotated[int, BeforeValidator(_not_bool)]
Number = Annotated[float, BeforeValidator(_not_bool)]
PositiveLength = Annotated[float, BeforeValidator(_not_bool), Field(gt=0)]
Origin = Annotated[list[Number], Field(min_length=2, max_length=2)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)


class ArucoGridSpec(_Model):
    """A grid of ArUco markers (`lightcal.capture.boards.ArucoGridBoard`)."""

    version: Literal[1] = BOARD_FILE_VERSION
    type: Literal["aruco_grid"]
    dictionary: str
    markers_x: Count = Field(ge=1)
    markers_y: Count = Field(ge=1)
    marker_length_m: PositiveLength
    separation_m: PositiveLength
    first_id: Count = Field(default=0, ge=0)
    origin_world_m: Origin = Field(default_factory=lambda: [0.0, 0.0])


class CharucoSpec(_Model):
    """A ChArUco board (`lightcal.capture.boards.CharucoBoard`)."""

    version: Literal[1] = BOARD_FILE_VERSION
    type: Literal["charuco"]
    dictionary: str
    squares_x: Count = Field(ge=2)
    squares_y: Count = Field(ge=2)
    square_length_m: PositiveLength
    marker_length_m: PositiveLength
    origin_world_m: Origin = Field(default_factory=lambda: [0.0, 0.0])


class ChessboardSpec(_Model):
    """A plain chessboard (`lightcal.capture.boards.Chessboard`), for intrinsics only."""

    version: Literal[1] = BOARD_FILE_VERSION
    type: Literal["chessboard"]
    inner_x: Count = Field(ge=2)
    inner_y: Count = Field(ge=2)
    square_length_m: PositiveLength


class LayoutMarkerSpec(_Model):
    """One marker of a `markers` board (`lightcal.capture.marker_layout.LayoutMarker`)."""

    dictionary: str | None = None
    id: Count = Field(ge=0)
    center_world_m: Origin
    size_m: PositiveLength
    rotation_deg: Number = 0.0


class MarkersSpec(_Model):
    """Markers placed one by one (`lightcal.capture.marker_layout.MarkerLayout`)."""

    version: Literal[1] = BOARD_FILE_VERSION
    type: Literal["markers"]
    dictionary: str | None = None
    markers: list[LayoutMarkerSpec] = Field(min_length=1)


AnyBoardSpec = ArucoGridSpec | CharucoSpec | ChessboardSpec | MarkersSpec

BoardSpec = Annotated[AnyBoardSpec, Field(discriminator="type")]
"""The content of a board file (a discriminated union on `type`)."""

_ADAPTER: TypeAdapter[AnyBoardSpec] = TypeAdapter(BoardSpec)

_KINDS = ("aruco_grid", "charuco", "chessboard", "markers")
_TYPES = "aruco_grid, charuco, chessboard or markers"


_EXPECTED = f"expected a board file (type {_TYPES})"

_OTHER_FILES = (
    ({"camera_matrix"}, "an OpenCV camera file"),
    ({"image_width", "image_height"}, "an OpenCV camera file"),
    ({"lightcal_version", "parameters"}, "a result file of lightcal calibrate"),
    ({"images", "lights"}, "a project file"),
)
"""Keys that name a file given where a board file was expected (without a board `type`)."""


def _other_file(data: dict[Any, Any]) -> str | None:
    """What a mapping without a board `type` is, when it is another file lightcal knows."""
    for keys, what in _OTHER_FILES:
        if keys <= data.keys():
            return what
    return None


def _is_opencv_yaml(path: Path, error: InputError) -> bool:
    """The YAML reader stopped at an OpenCV tag (`!!opencv-matrix`) or at the header
    older OpenCV writes (`%YAML:1.0`, not YAML): an OpenCV file."""
    cause = error.__cause__
    if isinstance(cause, yaml.constructor.ConstructorError):
        return "tag:yaml.org,2002:opencv-" in str(cause.problem or "")
    if not isinstance(cause, yaml.YAMLError):
        return False
    try:
        with path.open("rb") as stream:
            return stream.read(6) == b"%YAML:"
    except OSError:
        return False


def _format_loc(loc: tuple[Any, ...]) -> str:
    # The discriminator value is the first element of a union error's location: drop it.
    parts = loc[1:] if loc and loc[0] in _KINDS else loc
    out = ""
    for part in parts:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out or "(top level)"


def parse_board(data: Any, source: str | Path) -> AnyBoardSpec:
    """Validate a parsed board document.

    Args:
        data: The parsed JSON / YAML content.
        source: The file it came from, for error messages.

    Returns:
        The validated spec.

    Raises:
        InputError: Not a mapping, an unknown `type` or version, a missing or invalid field;
            a camera, project or result file is named as such.
    """
    if not isinstance(data, dict):
        raise InputError(source, f"expected a mapping with a 'type' ({_TYPES}) at the top level")
    kind = data.get("type")
    other = _other_file(data) if kind not in _KINDS else None
    if other is not None:
        raise InputError(source, f"{other}, not a board file: {_EXPECTED}")
    version = data.get("version", BOARD_FILE_VERSION)
    if version != BOARD_FILE_VERSION:
        raise InputError(
            source, f"version: this lightcal reads board file version 1, got {version!r}"
        )
    if kind not in _KINDS:
        raise InputError(source, f"type: expected {_TYPES}, got {kind!r}")
    try:
        return _ADAPTER.validate_python(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        more = f" (and {exc.error_count() - 1} more problems)" if exc.error_count() > 1 else ""
        msg = err["msg"].removeprefix("Value error, ")
        raise InputError(source, f"{_format_loc(err['loc'])}: {msg}{more}") from exc


def _layout_from_spec(spec: MarkersSpec) -> MarkerLayout:
    """The layout of a `markers` spec; errors name `markers[i].<field>`."""
    if spec.dictionary is not None:
        aruco_dictionary(spec.dictionary)
    markers = []
    for i, entry in enumerate(spec.markers):
        dictionary = entry.dictionary if entry.dictionary is not None else spec.dictionary
        if dictionary is None:
            raise InputError(
                f"markers[{i}].dictionary",
                "expected the marker's dictionary, or a 'dictionary' for every marker at "
                "the top of the file",
            )
        try:
            markers.append(
                LayoutMarker(
                    dictionary,
                    entry.id,
                    (entry.center_world_m[0], entry.center_world_m[1]),
                    entry.size_m,
                    entry.rotation_deg,
                )
            )
        except InputError as exc:
            field = "dictionary" if exc.source == "dictionary" else exc.source
            raise InputError(f"markers[{i}].{field}", exc.detail) from exc
    return MarkerLayout(tuple(markers))


def board_from_spec(spec: AnyBoardSpec, source: str | Path = "board") -> Board:
    """The board object of a spec; a board the spec cannot build is an InputError on `source`."""
    try:
        if isinstance(spec, ArucoGridSpec):
            return ArucoGridBoard(
                spec.dictionary,
                spec.markers_x,
                spec.markers_y,
                spec.marker_length_m,
                spec.separation_m,
                first_id=spec.first_id,
                origin_world_m=(spec.origin_world_m[0], spec.origin_world_m[1]),
            )
        if isinstance(spec, CharucoSpec):
            return CharucoBoard(
                spec.dictionary,
                spec.squares_x,
                spec.squares_y,
                spec.square_length_m,
                spec.marker_length_m,
                origin_world_m=(spec.origin_world_m[0], spec.origin_world_m[1]),
            )
        if isinstance(spec, MarkersSpec):
            return _layout_from_spec(spec)
        return Chessboard(spec.inner_x, spec.inner_y, spec.square_length_m)
    except InputError as exc:
        raise InputError(source, f"{exc.source}: {exc.detail}") from exc


def board_to_spec(board: Board) -> AnyBoardSpec:
    """The file description of a board object."""
    if isinstance(board, ArucoGridBoard):
        return ArucoGridSpec(
            type="aruco_grid",
            dictionary=board.dictionary,
            markers_x=board.markers_x,
            markers_y=board.markers_y,
            marker_length_m=board.marker_length_m,
            separation_m=board.separation_m,
            first_id=board.first_id,
            origin_world_m=list(board.origin_world_m),
        )
    if isinstance(board, CharucoBoard):
        return CharucoSpec(
            type="charuco",
            dictionary=board.dictionary,
            squares_x=board.squares_x,
            squares_y=board.squares_y,
            square_length_m=board.square_length_m,
            marker_length_m=board.marker_length_m,
            origin_world_m=list(board.origin_world_m),
        )
    if isinstance(board, Chessboard):
        return ChessboardSpec(
            type="chessboard",
            inner_x=board.inner_x,
            inner_y=board.inner_y,
            square_length_m=board.square_length_m,
        )
    if isinstance(board, MarkerLayout):
        dictionaries = board.dictionaries
        common = dictionaries[0] if len(dictionaries) == 1 else None
        return MarkersSpec(
            type="markers",
            dictionary=common,
            markers=[
                LayoutMarkerSpec(
                    dictionary=None if common is not None else m.dictionary,
                    id=m.id,
                    center_world_m=list(m.center_world_m),
                    size_m=m.size_m,
                    rotation_deg=m.rotation_deg,
                )
                for m in board.markers
            ],
        )
    raise InputError(
        "board",
        f"expected an ArucoGridBoard, CharucoBoard, Chessboard or MarkerLayout, got {type(board)}",
    )


def _check_suffix(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix not in _SUFFIXES:
        raise InputError(
            path, f"unsupported board file suffix {path.suffix!r}: expected .json, .yaml or .yml"
        )
    return suffix


def read_board(path: str | Path) -> Board:
    """Read a board file (JSON or YAML by suffix, format in the module docstring).

    Args:
        path: The board file.

    Returns:
        An `ArucoGridBoard`, `CharucoBoard`, `Chessboard` or `MarkerLayout`.

    Raises:
        InputError: The file is missing, unreadable, not valid JSON / YAML, or describes
            no valid board; the message names the file (and line or field).
    """
    path = Path(path)
    suffix = _check_suffix(path)
    try:
        data = read_document(
            path,
            what="board file",
            as_json=suffix == ".json",
            empty=f"empty file: expected a board description with a 'type' ({_TYPES})",
        )
    except InputError as exc:
        if _is_opencv_yaml(path, exc):
            raise InputError(path, f"an OpenCV camera file, not a board file: {_EXPECTED}") from exc
        raise
    return board_from_spec(parse_board(data, path), path)


def write_board(board: Board, path: str | Path) -> None:
    """Write a board file atomically (JSON for `.json`, YAML for `.yaml` / `.yml`).

    Raises:
        InputError: Unsupported suffix, or the folder does not exist / cannot be written.
    """
    path = Path(path)
    suffix = _check_suffix(path)
    data = board_to_spec(board).model_dump(mode="json", exclude_none=True)
    if suffix == ".json":
        text = json.dumps(data, indent=2) + "\n"
    else:
        text = yaml.safe_dump(data, sort_keys=False)
    if not path.parent.is_dir():
        raise InputError(path, f"cannot write: folder {str(path.parent)!r} does not exist")
    try:
        atomic_write_text(path, text)
    except OSError as exc:
        raise InputError(path, f"cannot write: {exc.strerror or exc}") from exc
