"""`lightcal synth`: write a synthetic calibration dataset with known ground truth.

Renders images of a flat wall lit by a rig of lights from a seeded random set of camera
poses, adds sensor noise, and writes the images, the camera file, the light's profile file,
a ready-to-run project (measured poses with pose noise, an initial guess that is off) and
truth.json (see `lightcal.synthetic.dataset`). One progress line per image goes to stderr.

Departures (`lightcal.synthetic.departures`, issue 24): options that make data depart from
what the project declares in one everyday way, each recorded in truth.json under
"departures" (name -> parameters) and none by default:

- `--ambient FRACTION`: room light, a uniform value on every pixel: FRACTION times the
  brightest beam value of the median image (lower median of the images' beam peaks),
  scaled by each image's exposure; the project estimates no offset.
- `--undeclared-vignetting K1 K2`: the images carry V = 1 + K1 r^2 + K2 r^4 (the
  convention of `--vignetting`), the project declares the `radiance` sensor model.
- `--rid-rim AMPLITUDE`: the true profile is the declared one times
  1 + AMPLITUDE exp(-((theta - theta_half) / w)^2), w = 0.15 theta_half; the project
  gets the plain profile.
- `--gamma G`: the stored value above black is W (x / W)^(1/G), x the linear value above
  black, W = white - black; the project declares linear data.
- `--pose-error-mm MM`, `--pose-error-deg DEG`: the measured poses get an extra random
  error of these sigmas on top of `--pose-noise-mm/deg`, whose covariance the project
  still declares.
- `--bow-mm MM`: the wall is z = MM/1000 max(0, 1 - |(x, y) - (x0, y0)|^2 / R^2), R = 1 m
  around where the views look: MM > 0 bulges towards the cameras, MM < 0 is a bowl.
  `--declare-wall-mesh` also writes that wall as a triangle mesh (`wall_mesh.ply`) and
  declares it in the project (`wall.mesh`), which then models it.
- `--albedo-texture AMPLITUDE`: the wall's albedo is 1 + AMPLITUDE t(x, y), t a smooth
  random field in [-1, 1] with 10-30 cm features, the same in every view.
- `--attenuation C`: a medium (clear water): each value is multiplied by
  exp(-C (d_light + d_camera)), C in 1/m. Three values C_R C_G C_B (of `--attenuation` or
  `--backscatter`) make a colour dataset, each channel in its own water, `--colour R G B`
  the channels' relative light scales (`lightcal.cli.synth_colour`).
- `--corner D DEPTH ALBEDO`: a ceiling and a side wall meet the wall D m from where the
  views look; their bounce light, computed by brute force
  (`lightcal.synthetic.bounce_reference`), is added. `--declare-surroundings` makes the
  project declare them (`surroundings:`, docs/model.md "Inter-reflection").
- `--port D_MM T_MM NG NW`: the camera looks through a flat port (docs/model.md, "The
  camera's flat port"): each pixel centre's ray refracted into the water
  (`lightcal.synthetic.port_imaging`); `--declare-port` makes the project declare it
  (`camera.port`).
- `--light-port D_MM T_MM NG NW`: every light shines through a flat port (docs/model.md,
  "The light's flat port"), computed per pixel centre by
  `lightcal.synthetic.light_port_imaging`; `--declare-light-port` makes the project
  declare it (`lights[i].port`).

`--declare-medium given|estimated` makes the project declare that water (`medium:` with
the true C, or estimated from 0): data whose project models the medium
(`lightcal/cli/synth_options.py`).

`--real-world`: photos as a user's camera gives them and no project
(`lightcal.cli.synth_real_world`).

`--dark-frames` (with `--ambient`): also a light-off photo of each view, the room light
alone through the same sensor with its own noise (`images/view_NN_dark.png`), declared as
the image's `dark` in the project, which subtracts it before the fit.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import TYPE_CHECKING

from lightcal.cli.synth_colour import colour_medium, water_of
from lightcal.cli.synth_options import (
    MAX_POSE_MM,
    build,
    declared_medium,
    departures_of,
    register_departures,
)
from lightcal.cli.synth_real_world import register_real_world
from lightcal.errors import InputError
from lightcal.synthetic.light_models import LIGHT_MODELS

if TYPE_CHECKING:
    from lightcal.core.wall import WallReflectance

DEFAULT_VIGNETTING = (-0.25, 0.05)
"""Radial fall-off of `--sensor map` without `--vignetting`: V = 0.8 in the corners."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "synth",
        help="write a synthetic calibration dataset with known ground truth",
        description=(
            "Render a wall lit by a camera-mounted light from random camera poses and write "
            "OUT_DIR/images/view_NN.png, camera.yaml, project.json (measured poses, "
            "initial guess off the truth) and truth.json."
        ),
    )
    p.add_argument("out_dir", metavar="OUT_DIR", help="dataset folder (new or empty)")
    g = p.add_argument_group("scene")
    g.add_argument("--views", type=int, default=12, help="number of images (default 12)")
    g.add_argument(
        "--distance",
        type=float,
        nargs=2,
        default=(0.8, 2.5),
        metavar=("MIN_M", "MAX_M"),
        help="camera-to-wall distance along the optical axis, metres (default 0.8 2.5)",
    )
    g.add_argument(
        "--tilt-deg", type=float, default=35.0, help="largest tilt from the wall normal (35)"
    )
    g.add_argument(
        "--roll-deg", type=float, default=30.0, help="largest roll about the optical axis (30)"
    )
    g = p.add_argument_group("camera")
    g.add_argument("--width", type=int, default=1200, help="image width, pixels (1200)")
    g.add_argument("--height", type=int, default=800, help="image height, pixels (800)")
    g.add_argument("--fx", type=float, default=None, help="focal length, pixels (0.9 x width)")
    g.add_argument("--fy", type=float, default=None, help="focal length y, pixels (fx)")
    g.add_argument("--cx", type=float, default=None, help="principal point (width - 1) / 2")
    g.add_argument("--cy", type=float, default=None, help="principal point (height - 1) / 2")
    g.add_argument(
        "--distortion",
        type=float,
        nargs="+",
        default=(),
        metavar="K",
        help="OpenCV distortion k1 k2 p1 p2 [k3 [k4 k5 k6]] (default none)",
    )
    g = p.add_argument_group("lights")
    g.add_argument("--light", choices=LIGHT_MODELS, default="cos_power", help="profile (cos_power)")
    g.add_argument("--half-angle-deg", type=float, default=30.0, help="half-intensity angle (30)")
    g.add_argument("--lights", type=int, default=1, help="number of lights (1)")
    g.add_argument(
        "--light-radius-m",
        type=float,
        nargs=2,
        default=(0.08, 0.12),
        metavar=("MIN_M", "MAX_M"),
        help="distance of a light from the optical axis, metres (0.08 0.12)",
    )
    g.add_argument(
        "--init-offset-m", type=float, default=0.1, help="initial guess position error (0.1)"
    )
    g.add_argument(
        "--init-offset-deg", type=float, default=10.0, help="initial guess axis error (10)"
    )
    g = p.add_argument_group("sensor")
    g.add_argument("--bit-depth", type=int, choices=(10, 12, 14, 16), default=14)
    g.add_argument("--black-level", type=float, default=None, help="DN (2^(bits - 5))")
    g.add_argument("--full-well-e", type=float, default=20000.0, help="electrons (20000)")
    g.add_argument("--read-noise-e", type=float, default=3.0, help="electrons (3)")
    g.add_argument(
        "--exposure-target",
        type=float,
        default=0.7,
        help="brightest pixel as a fraction of the usable range (0.7)",
    )
    g.add_argument(
        "--noise", action=argparse.BooleanOptionalAction, default=True, help="sensor noise"
    )
    g.add_argument(
        "--sensor",
        choices=("radiance", "cos4", "paper", "map"),
        default=None,
        help="fall-off model (radiance; map with --vignetting)",
    )
    g.add_argument(
        "--vignetting",
        type=float,
        nargs="+",
        default=None,
        metavar="C",
        help=f"radial fall-off c1 c2 ... for --sensor map (default {DEFAULT_VIGNETTING})",
    )
    g = p.add_argument_group("wall")
    g.add_argument(
        "--wall",
        choices=("lambertian", "plastic", "oren_nayar"),
        default="lambertian",
        help="the wall's true reflectance (lambertian); the project still says lambertian",
    )
    g.add_argument("--roughness", type=float, default=None, help="plastic: GGX alpha (0.3)")
    g.add_argument(
        "--ior", type=float, default=None, help="plastic: coat index of refraction (1.5)"
    )
    g.add_argument(
        "--albedo", type=float, default=None, help="plastic: diffuse albedo of the base (0.8)"
    )
    g.add_argument("--sigma-deg", type=float, default=None, help="oren_nayar: roughness (20)")
    g = p.add_argument_group("measurement error")
    g.add_argument(
        "--pose-noise-mm", type=float, default=0.5, help="camera centre error sigma (0.5)"
    )
    g.add_argument(
        "--pose-noise-deg", type=float, default=0.05, help="camera rotation error sigma (0.05)"
    )
    register_departures(p)
    g = p.add_argument_group("output")
    g.add_argument("--format", choices=("png", "tiff"), default="png", help="image files (png)")
    g.add_argument("--seed", type=int, default=0, help="random seed (0)")
    g.add_argument("--force", action="store_true", help="replace the dataset in OUT_DIR")
    g.add_argument("--quiet", action="store_true", help="no progress lines")
    register_real_world(g)
    defaults = {a.dest: (a.default, a.option_strings[0]) for a in p._actions if a.option_strings}
    p.set_defaults(func=run, synth_defaults=defaults)


def _check_scene(args: argparse.Namespace) -> None:
    """The single-value scene options (SceneConfig takes them as ranges)."""
    from lightcal.synthetic.views import MAX_TILT_DEG

    if not (0.0 <= args.tilt_deg <= MAX_TILT_DEG):  # (NaN too)
        raise InputError(
            "--tilt-deg",
            f"expected a value in [0, {MAX_TILT_DEG:g}] degrees, got {args.tilt_deg:g}",
        )
    if not (-180.0 <= args.roll_deg <= 180.0):
        raise InputError(
            "--roll-deg", f"expected a value in [-180, 180] degrees, got {args.roll_deg:g}"
        )
    if math.isfinite(args.pose_noise_mm) and args.pose_noise_mm > MAX_POSE_MM:
        raise InputError(
            "--pose-noise-mm", f"expected at most {MAX_POSE_MM:g} mm, got {args.pose_noise_mm:g}"
        )


def _wall(args: argparse.Namespace) -> WallReflectance:
    """The true wall of --wall and its options (errors renamed after the options)."""
    from lightcal.synthetic.walls import WALL_PARAMETERS, true_wall

    names = [name for parameters in WALL_PARAMETERS.values() for name in parameters]
    return build(lambda: true_wall(args.wall, {name: getattr(args, name) for name in names}))


def run(args: argparse.Namespace) -> int:
    if args.real_world:
        from lightcal.cli.synth_real_world import run_real_world

        return run_real_world(args, args.synth_defaults)
    from lightcal.core.camera import Camera
    from lightcal.synthetic.camera_limits import (
        check_distortion,
        check_image_size,
        check_intrinsics,
    )
    from lightcal.synthetic.dataset import SynthConfig, write_dataset
    from lightcal.synthetic.scenes import RigConfig, SceneConfig, SensorConfig

    sensor_model = args.sensor
    if sensor_model is None:
        sensor_model = "map" if args.vignetting is not None else "radiance"
    if args.vignetting is not None and sensor_model != "map":
        raise InputError(
            "--vignetting", f"applies to --sensor map only, got --sensor {sensor_model}"
        )
    coeffs = None
    if sensor_model == "map":
        coeffs = tuple(args.vignetting) if args.vignetting is not None else DEFAULT_VIGNETTING
    if not args.out_dir.strip():
        raise InputError("OUT_DIR", f"expected the path of a dataset folder, got {args.out_dir!r}")
    build(lambda: check_image_size(args.width, args.height))
    build(
        lambda: check_intrinsics(
            args.width, args.height, fx=args.fx, fy=args.fy, cx=args.cx, cy=args.cy
        )
    )
    if not args.pose_noise_mm >= 0.0:
        raise InputError("--pose-noise-mm", f"expected a value >= 0, got {args.pose_noise_mm:g}")
    _check_scene(args)
    args, channels = water_of(args)
    departures = departures_of(args, sensor_model)
    if args.dark_frames and not args.ambient > 0.0:
        raise InputError(
            "--dark-frames",
            "expected room light to photograph (--ambient FRACTION > 0): without it a "
            "light-off photo is black",
        )
    medium = declared_medium(args) if channels is None else colour_medium(args, channels)
    fx = 0.9 * args.width if args.fx is None else args.fx
    camera = build(
        lambda: Camera.from_params(
            fx=fx,
            fy=fx if args.fy is None else args.fy,
            cx=(args.width - 1) / 2 if args.cx is None else args.cx,
            cy=(args.height - 1) / 2 if args.cy is None else args.cy,
            width=args.width,
            height=args.height,
            dist=tuple(args.distortion),
        )
    )
    build(lambda: check_distortion(camera))
    scene = build(
        lambda: SceneConfig(
            n_views=args.views,
            distance_range_m=(args.distance[0], args.distance[1]),
            tilt_range_deg=(0.0, args.tilt_deg),
            roll_range_deg=(-abs(args.roll_deg), abs(args.roll_deg)),
        )
    )
    rig = build(
        lambda: RigConfig(
            n_lights=args.lights,
            model=args.light,
            half_angle_deg=args.half_angle_deg,
            radius_range_m=(args.light_radius_m[0], args.light_radius_m[1]),
        )
    )
    sensor = build(
        lambda: SensorConfig(
            bit_depth=args.bit_depth,
            full_well_e=args.full_well_e,
            read_noise_e=args.read_noise_e,
            black_level_dn=args.black_level,
            exposure_target=args.exposure_target,
            noise=args.noise,
            model=sensor_model,
            vignetting_coeffs=coeffs,
        )
    )
    config = build(
        lambda: SynthConfig(
            camera=camera,
            scene=scene,
            rig=rig,
            sensor=sensor,
            pose_noise_m=args.pose_noise_mm / 1000.0,
            pose_noise_deg=args.pose_noise_deg,
            init_offset_m=args.init_offset_m,
            init_offset_deg=args.init_offset_deg,
            seed=args.seed,
            image_format=args.format,
            wall=_wall(args),
            departures=departures,
            medium=medium,
            declare_surroundings=args.declare_surroundings,
            dark_frames=args.dark_frames,
            declare_wall_mesh=args.declare_wall_mesh,
            albedo_map=args.declare_albedo_map,
            channels=channels,
            declare_port=args.declare_port,
            declare_light_port=args.declare_light_port,
        )
    )

    def progress(line: str) -> None:
        print(f"lightcal synth: {line}", file=sys.stderr, flush=True)

    from pathlib import Path

    from lightcal.cli.progress import ensure_kernels
    from lightcal.synthetic.dataset_files import check_target

    check_target(Path(args.out_dir), force=args.force)  # before compiling and rendering
    ensure_kernels(quiet=args.quiet)
    try:
        dataset = build(
            lambda: write_dataset(
                args.out_dir, config, force=args.force, progress=None if args.quiet else progress
            )
        )
    except MemoryError:
        raise InputError(
            "--width/--height",
            f"not enough memory to render {args.views} images of {args.width} x {args.height} "
            "pixels; expected smaller images",
        ) from None
    print(
        f"wrote {len(dataset.image_paths)} images, {dataset.project_path} and {dataset.truth_path}"
    )
    return 0
