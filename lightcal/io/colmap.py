"""COLMAP sparse models exported as text: cameras.txt, images.txt and points3D.txt.

A COLMAP sparse model exported as text (`colmap model_converter --output_type TXT`) is a
folder with `cameras.txt`, `images.txt` and `points3D.txt`. `read_colmap_text` reads the
three files as COLMAP wrote them: COLMAP's arbitrary world (origin, orientation, scale)
and units. Moving the poses into the wall's world frame in metres is computation, done by
`lightcal.capture.colmap_align.read_colmap_model`.

Poses are `T_camera_world` (X_c = R X_w + t), as in COLMAP's images.txt
(QW QX QY QZ TX TY TZ map COLMAP world to camera).

cameras.txt is parsed by `lightcal.io.camera_file.read_camera`; images.txt and
points3D.txt are parsed here. Malformed lines raise `InputError` naming the file
and its 1-based line number.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from lightcal.core.camera import Camera
from lightcal.core.rotations import matrix_from_quaternion_wxyz
from lightcal.errors import InputError
from lightcal.io.camera_file import read_camera
from lightcal.io.text_files import read_text

COLMAP_FILES = ("cameras.txt", "images.txt", "points3D.txt")
"""The three files of a COLMAP text model."""

QUATERNION_NORM_TOL = 1e-3
"""Largest accepted `| |q| - 1 |` for an images.txt quaternion (it is then re-normalised)."""


# --------------------------------------------------------------------------- parsers


@dataclass(frozen=True, eq=False)
class ColmapImageRecord:
    """One image of images.txt as COLMAP stores it (COLMAP world, COLMAP units).

    Attributes:
        image_id: IMAGE_ID.
        q_wxyz: (4,) QW QX QY QZ, re-normalised to unit norm.
        t: (3,) TX TY TZ, COLMAP units.
        camera_id: CAMERA_ID.
        name: NAME (everything after CAMERA_ID, so names with spaces survive).
        line: 1-based line number of the image line in images.txt.
    """

    image_id: int
    q_wxyz: NDArray[np.float64]
    t: NDArray[np.float64]
    camera_id: int
    name: str
    line: int

    @property
    def R_camera_colmap(self) -> NDArray[np.float64]:
        """(3, 3) COLMAP world -> camera rotation."""
        return matrix_from_quaternion_wxyz(self.q_wxyz)


def _read_lines(path: Path) -> list[str]:
    """All lines of a text file, or InputError if it cannot be read."""
    return read_text(path, "COLMAP text model file").splitlines()


def _parse_int(token: str, *, what: str, path: Path, line: int) -> int:
    try:
        return int(token)
    except ValueError as exc:
        raise InputError(path, f"{what}: expected an integer, got {token!r}", line=line) from exc


def _parse_floats(
    tokens: Sequence[str], *, what: str, path: Path, line: int
) -> NDArray[np.float64]:
    try:
        values = np.array([float(token) for token in tokens], dtype=np.float64)
    except ValueError as exc:
        raise InputError(
            path, f"{what}: expected numbers, got {' '.join(tokens)!r}", line=line
        ) from exc
    if not np.all(np.isfinite(values)):
        raise InputError(
            path, f"{what}: expected finite numbers, got {' '.join(tokens)!r}", line=line
        )
    return values


def _is_skipped(text: str) -> bool:
    """Blank lines and `#` comments carry no record."""
    stripped = text.strip()
    return not stripped or stripped.startswith("#")


def read_camera_ids(path: str | Path) -> list[int]:
    """The CAMERA_IDs of a COLMAP cameras.txt, in file order (the first field of each line).

    Raises:
        InputError: Missing file, a non-integer or repeated CAMERA_ID (with the line).
    """
    file = Path(path)
    ids: list[int] = []
    for number, text in enumerate(_read_lines(file), start=1):
        if _is_skipped(text):
            continue
        camera_id = _parse_int(text.split()[0], what="CAMERA_ID", path=file, line=number)
        if camera_id in ids:
            raise InputError(
                file, f"CAMERA_ID {camera_id} appears twice, expected unique ids", line=number
            )
        ids.append(camera_id)
    return ids


def read_images_txt(path: str | Path) -> list[ColmapImageRecord]:
    """Parse a COLMAP images.txt: two lines per image, the second (POINTS2D) possibly empty.

    Image line: `IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME`; the next physical
    line is always the image's POINTS2D line, `X Y POINT3D_ID` triples (it is checked,
    not kept). Blank lines and `#` comments between images are skipped. A missing
    POINTS2D line at the end of the file counts as empty.

    Args:
        path: The images.txt file.

    Returns:
        The images in file order.

    Raises:
        InputError: Missing file; a malformed line (file and line number); a
            quaternion whose norm is not 1 within `QUATERNION_NORM_TOL`; a repeated
            IMAGE_ID or NAME.
    """
    file = Path(path)
    lines = _read_lines(file)
    records: list[ColmapImageRecord] = []
    seen_ids: dict[int, int] = {}
    seen_names: dict[str, int] = {}
    index = 0
    while index < len(lines):
        number = index + 1
        text = lines[index]
        index += 1
        if _is_skipped(text):
            continue
        fields = text.strip().split(maxsplit=9)
        if len(fields) != 10:
            raise InputError(
                file,
                "image line: expected 10 fields 'IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME', "
                f"got {len(fields)}",
                line=number,
            )
        image_id = _parse_int(fields[0], what="IMAGE_ID", path=file, line=number)
        q = _parse_floats(fields[1:5], what="QW QX QY QZ", path=file, line=number)
        t = _parse_floats(fields[5:8], what="TX TY TZ", path=file, line=number)
        camera_id = _parse_int(fields[8], what="CAMERA_ID", path=file, line=number)
        name = fields[9].strip()
        norm = float(np.linalg.norm(q))
        if abs(norm - 1.0) > QUATERNION_NORM_TOL:
            raise InputError(
                file,
                f"QW QX QY QZ: expected a unit quaternion (norm 1 within "
                f"{QUATERNION_NORM_TOL:g}), got norm {norm:.6g}",
                line=number,
            )
        if image_id in seen_ids:
            raise InputError(
                file,
                f"IMAGE_ID {image_id} already used on line {seen_ids[image_id]}, "
                "expected unique ids",
                line=number,
            )
        if name in seen_names:
            raise InputError(
                file,
                f"NAME {name!r} already used on line {seen_names[name]}, expected unique names",
                line=number,
            )
        seen_ids[image_id] = number
        seen_names[name] = number
        if index < len(lines):
            _check_points2d(lines[index], path=file, line=index + 1)
            index += 1
        q = q / norm
        q.flags.writeable = False
        t.flags.writeable = False
        records.append(
            ColmapImageRecord(
                image_id=image_id, q_wxyz=q, t=t, camera_id=camera_id, name=name, line=number
            )
        )
    return records


def _check_points2d(text: str, *, path: Path, line: int) -> None:
    """Check a POINTS2D line: (X, Y, POINT3D_ID) triples, or nothing."""
    tokens = text.split()
    if len(tokens) % 3 != 0:
        raise InputError(
            path,
            f"POINTS2D line: expected (X, Y, POINT3D_ID) triples, got {len(tokens)} values "
            "(every image line must be followed by its POINTS2D line, possibly empty)",
            line=line,
        )
    try:
        values = np.array(tokens, dtype=np.float64).reshape(-1, 3)
    except ValueError as exc:
        raise InputError(
            path, "POINTS2D line: expected numbers 'X Y POINT3D_ID ...'", line=line
        ) from exc
    ids = values[:, 2]
    if not (np.all(np.isfinite(values)) and np.all(ids == np.round(ids))):
        raise InputError(
            path,
            "POINTS2D line: expected finite X Y and integer POINT3D_ID in every triple",
            line=line,
        )


def read_points3d_txt(path: str | Path) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Parse a COLMAP points3D.txt.

    Line: `POINT3D_ID X Y Z R G B ERROR TRACK[]`, TRACK as (IMAGE_ID, POINT2D_IDX) pairs
    (checked, not kept).

    Args:
        path: The points3D.txt file.

    Returns:
        point_ids: (N,) POINT3D_IDs in file order.
        points_colmap: (N, 3) X Y Z in COLMAP's world and units.

    Raises:
        InputError: Missing file, a malformed line (file and line number), a repeated id.
    """
    file = Path(path)
    ids: list[int] = []
    rows: list[NDArray[np.float64]] = []
    seen: dict[int, int] = {}
    for number, text in enumerate(_read_lines(file), start=1):
        if _is_skipped(text):
            continue
        tokens = text.split()
        if len(tokens) < 8 or (len(tokens) - 8) % 2 != 0:
            raise InputError(
                file,
                "expected 'POINT3D_ID X Y Z R G B ERROR' followed by (IMAGE_ID, POINT2D_IDX) "
                f"pairs, got {len(tokens)} fields",
                line=number,
            )
        point_id = _parse_int(tokens[0], what="POINT3D_ID", path=file, line=number)
        xyz = _parse_floats(tokens[1:4], what="X Y Z", path=file, line=number)
        for token in tokens[4:7]:
            _parse_int(token, what="R G B", path=file, line=number)
        _parse_floats(tokens[7:8], what="ERROR", path=file, line=number)
        for token in tokens[8:]:
            _parse_int(token, what="TRACK", path=file, line=number)
        if point_id in seen:
            raise InputError(
                file,
                f"POINT3D_ID {point_id} already used on line {seen[point_id]}, expected unique ids",
                line=number,
            )
        seen[point_id] = number
        ids.append(point_id)
        rows.append(xyz)
    point_ids = np.array(ids, dtype=np.int64)
    points = np.array(rows, dtype=np.float64).reshape(-1, 3)
    return point_ids, points


# --------------------------------------------------------------------------- model


@dataclass(frozen=True, eq=False)
class ColmapTextModel:
    """A COLMAP text model as stored (COLMAP world, COLMAP units).

    Attributes:
        folder: The folder the three files were read from.
        cameras: CAMERA_ID -> camera, every camera of cameras.txt.
        images: The registered images of images.txt, by increasing IMAGE_ID (at least one).
        point_ids: (N,) POINT3D_IDs of points3D.txt, in file order.
        points_colmap: (N, 3) their X Y Z in COLMAP's world and units.
    """

    folder: Path
    cameras: dict[int, Camera]
    images: list[ColmapImageRecord]
    point_ids: NDArray[np.int64]
    points_colmap: NDArray[np.float64]

    @property
    def images_path(self) -> Path:
        """The images.txt file."""
        return self.folder / COLMAP_FILES[1]

    @property
    def points_path(self) -> Path:
        """The points3D.txt file."""
        return self.folder / COLMAP_FILES[2]


def read_colmap_text(folder: str | Path) -> ColmapTextModel:
    """Read the three files of a COLMAP text model, checking that they agree.

    Args:
        folder: Folder with cameras.txt, images.txt and points3D.txt.

    Returns:
        The model as COLMAP stores it.

    Raises:
        InputError: A missing folder or file; a malformed line (file and line); an
            image referencing a camera absent from cameras.txt; no image.
    """
    root = Path(folder)
    if not root.is_dir():
        raise InputError(root, "expected a folder holding a COLMAP text model, not found")
    missing = [name for name in COLMAP_FILES if not (root / name).is_file()]
    if missing:
        raise InputError(
            root,
            f"missing {', '.join(missing)}: expected a COLMAP text model "
            "(cameras.txt, images.txt, points3D.txt; export one with "
            "`colmap model_converter --output_type TXT`)",
        )
    cameras_path, images_path, points_path = (root / name for name in COLMAP_FILES)

    camera_ids = read_camera_ids(cameras_path)
    cameras = {
        camera_id: read_camera(cameras_path, camera_id=camera_id) for camera_id in camera_ids
    }

    records = read_images_txt(images_path)
    for record in records:
        if record.camera_id not in cameras:
            raise InputError(
                images_path,
                f"image {record.image_id} ({record.name!r}) references CAMERA_ID "
                f"{record.camera_id}, expected one of cameras.txt's ids {sorted(cameras)}",
                line=record.line,
            )
    if not records:
        raise InputError(images_path, "expected at least one registered image, got none")

    point_ids, points_colmap = read_points3d_txt(points_path)
    return ColmapTextModel(
        folder=root,
        cameras=cameras,
        images=sorted(records, key=lambda r: r.image_id),
        point_ids=point_ids,
        points_colmap=points_colmap,
    )
