"""A non-planar wall given as a triangle mesh (`lightcal.core.wall_mesh`, issue 26).

- the plane z = 0 cut into triangles gives the planar renderer's values (to round-off),
  every sensor model, binned and merged super-pixels, and the whole-image render;
- a tilted, shifted plane (the world moved rigidly, cameras with it) gives the planar
  values through the general quad path: the model does not depend on the frame;
- the gradients on a bowed mesh agree with central differences;
- a light behind a footprint's plane lights nothing there;
- bad meshes are refused with messages naming the file.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from lightcal_app.solve_settings import project_for_solve, settings_of

from lightcal.cli.main import main
from lightcal.core.beam_start import sight_beam
from lightcal.core.camera import Camera
from lightcal.core.medium import Medium
from lightcal.core.render import render_image, render_pixels, shade
from lightcal.core.rid import CosPowerRID, IsotropicRID
from lightcal.core.rotations import matrix_from_rotvec
from lightcal.core.scene import Light, Rig, View
from lightcal.core.wall import OrenNayarWall, PlasticWall
from lightcal.core.wall_mesh import WallMesh, mesh_footprints
from lightcal.errors import InputError
from lightcal.io.project import load_project
from lightcal.io.wall_mesh_file import read_wall_mesh, write_wall_mesh
from lightcal.pipeline import calibrate_project
from lightcal.pipeline.load import load_images
from lightcal.pipeline.model import build_model
from lightcal.synthetic.height_field import BowedWall
from lightcal.synthetic.wall_meshes import height_field_mesh

CAMERA = Camera.from_params(
    fx=300.0, fy=300.0, cx=79.5, cy=59.5, width=160, height=120, dist=(-0.05, 0.01, 0, 0, 0)
)
VIEW = View.looking_at(np.array([0.3, 0.2, 1.4]), np.array([0.05, -0.02, 0.0]))
LIGHT = Light(
    CosPowerRID(6.0),
    np.array([0.1, -0.03, 0.0]),
    matrix_from_rotvec(np.array([0.05, -0.1, 0.0])),
    scale=2.0,
)
RIG = Rig.single(LIGHT)
PLANE = height_field_mesh(None, (-2.0, -2.0, 2.0, 2.0), spacing_m=0.25)


def _pixels(n: int, width: int, height: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.stack([rng.integers(0, width, n), rng.integers(0, height, n)], axis=1)


@pytest.mark.parametrize("sensor", ["radiance", "cos4", "paper", "map"])
@pytest.mark.parametrize("binning", [1, 2, 4])
def test_a_plane_mesh_gives_the_planar_values(sensor: str, binning: int) -> None:
    vmap = 1.0 - 0.2 * np.linspace(0, 1, CAMERA.width)[None, :] * np.ones((CAMERA.height, 1))
    pix = _pixels(300, CAMERA.width // binning, CAMERA.height // binning)
    kw = {"sensor": sensor, "vignetting": vmap, "binning": binning}
    plane = render_pixels(CAMERA, VIEW, RIG, pix, **kw)
    mesh = render_pixels(CAMERA, VIEW, RIG, pix, mesh=PLANE, **kw)
    np.testing.assert_array_equal(np.ma.getmaskarray(mesh), np.ma.getmaskarray(plane))
    assert plane.count() > 250
    np.testing.assert_allclose(mesh.compressed(), plane.compressed(), rtol=1e-12, atol=0)


def test_triangles_reaching_behind_the_camera_are_clipped() -> None:
    """Two triangles of 2 km: each reaches behind the camera (its projection unbounded),
    and every pixel still finds the plane."""
    huge = WallMesh(
        np.array([[-1e3, -1e3, 0.0], [1e3, -1e3, 0.0], [1e3, 1e3, 0.0], [-1e3, 1e3, 0.0]]),
        np.array([[0, 1, 2], [0, 2, 3]]),
    )
    view = View.looking_at(np.array([0.3, 0.2, 1.4]), np.array([1.5, -0.2, 0.0]))
    centers = huge.vertices_world - view.center_world
    assert np.any((centers @ view.R_camera_world.T)[:, 2] < 0.0)  # behind the camera
    pix = _pixels(300, CAMERA.width, CAMERA.height, seed=5)
    plane = render_pixels(CAMERA, view, RIG, pix)
    mesh = render_pixels(CAMERA, view, RIG, pix, mesh=huge)
    assert plane.count() == len(pix)
    np.testing.assert_array_equal(np.ma.getmaskarray(mesh), np.ma.getmaskarray(plane))
    np.testing.assert_allclose(mesh.compressed(), plane.compressed(), rtol=1e-12, atol=0)


def test_a_plane_mesh_gives_the_planar_image_and_gradients() -> None:
    plane = render_image(CAMERA, VIEW, RIG)
    mesh = render_image(CAMERA, VIEW, RIG, mesh=PLANE)
    np.testing.assert_array_equal(np.ma.getmaskarray(mesh), np.ma.getmaskarray(plane))
    np.testing.assert_allclose(mesh.compressed(), plane.compressed(), rtol=1e-12, atol=0)
    from lightcal.core.footprint import pixel_footprints

    pix = _pixels(200, CAMERA.width, CAMERA.height, seed=1)
    a = shade(pixel_footprints(CAMERA, VIEW, pix), VIEW, RIG, want_grad=True)
    b = shade(mesh_footprints(CAMERA, VIEW, pix, PLANE), VIEW, RIG, want_grad=True)
    assert a.grad_position is not None and b.grad_position is not None
    scale = np.abs(a.grad_position).max()
    np.testing.assert_allclose(b.grad_position, a.grad_position, rtol=0, atol=1e-11 * scale)


def test_water_on_a_plane_mesh_gives_the_planar_values() -> None:
    """The medium's transmittance and backscatter need distances only: on the plane as a
    mesh, the planar values, their gradients and the medium's."""
    from lightcal.core.footprint import pixel_footprints

    water = Medium(attenuation_per_m=0.3, backscatter_per_m=0.5, phase_g=0.8)
    pix = _pixels(200, CAMERA.width, CAMERA.height, seed=8)
    a = shade(pixel_footprints(CAMERA, VIEW, pix), VIEW, RIG, want_grad=True, medium=water)
    b = shade(mesh_footprints(CAMERA, VIEW, pix, PLANE), VIEW, RIG, want_grad=True, medium=water)
    np.testing.assert_allclose(b.values.compressed(), a.values.compressed(), rtol=1e-12)
    for got, want in ((b.grad_position, a.grad_position), (b.grad_medium, a.grad_medium)):
        assert got is not None and want is not None
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-11 * np.abs(want).max())


def _moved(Q: np.ndarray, s: np.ndarray) -> tuple[WallMesh, View]:
    """The plane mesh and the view moved rigidly by x -> Q x + s."""
    mesh = WallMesh(PLANE.vertices_world @ Q.T + s, PLANE.faces)
    R = VIEW.R_camera_world @ Q.T
    center = Q @ VIEW.center_world + s
    return mesh, View(R, -R @ center)


@pytest.mark.parametrize("sensor", ["radiance", "paper"])
def test_a_tilted_plane_mesh_gives_the_planar_values(sensor: str) -> None:
    """The world turned by 20 degrees and shifted: every quad is off z = 0 and takes the
    general quad loop; the light moves with the camera, so the values are the plane's."""
    Q = matrix_from_rotvec(np.array([math.radians(20.0), math.radians(-8.0), 0.3]))
    mesh, view = _moved(Q, np.array([0.2, -0.1, 0.4]))
    pix = _pixels(300, CAMERA.width, CAMERA.height, seed=2)
    plane = render_pixels(CAMERA, VIEW, RIG, pix, sensor=sensor)
    fp = mesh_footprints(CAMERA, view, pix, mesh, sensor=sensor)
    assert np.all(fp.corners_world[fp.valid][..., 2] != 0.0)  # off the plane's fast paths
    tilted = shade(fp, view, RIG).values
    np.testing.assert_array_equal(np.ma.getmaskarray(tilted), np.ma.getmaskarray(plane))
    np.testing.assert_allclose(tilted.compressed(), plane.compressed(), rtol=1e-12, atol=0)


WALLS = {
    "plastic": PlasticWall.from_albedo(0.2, 1.5, 0.8),
    "oren_nayar": OrenNayarWall(math.radians(25.0)),
}


@pytest.mark.parametrize("name", list(WALLS))
@pytest.mark.parametrize("tilted", [False, True])
def test_reflectance_models_take_each_footprints_normal(name: str, tilted: bool) -> None:
    """B on a mesh takes the footprints' own normals: the plane z = 0 as a mesh, or the
    world turned (every normal off +z), gives the planar values and gradients."""
    wall = WALLS[name]
    mesh, view = PLANE, VIEW
    if tilted:
        Q = matrix_from_rotvec(np.array([math.radians(-15.0), math.radians(10.0), 0.2]))
        mesh, view = _moved(Q, np.array([0.1, 0.2, 0.3]))
    pix = _pixels(300, CAMERA.width, CAMERA.height, seed=6)
    from lightcal.core.footprint import pixel_footprints

    a = shade(pixel_footprints(CAMERA, VIEW, pix), VIEW, RIG, want_grad=True, wall=wall)
    b = shade(mesh_footprints(CAMERA, view, pix, mesh), view, RIG, want_grad=True, wall=wall)
    assert np.ptp(a.values.compressed()) > 0.0
    np.testing.assert_allclose(b.values.compressed(), a.values.compressed(), rtol=1e-11)
    for got, want in ((b.grad_position, a.grad_position), (b.grad_wall, a.grad_wall)):
        assert got is not None and want is not None
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-10 * np.abs(want).max())


BOWED = height_field_mesh(BowedWall(0.05, (0.05, 0.0), 0.6), (-1.5, -1.5, 1.5, 1.5), spacing_m=0.05)


def test_gradients_on_a_bowed_mesh_agree_with_central_differences() -> None:
    pix = _pixels(150, CAMERA.width, CAMERA.height, seed=3)
    fp = mesh_footprints(CAMERA, VIEW, pix, BOWED)
    assert np.ptp(fp.corners_world[fp.valid][..., 2]) > 0.01
    s = shade(fp, VIEW, RIG, want_grad=True)
    assert s.grad_position is not None and s.grad_rotation is not None
    h = 1e-6
    for k in range(3):
        step = np.zeros(3)
        step[k] = h
        up = shade(fp, VIEW, Rig.single(LIGHT.replace(t_camera_light=LIGHT.t_camera_light + step)))
        down = shade(
            fp, VIEW, Rig.single(LIGHT.replace(t_camera_light=LIGHT.t_camera_light - step))
        )
        numeric = (up.values - down.values).filled(0.0) / (2 * h)
        scale = np.abs(numeric).max()
        np.testing.assert_allclose(s.grad_position[0, :, k], numeric, atol=1e-6 * scale)
        turn = matrix_from_rotvec(step)
        up = shade(fp, VIEW, Rig.single(LIGHT.replace(R_camera_light=turn @ LIGHT.R_camera_light)))
        down = shade(
            fp, VIEW, Rig.single(LIGHT.replace(R_camera_light=turn.T @ LIGHT.R_camera_light))
        )
        numeric = (up.values - down.values).filled(0.0) / (2 * h)
        np.testing.assert_allclose(s.grad_rotation[0, :, k], numeric, atol=1e-6 * scale)


def test_wall_gradients_on_a_bowed_mesh_agree_with_central_differences() -> None:
    wall = WALLS["plastic"]
    pix = _pixels(150, CAMERA.width, CAMERA.height, seed=7)
    fp = mesh_footprints(CAMERA, VIEW, pix, BOWED)
    s = shade(fp, VIEW, RIG, want_grad=True, wall=wall)
    assert s.grad_position is not None and s.grad_wall is not None
    h = 1e-6
    for k in range(3):
        step = np.zeros(3)
        step[k] = h
        moved = [LIGHT.replace(t_camera_light=LIGHT.t_camera_light + e) for e in (step, -step)]
        up, down = (shade(fp, VIEW, Rig.single(m), wall=wall).values for m in moved)
        numeric = (up - down).filled(0.0) / (2 * h)
        np.testing.assert_allclose(
            s.grad_position[0, :, k], numeric, atol=1e-6 * np.abs(numeric).max()
        )
    p = wall.parameters()
    for k in range(len(p)):
        step = np.zeros(len(p))
        step[k] = 1e-6 * max(1.0, abs(p[k]))
        up, down = (
            shade(fp, VIEW, RIG, wall=wall.with_parameters(p + e)).values for e in (step, -step)
        )
        numeric = (up - down).filled(0.0) / (2 * step[k])
        np.testing.assert_allclose(
            s.grad_wall[:, k], numeric, atol=1e-6 * np.abs(numeric).max() + 1e-300
        )


def test_the_sensor_divides_by_the_true_area_of_a_tilted_footprint() -> None:
    """The plane turned by 30 degrees about x, the camera with it: each footprint's area
    (a quad in 3-D) and normal are the plane's, turned."""
    Q = matrix_from_rotvec(np.array([math.radians(30.0), 0.0, 0.0]))
    mesh, view = _moved(Q, np.array([0.0, 0.0, 0.3]))
    pix = _pixels(100, CAMERA.width, CAMERA.height, seed=4)
    from lightcal.core.footprint import pixel_footprints

    plane = pixel_footprints(CAMERA, VIEW, pix)
    tilted = mesh_footprints(CAMERA, view, pix, mesh)
    np.testing.assert_allclose(tilted.area_m2, plane.area_m2, rtol=1e-9)
    normals = tilted.normals_world[tilted.valid]
    np.testing.assert_allclose(normals, np.broadcast_to(Q[:, 2], normals.shape), atol=1e-9)


def test_a_light_behind_the_footprints_plane_lights_nothing() -> None:
    """A floor z = 0 (y < 0.1) and a slope rising from it, z = (3 / 1.9) (y - 0.1): an
    isotropic light at (0, 1.5, 0.5), behind the slope's plane and in front of the
    floor's, lights the floor's pixels and none of the slope's."""
    vertices = np.array(
        [[-2, -2, 0.0], [2, -2, 0.0], [-2, 0.1, 0.0], [2, 0.1, 0.0], [-2, 2, 3.0], [2, 2, 3.0]]
    )
    faces = np.array([[0, 1, 3], [0, 3, 2], [2, 3, 5], [2, 5, 4]])
    mesh = WallMesh(vertices, faces)
    view = View.looking_at(np.array([0.0, -0.5, 1.5]), np.array([0.0, 0.3, 0.0]))
    pix = np.stack(np.meshgrid(np.arange(0, 160, 8), np.arange(0, 120, 8)), -1).reshape(-1, 2)
    fp = mesh_footprints(CAMERA, view, pix, mesh)
    assert fp.normals_world is not None
    on_slope = fp.valid & (fp.centers_world[:, 1] > 0.15)
    on_floor = fp.valid & (fp.centers_world[:, 1] < 0.05)
    assert on_slope.sum() > 10 and on_floor.sum() > 10
    L_camera = view.R_camera_world @ (np.array([0.0, 1.5, 0.5]) - view.center_world)
    light = Light(IsotropicRID(), L_camera, np.eye(3))
    values = shade(fp, view, Rig.single(light), want_grad=True)
    assert np.all(values.values[on_slope] == 0.0)
    assert values.grad_position is not None
    assert np.all(values.grad_position[0, on_slope] == 0.0)
    assert np.all(values.values[on_floor] > 0.0)


def test_the_beams_sighting_on_a_mesh() -> None:
    """The initial guess's spot (`beam_start.sight_beam`) back-projected onto the plane
    as a mesh lands where it lands on the plane; onto a bulge, on the bulge."""
    image = render_image(CAMERA, VIEW, RIG).filled(0.0)
    usable = np.ones(image.shape, dtype=bool)
    plane = sight_beam(image, usable, CAMERA, VIEW)
    on_mesh = sight_beam(image, usable, CAMERA, VIEW, mesh=PLANE)
    assert plane is not None and on_mesh is not None
    np.testing.assert_allclose(on_mesh.point_camera, plane.point_camera, rtol=1e-12)
    np.testing.assert_allclose(on_mesh.wall_normal_camera, plane.wall_normal_camera, atol=1e-12)
    bulge = sight_beam(image, usable, CAMERA, VIEW, mesh=BOWED)
    assert bulge is not None
    point_world = VIEW.R_camera_world.T @ bulge.point_camera + VIEW.center_world
    assert point_world[2] > 0.01  # on the 5 cm bulge
    assert bulge.point_camera[2] < plane.point_camera[2]


# ------------------------------------------------------------------------ bad inputs


def test_a_mesh_is_checked() -> None:
    with pytest.raises(ValueError, match=r"^vertices: expected finite coordinates, vertex 1 "):
        WallMesh(np.array([[0, 0, 0], [np.nan, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))
    with pytest.raises(ValueError, match=r"^faces: expected vertex indices in 0\.\.2, got 0\.\.3$"):
        WallMesh(np.zeros((3, 3)), np.array([[0, 1, 3]]))
    with pytest.raises(ValueError, match=r"^faces: expected an \(F, 3\) array of F >= 1"):
        WallMesh(np.zeros((3, 3)), np.zeros((0, 3), dtype=int))


def test_mesh_files_are_checked(tmp_path: Path) -> None:
    missing = tmp_path / "missing.ply"
    with pytest.raises(InputError) as err:
        read_wall_mesh(missing)
    assert str(err.value) == (
        f"{missing}: wall mesh: file not found (expected a triangle mesh trimesh reads)"
    )
    corrupt = tmp_path / "corrupt.ply"
    corrupt.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 9\nend_header\n")
    with pytest.raises(InputError, match=r"corrupt\.ply: wall mesh: "):
        read_wall_mesh(corrupt)
    points = tmp_path / "points.obj"
    points.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(InputError) as err:
        read_wall_mesh(points)
    assert str(err.value) == (
        f"{points}: wall mesh: the file holds no triangles (expected a triangle mesh)"
    )
    nan = tmp_path / "nan.obj"
    nan.write_text("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(InputError) as err:
        read_wall_mesh(nan)
    assert str(err.value).startswith(
        f"{nan}: wall mesh: vertices: expected finite coordinates, vertex 1 is"
    )


def test_a_mesh_round_trips(tmp_path: Path) -> None:
    write_wall_mesh(tmp_path / "m.ply", BOWED)
    back = read_wall_mesh(tmp_path / "m.ply")
    np.testing.assert_array_equal(back.vertices_world, BOWED.vertices_world)
    np.testing.assert_array_equal(back.faces, BOWED.faces)


# ----------------------------------------------------------------- the project file


def test_synth_declares_the_bowed_walls_mesh(tmp_path: Path) -> None:
    folder = tmp_path / "bow"
    argv = ["synth", str(folder), "--views", "3", "--width", "96", "--height", "72"]
    assert main([*argv, "--bow-mm", "5", "--declare-wall-mesh", "--quiet"]) == 0
    project = load_project(folder / "project.json")
    assert project.spec.wall.mesh == "wall_mesh.ply"
    assert project.wall_mesh is not None
    assert project.wall_mesh.z_range_m == pytest.approx((0.0, 0.005), abs=2e-5)


def _project_with_wall(folder: Path, wall: dict, name: str) -> Path:
    doc = json.loads((folder / "project.json").read_text())
    doc["wall"] = wall
    path = folder / name
    path.write_text(json.dumps(doc))
    return path


def _plane_at(z: float, x0: float = 0.0) -> WallMesh:
    """A 10 m square of the plane at height z around (x0, 0)."""
    plane = height_field_mesh(None, (x0 - 5.0, -5.0, x0 + 5.0, 5.0), spacing_m=1.0)
    return WallMesh(plane.vertices_world + np.array([0.0, 0.0, z]), plane.faces)


def test_project_wall_mesh_errors(tiny_dataset: Path) -> None:
    folder = tiny_dataset
    made: list[Path] = []
    try:
        path = _project_with_wall(folder, {"mesh": "missing.ply"}, "mesh_missing.json")
        made.append(path)
        with pytest.raises(InputError) as err:
            load_project(path)
        assert str(err.value) == (
            f"{path}: wall.mesh: wall mesh file not found: {folder / 'missing.ply'}"
        )
        write_wall_mesh(folder / "above.ply", _plane_at(3.0))
        made.append(folder / "above.ply")
        path = _project_with_wall(folder, {"mesh": "above.ply"}, "mesh_above.json")
        made.append(path)
        with pytest.raises(InputError) as err:
            load_project(path)
        assert re.fullmatch(
            re.escape(f"{path}: lights[0].initial.position_m: the light is on or behind the ")
            + r"wall in image 'view_00' \(world z = [0-9.]+ m\); expected it in front "
            + re.escape("(z > 3 m, the wall mesh's lowest point)"),
            str(err.value),
        ), str(err.value)
        write_wall_mesh(folder / "plane.ply", _plane_at(0.0))
        made.append(folder / "plane.ply")
        path = _project_with_wall(folder, {"mesh": "plane.ply"}, "mesh_plane.json")
        made.append(path)
        project = load_project(path)
        assert project.wall_mesh is not None
        # The Solve tab's wall model keeps the mesh.
        settings = dataclasses.replace(settings_of(project), wall_model="plastic")
        edited = project_for_solve(project, settings)
        assert edited.spec.wall.mesh == "plane.ply" and edited.wall_mesh is not None
        write_wall_mesh(folder / "far.ply", _plane_at(0.0, x0=100.0))
        made.append(folder / "far.ply")
        path = _project_with_wall(folder, {"mesh": "far.ply"}, "mesh_far.json")
        made.append(path)
        project = load_project(path)
        with pytest.raises(InputError) as err:
            build_model(project, load_images(project))
        assert str(err.value) == (
            f"{path}: wall.mesh: no selected pixel of any image meets the wall mesh "
            "'far.ply'; expected a mesh in the world frame of the images' poses, in metres, "
            "under the views"
        )
    finally:
        for p in made:
            p.unlink(missing_ok=True)


def test_a_plane_mesh_calibrates_as_the_plane(tiny_dataset: Path) -> None:
    """The whole calibration (selection, solve, fit test with its causes and angle bins,
    uncertainty with the poses' and the flatness' terms) on the plane z = 0 given as a
    mesh gives the plane's result."""
    folder = tiny_dataset
    made = [folder / "plane_cal.ply"]
    try:
        write_wall_mesh(made[0], _plane_at(0.0))
        results = []
        for wall, name in (({}, "plane_cal.json"), ({"mesh": "plane_cal.ply"}, "mesh_cal.json")):
            wall = {**wall, "flatness_mm": 2.0, "model": "plastic"}
            path = _project_with_wall(folder, wall, name)
            made.append(path)
            results.append(calibrate_project(load_project(path))[2])
        plane, mesh = results
        assert mesh.pixels_used == plane.pixels_used
        np.testing.assert_allclose(mesh.x, plane.x, rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(mesh.covariance, plane.covariance, rtol=1e-6, atol=1e-14)
        for a, b in zip(mesh.fit["causes"], plane.fit["causes"], strict=True):
            assert a["cause"] == b["cause"]
            assert a["relative_effect"] == pytest.approx(b["relative_effect"], rel=1e-6, abs=1e-12)
        for angle in ("mirror", "incidence"):
            a, b = mesh.fit[angle], plane.fit[angle]
            np.testing.assert_allclose(a["bin_edges_deg"], b["bin_edges_deg"], atol=1e-9)
            assert a["count"] == b["count"]
    finally:
        for p in made:
            p.unlink(missing_ok=True)


def test_plan_on_a_plane_mesh_plans_as_on_the_plane(tiny_dataset: Path) -> None:
    """`lightcal plan` renders its candidate views on the mesh: on the plane as a mesh,
    the plane's plan."""
    from lightcal.api import plan

    folder = tiny_dataset
    made = [folder / "plan_plane.ply"]
    try:
        write_wall_mesh(made[0], _plane_at(0.0))
        plans = {}
        for name, wall in (("plane", {}), ("mesh", {"mesh": made[0].name})):
            path = _project_with_wall(folder, wall, f"plan_{name}.json")
            made.append(path)
            plans[name] = plan(path, n=2, notify=None)
        a, b = plans["plane"], plans["mesh"]
        assert [v.candidate.instruction() for v in b.views] == [
            v.candidate.instruction() for v in a.views
        ]
        np.testing.assert_allclose(b.views[0].after.log_det, a.views[0].after.log_det, rtol=1e-9)
    finally:
        for p in made:
            p.unlink(missing_ok=True)
