"""Write a synthetic calibration dataset with its ground truth (`lightcal synth`).

Layout of a dataset folder:

| file | content |
|---|---|
| `images/view_00.png` ... | 16-bit raw values (DN, black level included); `.tif` for TIFF |
| `images/view_00_dark.png` ... | with `dark_frames`: the light-off photo of each view |
| `camera.yaml` | the intrinsics (OpenCV FileStorage) |
| `rid.csv` | model `table`: the symmetric profile |
| `light.ies` | model `ies`: axial IES file; `table2d`: IES with C-planes over 0..360 |
| `vignetting.json` | the radial fall-off, for the `map` sensor model |
| `project.json` | a complete project, see below |
| `truth.json` | the ground truth, see below |

The project (`lightcal.io.project`) names the camera file, every image with its *measured*
pose (the truth plus pose noise) and exposure time, the sensor's levels and noise model,
the lights' RIDs with a deliberately wrong initial guess, the default selection and solver.
The truth holds the true poses and lights (`describe_pose`, scale in DN, RID), the sensor,
the seed, the configuration and the lightcal version.

The pixel value model: an image's expected value above the black level is the renderer's
value (`render_image`) of the true rig, its light scales in DN at the first image's
exposure (the project's are relative to it); the sensor (`scenes.apply_sensor`) adds
noise, the black level, rounds and clips.
Everything the truth renders with (camera, RIDs, fall-off map, exposures) is read back from
the files just written, so it is exactly what `load_project` gives a calibration.

Departures (`SynthConfig.departures`, `lightcal.synthetic.departures`): data that departs
from what its project declares in one everyday way (room light, undeclared vignetting, a
rimmed light profile, a tone curve, poses worse than declared, a bowed wall, an albedo
texture, an absorbing medium, a corner). `lightcal.synthetic.imaging` makes the images
(the light scale from the true rig on the flat wall); truth.json records each departure.
A colour dataset (`SynthConfig.channels`, `lightcal.synthetic.colour`) writes 3-channel
images, each channel in its own water with its own noise; `lightcal.synthetic.dataset_images`
renders and writes every view's image.

The dataset is built in a hidden folder beside `out_dir` and renamed into place when
complete. With `force`, an existing folder's dataset files are replaced one by one (each
atomically), `project.json` last; other files in the folder are left alone.
Randomness: `np.random.default_rng(seed)` spawns one stream per purpose (views, exposures,
rig, pose noise, initial guess, sensor noise, then the albedo texture and the extra pose
error of the departures), so the same configuration and seed give byte-identical datasets,
and a departure leaves the draws of the others unchanged.
"""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from lightcal.core.camera import Camera
from lightcal.core.scene import Light, Rig, View
from lightcal.core.wall import LAMBERTIAN, WallReflectance
from lightcal.errors import InputError
from lightcal.io.atomic import atomic_write_text
from lightcal.io.camera_file import read_camera, write_camera
from lightcal.io.medium_spec import MediumSpec
from lightcal.io.project import (
    CameraSpec,
    ExposureSpec,
    ImageSpec,
    LightSpec,
    NoiseSpec,
    ProjectFile,
    SensorSpec,
    build_rid,
    load_project,
    save_project,
)
from lightcal.synthetic.colour import (
    ColourChannels,
    check_colour_config,
    colour_truth,
    declared_channels,
)
from lightcal.synthetic.dataset_files import (
    CAMERA_NAME,
    IMAGE_SUFFIX,
    PROJECT_NAME,
    TRUTH_FORMAT,
    TRUTH_NAME,
    ImageFormat,
    check_target,
    declared_port,
    declared_pose_covariance,
    declared_wall,
    initial_spec,
    make_staging,
    pose_kind,
    pose_spec,
    publish,
    read_truth,
    rid_file,
    truth_document,
    vignetting_file,
)
from lightcal.synthetic.dataset_images import write_images
from lightcal.synthetic.departure_truth import departures_truth
from lightcal.synthetic.departures import Departures
from lightcal.synthetic.imaging import AmbientLevels, make_imaging
from lightcal.synthetic.rid_rim import rimmed_rid
from lightcal.synthetic.scenes import (
    RigConfig,
    SceneConfig,
    SensorConfig,
    check_in_front,
    describe_rid,
    initial_guess,
    noise_model,
    peak_signal,
    perturb_view,
    sample_exposure_times,
    sample_rig,
    sample_views,
    signal_scale,
    white_level,
)
from lightcal.synthetic.wall_meshes import write_synthetic_wall_mesh

__all__ = [
    "TRUTH_FORMAT",
    "Departures",
    "ImageFormat",
    "SynthConfig",
    "SynthDataset",
    "read_truth",
    "write_dataset",
]

Progress = Callable[[str], None]
_LARGEST = dict(pose_noise_m=0.1, pose_noise_deg=10.0, init_offset_m=5.0, init_offset_deg=180.0)


@dataclass(frozen=True)
class SynthConfig:
    """Everything that defines a synthetic dataset.

    Attributes:
        camera: The intrinsics and image size.
        scene: The camera poses and exposure times.
        rig: The lights.
        sensor: The sensor and its fall-off model.
        pose_noise_m: Standard deviation of the error of each measured camera-centre
            coordinate, metres.
        pose_noise_deg: Standard deviation of each component of the measured rotation's
            error, degrees.
        init_offset_m: Distance of the initial guess from each true light position, metres.
        init_offset_deg: Angle between the initial guess's and each true light axis, degrees.
        seed: The seed of every random choice.
        image_format: "png" (16-bit) or "tiff" (16-bit, uncompressed).
        wall: The wall's true reflectance (the project written says Lambertian, as a
            user's first project would; truth.json records the true model).
        departures: How the data departs from what the project declares (none by default).
        dark_frames: With room light (`Departures.ambient_fraction` > 0), also write a
            light-off photo of each view (`images/view_NN_dark`: the room light alone
            through the same sensor, its own noise) and declare it as the image's `dark`.
        medium: What the project declares of the medium (air unless `--declare-medium`).
        declare_wall_mesh, albedo_map, declare_surroundings: the project declares the true
            wall's mesh (`wall.mesh`), an albedo map with a dense selection
            (`declared_wall`), the `corner` departure's surfaces (`surroundings`).
        channels: A colour dataset's channels (`lightcal.synthetic.colour`: their water
            replaces the departures', which must have none), or None: one channel.
        declare_port: the project declares the `port` departure (`camera.port`);
            declare_light_port its `light_port` departure (each `lights[i].port`).
    """

    camera: Camera
    scene: SceneConfig = field(default_factory=SceneConfig)
    rig: RigConfig = field(default_factory=RigConfig)
    sensor: SensorConfig = field(default_factory=SensorConfig)
    pose_noise_m: float = 0.0005
    pose_noise_deg: float = 0.05
    init_offset_m: float = 0.1
    init_offset_deg: float = 10.0
    seed: int = 0
    image_format: ImageFormat = "png"
    wall: WallReflectance = LAMBERTIAN
    departures: Departures = field(default_factory=Departures)
    dark_frames: bool = False
    medium: MediumSpec = field(default_factory=MediumSpec)
    declare_wall_mesh: bool = False
    albedo_map: bool = False
    declare_surroundings: bool = False
    channels: ColourChannels | None = None
    declare_port: bool = False
    declare_light_port: bool = False

    def __post_init__(self) -> None:
        check_colour_config(self)
        if self.declare_port and self.departures.port is None:
            raise InputError("declare_port", "expected a port to declare (departures.port)")
        if self.declare_light_port and self.departures.light_port is None:
            raise InputError(
                "declare_light_port", "expected a port to declare (departures.light_port)"
            )
        if self.dark_frames and self.departures.ambient_fraction == 0.0:
            raise InputError(
                "dark_frames",
                "expected room light to photograph (ambient_fraction > 0): without it a "
                "light-off photo is black",
            )
        for name, high in _LARGEST.items():
            value, unit = getattr(self, name), "m" if name.endswith("_m") else "degrees"
            if not (math.isfinite(value) and value >= 0.0):
                raise InputError(name, f"expected a finite value >= 0, got {value!r}")
            if value > high:
                raise InputError(name, f"expected at most {high:g} {unit}, got {value:g}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise InputError("seed", f"expected an integer >= 0, got {self.seed!r}")
        if self.image_format not in IMAGE_SUFFIX:
            raise InputError("image_format", f"expected 'png' or 'tiff', got {self.image_format!r}")
        radiance_only = {  # (checked before the corner's bounce reference is built)
            "undeclared_vignetting": self.departures.undeclared_vignetting is not None,
            "corner": self.departures.corner is not None,
        }
        for name in (k for k, used in radiance_only.items() if used):
            if self.sensor.model != "radiance":
                got = self.sensor.model
                raise InputError(name, f"applies to the radiance sensor model only, got {got!r}")


@dataclass(frozen=True, eq=False)
class SynthDataset:
    """What `write_dataset` wrote.

    Attributes:
        folder: The dataset folder.
        project_path: Its project.json.
        truth_path: Its truth.json.
        image_paths: One per view.
        camera: The camera (as read back from camera.yaml).
        views: The true views, with the relative exposures of the project.
        measured_views: The views the project states (pose noise and error added).
        rig: The true lights, scales in DN (a `rid_rim` departure's rimmed profile).
        initial_lights: The project's initial guesses (the declared profile).
        vignetting: (H, W) fall-off map of the "map" model, else None.
    """

    folder: Path
    project_path: Path
    truth_path: Path
    image_paths: list[Path]
    camera: Camera
    views: list[View]
    measured_views: list[View]
    rig: Rig
    initial_lights: list[Light]
    vignetting: NDArray[np.float64] | None


# ------------------------------------------------------------------------------ write


def write_dataset(
    out_dir: str | Path,
    config: SynthConfig,
    *,
    force: bool = False,
    progress: Progress | None = None,
) -> SynthDataset:
    """Render and write a synthetic dataset (layout in the module docstring).

    Args:
        out_dir: The dataset folder: new, empty, or (with `force`) one whose dataset
            files are replaced.
        config: What to synthesise.
        force: Allow a non-empty `out_dir`.
        progress: Called with one line of text per written image.

    Returns:
        What was written, with the truth in memory.

    Raises:
        InputError: `out_dir` is not empty (without `force`) or not a folder, a
            configuration that lights nothing or whose initial guess sits behind the wall.
    """
    out_dir = Path(out_dir)
    occupied = check_target(out_dir, force=force)
    staging = make_staging(out_dir)
    try:
        dataset = _write_into(staging, config, progress, out_dir)
        publish(staging, out_dir, occupied=occupied)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return replace(  # the staged dataset, at its final place
        dataset,
        folder=out_dir,
        project_path=out_dir / PROJECT_NAME,
        truth_path=out_dir / TRUTH_NAME,
        image_paths=[out_dir / p.relative_to(staging) for p in dataset.image_paths],
    )


def _write_into(
    folder: Path, config: SynthConfig, progress: Progress | None, final_dir: Path
) -> SynthDataset:
    root = np.random.default_rng(config.seed)
    rng_views, rng_exposure, rng_rig, rng_pose, rng_init, rng_sensor = root.spawn(6)
    rng_texture, rng_pose_error = root.spawn(2)  # the departures': the six above unchanged
    (rng_dark,) = root.spawn(1)  # the light-off photos' noise: the eight above unchanged
    sensor = config.sensor
    departures = config.departures
    project_path = folder / PROJECT_NAME

    # Files the truth is rendered from, read back as a calibration will read them.
    write_camera(config.camera, folder / CAMERA_NAME)
    camera = read_camera(folder / CAMERA_NAME)
    vignetting_rel, vignetting = vignetting_file(sensor, camera, folder)
    rid_spec = rid_file(config.rig, folder)
    rid = build_rid(rid_spec, folder, project_path, "lights[0].rid")
    true_rid = rid
    if departures.rid_rim_amplitude > 0.0:
        true_rid = rimmed_rid(rid, departures.rid_rim_amplitude)

    # The scene.
    poses = sample_views(config.scene, rng_views)
    times_s = sample_exposure_times(config.scene, rng_exposure)
    exposure_specs = [ExposureSpec(exposure_time_s=float(t)) for t in times_s]
    reference = exposure_specs[0].factor()
    views = [
        View(v.R_camera_world, v.t_camera_world, e.factor() / reference)
        for v, e in zip(poses, exposure_specs, strict=True)
    ]
    relative_rig = sample_rig(config.rig, rng_rig)
    relative_rig = Rig(tuple(light.replace(rid=true_rid) for light in relative_rig.lights))
    peak = peak_signal(camera, views, relative_rig, sensor=sensor.model, vignetting=vignetting)
    k = signal_scale(peak, sensor)
    rig = Rig(tuple(light.replace(scale=light.scale * k) for light in relative_rig.lights))
    measured = [
        perturb_view(
            v,
            rng_pose,
            position_sigma_m=config.pose_noise_m,
            angle_sigma_rad=math.radians(config.pose_noise_deg),
            field="pose_noise_m",
        )
        for v in views
    ]
    if departures.pose_error_m > 0.0 or departures.pose_error_deg > 0.0:
        measured = [
            perturb_view(
                v,
                rng_pose_error,
                position_sigma_m=departures.pose_error_m,
                angle_sigma_rad=math.radians(departures.pose_error_deg),
                field="pose_error_m",
            )
            for v in measured
        ]
    initial = [
        initial_guess(
            light,
            rng_init,
            offset_m=config.init_offset_m,
            offset_rad=math.radians(config.init_offset_deg),
        )
        for light in rig.lights
    ]
    if true_rid is not rid:  # the initial guess has the declared profile
        initial = [light.replace(rid=rid) for light in initial]
    check_in_front(initial, measured)  # (as the project will, before the rendering)

    # The images.
    if departures.corner is not None and progress is not None:
        progress("the corner's bounce light: building its cells and transfers (seconds)")
    if config.channels is not None:  # (the widest water's checks; each channel's below)
        departures = config.channels.widest(departures)
    imaging = make_imaging(
        camera, views, rig, departures, rng_texture, sensor=sensor.model, vignetting=vignetting,
        wall=config.wall,
    )  # fmt: skip
    imagings = [imaging] if config.channels is None else config.channels.imagings(imaging)
    ambients: list[AmbientLevels] | None = None
    if departures.ambient_fraction > 0.0:
        ambients = [im.ambient(views, departures.ambient_fraction) for im in imagings]
    written = write_images(
        folder, imagings=imagings, ambients=ambients, views=views, measured=measured,
        times_s=times_s, sensor=sensor, gamma=departures.gamma, image_format=config.image_format,
        dark_frames=config.dark_frames, rngs=(rng_sensor, rng_dark), progress=progress,
    )  # fmt: skip
    image_paths, view_truth = written.paths, written.views

    # The project: the measured poses with the covariance of their error.
    pose_covariance = declared_pose_covariance(config.pose_noise_m, config.pose_noise_deg)
    gain, read_variance = noise_model(sensor)
    spec = ProjectFile(
        camera=CameraSpec(path=CAMERA_NAME, port=declared_port(config)),
        sensor=SensorSpec(
            model=sensor.model,
            vignetting=vignetting_rel,
            black_level=sensor.black_level,
            white_level=white_level(sensor),
            noise=NoiseSpec(gain=gain, read_variance=read_variance),
            channels=declared_channels(config.channels),
        ),
        images=[
            ImageSpec(
                path=truth["path"],
                name=truth["name"],
                T_camera_world=pose_spec(measured[i], pose_covariance),
                exposure=exposure_specs[i],
                dark=truth.get("dark"),
            )
            for i, truth in enumerate(view_truth)
        ],
        lights=[
            LightSpec(
                name=light.name,
                rid=rid_spec,
                pose=pose_kind(light.rid),
                initial=initial_spec(initial[j]),
                port=declared_port(config, light=True),
            )
            for j, light in enumerate(rig.lights)
        ],
        medium=config.medium,  # the default solver
        **declared_wall(config.camera, albedo_map=config.albedo_map),
        surroundings=imaging.declared(config.declare_surroundings),
    )
    if config.declare_wall_mesh:  # the true wall's shape, as a mesh beside the project
        mesh_name = write_synthetic_wall_mesh(folder, camera, views, imaging.wall_shape)
        wall = spec.wall.model_copy(update={"mesh": mesh_name})
        spec = spec.model_copy(update={"wall": wall})

    # The truth.
    rid_truth = describe_rid(rid)
    if rid_spec.path is not None:
        rid_truth["path"] = rid_spec.path
    departure_truth = departures_truth(
        departures,
        imaging,
        ambient=None if ambients is None else ambients[0],
        view_names=[v["name"] for v in view_truth],
        declared_rid=rid,
        declared_rid_truth=rid_truth,
        pose_noise_m=config.pose_noise_m,
        pose_noise_deg=config.pose_noise_deg,
        sensor=sensor,
    )
    if true_rid is not rid:
        rid_truth = describe_rid(true_rid)
    truth = truth_document(
        config,
        camera=camera,
        vignetting_rel=vignetting_rel,
        view_truth=view_truth,
        departure_truth=departure_truth,
        rig=rig,
        relative_rig=relative_rig,
        initial=initial,
        rid_truth=rid_truth,
    )
    if config.channels is not None:
        truth = colour_truth(
            truth, config.channels, phase_g=departures.phase_g, ambients=ambients,
            view_channels=written.channels,
        )  # fmt: skip
    atomic_write_text(folder / TRUTH_NAME, json.dumps(truth, indent=2) + "\n")
    save_project(spec, project_path)
    try:
        load_project(project_path)  # the dataset must load: fail here rather than later
    except InputError as exc:
        raise InputError(final_dir / PROJECT_NAME, exc.detail) from exc

    return SynthDataset(
        folder=folder,
        project_path=project_path,
        truth_path=folder / TRUTH_NAME,
        image_paths=image_paths,
        camera=camera,
        views=views,
        measured_views=measured,
        rig=rig,
        initial_lights=initial,
        vignetting=vignetting,
    )
