"""Tests of lightcal.synthetic: scenes (views, rigs, sensor) and dataset (dataset folders)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from lightcal.core.camera import Camera
from lightcal.core.pose import rotation_from_axis
from lightcal.core.render import render_image
from lightcal.core.rid import CosPowerRID, IsotropicRID, SymmetricTableRID, Table2DRID
from lightcal.core.scene import Light, Rig, View
from lightcal.errors import InputError
from lightcal.io.images import read_image
from lightcal.io.project import load_project
from lightcal.synthetic import dataset_images
from lightcal.synthetic.dataset import SynthConfig, read_truth, write_dataset
from lightcal.synthetic.scenes import (
    RigConfig,
    SceneConfig,
    SensorConfig,
    apply_sensor,
    conversion_gain,
    elliptical_beam_table,
    initial_guess,
    make_rid,
    noise_model,
    peak_signal,
    perturb_view,
    sample_rig,
    sample_views,
    signal_scale,
    symmetric_profile_table,
    white_level,
)


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    c = float(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)))
    return math.degrees(math.acos(min(1.0, max(-1.0, c))))


def small_camera(width: int = 160, height: int = 120) -> Camera:
    return Camera.from_params(
        fx=0.9 * width, fy=0.9 * width, cx=(width - 1) / 2 + 0.7, cy=(height - 1) / 2 - 0.4,
        width=width, height=height, dist=(-0.05, 0.01, 0.0005, -0.0003, 0.0),
    )  # fmt: skip


# --------------------------------------------------------------------------------- views


def test_sample_views_ranges_stratification_and_wall_in_view():
    config = SceneConfig(
        n_views=12,
        distance_range_m=(0.8, 2.5),
        tilt_range_deg=(5.0, 35.0),
        roll_range_deg=(-30, 30),
    )
    views = sample_views(config, np.random.default_rng(3))
    assert len(views) == 12
    camera = Camera.from_params(fx=1080, fy=1080, cx=599.5, cy=399.5, width=1200, height=800)
    corners = np.array([[-0.5, -0.5], [1199.5, -0.5], [-0.5, 799.5], [1199.5, 799.5]])
    rays_camera, _ = camera.rays_camera(corners)
    distances, tilts = [], []
    for view in views:
        center = view.center_world
        assert center[2] > 0.0
        axis = view.R_camera_world[2]  # optical axis, world frame
        distances.append(-center[2] / axis[2])  # along the axis to z = 0
        tilts.append(math.degrees(math.acos(-axis[2])))
        # Every corner ray of a 1200 x 800 image hits the wall in front of the camera.
        rays_world = rays_camera @ view.R_camera_world
        assert np.all(rays_world[:, 2] < 0.0)
    distances_arr, tilts_arr = np.array(distances), np.array(tilts)
    assert np.all((distances_arr >= 0.8) & (distances_arr <= 2.5))
    assert np.all((tilts_arr >= 5.0 - 1e-9) & (tilts_arr <= 35.0 + 1e-9))
    # Stratified: exactly one distance (and one tilt) in each twelfth of the range.
    strata = np.floor((distances_arr - 0.8) / (1.7 / 12)).astype(int)
    assert sorted(strata.tolist()) == list(range(12))
    tilt_strata = np.floor((tilts_arr - 5.0) / (30.0 / 12)).astype(int)
    assert sorted(tilt_strata.tolist()) == list(range(12))


def test_sample_views_roll_within_range():
    config = SceneConfig(n_views=20, tilt_range_deg=(0.0, 0.0), roll_range_deg=(-10.0, 10.0))
    for view in sample_views(config, np.random.default_rng(0)):
        # With no tilt the camera x axis lies in the wall plane; its angle to the x axis of
        # the unrolled camera (world -x, see View.looking_at with up = -y) is the roll.
        x_axis = view.R_camera_world[0]
        assert abs(x_axis[2]) < 1e-12
        roll = math.degrees(math.atan2(-x_axis[1], -x_axis[0]))
        assert -10.0 <= roll <= 10.0


def test_sample_views_same_seed_same_views_other_seed_other_views():
    config = SceneConfig(n_views=5)
    a = sample_views(config, np.random.default_rng(7))
    b = sample_views(config, np.random.default_rng(7))
    c = sample_views(config, np.random.default_rng(8))
    for va, vb in zip(a, b, strict=True):
        assert np.array_equal(va.R_camera_world, vb.R_camera_world)
        assert np.array_equal(va.t_camera_world, vb.t_camera_world)
    assert not np.allclose(a[0].t_camera_world, c[0].t_camera_world)


def test_scene_config_errors():
    expected = r"^distance_range_m: expected 0\.001 <= min <= max <= 1000, got \(2\.5, 0\.8\)$"
    with pytest.raises(InputError, match=expected):
        SceneConfig(distance_range_m=(2.5, 0.8))
    with pytest.raises(InputError, match=r"^tilt_range_deg: expected 0 <= min <= max <= 80"):
        SceneConfig(tilt_range_deg=(0.0, 85.0))
    with pytest.raises(InputError, match=r"^n_views: expected an integer >= 1, got 0$"):
        SceneConfig(n_views=0)


def test_perturb_view_zero_noise_is_identity_and_noise_has_the_right_size():
    view = sample_views(SceneConfig(n_views=1), np.random.default_rng(1))[0]
    same = perturb_view(view, np.random.default_rng(0), position_sigma_m=0.0, angle_sigma_rad=0.0)
    assert np.array_equal(same.R_camera_world, view.R_camera_world)
    assert np.allclose(same.t_camera_world, view.t_camera_world, atol=1e-15)
    rng = np.random.default_rng(2)
    shifts, angles = [], []
    for _ in range(400):
        p = perturb_view(view, rng, position_sigma_m=0.001, angle_sigma_rad=math.radians(0.1))
        shifts.append(p.center_world - view.center_world)
        dR = p.R_camera_world @ view.R_camera_world.T
        angles.append(math.degrees(math.acos(min(1.0, (np.trace(dR) - 1) / 2))))
    assert np.std(np.array(shifts)) == pytest.approx(0.001, rel=0.1)
    # |delta| of a 3-D Gaussian with sigma 0.1 deg: RMS sqrt(3) * 0.1.
    assert math.sqrt(np.mean(np.square(angles))) == pytest.approx(math.sqrt(3) * 0.1, rel=0.1)


# -------------------------------------------------------------------------------- lights


def test_symmetric_profile_halves_at_the_half_angle():
    theta_deg, values = symmetric_profile_table(30.0)
    assert theta_deg[0] == 0.0 and theta_deg[-1] == 90.0 and values[0] == 1.0
    assert values[-1] == 0.0
    rid = SymmetricTableRID(np.radians(theta_deg), values)
    exact = rid.value_and_derivatives(np.array(math.radians(30.0)), exact=True)[0]
    assert float(exact) == pytest.approx(0.5, abs=1e-12)  # the table's own interpolation
    assert rid.half_angle_rad == pytest.approx(math.radians(30.0), abs=1e-9)


def test_elliptical_beam_half_angles_and_lopsidedness():
    theta_deg, phi_deg, values = elliptical_beam_table(30.0, aspect=0.5, skew=0.0)
    rid = Table2DRID(np.radians(theta_deg), np.radians(phi_deg), values)

    # cos^m with m from the half angle: 0.5 at 30 deg along phi = 0, at 15 deg along 90.
    def exact(theta_deg: float, phi_rad: float) -> float:  # the table, not the grid
        theta = np.array(math.radians(theta_deg))
        return float(rid.value_and_derivatives(theta, np.array(phi_rad), exact=True)[0])

    assert exact(30.0, 0.0) == pytest.approx(0.5, abs=1e-9)
    assert exact(15.0, math.pi / 2) == pytest.approx(0.5, abs=1e-9)
    _, _, lopsided = elliptical_beam_table(30.0, aspect=0.5, skew=0.25)
    i_180 = int(np.argmin(np.abs(phi_deg - 180.0)))
    j = int(np.argmin(np.abs(theta_deg - 20.0)))
    expected_ratio = (1 + 0.25 * math.sin(math.radians(20))) / (
        1 - 0.25 * math.sin(math.radians(20))
    )
    assert lopsided[0, j] / lopsided[i_180, j] == pytest.approx(expected_ratio, rel=1e-12)


def test_sample_rig_positions_axes_and_names():
    config = RigConfig(n_lights=3, radius_range_m=(0.05, 0.3), max_axis_tilt_deg=20.0)
    rig = sample_rig(config, np.random.default_rng(4))
    assert [light.name for light in rig.lights] == ["light_1", "light_2", "light_3"]
    assert rig.lights[0].scale == 1.0
    for light in rig.lights:
        radius = math.hypot(light.t_camera_light[0], light.t_camera_light[1])
        assert 0.05 <= radius <= 0.3
        assert -0.02 <= light.t_camera_light[2] <= 0.02
        assert angle_deg(light.axis_camera, np.array([0.0, 0.0, 1.0])) <= 20.0
        # Symmetric profile: the canonical rotation of its axis.
        assert np.allclose(light.R_camera_light, rotation_from_axis(light.axis_camera))
        assert 0.6 <= light.scale <= 1.4
    # Spread around the camera: 120 degrees apart.
    az = [math.degrees(math.atan2(lt.t_camera_light[1], lt.t_camera_light[0])) for lt in rig.lights]
    assert (az[1] - az[0]) % 360 == pytest.approx(120.0)
    # The default is one light about 10 cm beside the camera (+x side), 30 degree half angle.
    one = sample_rig(RigConfig(), np.random.default_rng(0)).lights[0]
    assert one.name == "light"
    assert 0.08 <= np.linalg.norm(one.t_camera_light[:2]) <= 0.12
    assert one.t_camera_light[0] > 0.07
    assert isinstance(one.rid, CosPowerRID)
    assert one.rid.half_angle_rad == pytest.approx(math.radians(30.0))


def test_sample_rig_general_and_isotropic_orientations():
    general = sample_rig(RigConfig(model="table2d"), np.random.default_rng(5)).lights[0]
    assert isinstance(general.rid, Table2DRID)
    # A random roll about the axis: not the canonical minimal rotation.
    assert not np.allclose(general.R_camera_light, rotation_from_axis(general.axis_camera))
    iso = sample_rig(RigConfig(model="isotropic"), np.random.default_rng(5)).lights[0]
    assert isinstance(iso.rid, IsotropicRID)
    assert np.array_equal(iso.R_camera_light, np.eye(3))


def test_initial_guess_is_off_by_exactly_the_offsets():
    light = sample_rig(RigConfig(), np.random.default_rng(1)).lights[0]
    guess = initial_guess(
        light, np.random.default_rng(2), offset_m=0.1, offset_rad=math.radians(10)
    )
    assert np.linalg.norm(guess.t_camera_light - light.t_camera_light) == pytest.approx(0.1)
    assert angle_deg(guess.axis_camera, light.axis_camera) == pytest.approx(10.0)
    assert guess.rid is light.rid and guess.scale == light.scale


def test_rig_config_errors():
    models = "isotropic, cos_power, gaussian, table, table2d, ies"
    with pytest.raises(InputError, match=rf"^model: expected one of {models}, got 'laser'$"):
        RigConfig(model="laser")  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"^half_angle_deg: expected a value in \(0, 85\)"):
        RigConfig(half_angle_deg=90.0)


# -------------------------------------------------------------------------------- sensor


def test_noise_model_and_levels_by_hand():
    s = SensorConfig(bit_depth=14, full_well_e=20000.0, read_noise_e=3.0)
    assert s.black_level == 512.0 and white_level(s) == 16383.0
    g = (16383.0 - 512.0) / 20000.0
    assert conversion_gain(s) == pytest.approx(g)
    assert noise_model(s) == pytest.approx((g, (3.0 * g) ** 2 + 1.0 / 12.0))
    assert SensorConfig(bit_depth=12).black_level == 128.0
    assert SensorConfig(bit_depth=16).black_level == 2048.0
    assert noise_model(SensorConfig(noise=False)) == (0.0, 1.0 / 12.0)
    assert signal_scale(100.0, s) == pytest.approx(0.7 * (16383.0 - 512.0) / 100.0)
    with pytest.raises(InputError, match=r"^lights: the lights illuminate nothing"):
        signal_scale(0.0, s)


def test_sensor_noise_statistics_match_the_noise_model():
    s = SensorConfig(bit_depth=14, full_well_e=20000.0, read_noise_e=3.0)
    gain, read_variance = noise_model(s)
    rng = np.random.default_rng(11)
    for level in (30.0, 1000.0, 8000.0):
        signal = np.full((300, 300), level)
        dn, saturated = apply_sensor(signal, s, rng)
        assert dn.dtype == np.uint16 and not saturated.any()
        values = dn.astype(np.float64) - s.black_level
        assert values.mean() == pytest.approx(level, abs=0.05 + 0.002 * level)
        assert values.var() == pytest.approx(gain * level + read_variance, rel=0.03)


def test_sensor_quantises_clips_and_marks_saturation_without_noise():
    s = SensorConfig(bit_depth=12, noise=False)  # black 128, white 4095
    signal = np.ma.masked_array(
        np.array([[0.0, 100.4, 100.6, 3966.0, 3967.0, 1e6]]),
        mask=[[True, False, False, False, False, False]],
    )
    dn, saturated = apply_sensor(signal, s, np.random.default_rng(0))
    assert dn.tolist() == [[128, 228, 229, 4094, 4095, 4095]]
    assert saturated.tolist() == [[False, False, False, False, True, True]]


def test_sensor_masked_pixels_are_black_level_plus_read_noise():
    s = SensorConfig()
    signal = np.ma.masked_array(np.full((200, 200), 5000.0), mask=np.ones((200, 200), bool))
    dn, _ = apply_sensor(signal, s, np.random.default_rng(3))
    values = dn.astype(np.float64) - s.black_level
    assert abs(values.mean()) < 0.05
    assert values.var() == pytest.approx(noise_model(s)[1], rel=0.05)


def test_peak_signal_on_a_grid_is_close_to_the_exact_peak():
    camera = small_camera()
    views = sample_views(SceneConfig(n_views=2), np.random.default_rng(0))
    rig = sample_rig(RigConfig(), np.random.default_rng(0))
    exact = peak_signal(camera, views, rig)
    expected = max(float(render_image(camera, v, rig).max()) for v in views)
    assert exact == expected
    on_grid = peak_signal(camera, views, rig, max_pixels=500)  # every 7th pixel
    assert on_grid <= exact
    assert on_grid == pytest.approx(exact, rel=0.01)


def test_sensor_config_errors():
    with pytest.raises(InputError, match=r"^bit_depth: expected 10, 12, 14 or 16, got 13$"):
        SensorConfig(bit_depth=13)
    with pytest.raises(InputError, match=r"^vignetting_coeffs: expected radial vignetting"):
        SensorConfig(model="map")
    with pytest.raises(InputError, match=r"^black_level_dn: expected a value in \[0, 4095\)"):
        SensorConfig(bit_depth=12, black_level_dn=5000.0)


# ------------------------------------------------------------------------------ datasets


def small_config(**changes: Any) -> SynthConfig:
    base: dict[str, Any] = {
        "camera": small_camera(),
        "scene": SceneConfig(n_views=4),
        "sensor": SensorConfig(noise=False),
        "seed": 5,
    }
    base.update(changes)
    return SynthConfig(**base)


def rendered_dn(dataset, i: int) -> np.ma.MaskedArray:
    return render_image(
        dataset.camera,
        dataset.views[i],
        dataset.rig,
        sensor=small_config().sensor.model if dataset.vignetting is None else "map",
        vignetting=dataset.vignetting,
    )


def test_noise_free_dataset_loads_and_images_equal_the_render(tmp_path: Path):
    out = tmp_path / "data"
    config = small_config()
    dataset = write_dataset(out, config)
    project = load_project(out / "project.json")
    assert project.camera == config.camera == dataset.camera
    assert len(project.views) == 4 and project.names == ["view_00", "view_01", "view_02", "view_03"]
    assert [p.name for p in project.image_paths] == [f"view_0{i}.png" for i in range(4)]
    sensor = project.spec.sensor
    assert (sensor.black_level, sensor.white_level) == (512.0, 16383.0)
    assert sensor.noise is not None and sensor.noise.gain == 0.0
    peak = 0.0
    for i, path in enumerate(project.image_paths):
        # The project states the measured poses and the relative exposures of the truth.
        assert np.array_equal(
            project.views[i].R_camera_world, dataset.measured_views[i].R_camera_world
        )
        assert project.views[i].exposure == dataset.views[i].exposure
        image = read_image(path, black_level=512.0, white_level=16383.0)
        expected = rendered_dn(dataset, i)
        valid = ~np.ma.getmaskarray(expected)
        assert valid.mean() > 0.99
        assert np.max(np.abs(image.values[valid] - expected[valid])) <= 0.5 + 1e-9
        assert np.all(image.values[~valid] == 0.0)
        peak = max(peak, float(image.values.max()))
    # The brightest pixel sits at the exposure target of the usable range.
    assert peak == pytest.approx(0.7 * (16383 - 512), abs=0.5)
    assert sorted({v.exposure for v in project.views}) != [1.0]  # exposures vary
    assert not list(tmp_path.glob(".*partial"))  # no staging folder left


def test_noisy_dataset_residuals_follow_the_noise_model(tmp_path: Path):
    dataset = write_dataset(tmp_path / "d", small_config(sensor=SensorConfig()))
    gain, read_variance = noise_model(SensorConfig())
    project = load_project(dataset.project_path)
    assert project.spec.sensor.noise is not None
    assert project.spec.sensor.noise.gain == gain
    assert project.spec.sensor.noise.read_variance == read_variance
    z = []
    for i, path in enumerate(dataset.image_paths):
        image = read_image(path, black_level=512.0, white_level=16383.0)
        expected = rendered_dn(dataset, i)
        valid = ~np.ma.getmaskarray(expected)
        z.append(
            (image.values[valid] - expected[valid])
            / np.sqrt(gain * expected[valid] + read_variance)
        )
    zz = np.concatenate(z)
    assert abs(zz.mean()) < 0.02
    assert zz.std() == pytest.approx(1.0, abs=0.03)


def test_truth_file_holds_the_true_poses_lights_and_settings(tmp_path: Path):
    config = small_config(init_offset_m=0.1, init_offset_deg=10.0, pose_noise_m=0.002)
    dataset = write_dataset(tmp_path / "d", config)
    truth = read_truth(dataset.truth_path)
    assert truth["seed"] == 5 and truth["lightcal_version"]
    assert truth["camera"]["width"] == 160 and truth["camera"]["path"] == "camera.yaml"
    assert truth["sensor"]["bit_depth"] == 14 and truth["sensor"]["black_level_dn"] == 512.0
    light, true_light = truth["lights"][0], dataset.rig.lights[0]
    assert light["position_m"] == true_light.t_camera_light.tolist()
    assert light["R_camera_light"] == true_light.R_camera_light.tolist()
    assert light["scale"] == true_light.scale
    assert light["rid"]["type"] == "cos_power"
    assert light["rid"]["half_angle_deg"] == pytest.approx(30.0)
    assert math.dist(light["initial"]["position_m"], light["position_m"]) == pytest.approx(0.1)
    initial_axis = np.array(light["initial"]["axis_camera"])
    assert angle_deg(initial_axis, np.array(light["axis_camera"])) == pytest.approx(10.0)
    project = load_project(dataset.project_path)
    assert project.lights[0].initial.t_camera_light.tolist() == light["initial"]["position_m"]
    assert project.lights[0].initial.rid == true_light.rid
    for i, v in enumerate(truth["views"]):
        assert v["T_camera_world"]["R"] == dataset.views[i].R_camera_world.tolist()
        assert v["T_camera_world"]["t"] == dataset.views[i].t_camera_world.tolist()
        assert 0.8 <= v["distance_m"] <= 2.5 and 0.0 <= v["tilt_deg"] <= 35.0
        # The project's pose is the measured one, a few mm off the truth.
        offset = np.linalg.norm(project.views[i].center_world - dataset.views[i].center_world)
        assert 0.0 < offset < 0.02


@pytest.mark.parametrize("model", ["isotropic", "gaussian", "table", "ies", "table2d"])
def test_every_light_model_writes_a_loadable_profile(tmp_path: Path, model: str):
    config = small_config(
        camera=small_camera(40, 30),
        scene=SceneConfig(n_views=2),
        rig=RigConfig(model=model, n_lights=2),  # type: ignore[arg-type]
    )
    dataset = write_dataset(tmp_path / "d", config)
    project = load_project(dataset.project_path)
    files = {"table": "rid.csv", "ies": "light.ies", "table2d": "light.ies"}
    if model in files:
        assert (dataset.folder / files[model]).is_file()
        assert project.spec.lights[0].rid.path == files[model]
    assert [lu.initial.name for lu in project.lights] == ["light_1", "light_2"]
    kinds = {"isotropic": "isotropic", "table2d": "general"}
    assert project.lights[0].kind() == kinds.get(model, "symmetric")
    # The profile the truth was rendered with is the one the project loads ...
    loaded = project.lights[0].initial.rid
    true_rid = dataset.rig.lights[0].rid
    theta = np.radians(np.linspace(0.0, 80.0, 33))
    phi = np.linspace(0.0, 2 * math.pi, 33)
    assert np.array_equal(loaded(theta, phi), true_rid(theta, phi))
    # ... and the profile of the configuration (the IES C-planes map back to light azimuths).
    assert np.allclose(true_rid(theta, phi), make_rid(config.rig)(theta, phi), atol=1e-12)


def test_map_sensor_writes_the_fall_off_and_renders_with_it(tmp_path: Path):
    sensor = SensorConfig(noise=False, model="map", vignetting_coeffs=(-0.3, 0.05))
    dataset = write_dataset(tmp_path / "d", small_config(sensor=sensor))
    project = load_project(dataset.project_path)
    assert project.spec.sensor.model == "map"
    assert project.vignetting_path == dataset.folder / "vignetting.json"
    assert dataset.vignetting is not None
    corner = 1 - 0.3 * (np.hypot(79.5, 59.5) / np.hypot(80, 60)) ** 2
    corner += 0.05 * (np.hypot(79.5, 59.5) / np.hypot(80, 60)) ** 4
    assert dataset.vignetting[0, 0] == pytest.approx(corner)
    image = read_image(dataset.image_paths[0], black_level=512.0, white_level=16383.0)
    expected = render_image(
        dataset.camera, dataset.views[0], dataset.rig, sensor="map", vignetting=dataset.vignetting
    )
    valid = ~np.ma.getmaskarray(expected)
    assert np.max(np.abs(image.values[valid] - expected[valid])) <= 0.5 + 1e-9


def test_tiff_images_and_saturation(tmp_path: Path):
    sensor = SensorConfig(noise=False, bit_depth=12, exposure_target=1.5)
    dataset = write_dataset(tmp_path / "d", small_config(sensor=sensor, image_format="tiff"))
    assert dataset.image_paths[0].suffix == ".tif"
    truth = read_truth(dataset.truth_path)
    counts = [v["saturated_pixels"] for v in truth["views"]]
    i = int(np.argmax(counts))
    assert counts[i] > 0
    image = read_image(dataset.image_paths[i], black_level=128.0, white_level=4095.0)
    assert image.bit_depth == 16
    assert image.values.max() == 4095.0 - 128.0
    assert counts[i] == int(np.count_nonzero(image.values == 4095.0 - 128.0))
    assert np.all(image.saturated[image.values == 4095.0 - 128.0])


def test_non_empty_folder_is_refused_and_force_replaces_the_dataset(tmp_path: Path):
    out = tmp_path / "d"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    expected = (
        r"the folder is not empty: expected a new or empty folder "
        r"\(--force replaces the dataset in it\)$"
    )
    with pytest.raises(InputError, match=expected):
        write_dataset(out, small_config())
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]
    write_dataset(out, small_config(scene=SceneConfig(n_views=5)), force=True)
    assert (out / "images" / "view_04.png").is_file()
    dataset = write_dataset(out, small_config(scene=SceneConfig(n_views=2)), force=True)
    assert sorted(p.name for p in (out / "images").iterdir()) == ["view_00.png", "view_01.png"]
    assert (out / "notes.txt").read_text() == "keep me"
    assert len(load_project(dataset.project_path).views) == 2
    assert not list(tmp_path.glob(".*partial"))


def test_empty_existing_folder_is_used(tmp_path: Path):
    out = tmp_path / "empty"
    out.mkdir()
    write_dataset(out, small_config(scene=SceneConfig(n_views=1)))
    assert (out / "project.json").is_file() and (out / "truth.json").is_file()


def test_failure_leaves_nothing_behind(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    def broken(*args, **kwargs):
        raise RuntimeError("sensor broke")

    monkeypatch.setattr(dataset_images, "apply_sensor", broken)
    with pytest.raises(RuntimeError, match="sensor broke"):
        write_dataset(tmp_path / "d", small_config())
    assert list(tmp_path.iterdir()) == []


def test_same_config_same_bytes(tmp_path: Path):
    config = small_config(sensor=SensorConfig(), rig=RigConfig(model="table2d"))
    a = write_dataset(tmp_path / "a", config)
    b = write_dataset(tmp_path / "b", config)
    files_a = sorted(p.relative_to(a.folder) for p in a.folder.rglob("*") if p.is_file())
    files_b = sorted(p.relative_to(b.folder) for p in b.folder.rglob("*") if p.is_file())
    assert files_a == files_b
    for rel in files_a:
        assert (a.folder / rel).read_bytes() == (b.folder / rel).read_bytes(), rel
    json.loads((a.folder / "truth.json").read_text())  # valid JSON


def test_truth_scale_reproduces_the_images_with_a_fresh_rig(tmp_path: Path):
    """The truth file alone (pose, scale, RID) re-renders the images: nothing hidden."""
    dataset = write_dataset(tmp_path / "d", small_config())
    truth = read_truth(dataset.truth_path)
    lt = truth["lights"][0]
    light = Light(
        CosPowerRID(lt["rid"]["m"]), np.array(lt["position_m"]), np.array(lt["R_camera_light"]),
        scale=lt["scale"],
    )  # fmt: skip
    tv = truth["views"][1]
    view = View(
        np.array(tv["T_camera_world"]["R"]), np.array(tv["T_camera_world"]["t"]), tv["exposure"]
    )
    again = render_image(dataset.camera, view, Rig.single(light))
    image = read_image(dataset.image_paths[1], black_level=512.0, white_level=16383.0)
    valid = ~np.ma.getmaskarray(again)
    assert np.max(np.abs(image.values[valid] - again[valid])) <= 0.5 + 1e-9
