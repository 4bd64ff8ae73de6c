"""`lightcal synth`: write a synthetic calibration dataset with known ground truth.

Renders images of a flat wall lit by a rig of lights from a seeded random set of camera
poses, adds sensor noise, and writes the images, the camera file, the light's profile file,
a ready-to-run project (measured poses with pose noise, an initial guess that is off) and
truth.json (see `lightcal.synthetic.dataset`). One progress line per image goes to stderr.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING, TypeVar

from lightcal.errors import InputError
from lightcal.synthetic.light_models import LIGHT_MODELS

if TYPE_CHECKING:
    from lightcal.core.wall import WallReflectance

T = TypeVar("T")

DEFAULT_VIGNETTING = (-0.25, 0.05)
"""Radial fall-off of `--sensor map` without `--vignetting`: V = 0.8 in the corners."""

# Configuration fields -> the options that set them, for error messages.
_OPTIONS = {
    "n_views": "--views",
    "distance_range_m": "--distance",
    "tilt_range_deg": "--tilt-deg",
    "roll_range_deg": "--roll-deg",
    "n_lights": "--lights",
    "model": "--light",
    "half_angle_deg": "--half-angle-deg",
    "radius_range_m": "--light-radius-m",
    "bit_depth": "--bit-depth",
    "full_well_e": "--full-well-e",
    "read_noise_e": "--read-noise-e",
    "black_level_dn": "--black-level",
    "exposure_target": "--exposure-target",
    "vignetting_coeffs": "--vignetting",
    "pose_noise_m": "--pose-noise-mm",
    "pose_noise_deg": "--pose-noise-deg",
    "init_offset_m": "--init-offset-m",
    "init_offset_deg": "--init-offset-deg",
    "seed": "--seed",
    "K": "--fx/--fy/--cx/--cy",
    "dist": "--distortion",
    "width": "--width",
    "height": "--height",
}


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
    g.add_argument("--roughness", type=float, default=0.3, help="plastic: GGX alpha (0.3)")
    g.add_argument("--ior", type=float, default=1.5, help="plastic: coat index of refraction (1.5)")
    g.add_argument(
        "--albedo", type=float, default=0.8, help="plastic: diffuse albedo of the base (0.8)"
    )
    g.add_argument("--sigma-deg", type=float, default=20.0, help="oren_nayar: roughness (20)")
    g = p.add_argument_group("measurement error")
    g.add_argument(
        "--pose-noise-mm", type=float, default=0.5, help="camera centre error sigma (0.5)"
    )
    g.add_argument(
        "--pose-noise-deg", type=float, default=0.05, help="camera rotation error sigma (0.05)"
    )
    g = p.add_argument_group("output")
    g.add_argument("--format", choices=("png", "tiff"), default="png", help="image files (png)")
    g.add_argument("--seed", type=int, default=0, help="random seed (0)")
    g.add_argument("--force", action="store_true", help="replace the dataset in OUT_DIR")
    g.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=run)


def _build(make: Callable[[], T]) -> T:
    """`make()`, with configuration errors renamed after the command-line option."""
    try:
        return make()
    except InputError as exc:
        raise InputError(_OPTIONS.get(exc.source, exc.source), exc.detail) from exc


def _wall(args: argparse.Namespace) -> WallReflectance:
    """The true wall of --wall and its options."""
    from lightcal.core.wall import LAMBERTIAN, OrenNayarWall, PlasticWall

    try:
        if args.wall == "plastic":
            return PlasticWall.from_albedo(args.roughness, args.ior, args.albedo)
        if args.wall == "oren_nayar":
            return OrenNayarWall(math.radians(args.sigma_deg))
    except ValueError as exc:
        raise InputError("--wall", str(exc)) from exc
    return LAMBERTIAN


def run(args: argparse.Namespace) -> int:
    from lightcal.core.camera import Camera
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
    if args.width <= 0 or args.height <= 0:
        raise InputError("--width/--height", f"expected > 0, got {args.width} x {args.height}")
    if not args.pose_noise_mm >= 0.0:
        raise InputError("--pose-noise-mm", f"expected a value >= 0, got {args.pose_noise_mm:g}")
    fx = 0.9 * args.width if args.fx is None else args.fx
    camera = _build(
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
    scene = _build(
        lambda: SceneConfig(
            n_views=args.views,
            distance_range_m=(args.distance[0], args.distance[1]),
            tilt_range_deg=(0.0, args.tilt_deg),
            roll_range_deg=(-abs(args.roll_deg), abs(args.roll_deg)),
        )
    )
    rig = _build(
        lambda: RigConfig(
            n_lights=args.lights,
            model=args.light,
            half_angle_deg=args.half_angle_deg,
            radius_range_m=(args.light_radius_m[0], args.light_radius_m[1]),
        )
    )
    sensor = _build(
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
    config = _build(
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
        )
    )

    def progress(line: str) -> None:
        print(f"lightcal synth: {line}", file=sys.stderr, flush=True)

    from lightcal.cli.progress import ensure_kernels

    ensure_kernels(quiet=args.quiet)
    dataset = _build(
        lambda: write_dataset(
            args.out_dir, config, force=args.force, progress=None if args.quiet else progress
        )
    )
    print(
        f"wrote {len(dataset.image_paths)} images, {dataset.project_path} and {dataset.truth_path}"
    )
    return 0
