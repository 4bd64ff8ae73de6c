"""Camera poses from a COLMAP model, moved into the wall's world frame (metres).

COLMAP's world is arbitrary (origin, orientation and scale). `read_colmap_model` reads a
text model (`lightcal.io.colmap.read_colmap_text`), fits the wall plane to its 3-D points
(`lightcal.core.plane_fit.fit_plane_ransac`) and maps COLMAP's world to ours (the wall is
z = 0, cameras at z > 0: docs/conventions.md, "Frames") by a similarity
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

Poses are `T_camera_world` (X_c = R X_w + t), as in COLMAP's images.txt. Under the
similarity the rotation composes, `R_cw = R_c_colmap @ R.T`, and the translation is
scaled, `t_cw = scale * t_c_colmap - R_cw @ t`.
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
from lightcal.errors import InputError
from lightcal.io.colmap import ColmapImageRecord, read_colmap_text

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
    def center_world(self) -> NDArray[np.float64]:
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


# --------------------------------------------------------------------------- model


def _metres_per_unit(
    scale: ScaleSpec,
    *,
    point_ids: NDArray[np.int64],
    points_colmap: NDArray[np.float64],
    centers_colmap: dict[str, NDArray[np.float64]],
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
        missing_names = [n for n in (scale.image_a, scale.image_b) if n not in centers_colmap]
        if missing_names:
            raise InputError(
                "scale",
                f"camera_baseline: expected image NAMEs present in {images_path}, "
                f"got unknown {missing_names}",
            )
        length = float(
            np.linalg.norm(centers_colmap[scale.image_b] - centers_colmap[scale.image_a])
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

    The files are read by `lightcal.io.colmap.read_colmap_text`. The metric scale is
    derived first (it does not depend on the plane), so the wall inlier threshold is given
    in metres and converted to COLMAP units.

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
    threshold_m = _check_distance(wall_inlier_threshold_m, name="wall_inlier_threshold_m")
    text = read_colmap_text(folder)
    images_path, points_path = text.images_path, text.points_path
    cameras, records = text.cameras, text.images
    point_ids, points_colmap = text.point_ids, text.points_colmap
    rotations = [record.R_camera_colmap for record in records]
    centers = np.array([-R.T @ record.t for R, record in zip(rotations, records, strict=True)])
    if point_ids.size < 3:
        raise InputError(
            points_path, f"expected at least 3 points to fit the wall plane, got {point_ids.size}"
        )

    metres_per_unit = _metres_per_unit(
        scale,
        point_ids=point_ids,
        points_colmap=points_colmap,
        centers_colmap={r.name: c for r, c in zip(records, centers, strict=True)},
        points_path=points_path,
        images_path=images_path,
    )
    try:
        plane = fit_plane_ransac(points_colmap, threshold=threshold_m / metres_per_unit, rng=rng)
    except InputError as exc:
        raise InputError(points_path, f"wall plane: {exc.detail}") from exc

    normal, offset = plane.normal, plane.offset
    heights = centers @ normal + offset
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
