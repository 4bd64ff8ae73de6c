"""Tests of lightcal.io.colmap (reading) and lightcal.capture.colmap_align (the wall frame)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from lightcal.capture.colmap_align import (
    SfmModel,
    camera_baseline,
    known_distance,
    read_colmap_model,
)
from lightcal.core.rotations import matrix_from_rotvec, quaternion_wxyz_from_matrix
from lightcal.errors import InputError
from lightcal.io.colmap import read_colmap_text, read_images_txt, read_points3d_txt

DATA = Path(__file__).parent / "data" / "colmap" / "wall"


def _rng() -> np.random.Generator:
    return np.random.default_rng(0)


# --------------------------------------------------------------------------- hand-made model


def test_hand_made_model() -> None:
    # See tests/data/colmap/wall/README.md. The wall normal towards the cameras is -z in
    # COLMAP, the origin the centroid (1, 1, 5) of the 4 wall points, the x axis left.jpg's
    # x axis (1, 0, 0); so y = n x x = (0, -1, 0) and R_world_colmap = diag(1, -1, -1).
    # Scale 0.5 m per unit: left.jpg centre (0, 0, 0) -> 0.5 * diag(1,-1,-1) (-1, -1, -5)
    # = (-0.5, 0.5, 2.5) and t = -R C = (0.5, 0.5, 2.5); right.jpg centre (1, 0, 0) ->
    # (0, 0.5, 2.5), t = (0, 0.5, 2.5).
    model = read_colmap_model(
        DATA, scale=camera_baseline("left.jpg", "right.jpg", distance_m=0.5), rng=_rng()
    )
    flip = np.diag([1.0, -1.0, -1.0])
    assert [image.name for image in model.images] == ["left.jpg", "right.jpg"]
    assert [image.camera_id for image in model.images] == [1, 1]
    left, right = model.images
    np.testing.assert_allclose(left.R_camera_world, flip, atol=1e-15)
    np.testing.assert_allclose(left.t_camera_world, [0.5, 0.5, 2.5], atol=1e-15)
    np.testing.assert_allclose(left.center_world, [-0.5, 0.5, 2.5], atol=1e-15)
    np.testing.assert_allclose(right.R_camera_world, flip, atol=1e-15)
    np.testing.assert_allclose(right.t_camera_world, [0.0, 0.5, 2.5], atol=1e-15)
    assert model.n_inliers == 4
    np.testing.assert_array_equal(model.wall_inliers, [True, True, True, True, False])
    assert model.plane_rms_m == pytest.approx(0.0, abs=1e-15)
    np.testing.assert_array_equal(model.point_ids, [1, 2, 3, 4, 5])
    np.testing.assert_allclose(
        model.points_world,
        [[-0.5, 0.5, 0], [0.5, 0.5, 0], [-0.5, -0.5, 0], [0.5, -0.5, 0], [0, 0, 1.0]],
        atol=1e-15,
    )
    similarity = model.transform_world_colmap
    assert similarity.scale == pytest.approx(0.5, abs=1e-15)
    np.testing.assert_allclose(similarity.R, flip, atol=1e-15)
    np.testing.assert_allclose(similarity.t, [-0.5, 0.5, 2.5], atol=1e-15)
    np.testing.assert_allclose(
        similarity.matrix @ [1.0, 1.0, 3.0, 1.0], [0.0, 0.0, 1.0, 1.0], atol=1e-15
    )
    # cameras.txt is read by read_camera: COLMAP's (320, 240) is OpenCV's (319.5, 239.5).
    camera = model.cameras[1]
    assert (camera.width, camera.height, camera.fx, camera.cx, camera.cy) == (
        640,
        480,
        500.0,
        319.5,
        239.5,
    )
    assert model.image("right.jpg") is right


def test_hand_made_model_other_scales_agree() -> None:
    by_points = read_colmap_model(
        DATA, scale=known_distance(point_ids=(1, 4), distance_m=np.sqrt(2.0)), rng=_rng()
    )
    by_coordinates = read_colmap_model(
        DATA,
        scale=known_distance(points_colmap=[[0, 0, 0], [0, 0, 2]], distance_m=1.0),
        rng=_rng(),
    )
    by_factor = read_colmap_model(DATA, scale=0.5, rng=_rng())
    for model in (by_points, by_coordinates, by_factor):
        assert model.transform_world_colmap.scale == pytest.approx(0.5, rel=1e-15)
        np.testing.assert_allclose(model.images[1].t_camera_world, [0.0, 0.5, 2.5], atol=1e-15)


def test_readers_keep_colmap_values() -> None:
    records = read_images_txt(DATA / "images.txt")
    assert [(r.image_id, r.camera_id, r.name, r.line) for r in records] == [
        (1, 1, "left.jpg", 5),
        (2, 1, "right.jpg", 7),
    ]
    np.testing.assert_array_equal(records[1].t, [-1.0, 0.0, 0.0])
    ids, points = read_points3d_txt(DATA / "points3D.txt")
    np.testing.assert_array_equal(ids, [1, 2, 3, 4, 5])
    np.testing.assert_array_equal(points[4], [1.0, 1.0, 3.0])
    text = read_colmap_text(DATA)
    assert [r.name for r in text.images] == ["left.jpg", "right.jpg"]
    assert sorted(text.cameras) == [1]
    assert (text.images_path, text.points_path) == (DATA / "images.txt", DATA / "points3D.txt")
    np.testing.assert_array_equal(text.point_ids, ids)
    np.testing.assert_array_equal(text.points_colmap, points)


# --------------------------------------------------------------------------- synthetic model


def _look_at(center: np.ndarray, target: np.ndarray, roll_rad: float) -> np.ndarray:
    """R_camera_world of a camera at `center` whose optical axis points at `target`."""
    z = target - center
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R_world_camera = np.stack([x, y, z], axis=1) @ matrix_from_rotvec([0.0, 0.0, roll_rad])
    return R_world_camera.T


def _write_model(
    folder: Path,
    *,
    R_cw: list[np.ndarray],
    t_cw: list[np.ndarray],
    points: np.ndarray,
    image_ids: list[int],
) -> None:
    """Write a COLMAP text model (poses and points in COLMAP's world and units)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "cameras.txt").write_text(
        "# Camera list\n"
        "1 PINHOLE 800 600 700 700 400 300\n"
        "2 SIMPLE_RADIAL 640 480 600 320 240 0.01\n"
    )
    lines = ["# Image list with two lines of data per image:", "#   IMAGE_ID, ..."]
    for k, (image_id, R, t) in enumerate(zip(image_ids, R_cw, t_cw, strict=True)):
        q = quaternion_wxyz_from_matrix(R)
        fields = [*(repr(float(v)) for v in q), *(repr(float(v)) for v in t)]
        lines.append(f"{image_id} {' '.join(fields)} {1 + k % 2} img_{image_id:03d}.png")
        lines.append("" if k % 3 == 0 else "10.5 20.25 1 30 40 -1")
    (folder / "images.txt").write_text("\n".join(lines) + "\n")
    rows = ["# 3D point list", "# POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[]"]
    for k, p in enumerate(points):
        rows.append(f"{k + 1} {' '.join(repr(float(v)) for v in p)} 128 128 128 0.5 1 0 2 3")
    (folder / "points3D.txt").write_text("\n".join(rows) + "\n")


class _Scene:
    """Ground truth in a metric frame with the wall at z = 0, and its COLMAP version."""

    def __init__(self, seed: int, *, n_images: int = 6) -> None:
        rng = np.random.default_rng(seed)
        self.wall = np.concatenate([rng.uniform(-1.5, 1.5, (80, 2)), np.zeros((80, 1))], axis=1)
        clutter = rng.uniform(-1.0, 1.0, (15, 3))
        clutter[:, 2] = rng.uniform(0.1, 0.6, 15)  # off the wall, towards the cameras
        self.points = np.concatenate([self.wall, clutter])
        self.R: list[np.ndarray] = []
        self.t: list[np.ndarray] = []
        for _ in range(n_images):
            center = np.array([*rng.uniform(-0.8, 0.8, 2), rng.uniform(0.7, 1.6)])
            target = np.array([*rng.uniform(-0.4, 0.4, 2), 0.0])
            R = _look_at(center, target, rng.uniform(-0.5, 0.5))
            self.R.append(R)
            self.t.append(-R @ center)
        # Image ids are not in file order; the lowest id (3) is the 4th image.
        self.image_ids = [7, 9, 12, 3, 20, 15][:n_images]

    def expected_in_our_frame(self) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Poses in our frame: origin at the wall points' centroid, x from image id 3."""
        origin = self.wall.mean(axis=0)
        first = self.R[int(np.argmin(self.image_ids))]
        x = first[0] - first[0, 2] * np.array([0.0, 0.0, 1.0])
        x /= np.linalg.norm(x)
        A = np.stack([x, np.cross([0.0, 0.0, 1.0], x), [0.0, 0.0, 1.0]])  # rows: our axes
        R_exp = [R @ A.T for R in self.R]
        t_exp = [t + R @ origin for R, t in zip(self.R, self.t, strict=True)]
        return R_exp, t_exp

    def write_colmap(
        self, folder: Path, *, scale: float, R_sim: np.ndarray, t_sim: np.ndarray
    ) -> None:
        """COLMAP world: X_colmap = scale R_sim X_true + t_sim."""
        R_col = [R @ R_sim.T for R in self.R]
        t_col = [scale * t - Rc @ t_sim for t, Rc in zip(self.t, R_col, strict=True)]
        points = scale * self.points @ R_sim.T + t_sim
        _write_model(folder, R_cw=R_col, t_cw=t_col, points=points, image_ids=self.image_ids)


SIMILARITIES = {
    # Wall normal (towards the cameras) -> (0, 0, -1): the plane fit's canonical normal
    # points away from the cameras, so it must be flipped.
    "flip": (3.7, matrix_from_rotvec([np.pi, 0.0, 0.0]), np.array([0.3, -2.0, 5.0])),
    "generic": (0.021, matrix_from_rotvec([0.4, -1.1, 2.3]), np.array([10.0, 4.0, -7.0])),
}


@pytest.mark.parametrize("similarity", sorted(SIMILARITIES))
def test_synthetic_model_recovers_poses_in_our_frame(tmp_path: Path, similarity: str) -> None:
    scene = _Scene(seed=1)
    scale, R_sim, t_sim = SIMILARITIES[similarity]
    scene.write_colmap(tmp_path, scale=scale, R_sim=R_sim, t_sim=t_sim)
    # Metric scale from the known distance between two wall points.
    distance = float(np.linalg.norm(scene.points[0] - scene.points[5]))
    model = read_colmap_model(
        tmp_path,
        scale=known_distance(point_ids=(1, 6), distance_m=distance),
        wall_inlier_threshold_m=0.01,
        rng=_rng(),
    )

    R_exp, t_exp = scene.expected_in_our_frame()
    order = np.argsort(scene.image_ids)
    assert [image.image_id for image in model.images] == sorted(scene.image_ids)
    for image, k in zip(model.images, order, strict=True):
        assert image.name == f"img_{scene.image_ids[k]:03d}.png"
        assert image.camera_id == 1 + k % 2
        np.testing.assert_allclose(image.R_camera_world, R_exp[k], atol=1e-9)
        np.testing.assert_allclose(image.t_camera_world, t_exp[k], atol=1e-6)
        assert image.center_world[2] > 0.5
    assert model.transform_world_colmap.scale == pytest.approx(1.0 / scale, rel=1e-9)
    assert model.n_inliers == 80
    assert model.wall_inliers[:80].all() and not model.wall_inliers[80:].any()
    assert model.plane_rms_m < 1e-9
    np.testing.assert_allclose(model.points_world[:80, 2], 0.0, atol=1e-9)
    np.testing.assert_allclose(model.points_world[:80].mean(axis=0), 0.0, atol=1e-9)
    assert sorted(model.cameras) == [1, 2]


def test_frame_does_not_depend_on_colmap_world(tmp_path: Path) -> None:
    scene = _Scene(seed=2)
    models: list[SfmModel] = []
    for name, (scale, R_sim, t_sim) in SIMILARITIES.items():
        scene.write_colmap(tmp_path / name, scale=scale, R_sim=R_sim, t_sim=t_sim)
        models.append(
            read_colmap_model(tmp_path / name, scale=1.0 / scale, rng=np.random.default_rng(1))
        )
    for a, b in zip(models[0].images, models[1].images, strict=True):
        np.testing.assert_allclose(a.R_camera_world, b.R_camera_world, atol=1e-9)
        np.testing.assert_allclose(a.t_camera_world, b.t_camera_world, atol=1e-6)


def test_scale_from_camera_baseline(tmp_path: Path) -> None:
    scene = _Scene(seed=3)
    scale, R_sim, t_sim = SIMILARITIES["generic"]
    scene.write_colmap(tmp_path, scale=scale, R_sim=R_sim, t_sim=t_sim)
    centers = [-R.T @ t for R, t in zip(scene.R, scene.t, strict=True)]
    baseline = float(np.linalg.norm(centers[0] - centers[4]))
    model = read_colmap_model(
        tmp_path,
        scale=camera_baseline("img_007.png", "img_020.png", distance_m=baseline),
        rng=_rng(),
    )
    assert model.transform_world_colmap.scale == pytest.approx(1.0 / scale, rel=1e-9)
    a, b = model.image("img_007.png"), model.image("img_020.png")
    assert np.linalg.norm(a.center_world - b.center_world) == pytest.approx(baseline, rel=1e-12)


def test_cameras_on_both_sides_of_the_wall(tmp_path: Path) -> None:
    scene = _Scene(seed=4)
    center = np.array([0.2, 0.1, -1.0])  # behind the wall
    scene.R[2] = _look_at(center, np.zeros(3), 0.0)
    scene.t[2] = -scene.R[2] @ center
    scene.write_colmap(tmp_path, scale=1.0, R_sim=np.eye(3), t_sim=np.zeros(3))
    with pytest.raises(
        InputError,
        match=r"images\.txt: expected every camera centre on the same side of the wall "
        r"plane, got 5 on one side \(.*\) and 1 on the other side or on the plane "
        r"\(img_012\.png\)$",
    ):
        read_colmap_model(tmp_path, scale=1.0, rng=_rng())


# --------------------------------------------------------------------------- errors


@pytest.fixture
def model_dir(tmp_path: Path) -> Path:
    folder = tmp_path / "model"
    shutil.copytree(DATA, folder)
    return folder


def _replace_line(path: Path, line: int, text: str) -> None:
    lines = path.read_text().splitlines()
    lines[line - 1] = text
    path.write_text("\n".join(lines) + "\n")


def test_missing_folder_and_files(tmp_path: Path, model_dir: Path) -> None:
    with pytest.raises(InputError, match=r"nope: expected a folder holding a COLMAP text model"):
        read_colmap_model(tmp_path / "nope", scale=1.0, rng=_rng())
    (model_dir / "points3D.txt").unlink()
    with pytest.raises(
        InputError, match=r"model: missing points3D\.txt: expected a COLMAP text model \("
    ):
        read_colmap_model(model_dir, scale=1.0, rng=_rng())


@pytest.mark.parametrize(
    ("file", "line", "text", "message"),
    [
        (
            "images.txt",
            5,
            "1 1 0 0 0 0 0 0 1",
            r"images\.txt:5: image line: expected 10 fields 'IMAGE_ID QW QX QY QZ TX TY TZ "
            r"CAMERA_ID NAME', got 9$",
        ),
        (
            "images.txt",
            5,
            "1 1 0 zero 0 0 0 0 1 left.jpg",
            r"images\.txt:5: QW QX QY QZ: expected numbers, got '1 0 zero 0'$",
        ),
        (
            "images.txt",
            5,
            "1 1 0 0 0 0 0 0 x left.jpg",
            r"images\.txt:5: CAMERA_ID: expected an integer, got 'x'$",
        ),
        (
            "images.txt",
            5,
            "1 0.5 0 0 0 0 0 0 1 left.jpg",
            r"images\.txt:5: QW QX QY QZ: expected a unit quaternion \(norm 1 within 0\.001\), "
            r"got norm 0\.5$",
        ),
        (
            "images.txt",
            6,
            "320.5 240.5 1 448.5",
            r"images\.txt:6: POINTS2D line: expected \(X, Y, POINT3D_ID\) triples, got 4 values",
        ),
        (
            "images.txt",
            7,
            "1 1 0 0 0 -1 0 0 1 right.jpg",
            r"images\.txt:7: IMAGE_ID 1 already used on line 5, expected unique ids$",
        ),
        (
            "points3D.txt",
            5,
            "2 2 0 5 250 250 250 0.1 1",
            r"points3D\.txt:5: expected 'POINT3D_ID X Y Z R G B ERROR' followed by "
            r"\(IMAGE_ID, POINT2D_IDX\) pairs, got 9 fields$",
        ),
        (
            "points3D.txt",
            6,
            "3 0 2 five 240 240 240 0.2",
            r"points3D\.txt:6: X Y Z: expected numbers, got '0 2 five'$",
        ),
        (
            "points3D.txt",
            7,
            "1 2 2 5 230 230 230 0.2 2 0",
            r"points3D\.txt:7: POINT3D_ID 1 already used on line 4, expected unique ids$",
        ),
        (
            "cameras.txt",
            4,
            "1 PINHOLE 640 480 500 500 320",
            r"cameras\.txt:4: PINHOLE: expected 4 parameters \(fx, fy, cx, cy\), got 3$",
        ),
    ],
)
def test_malformed_lines_name_file_and_line(
    model_dir: Path, file: str, line: int, text: str, message: str
) -> None:
    _replace_line(model_dir / file, line, text)
    with pytest.raises(InputError, match=message):
        read_colmap_model(model_dir, scale=1.0, rng=_rng())


def test_missing_points2d_line_is_reported(model_dir: Path) -> None:
    # Without its POINTS2D line, image 1 swallows image 2's line as its points.
    lines = (model_dir / "images.txt").read_text().splitlines()
    del lines[5]
    (model_dir / "images.txt").write_text("\n".join(lines) + "\n")
    with pytest.raises(
        InputError,
        match=r"images\.txt:6: POINTS2D line: expected \(X, Y, POINT3D_ID\) triples, got 10 "
        r"values \(every image line must be followed by its POINTS2D line, possibly empty\)$",
    ):
        read_colmap_model(model_dir, scale=1.0, rng=_rng())


def test_image_with_unknown_camera(model_dir: Path) -> None:
    _replace_line(model_dir / "images.txt", 7, "2 1 0 0 0 -1 0 0 4 right.jpg")
    with pytest.raises(
        InputError,
        match=r"images\.txt:7: image 2 \('right\.jpg'\) references CAMERA_ID 4, expected one "
        r"of cameras\.txt's ids \[1\]$",
    ):
        read_colmap_model(model_dir, scale=1.0, rng=_rng())


def test_fewer_than_three_points(model_dir: Path) -> None:
    lines = (model_dir / "points3D.txt").read_text().splitlines()
    (model_dir / "points3D.txt").write_text("\n".join(lines[:5]) + "\n")  # 3 comments
    with pytest.raises(
        InputError, match=r"points3D\.txt: expected at least 3 points to fit the wall plane, got 2$"
    ):
        read_colmap_model(model_dir, scale=1.0, rng=_rng())


def test_degenerate_plane(model_dir: Path) -> None:
    rows = [f"{k} {k * 0.1} 0 5 1 1 1 0.1" for k in range(1, 20)]
    (model_dir / "points3D.txt").write_text("\n".join(rows) + "\n")
    with pytest.raises(
        InputError,
        match=r"points3D\.txt: wall plane: degenerate plane: expected points spanning a plane",
    ):
        read_colmap_model(model_dir, scale=1.0, rng=_rng())


def test_no_images(model_dir: Path) -> None:
    (model_dir / "images.txt").write_text("# no image\n")
    with pytest.raises(
        InputError, match=r"images\.txt: expected at least one registered image, got none$"
    ):
        read_colmap_model(model_dir, scale=1.0, rng=_rng())


@pytest.mark.parametrize(
    ("scale", "message"),
    [
        (
            known_distance(point_ids=(1, 9), distance_m=1.0),
            r"^scale\.point_ids: expected POINT3D_IDs present in .*points3D\.txt, got unknown "
            r"id\(s\) \[9\]$",
        ),
        (
            camera_baseline("left.jpg", "middle.jpg", distance_m=1.0),
            r"^scale: camera_baseline: expected image NAMEs present in .*images\.txt, got "
            r"unknown \['middle\.jpg'\]$",
        ),
        (
            known_distance(points_colmap=[[1, 2, 3], [1, 2, 3]], distance_m=1.0),
            r"^scale: the two points_colmap coincide in the COLMAP model: no scale can be "
            r"derived$",
        ),
        (-2.0, r"^scale: expected metres per COLMAP unit > 0, got -2\.0$"),
        ("big", r"^scale: expected known_distance\(\.\.\.\), camera_baseline\(\.\.\.\) or a "),
    ],
)
def test_bad_scale(scale: object, message: str) -> None:
    with pytest.raises(InputError, match=message):
        read_colmap_model(DATA, scale=scale, rng=_rng())  # type: ignore[arg-type]


def test_scale_constructors_validate() -> None:
    with pytest.raises(InputError, match=r"^distance_m: expected a finite distance > 0 m, got 0$"):
        known_distance(point_ids=(1, 2), distance_m=0)
    with pytest.raises(
        InputError, match=r"^known_distance: expected exactly one of point_ids and points_colmap"
    ):
        known_distance(distance_m=1.0)
    with pytest.raises(InputError, match=r"^point_ids: expected two different POINT3D_IDs"):
        known_distance(point_ids=(3, 3), distance_m=1.0)
    with pytest.raises(InputError, match=r"^points_colmap: expected a finite \(2, 3\) array"):
        known_distance(points_colmap=[[0, 0, 0]], distance_m=1.0)
    with pytest.raises(InputError, match=r"^camera_baseline: expected two different image names"):
        camera_baseline("a.jpg", "a.jpg", distance_m=1.0)
