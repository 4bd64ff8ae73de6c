"""Camera poses from a COLMAP text model, moved into the wall's world frame.

A COLMAP sparse model exported as text (`colmap model_converter --output_type TXT`)
is a folder with `cameras.txt`, `images.txt` and `points3D.txt`. COLMAP's world is
arbitrary (origin, orientation and scale). `read_colmap_model` fits the wall plane
to the 3-D points and maps COLMAP's world to ours (docs/MODEL.md) by a similarity
`X_world = scale * R @ X_colmap + t`:

- the wall is z = 0, its normal +z oriented towards the cameras (all camera centres
  end up at z > 0; cameras on both sides of the wall are an error);
- the origin is the orthogonal projection onto the wall of the centroid of the
  wall's inlier points;
- the x axis is the x axis (image "right") of the first image, by IMAGE_ID, projected
  onto the wall; images whose x axis is within about 6 degrees of the wall normal are
  passed over. Seen from that camera, the world y axis (n x x) thus points roughly
  "up" in the image. This makes the frame independent of COLMAP's arbitrary world.
  (If every image's x axis is nearly normal to the wall, which no real capture does,
  the COLMAP axis least aligned with the normal is projected instead.)
- metres come from a `ScaleSpec`: a known distance between two 3-D points, a known
  baseline between two camera centres, or a plain factor (metres per COLMAP unit).

Poses are `T_camera_world` (X_c = R X_w + t), as in COLMAP's images.txt
(QW QX QY QZ TX TY TZ map COLMAP world to camera). Under the similarity the
rotation composes, `R_cw = R_c_colmap @ R.T`, and the translation is scaled,
`t_cw = scale * t_c_colmap - R_cw @ t`.

Only cameras.txt is parsed by `lightcal.io.camera_file.read_camera`; images.txt and
points3D.txt are parsed here. Malformed lines raise `InputError` naming the file
and its 1-based line number.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lightcal.core.camera import Camera
from lightcal.core.plane_fit import fit_plane_ransac
from lightcal.core.rotations import matrix_from_quaternion_wxyz
from lightcal.errors import InputError
from lightcal.io.camera_file import read_camera

COLMAP_FILES = ("cameras.txt", "images.txt", "points3D.txt")
"""The three files of a COLMAP text model."""

QUATERNION_NORM_TOL = 1e-3
"""Largest accepted `| |q| - 1 |` for an images.txt quaternion (it is then re-normalised)."""

_MIN_IN_PLANE_AXIS = 0.1
"""An image's x axis is used for the world x axis when its component in the wall plane
has at least this length (x axis more than ~5.7 degrees from the wall normal)."""


# --------------------------------------------------------------------------- scale


@dataclass(frozen=True, eq=False)
class KnownDistance:
    """Metric scale from the known distance between two 3-D points of the model.

    Build it with `known_distance`. Exactly one of `point_ids` and `points_colmap` is set.

    Attributes:
        distance_m: The true distance between the two points, metres.
        point_ids: Two POINT3D_IDs of points3D.txt, or None.
        points_colmap: (2, 3) two points in COLMAP's world coordinates, or None.
    """

    distance_m: float
    point_ids: tuple[int, int] | None = None
    points_colmap: NDArray[np.float64] | None = None


@dataclass(frozen=True)
class CameraBaseline:
    """Metric scale from the known distance between two camera centres.

    Build it with `camera_baseline`.

    Attributes:
        image_a: NAME of the first image in images.txt.
        image_b: NAME of the second image.
        distance_m: The true distance between the two camera centres, metres.
    """

    image_a: str
    image_b: str
    distance_m: float


ScaleSpec = KnownDistance | CameraBaseline | float
"""How COLMAP units become metres: a `KnownDistance`, a `CameraBaseline`, or a plain
factor in metres per COLMAP unit."""


def _check_distance(distance_m: float, *, name: str) -> float:
    """Return `distance_m` as a float if it is finite and > 0, else raise InputError."""
    try:
        value = float(distance_m)
    except (TypeError, ValueError) as exc:
        raise InputError(name, f"expected a distance in metres, got {distance_m!r}") from exc
    if not (math.isfinite(value) and value > 0.0):
        raise InputError(name, f"expected a finite distance > 0 m, got {distance_m!r}")
    return value


def known_distance(
    *,
    distance_m: float,
    point_ids: Sequence[int] | None = None,
    points_colmap: ArrayLike | None = None,
) -> KnownDistance:
    """Scale from the distance between two points: give their ids or their coordinates.

    Args:
        distance_m: True distance between the two points, metres, > 0.
        point_ids: Two distinct POINT3D_IDs of points3D.txt.
        points_colmap: (2, 3) two points in COLMAP's world coordinates (e.g. picked in
            the COLMAP GUI).

    Returns:
        The scale specification.

    Raises:
        InputError: Not exactly one of `point_ids`, `points_colmap`; wrong shapes;
            a non-positive distance.
    """
    distance = _check_distance(distance_m, name="distance_m")
    if (point_ids is None) == (points_colmap is None):
        raise InputError(
            "known_distance",
            "expected exactly one of point_ids and points_colmap, got "
            + ("both" if point_ids is not None else "neither"),
        )
    if point_ids is not None:
        ids = tuple(point_ids)
        if len(ids) != 2 or not all(
            isinstance(i, int | np.integer) and not isinstance(i, bool) for i in ids
        ):
            raise InputError("point_ids", f"expected two integer POINT3D_IDs, got {point_ids!r}")
        if ids[0] == ids[1]:
            raise InputError("point_ids", f"expected two different POINT3D_IDs, got {ids!r}")
        return KnownDistance(distance_m=distance, point_ids=(int(ids[0]), int(ids[1])))
    points = np.array(points_colmap, dtype=np.float64)
    if points.shape != (2, 3) or not np.all(np.isfinite(points)):
        raise InputError(
            "points_colmap", f"expected a finite (2, 3) array of two points, got {points.tolist()}"
        )
    points.flags.writeable = False
    return KnownDistance(distance_m=distance, points_colmap=points)


def camera_baseline(image_a: str, image_b: str, *, distance_m: float) -> CameraBaseline:
    """Scale from the distance between the centres of two cameras (image NAMEs).

    Args:
        image_a: NAME of the first image in images.txt.
        image_b: NAME of the second image, different from the first.
        distance_m: True distance between the two camera centres, metres, > 0.

    Returns:
        The scale specification.
    """
    distance = _check_distance(distance_m, name="distance_m")
    if image_a == image_b:
        raise InputError(
            "camera_baseline", f"expected two different image names, got {image_a!r} twice"
        )
    return CameraBaseline(image_a=image_a, image_b=image_b, distance_m=distance)


# --------------------------------------------------------------------------- results


@dataclass(frozen=True, eq=False)
class SimilarityTransform:
    """`X_world = scale * R @ X_colmap + t`: COLMAP's world to ours (metres).

    Attributes:
        scale: Metres per COLMAP unit, > 0.
        R: (3, 3) rotation, COLMAP world axes to our world axes.
        t: (3,) translation, metres.
    """

    scale: float
    R: NDArray[np.float64]
    t: NDArray[np.float64]

    def apply(self, points_colmap: ArrayLike) -> NDArray[np.float64]:
        """Map points from COLMAP's world to ours.

        Args:
            points_colmap: (N, 3) in COLMAP units.

        Returns:
            points_world: (N, 3) metres.
        """
        points = np.asarray(points_colmap, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 3:
            raise InputError("points_colmap", f"expected an (N, 3) array, got shape {points.shape}")
        return self.scale * points @ self.R.T + self.t

    @property
    def matrix(self) -> NDArray[np.float64]:
        """(4, 4) homogeneous matrix `[[scale R, t], [0, 1]]`."""
        matrix = np.eye(4)
        matrix[:3, :3] = self.scale * self.R
        matrix[:3, 3] = self.t
        return matrix


@dataclass(frozen=True, eq=False)
class SfmImage:
    """One registered image with its pose in our world frame.

    Attributes:
        image_id: IMAGE_ID in images.txt.
        name: NAME in images.txt (file name, relative to COLMAP's image folder).
        camera_id: CAMERA_ID, a key of `SfmModel.cameras`.
        R_camera_world: (3, 3) world -> camera rotation.
        t_camera_world: (3,) metres; X_c = R X_w + t.
    """

    image_id: int
    name: str
    camera_id: int
    R_camera_world: NDArray[np.float64]
    t_camera_world: NDArray[np.float64]

    @property
    def centre_world(self) -> NDArray[np.float64]:
        """(3,) camera centre in the world frame, metres: -R^T t."""
        return -self.R_camera_world.T @ self.t_camera_world


@dataclass(frozen=True, eq=False)
class SfmModel:
    """A COLMAP model in our world frame (wall z = 0, metres).

    Attributes:
        cameras: CAMERA_ID -> camera, every camera of cameras.txt.
        images: The registered images, by increasing IMAGE_ID.
        point_ids: (N,) POINT3D_IDs, in file order.
        points_world: (N, 3) the 3-D points in the world frame, metres.
        wall_inliers: (N,) True for the points within the threshold of the wall.
        plane_rms_m: RMS distance of the wall inliers to the fitted plane, metres.
        n_inliers: Number of wall inliers.
        transform_world_colmap: The similarity that maps COLMAP's world to ours.
    """

    cameras: dict[int, Camera]
    images: list[SfmImage]
    point_ids: NDArray[np.int64]
    points_world: NDArray[np.float64]
    wall_inliers: NDArray[np.bool_]
    plane_rms_m: float
    n_inliers: int
    transform_world_colmap: SimilarityTransform

    def image(self, name: str) -> SfmImage:
        """The image called `name` (its NAME in images.txt)."""
        for image in self.images:
            if image.name == name:
                return image
        raise InputError("name", f"expected the NAME of an image of the model, got {name!r}")


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
    try:
        return path.read_text(encoding="utf-8").splitlines()
    except FileNotFoundError as exc:
        raise InputError(path, "file not found, expected a COLMAP text model file") from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, f"cannot read the file as UTF-8 text: {exc}") from exc


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


def _metres_per_unit(
    scale: ScaleSpec,
    *,
    point_ids: NDArray[np.int64],
    points_colmap: NDArray[np.float64],
    centres_colmap: dict[str, NDArray[np.float64]],
    points_path: Path,
    images_path: Path,
) -> float:
    """Metres per COLMAP unit from a scale specification."""
    if isinstance(scale, KnownDistance):
        if scale.point_ids is not None:
            where = {int(point_id): k for k, point_id in enumerate(point_ids)}
            missing = [i for i in scale.point_ids if i not in where]
            if missing:
                raise InputError(
                    "scale.point_ids",
                    f"expected POINT3D_IDs present in {points_path}, got unknown id(s) {missing}",
                )
            pair = points_colmap[[where[i] for i in scale.point_ids]]
            what = f"points {scale.point_ids[0]} and {scale.point_ids[1]}"
        else:
            assert scale.points_colmap is not None  # known_distance sets exactly one
            pair = scale.points_colmap
            what = "the two points_colmap"
        length = float(np.linalg.norm(pair[1] - pair[0]))
        source = "scale"
    elif isinstance(scale, CameraBaseline):
        missing_names = [n for n in (scale.image_a, scale.image_b) if n not in centres_colmap]
        if missing_names:
            raise InputError(
                "scale",
                f"camera_baseline: expected image NAMEs present in {images_path}, "
                f"got unknown {missing_names}",
            )
        length = float(
            np.linalg.norm(centres_colmap[scale.image_b] - centres_colmap[scale.image_a])
        )
        what = f"the centres of images {scale.image_a!r} and {scale.image_b!r}"
        source = "scale"
    else:
        if isinstance(scale, bool) or not isinstance(scale, int | float):
            raise InputError(
                "scale",
                "expected known_distance(...), camera_baseline(...) or a number of metres "
                f"per COLMAP unit, got {scale!r}",
            )
        factor = float(scale)
        if not (math.isfinite(factor) and factor > 0.0):
            raise InputError("scale", f"expected metres per COLMAP unit > 0, got {scale!r}")
        return factor
    if not length > 0.0:
        raise InputError(source, f"{what} coincide in the COLMAP model: no scale can be derived")
    return scale.distance_m / length


def _wall_axes(normal: NDArray[np.float64], images: list[ColmapImageRecord]) -> NDArray[np.float64]:
    """(3, 3) rows = world x, y, z axes in COLMAP coordinates (z = the wall normal)."""
    candidates = [record.R_camera_colmap[0] for record in sorted(images, key=lambda r: r.image_id)]
    candidates += list(np.eye(3)[np.argsort(np.abs(normal))])
    for axis in candidates:
        in_plane = axis - (axis @ normal) * normal
        length = float(np.linalg.norm(in_plane))
        if length >= _MIN_IN_PLANE_AXIS:
            x_axis = in_plane / length
            break
    else:  # pragma: no cover - the least aligned COLMAP axis always qualifies
        raise AssertionError("no in-plane axis")
    y_axis = np.cross(normal, x_axis)
    return np.stack([x_axis, y_axis, normal])


def read_colmap_model(
    folder: str | Path,
    *,
    scale: ScaleSpec,
    wall_inlier_threshold_m: float = 0.005,
    rng: np.random.Generator,
) -> SfmModel:
    """Read a COLMAP text model and express its poses in the wall's world frame (metres).

    The metric scale is derived first (it does not depend on the plane), so the wall
    inlier threshold is given in metres and converted to COLMAP units.

    Args:
        folder: Folder with cameras.txt, images.txt and points3D.txt.
        scale: `known_distance(...)`, `camera_baseline(...)` or metres per COLMAP unit.
        wall_inlier_threshold_m: Largest distance of a wall point to the plane, metres.
        rng: Source of the RANSAC samples.

    Returns:
        The model in our world frame; see the module docstring for the axes.

    Raises:
        InputError: A missing folder or file; a malformed line (file and line); an
            image referencing a camera absent from cameras.txt; no image; fewer than 3
            points; a degenerate (collinear) point cloud; cameras on both sides of or
            on the wall; a scale that names unknown points or images.
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
    threshold_m = _check_distance(wall_inlier_threshold_m, name="wall_inlier_threshold_m")
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
    records = sorted(records, key=lambda r: r.image_id)
    rotations = [record.R_camera_colmap for record in records]
    centres = np.array([-R.T @ record.t for R, record in zip(rotations, records, strict=True)])

    point_ids, points_colmap = read_points3d_txt(points_path)
    if point_ids.size < 3:
        raise InputError(
            points_path, f"expected at least 3 points to fit the wall plane, got {point_ids.size}"
        )

    metres_per_unit = _metres_per_unit(
        scale,
        point_ids=point_ids,
        points_colmap=points_colmap,
        centres_colmap={r.name: c for r, c in zip(records, centres, strict=True)},
        points_path=points_path,
        images_path=images_path,
    )
    try:
        plane = fit_plane_ransac(points_colmap, threshold=threshold_m / metres_per_unit, rng=rng)
    except InputError as exc:
        raise InputError(points_path, f"wall plane: {exc.detail}") from exc

    normal, offset = plane.normal, plane.offset
    heights = centres @ normal + offset
    if np.all(heights < 0.0):
        normal, offset, heights = -normal, -offset, -heights
    if not np.all(heights > 0.0):
        front = [r.name for r, h in zip(records, heights, strict=True) if h > 0.0]
        back = [r.name for r, h in zip(records, heights, strict=True) if h <= 0.0]
        raise InputError(
            images_path,
            "expected every camera centre on the same side of the wall plane, got "
            f"{len(front)} on one side ({', '.join(front[:5])}) and {len(back)} on the other "
            f"side or on the plane ({', '.join(back[:5])})",
        )

    centroid = points_colmap[plane.inliers].mean(axis=0)
    origin = centroid - (centroid @ normal + offset) * normal
    R_world_colmap = _wall_axes(normal, records)
    t_world = -metres_per_unit * (R_world_colmap @ origin)
    R_world_colmap.flags.writeable = False
    t_world.flags.writeable = False
    transform = SimilarityTransform(scale=metres_per_unit, R=R_world_colmap, t=t_world)

    images: list[SfmImage] = []
    for record, R_camera_colmap in zip(records, rotations, strict=True):
        R_camera_world = R_camera_colmap @ R_world_colmap.T
        t_camera_world = metres_per_unit * record.t - R_camera_world @ t_world
        R_camera_world.flags.writeable = False
        t_camera_world.flags.writeable = False
        images.append(
            SfmImage(
                image_id=record.image_id,
                name=record.name,
                camera_id=record.camera_id,
                R_camera_world=R_camera_world,
                t_camera_world=t_camera_world,
            )
        )
    points_world = transform.apply(points_colmap)
    points_world.flags.writeable = False
    point_ids.flags.writeable = False
    return SfmModel(
        cameras=cameras,
        images=images,
        point_ids=point_ids,
        points_world=points_world,
        wall_inliers=plane.inliers,
        plane_rms_m=plane.rms * metres_per_unit,
        n_inliers=plane.n_inliers,
        transform_world_colmap=transform,
    )
