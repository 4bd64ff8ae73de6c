"""Tests of the departures of `lightcal synth` (issue 24): data that departs from its project.

Each departure is checked against a dataset of the same seed without it, in closed form
where there is one (noise-free images, so the only difference is the departure and the
rounding to integers: |image - expected| <= 1 DN where both are rounded).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.optimize import brentq

import lightcal.cli.progress
from lightcal.cli.main import main
from lightcal.core.camera import Camera
from lightcal.core.render import render_image
from lightcal.core.rid import CosPowerRID, SymmetricTableRID, Table2DRID
from lightcal.core.scene import Rig
from lightcal.core.wall import PlasticWall
from lightcal.errors import InputError
from lightcal.io.images import read_image
from lightcal.io.project import load_project
from lightcal.synthetic.dataset import SynthConfig, SynthDataset, read_truth, write_dataset
from lightcal.synthetic.departures import DEPARTURE_NAMES, Departures, read_departures
from lightcal.synthetic.height_field import (
    BowedWall,
    intersect,
    render_height_field,
    surface_points,
)
from lightcal.synthetic.imaging import ambient_levels
from lightcal.synthetic.rid_rim import half_angles_rad, rim_factor
from lightcal.synthetic.scenes import (
    RigConfig,
    SceneConfig,
    SensorConfig,
    sample_rig,
    sample_views,
)
from lightcal.synthetic.texture import AlbedoTexture, sample_albedo_texture

BLACK, WHITE = 512.0, 16383.0  # 14 bits


def small_camera(width: int = 240, height: int = 160) -> Camera:
    return Camera.from_params(
        fx=0.9 * width, fy=0.9 * width, cx=(width - 1) / 2 + 0.7, cy=(height - 1) / 2 - 0.4,
        width=width, height=height, dist=(-0.05, 0.01, 0.0005, -0.0003, 0.0),
    )  # fmt: skip


def config(**changes: Any) -> SynthConfig:
    base: dict[str, Any] = {
        "camera": small_camera(),
        "scene": SceneConfig(n_views=4),
        "sensor": SensorConfig(noise=False),
        "seed": 5,
    }
    base.update(changes)
    return SynthConfig(**base)


def pair(tmp_path: Path, departures: Departures, **changes: Any) -> tuple[SynthDataset, ...]:
    """The same dataset without and with `departures`."""
    plain = write_dataset(tmp_path / "plain", config(**changes))
    departed = write_dataset(tmp_path / "departed", config(departures=departures, **changes))
    return plain, departed


def image(dataset: SynthDataset, i: int) -> np.ndarray:
    """(H, W) the stored values above black, DN."""
    return read_image(dataset.image_paths[i], black_level=BLACK, white_level=WHITE).values


def valid(dataset: SynthDataset, i: int) -> np.ndarray:
    expected = render_image(dataset.camera, dataset.views[i], dataset.rig)
    return ~np.ma.getmaskarray(expected)


# ------------------------------------------------------------------------------ defaults


def test_no_departure_by_default_and_truth_has_no_departures_key(tmp_path: Path):
    assert Departures().names == ()
    dataset = write_dataset(tmp_path / "d", config())
    truth = read_truth(dataset.truth_path)
    assert "departures" not in truth
    assert read_departures(truth) == {}


def test_a_departure_leaves_the_other_random_draws_unchanged(tmp_path: Path):
    """The departures' streams are spawned after the others: poses, rig, exposures and
    images of the rest stay the same."""
    plain, departed = pair(tmp_path, Departures(pose_error_m=0.003, albedo_texture_amplitude=0.2))
    truth_a, truth_b = read_truth(plain.truth_path), read_truth(departed.truth_path)
    assert truth_a["lights"] == truth_b["lights"]
    for va, vb in zip(truth_a["views"], truth_b["views"], strict=True):
        assert va["T_camera_world"] == vb["T_camera_world"]
        assert va["exposure_time_s"] == vb["exposure_time_s"]
        assert va["T_camera_world_measured"] != vb["T_camera_world_measured"]


# ------------------------------------------------------------------------------- ambient


def test_ambient_levels_by_hand():
    levels = ambient_levels(0.1, [100.0, 400.0, 200.0, 300.0], [1.0, 2.0, 0.5, 1.0])
    assert levels.reference == 2  # sorted peaks 100, 200, 300, 400: the lower median is 200
    assert levels.reference_peak_dn == 200.0 and levels.reference_exposure == 0.5
    assert levels.per_exposure_dn == pytest.approx(0.1 * 200.0 / 0.5)
    assert levels.levels_dn == pytest.approx((40.0, 80.0, 20.0, 40.0))


def test_ambient_adds_the_stated_level_scaled_by_exposure(tmp_path: Path):
    plain, departed = pair(tmp_path, Departures(ambient_fraction=0.1))
    truth = read_truth(departed.truth_path)
    ambient = read_departures(truth)["ambient"]
    # The reference is the image of the lower-median beam peak (the plain dataset's peaks).
    peaks = [v["peak_signal_dn"] for v in read_truth(plain.truth_path)["views"]]
    ref = int(np.argsort(peaks, kind="stable")[(len(peaks) - 1) // 2])
    assert ambient["reference_view"] == f"view_0{ref}"
    assert ambient["reference_peak_dn"] == pytest.approx(peaks[ref], rel=1e-12)
    exposures = [view.exposure for view in departed.views]
    for i in range(4):
        level = 0.1 * peaks[ref] * exposures[i] / exposures[ref]
        assert ambient["levels_dn"][i] == pytest.approx(level, rel=1e-12)
        difference = image(departed, i) - image(plain, i)
        assert np.all(np.abs(difference - level) <= 1.0)
    assert len(set(ambient["levels_dn"])) > 1  # the exposures differ: so do the levels
    # The project estimates no offset.
    sensor = load_project(departed.project_path).spec.sensor
    assert sensor.offset == 0.0 and sensor.estimate_offset is False


def test_ambient_goes_through_the_declared_fall_off_map(tmp_path: Path):
    sensor = SensorConfig(noise=False, model="map", vignetting_coeffs=(-0.3, 0.05))
    plain, departed = pair(tmp_path, Departures(ambient_fraction=0.2), sensor=sensor)
    assert plain.vignetting is not None
    levels = read_departures(read_truth(departed.truth_path))["ambient"]["levels_dn"]
    for i in range(4):
        difference = image(departed, i) - image(plain, i)
        assert np.all(np.abs(difference - levels[i] * plain.vignetting) <= 1.0)


# --------------------------------------------------------------------------------- gamma


def test_gamma_maps_the_linear_value_as_stated(tmp_path: Path):
    dataset = write_dataset(tmp_path / "d", config(departures=Departures(gamma=2.2)))
    for i in range(2):
        x = render_image(dataset.camera, dataset.views[i], dataset.rig).filled(0.0)
        usable = WHITE - BLACK
        expected = np.rint(BLACK + usable * (x / usable) ** (1 / 2.2)) - BLACK
        assert np.max(np.abs(image(dataset, i) - expected)) <= 1.0
        assert np.count_nonzero(image(dataset, i) != expected) < 0.001 * x.size
    truth = read_truth(dataset.truth_path)
    assert read_departures(truth)["gamma"]["gamma"] == 2.2
    sensor = load_project(dataset.project_path).spec.sensor
    assert sensor.response is None and not sensor.assume_linear  # declared as usual


# --------------------------------------------------------------------------- attenuation


def test_attenuation_ratio_is_exp_of_minus_c_times_both_distances(tmp_path: Path):
    c = 0.4
    plain, departed = pair(tmp_path, Departures(attenuation_per_m=c))
    light = departed.rig.lights[0]
    for i in range(4):
        view = departed.views[i]
        points, _ = surface_points(departed.camera, view, BowedWall(0.0))
        d_light = np.linalg.norm(points - light.position_world(view), axis=-1)
        d_camera = np.linalg.norm(points - view.center_world, axis=-1)
        factor = np.exp(-c * (d_light + d_camera))
        ok = valid(plain, i)
        # Both images are rounded: |B - f A| <= 0.5 + 0.5 f.
        assert np.all(np.abs(image(departed, i) - factor * image(plain, i))[ok] <= 1.0)
        assert factor[ok].max() < 0.7  # metres of water: a strong effect
    truth = read_departures(read_truth(departed.truth_path))
    assert truth["attenuation"]["coefficient_per_m"] == c


def test_attenuation_applies_each_light_its_own_distance(tmp_path: Path):
    c = 0.5
    rig = RigConfig(n_lights=2, radius_range_m=(0.2, 0.25))
    _, departed = pair(tmp_path, Departures(attenuation_per_m=c), rig=rig)
    view = departed.views[0]
    points, _ = surface_points(departed.camera, view, BowedWall(0.0))
    d_camera = np.linalg.norm(points - view.center_world, axis=-1)
    expected = np.zeros(points.shape[:2])
    for light in departed.rig.lights:
        alone = render_image(departed.camera, view, Rig.single(light)).filled(0.0)
        d_light = np.linalg.norm(points - light.position_world(view), axis=-1)
        expected += alone * np.exp(-c * (d_light + d_camera))
    ok = valid(departed, 0)
    assert np.all(np.abs(image(departed, 0) - expected)[ok] <= 0.5 + 1e-6)


def test_backscatter_adds_beta_times_the_ray_integral(tmp_path: Path):
    """Water that scatters: each pixel gains scale x exposure x beta x S over the same
    water without backscatter, S the integral along the ray to the pixel centre's wall
    point (here by adaptive quadrature, `tests/test_medium.py`)."""
    from lightcal.core.medium import Medium
    from tests.test_medium import _scatter_reference

    c, beta, g = 0.3, 3.0, 0.5
    clear = write_dataset(tmp_path / "clear", config(departures=Departures(attenuation_per_m=c)))
    murky = write_dataset(
        tmp_path / "murky",
        config(departures=Departures(attenuation_per_m=c, backscatter_per_m=beta, phase_g=g)),
    )
    light, view = murky.rig.lights[0], murky.views[0]
    points, _ = surface_points(murky.camera, view, BowedWall(0.0))
    ok = valid(murky, 0)
    rows, cols = np.nonzero(ok)
    pick = np.arange(0, rows.size, max(1, rows.size // 40))
    s = np.array(
        [
            _scatter_reference(points[r, q], view.center_world, light, view, Medium(c, beta, g))
            for r, q in zip(rows[pick], cols[pick], strict=True)
        ]
    )
    expected = light.scale * view.exposure * beta * s
    gained = (image(murky, 0) - image(clear, 0))[rows[pick], cols[pick]]
    assert expected.max() > 20.0  # a visible veil, DN
    assert np.all(np.abs(gained - expected) <= 1.0)
    truth = read_departures(read_truth(murky.truth_path))
    assert truth["backscatter"]["beta_per_m"] == beta and truth["backscatter"]["phase_g"] == g


# ----------------------------------------------------------------- undeclared vignetting


def test_undeclared_vignetting_ratio_is_the_radial_fall_off(tmp_path: Path):
    k1, k2 = -0.3, 0.05
    plain, departed = pair(tmp_path, Departures(undeclared_vignetting=(k1, k2)))
    v, u = np.mgrid[0:160, 0:240].astype(np.float64)
    r2 = ((u - 119.5) ** 2 + (v - 79.5) ** 2) / (math.hypot(240, 160) / 2) ** 2
    falloff = 1 + k1 * r2 + k2 * r2**2
    for i in range(4):
        ok = valid(plain, i)
        assert np.all(np.abs(image(departed, i) - falloff * image(plain, i))[ok] <= 1.0)
    project = load_project(departed.project_path)
    assert project.spec.sensor.model == "radiance" and project.spec.sensor.vignetting is None
    assert not (departed.folder / "vignetting.json").exists()
    record = read_departures(read_truth(departed.truth_path))["undeclared_vignetting"]
    assert record["coeffs"] == [k1, k2] and record["center_px"] == [119.5, 79.5]


def test_undeclared_vignetting_needs_the_radiance_model_and_a_positive_fall_off(tmp_path: Path):
    sensor = SensorConfig(noise=False, model="map", vignetting_coeffs=(-0.2,))
    expected = r"^undeclared_vignetting: applies to the radiance sensor model only, got 'map'$"
    with pytest.raises(InputError, match=expected):
        config(sensor=sensor, departures=Departures(undeclared_vignetting=(-0.3, 0.0)))
    with pytest.raises(InputError, match=r"^undeclared_vignetting: the fall-off reaches -0\.9"):
        write_dataset(tmp_path / "d", config(departures=Departures(undeclared_vignetting=(-2, 0))))
    assert not (tmp_path / "d").exists()


# ---------------------------------------------------------------------------- the rim


def test_rid_rim_is_the_declared_profile_times_the_rim(tmp_path: Path):
    plain, departed = pair(tmp_path, Departures(rid_rim_amplitude=0.3))
    declared = CosPowerRID.from_half_angle(math.radians(30.0))
    true_rid = departed.rig.lights[0].rid
    assert isinstance(true_rid, SymmetricTableRID)
    theta = np.radians(np.array([0.0, 10.0, 25.5, 30.0, 34.5, 50.0, 70.0]))
    ratio = true_rid(theta) / declared(theta)
    # w = 0.15 x 30 = 4.5 degrees: e^-1 of the amplitude 4.5 degrees from the half angle.
    assert ratio == pytest.approx(
        [1.0, 1.0, 1 + 0.3 / math.e, 1.3, 1 + 0.3 / math.e, 1, 1], abs=2e-4
    )
    assert np.allclose(ratio, rim_factor(theta, math.radians(30.0), 0.3), atol=2e-4)
    # The project gets the plain profile; the truth records the rimmed one.
    project = load_project(departed.project_path)
    assert project.spec.lights[0].rid.type == "cos_power"
    assert project.lights[0].initial.rid == declared == plain.rig.lights[0].rid
    truth = read_truth(departed.truth_path)
    assert truth["lights"][0]["rid"]["type"] == "table"
    record = read_departures(truth)["rid_rim"]
    assert record["half_angle_deg"] == pytest.approx(30.0)
    assert record["declared_rid"]["type"] == "cos_power"
    # The images are those of the rimmed light.
    for i in range(2):
        expected = render_image(departed.camera, departed.views[i], departed.rig)
        ok = ~np.ma.getmaskarray(expected)
        assert np.max(np.abs(image(departed, i) - expected.filled(0.0))[ok]) <= 0.5 + 1e-6
        assert not np.array_equal(image(departed, i), image(plain, i))


def test_rid_rim_of_a_2d_table_follows_each_azimuths_half_angle(tmp_path: Path):
    rig = RigConfig(model="table2d")
    dataset = write_dataset(
        tmp_path / "d",
        config(camera=small_camera(40, 30), rig=rig, departures=Departures(rid_rim_amplitude=0.5)),
    )
    declared = load_project(dataset.project_path).lights[0].initial.rid
    true_rid = dataset.rig.lights[0].rid
    assert isinstance(declared, Table2DRID) and isinstance(true_rid, Table2DRID)
    phi = np.radians(np.array([0.0, 45.0, 90.0]))
    halves = half_angles_rad(declared, phi)
    # Along phi = 0 the skewed beam cos^m(theta) (1 + 0.25 sin(theta)), m of 30 degrees,
    # halves beyond 30 degrees; along 90 degrees at 0.6 x 30 = 18 (no skew there).
    m = -math.log(2) / math.log(math.cos(math.radians(30.0)))
    along_x = brentq(lambda t: math.cos(t) ** m * (1 + 0.25 * math.sin(t)) - 0.5, 0.1, 1.2)
    assert halves[0] == pytest.approx(along_x, abs=2e-3)
    assert halves[2] == pytest.approx(math.radians(18.0), abs=2e-3)
    ratio = true_rid(halves, phi) / declared(halves, phi)
    assert ratio == pytest.approx(1.5, abs=0.01)
    record = read_departures(read_truth(dataset.truth_path))["rid_rim"]
    assert len(record["half_angle_deg"]) == len(record["azimuths_deg"]) == 72


def test_rid_rim_needs_a_half_angle(tmp_path: Path):
    expected = r"^rid_rim_amplitude: expected a light with a half-intensity angle, got an isotropic"
    with pytest.raises(InputError, match=expected):
        write_dataset(
            tmp_path / "d",
            config(rig=RigConfig(model="isotropic"), departures=Departures(rid_rim_amplitude=0.2)),
        )


# --------------------------------------------------------------------------- pose error


def test_pose_error_makes_poses_worse_than_their_declared_covariance(tmp_path: Path):
    noise_m, error_m = 0.0005, 0.004
    cfg = config(
        camera=small_camera(20, 16),
        scene=SceneConfig(n_views=60),
        pose_noise_m=noise_m,
        pose_noise_deg=0.05,
        departures=Departures(pose_error_m=error_m, pose_error_deg=0.5),
    )
    dataset = write_dataset(tmp_path / "d", cfg)
    project = load_project(dataset.project_path)
    shifts, angles = [], []
    for i, spec in enumerate(project.spec.images):
        covariance = np.array(spec.T_camera_world.covariance)
        assert np.allclose(np.diag(covariance), [math.radians(0.05) ** 2] * 3 + [noise_m**2] * 3)
        shifts.append(project.views[i].center_world - dataset.views[i].center_world)
        dR = project.views[i].R_camera_world @ dataset.views[i].R_camera_world.T
        angles.append(math.degrees(math.acos(min(1.0, (np.trace(dR) - 1) / 2))))
    # sigma per coordinate sqrt(noise^2 + error^2); |rotation vector| RMS sqrt(3) sigma.
    assert np.std(shifts) == pytest.approx(math.hypot(noise_m, error_m), rel=0.15)
    expected_rms = math.sqrt(3) * math.hypot(0.05, 0.5)
    assert math.sqrt(np.mean(np.square(angles))) == pytest.approx(expected_rms, rel=0.15)
    record = read_departures(read_truth(dataset.truth_path))["pose_error"]
    assert record == {
        "position_sigma_mm": pytest.approx(4.0),
        "angle_sigma_deg": 0.5,
        "declared_position_sigma_mm": pytest.approx(0.5),
        "declared_angle_sigma_deg": 0.05,
    }


def test_pose_error_changes_no_image(tmp_path: Path):
    plain, departed = pair(tmp_path, Departures(pose_error_m=0.002))
    for a, b in zip(plain.image_paths, departed.image_paths, strict=True):
        assert a.read_bytes() == b.read_bytes()


# ------------------------------------------------------------------ the height field


def test_bowed_wall_height_gradient_and_normals():
    wall = BowedWall(0.02, (0.1, -0.2), 1.0)
    xy = np.array([[0.1, -0.2], [0.6, -0.2], [0.1, 0.8], [2.0, 0.0], [0.4, 0.1]])
    assert wall.height(xy).tolist() == pytest.approx([0.02, 0.015, 0.0, 0.0, 0.02 * (1 - 0.18)])
    eps = 1e-7
    dx, dy = np.array([eps, 0.0]), np.array([0.0, eps])
    numeric = np.stack(
        [
            (wall.height(xy + dx) - wall.height(xy - dx)) / (2 * eps),
            (wall.height(xy + dy) - wall.height(xy - dy)) / (2 * eps),
        ],
        axis=1,
    )
    inside = [0, 1, 3, 4]  # not on the rim's kink
    assert np.allclose(wall.gradient(xy)[inside], numeric[inside], atol=1e-8)
    normals = wall.normals(xy)
    assert np.allclose(np.linalg.norm(normals, axis=1), 1.0)
    assert normals[1] == pytest.approx(np.array([0.02, 0.0, 1.0]) / math.hypot(0.02, 1.0))


def test_intersect_lands_on_the_height_field():
    wall = BowedWall(-0.05, (0.0, 0.0), 1.0)
    origin = np.array([0.2, 0.1, 1.5])
    rng = np.random.default_rng(0)
    rays = np.column_stack([rng.uniform(-0.6, 0.6, (500, 2)), -np.ones(500)])
    points, ok = intersect(origin, rays, wall)
    assert ok.all()
    assert np.allclose(points[:, 2], wall.height(points[:, :2]), atol=1e-12)
    lam = (points - origin) / rays
    assert np.allclose(lam, lam[:, :1], rtol=1e-12) and np.all(lam > 0)
    # Straight down onto the centre: the bowl's bottom.
    centre, ok = intersect(np.array([0.0, 0.0, 2.0]), np.array([[0.0, 0.0, -1.0]]), wall)
    assert ok[0] and centre[0] == pytest.approx([0.0, 0.0, -0.05])
    # A ray away from the wall misses.
    _, ok = intersect(origin, np.array([[0.0, 0.0, 1.0], [np.nan] * 3]), wall)
    assert not ok.any()


@pytest.mark.parametrize("sensor", ["radiance", "cos4", "paper", "map"])
@pytest.mark.parametrize("model", ["cos_power", "table2d"])
def test_flat_height_field_agrees_with_the_renderer(sensor: str, model: str):
    """Bow 0: the point sample agrees with the footprint integral to 1e-4 on lit pixels."""
    camera = small_camera()
    views = sample_views(SceneConfig(n_views=3), np.random.default_rng(1))
    rig = sample_rig(RigConfig(model=model, n_lights=2), np.random.default_rng(2))  # type: ignore[arg-type]
    vignetting = None
    if sensor == "map":
        v, u = np.mgrid[0:160, 0:240]
        vignetting = 1.0 - 0.2 * ((u - 119.5) ** 2 + (v - 79.5) ** 2) / 144.0**2
    for wall in (None, PlasticWall.from_albedo(0.3, 1.5, 0.8)):
        extra: dict[str, Any] = {} if wall is None else {"wall": wall}
        for view in views:
            kw: dict[str, Any] = {"sensor": sensor, "vignetting": vignetting, **extra}
            flat = render_image(camera, view, rig, **kw)
            sampled = render_height_field(camera, view, rig, BowedWall(0.0), **kw)
            assert np.array_equal(np.ma.getmaskarray(flat), np.ma.getmaskarray(sampled))
            lit = ~np.ma.getmaskarray(flat) & (flat.filled(0.0) > 0.02 * flat.max())
            assert np.count_nonzero(lit) > 1000
            relative = np.abs(sampled.data[lit] / flat.data[lit] - 1.0)
            assert relative.max() < 1e-4


def test_bow_brightens_a_bulge_and_records_its_shape(tmp_path: Path):
    plain, departed = pair(tmp_path, Departures(bow_m=0.03))
    record = read_departures(read_truth(departed.truth_path))["bow"]
    assert record["depth_mm"] == pytest.approx(30.0) and record["radius_m"] == 1.0
    assert record["shape"] == "bulge towards the cameras"
    x0, y0 = record["center_world_m"]
    hits = []
    for view in departed.views:
        axis, c = view.R_camera_world[2], view.center_world
        hits.append(c[:2] - c[2] / axis[2] * axis[:2])
    assert (x0, y0) == pytest.approx(tuple(np.mean(hits, axis=0)))
    wall = BowedWall(0.03, (x0, y0), 1.0)
    for i in range(4):
        # The images are the height-field renderer's (rounded) ...
        expected = render_height_field(departed.camera, departed.views[i], departed.rig, wall)
        ok = ~np.ma.getmaskarray(expected)
        assert np.max(np.abs(image(departed, i) - expected.filled(0.0))[ok]) <= 0.5 + 1e-6
    # ... and differ from the flat wall's by percents (a 3 cm bulge at 0.8-2.5 m).
    ok = valid(plain, 0)
    ratio = image(departed, 0)[ok] / np.maximum(image(plain, 0)[ok], 1.0)
    bright = image(plain, 0)[ok] > 1000
    assert np.median(np.abs(ratio[bright] - 1.0)) > 0.005


# ------------------------------------------------------------------------- the texture


def test_albedo_texture_is_bounded_and_has_10_to_30_cm_features():
    texture = sample_albedo_texture(0.2, np.random.default_rng(3))
    xy = np.random.default_rng(4).uniform(-2, 2, (20000, 2))
    t = texture.field(xy)
    assert np.all(np.abs(t) <= 1.0) and t.std() > 0.1
    wavelengths = texture.describe()["wavelengths_m"]
    assert all(0.2 <= w <= 0.6 for w in wavelengths)
    assert np.all(np.abs(texture.factor(xy) - 1.0) <= 0.2)


def test_albedo_texture_ratio_is_the_texture_at_the_pixels_point(tmp_path: Path):
    amplitude = 0.25
    plain, departed = pair(tmp_path, Departures(albedo_texture_amplitude=amplitude))
    record = read_departures(read_truth(departed.truth_path))["albedo_texture"]
    # Rebuilt from truth.json alone.
    wavelengths = np.array(record["wavelengths_m"])
    directions = np.radians(record["directions_deg"])
    texture = AlbedoTexture(
        record["amplitude"],
        (2 * np.pi / wavelengths)[:, None]
        * np.column_stack([np.cos(directions), np.sin(directions)]),
        np.array(record["phases_rad"]),
        np.array(record["weights"]),
    )
    ratios = []
    for i in range(4):
        points, _ = surface_points(departed.camera, departed.views[i], BowedWall(0.0))
        factor = texture.factor(points[..., :2])
        ok = valid(plain, i)
        assert np.all((factor[ok] >= 1 - amplitude) & (factor[ok] <= 1 + amplitude))
        # Both images are rounded: |B - f A| <= 0.5 + 0.5 f.
        error = np.abs(image(departed, i) - factor * image(plain, i))
        assert np.all((error <= 0.5 + 0.5 * factor + 1e-9)[ok])
        bright = ok & (image(plain, i) > 1000)
        ratios.append(image(departed, i)[bright] / image(plain, i)[bright])
    every = np.concatenate(ratios)
    assert np.all((every > 1 - amplitude - 0.002) & (every < 1 + amplitude + 0.002))
    assert every.max() - every.min() > 0.1  # it varies across the wall


# ----------------------------------------------------------------------- all together


def test_every_departure_together_is_recorded_and_the_dataset_loads(tmp_path: Path):
    departures = Departures(
        ambient_fraction=0.05,
        undeclared_vignetting=(-0.2, 0.02),
        rid_rim_amplitude=0.2,
        gamma=1.8,
        pose_error_m=0.002,
        pose_error_deg=0.2,
        bow_m=-0.01,
        albedo_texture_amplitude=0.1,
        attenuation_per_m=0.1,
        backscatter_per_m=0.2,
        corner=(0.7, 0.5, 0.8),
    )
    # All but the camera's and the lights' flat ports, rendered on the flat wall without
    # them.
    ports = ("port", "light_port")
    assert departures.names == tuple(n for n in DEPARTURE_NAMES if n not in ports)
    cfg = config(sensor=SensorConfig(), departures=departures)
    dataset = write_dataset(tmp_path / "a", cfg)
    again = write_dataset(tmp_path / "b", cfg)
    for a, b in zip(dataset.image_paths, again.image_paths, strict=True):
        assert a.read_bytes() == b.read_bytes()  # seeded
    truth = read_truth(dataset.truth_path)
    found = read_departures(truth)
    assert list(found) == list(departures.names)
    assert found["bow"]["shape"] == "bowl" and found["gamma"]["gamma"] == 1.8
    assert found["ambient"]["fraction"] == 0.05
    assert found["attenuation"]["coefficient_per_m"] == 0.1
    assert found["backscatter"]["beta_per_m"] == 0.2 and found["backscatter"]["phase_g"] == 0.9
    assert (
        found["corner"]["depth_m"] == 0.5 and len(found["corner"]["surroundings"]["surfaces"]) == 2
    )
    json.dumps(truth)
    assert len(load_project(dataset.project_path).views) == 4


def test_read_departures_refuses_unknown_names():
    with pytest.raises(InputError, match=r"^departures: expected a mapping of ambient, "):
        read_departures({"departures": {"fog": {}}})


DEPARTURE_ERRORS = [
    ({"ambient_fraction": -0.1}, "ambient_fraction: expected a finite value >= 0, got -0.1"),
    ({"gamma": 0.0}, "gamma: expected a finite value > 0, got 0"),
    ({"gamma": math.nan}, "gamma: expected a finite value > 0, got nan"),
    ({"attenuation_per_m": -1.0}, "attenuation_per_m: expected a finite value >= 0, got -1"),
    ({"albedo_texture_amplitude": 1.0}, "albedo_texture_amplitude: expected a value in [0, 1), "
     "got 1"),
    ({"bow_m": 0.2}, "bow_m: expected a value within +-0.1 m, got 0.2"),
    ({"undeclared_vignetting": (math.inf, 0.0)}, "undeclared_vignetting: expected two finite "
     "numbers k1 k2, got (inf, 0.0)"),
]  # fmt: skip


@pytest.mark.parametrize(("changes", "message"), DEPARTURE_ERRORS)
def test_departures_errors(changes: dict[str, Any], message: str):
    with pytest.raises(InputError) as caught:
        Departures(**changes)
    assert str(caught.value) == message


# -------------------------------------------------------------------------------- CLI

SMALL = ["--views", "3", "--width", "80", "--height", "60", "--quiet", "--no-noise"]


@pytest.fixture
def no_warmup(monkeypatch: pytest.MonkeyPatch) -> None:
    """The kernels compile on first use anyway; these tests are about the options."""
    monkeypatch.setattr(lightcal.cli.progress, "ensure_kernels", lambda **kwargs: None)


def test_cli_departure_options_reach_truth_json(tmp_path: Path, no_warmup: None):
    out = tmp_path / "ds"
    argv = [
        "synth", str(out), *SMALL, "--ambient", "0.1", "--undeclared-vignetting", "-0.3", "0.05",
        "--rid-rim", "0.25", "--gamma", "2.2", "--pose-error-mm", "2", "--pose-error-deg", "0.3",
        "--bow-mm", "15", "--albedo-texture", "0.2", "--attenuation", "0.05",
        "--backscatter", "0.3", "--phase-g", "0.6", "--corner", "0.6", "0.4", "0.7",
    ]  # fmt: skip
    assert main(argv) == 0
    found = read_departures(json.loads((out / "truth.json").read_text()))
    ports = ("port", "light_port")  # (rendered without the others)
    assert list(found) == [n for n in DEPARTURE_NAMES if n not in ports]
    assert found["ambient"]["fraction"] == 0.1
    assert found["undeclared_vignetting"]["coeffs"] == [-0.3, 0.05]
    assert found["rid_rim"]["amplitude"] == 0.25
    assert found["gamma"]["gamma"] == 2.2
    assert found["pose_error"]["position_sigma_mm"] == pytest.approx(2.0)
    assert found["pose_error"]["angle_sigma_deg"] == 0.3
    assert found["pose_error"]["declared_position_sigma_mm"] == pytest.approx(0.5)
    assert found["bow"]["depth_mm"] == pytest.approx(15.0)
    assert found["albedo_texture"]["amplitude"] == 0.2
    assert found["attenuation"]["coefficient_per_m"] == 0.05
    assert found["backscatter"] == {
        "beta_per_m": 0.3,
        "phase_g": 0.6,
        "formula": found["backscatter"]["formula"],
    }
    assert (found["corner"]["distance_m"], found["corner"]["albedo"]) == (0.6, 0.7)
    project = load_project(out / "project.json")
    assert project.surroundings is None  # without --declare-surroundings
    assert (
        project.spec.sensor.model == "radiance" and project.spec.lights[0].rid.type == "cos_power"
    )


def test_cli_help_documents_every_departure(capsys):
    with pytest.raises(SystemExit):
        main(["synth", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for option in (
        "--ambient FRACTION", "--undeclared-vignetting K1 K2", "--rid-rim AMPLITUDE",
        "--gamma G", "--pose-error-mm MM", "--pose-error-deg DEG", "--bow-mm MM",
        "--albedo-texture AMPLITUDE", "--attenuation C",
    ):  # fmt: skip
        assert option in text


CLI_ERRORS = [
    (["--ambient", "-0.1"], "--ambient: expected a finite value >= 0, got -0.1"),
    (["--ambient", "nan"], "--ambient: expected a finite value >= 0, got nan"),
    (["--gamma", "0"], "--gamma: expected a finite value > 0, got 0"),
    (["--gamma", "nan"], "--gamma: expected a finite value > 0, got nan"),
    (["--attenuation", "-1"], "--attenuation: expected a finite value >= 0, got -1"),
    (["--albedo-texture", "1"], "--albedo-texture: expected a value in [0, 1), got 1"),
    (["--bow-mm", "150"], "--bow-mm: expected a value within +-100 mm, got 150"),
    (["--bow-mm", "nan"], "--bow-mm: expected a value within +-100 mm, got nan"),
    (["--pose-error-mm", "-2"], "--pose-error-mm: expected a finite value >= 0, got -2"),
    (["--pose-error-deg", "inf"], "--pose-error-deg: expected a finite value >= 0, got inf"),
    (["--rid-rim", "-0.5"], "--rid-rim: expected a finite value >= 0, got -0.5"),
    (["--rid-rim", "0.3", "--light", "isotropic"], "--rid-rim: expected a light with a "
     "half-intensity angle, got --light isotropic"),
    (["--undeclared-vignetting", "-0.3", "0.05", "--vignetting", "-0.2"],
     "--undeclared-vignetting: applies to --sensor radiance only, got --sensor map"),
    (["--undeclared-vignetting", "nan", "0"], "--undeclared-vignetting: expected two finite "
     "numbers k1 k2, got (nan, 0.0)"),
    (["--undeclared-vignetting", "-2", "0"], "--undeclared-vignetting: the fall-off reaches "
     "-0.944 inside the image; expected V > 0 everywhere"),
]  # fmt: skip


@pytest.mark.parametrize(("args", "message"), CLI_ERRORS)
def test_cli_departure_errors(
    tmp_path: Path, capsys, no_warmup: None, args: list[str], message: str
):
    out = tmp_path / "ds"
    assert main(["synth", str(out), *SMALL, *args]) == 2
    assert capsys.readouterr().err == f"lightcal synth: error: {message}\n"
    assert not out.exists()
