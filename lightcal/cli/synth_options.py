"""The options of `lightcal synth` that make data depart from their project (issue 24,
`lightcal.synthetic.departures`), `--declare-medium`, and the configuration errors
renamed after the options that set the fields (`build`).

Cheap imports only: `lightcal --help` builds the parser from here.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeVar

from lightcal.errors import InputError

if TYPE_CHECKING:
    from lightcal.io.medium_spec import MediumSpec
    from lightcal.synthetic.departures import Departures

T = TypeVar("T")

MAX_POSE_MM = 100.0
"""Largest --pose-noise-mm and --pose-error-mm."""

# Configuration fields -> the options that set them, for error messages.
OPTIONS = {
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
    "size": "--width/--height",
    "fx": "--fx",
    "fy": "--fy",
    "cx": "--cx",
    "cy": "--cy",
    "roughness": "--roughness",
    "ior": "--ior",
    "albedo": "--albedo",
    "sigma_deg": "--sigma-deg",
    "wall": "--wall",
    "dist": "--distortion",
    "width": "--width",
    "height": "--height",
    "ambient_fraction": "--ambient",
    "undeclared_vignetting": "--undeclared-vignetting",
    "rid_rim_amplitude": "--rid-rim",
    "gamma": "--gamma",
    "pose_error_m": "--pose-error-mm",
    "pose_error_deg": "--pose-error-deg",
    "bow_m": "--bow-mm",
    "albedo_texture_amplitude": "--albedo-texture",
    "attenuation_per_m": "--attenuation",
    "backscatter_per_m": "--backscatter",
    "phase_g": "--phase-g",
    "colour": "--colour",
    "albedo_map": "--declare-albedo-map",
    "medium": "--declare-medium",
    "dark_frames": "--dark-frames",
    "declare_wall_mesh": "--declare-wall-mesh",
    "corner": "--corner",
    "declare_surroundings": "--declare-surroundings",
    "port": "--port",
    "declare_port": "--declare-port",
    "light_port": "--light-port",
    "declare_light_port": "--declare-light-port",
}


def build(make: Callable[[], T]) -> T:
    """`make()`, with configuration errors renamed after the command-line option."""
    try:
        return make()
    except InputError as exc:
        raise InputError(OPTIONS.get(exc.source, exc.source), exc.detail) from exc


def register_departures(p: argparse.ArgumentParser) -> None:
    """The departures' options and `--declare-medium`."""
    g = p.add_argument_group(
        "departures",
        "data that departs from what project.json declares, recorded in truth.json under "
        '"departures" (none by default)',
    )
    g.add_argument(
        "--ambient",
        type=float,
        default=0.0,
        metavar="FRACTION",
        help="room light: add FRACTION x the brightest beam value of the median image to "
        "every pixel, scaled by each image's exposure; the project estimates no offset (0)",
    )
    g.add_argument(
        "--undeclared-vignetting",
        type=float,
        nargs=2,
        default=None,
        metavar=("K1", "K2"),
        help="the images carry the fall-off V = 1 + K1 r^2 + K2 r^4 (as --vignetting) "
        "while the project declares --sensor radiance (none)",
    )
    g.add_argument(
        "--rid-rim",
        type=float,
        default=0.0,
        metavar="AMPLITUDE",
        help="the light's true profile has a bright rim: the declared one x (1 + AMPLITUDE "
        "exp(-((theta - theta_half) / w)^2)), w = 0.15 theta_half; the project gets the "
        "plain profile (0)",
    )
    g.add_argument(
        "--gamma",
        type=float,
        default=1.0,
        metavar="G",
        help="tone curve: the stored value above black is W (x / W)^(1/G), x the linear "
        "value, W = white - black; the project declares linear data (1)",
    )
    g.add_argument(
        "--pose-error-mm",
        type=float,
        default=0.0,
        metavar="MM",
        help="extra camera centre error sigma beyond --pose-noise-mm, whose covariance the "
        "project still declares (0)",
    )
    g.add_argument(
        "--pose-error-deg",
        type=float,
        default=0.0,
        metavar="DEG",
        help="extra camera rotation error sigma beyond --pose-noise-deg (0)",
    )
    g.add_argument(
        "--bow-mm",
        type=float,
        default=0.0,
        metavar="MM",
        help="the wall is not flat: z = MM/1000 max(0, 1 - r^2 / (1 m)^2), r from where the "
        "views look; MM > 0 bulges towards the cameras, < 0 a bowl; |MM| <= 100 (0)",
    )
    g.add_argument(
        "--declare-wall-mesh",
        action="store_true",
        help="with --bow-mm: also write the bowed wall as a triangle mesh (wall_mesh.ply, "
        "2 cm triangles) and declare it in the project (wall.mesh)",
    )
    g.add_argument(
        "--albedo-texture",
        type=float,
        default=0.0,
        metavar="AMPLITUDE",
        help="the wall's albedo is 1 + AMPLITUDE t(x, y), t a smooth random field in "
        "[-1, 1] with 10-30 cm features; 0 <= AMPLITUDE < 1 (0)",
    )
    g.add_argument(
        "--attenuation",
        type=float,
        nargs="+",
        default=None,
        metavar="C",
        help="a medium (clear water): each value x exp(-C (d_light + d_camera)), C in 1/m; "
        "three values C_R C_G C_B (or three --backscatter values) make a colour dataset: "
        "3-channel 16-bit images, each channel in its own water (0)",
    )
    g.add_argument(
        "--backscatter",
        type=float,
        nargs="+",
        default=None,
        metavar="BETA",
        help="the water scatters the beam back: each pixel gains BETA x the single-"
        "scattering integral along its ray (attenuated by --attenuation), BETA in 1/m; "
        "three values: one per colour channel (R G B); --sensor radiance only (0)",
    )
    g.add_argument(
        "--colour",
        type=float,
        nargs=3,
        default=None,
        metavar=("R", "G", "B"),
        help="a colour dataset's wall-times-light colour: each channel's light scale, "
        "relative (the brightest channel at --exposure-target); values > 0 (1 1 1)",
    )
    g.add_argument(
        "--phase-g",
        type=float,
        default=0.9,
        metavar="G",
        help="the Henyey-Greenstein asymmetry of --backscatter's scattering (0.9)",
    )
    g.add_argument(
        "--declare-medium",
        choices=("given", "estimated"),
        default=None,
        help="the project declares the water of --attenuation and --backscatter: given "
        "(their true values) or estimated (from 0, with the light; --phase-g given); a "
        "colour dataset's project solves its channels jointly (sensor.channels, the medium "
        "per channel, estimated from c = 0.2 and beta = 0.5 /m); truth.json still records "
        "them (none)",
    )
    g.add_argument(
        "--declare-albedo-map",
        action="store_true",
        help="the project estimates the wall's albedo map (wall.albedo_map) on a dense "
        "selection (strategy all, binned to about 9600 pixels an image): for "
        "--albedo-texture",
    )
    g.add_argument(
        "--corner",
        type=float,
        nargs=3,
        default=None,
        metavar=("D", "DEPTH", "ALBEDO"),
        help="inter-reflection: a ceiling and a side wall DEPTH m deep meet the wall at right "
        "angles D m from where the views look, Lambertian of ALBEDO like the wall; their "
        "bounce light (brute force, every bounce) is added, pixels that see them or wall they "
        "shadow are black; --sensor radiance only (none)",
    )
    g.add_argument(
        "--declare-surroundings",
        action="store_true",
        help="the project declares the surfaces of --corner (`surroundings:`, their true "
        "geometry and albedo)",
    )
    g.add_argument(
        "--port",
        type=float,
        nargs=4,
        default=None,
        metavar=("D_MM", "T_MM", "NG", "NW"),
        help="the camera looks through a flat port: its inner face D_MM mm in front of the "
        "centre of projection, T_MM mm of glass of index NG, water of index NW outside "
        "(each pixel's ray refracted, point-sampled; flat wall, Lambertian, no backscatter) "
        "(none)",
    )
    g.add_argument(
        "--declare-port",
        action="store_true",
        help="the project declares --port (camera.port)",
    )
    g.add_argument(
        "--light-port",
        type=float,
        nargs=4,
        default=None,
        metavar=("D_MM", "T_MM", "NG", "NW"),
        help="every light shines through a flat port along its axis: its inner face D_MM mm "
        "in front of the emitter, T_MM mm of glass of index NG, water of index NW outside "
        "(the air direction solved per pixel, the irradiance point-sampled with the "
        "Fresnel transmittance; with --backscatter the refracted beam's veil; flat wall, "
        "Lambertian, no --port) (none)",
    )
    g.add_argument(
        "--declare-light-port",
        action="store_true",
        help="the project declares --light-port (lights[i].port)",
    )
    g.add_argument(
        "--dark-frames",
        action="store_true",
        help="with --ambient: also write a light-off photo of each view (the room light "
        "alone, same exposure, its own noise) as images/view_NN_dark, declared as the "
        "image's dark in the project, which then subtracts it",
    )


def departures_of(args: argparse.Namespace, sensor_model: str) -> Departures:
    """The departures of the options (millimetres checked before they become metres)."""
    from lightcal.synthetic.departures import MAX_BOW_M, Departures

    if not (math.isfinite(args.pose_error_mm) and args.pose_error_mm >= 0.0):
        raise InputError(
            "--pose-error-mm", f"expected a finite value >= 0, got {args.pose_error_mm:g}"
        )
    if args.pose_error_mm > MAX_POSE_MM:
        raise InputError(
            "--pose-error-mm", f"expected at most {MAX_POSE_MM:g} mm, got {args.pose_error_mm:g}"
        )
    limit_mm = MAX_BOW_M * 1000.0
    if not (math.isfinite(args.bow_mm) and abs(args.bow_mm) <= limit_mm):
        raise InputError(
            "--bow-mm", f"expected a value within +-{limit_mm:g} mm, got {args.bow_mm:g}"
        )
    if args.declare_wall_mesh and args.bow_mm == 0.0:
        raise InputError(
            "--declare-wall-mesh",
            "expected a bowed wall to declare (--bow-mm MM, MM != 0): the plane z = 0 needs "
            "no mesh",
        )
    if args.undeclared_vignetting is not None and sensor_model != "radiance":
        raise InputError(
            "--undeclared-vignetting",
            f"applies to --sensor radiance only, got --sensor {sensor_model}",
        )
    if args.rid_rim > 0.0 and args.light == "isotropic":
        raise InputError(
            "--rid-rim", "expected a light with a half-intensity angle, got --light isotropic"
        )
    vignetting = args.undeclared_vignetting
    if args.declare_surroundings and args.corner is None:
        raise InputError(
            "--declare-surroundings", "expected --corner D DEPTH ALBEDO (the surfaces to declare)"
        )
    corner = None if args.corner is None else (args.corner[0], args.corner[1], args.corner[2])
    if args.declare_port and args.port is None:
        raise InputError("--declare-port", "expected --port D_MM T_MM NG NW (the port to declare)")
    port = None if args.port is None else (args.port[0], args.port[1], args.port[2], args.port[3])
    if args.declare_light_port and args.light_port is None:
        raise InputError(
            "--declare-light-port", "expected --light-port D_MM T_MM NG NW (the port to declare)"
        )
    light_port = None if args.light_port is None else tuple(args.light_port)
    return build(
        lambda: Departures(
            ambient_fraction=args.ambient,
            undeclared_vignetting=None if vignetting is None else (vignetting[0], vignetting[1]),
            rid_rim_amplitude=args.rid_rim,
            gamma=args.gamma,
            pose_error_m=args.pose_error_mm / 1000.0,
            pose_error_deg=args.pose_error_deg,
            bow_m=args.bow_mm / 1000.0,
            albedo_texture_amplitude=args.albedo_texture,
            attenuation_per_m=args.attenuation,
            backscatter_per_m=args.backscatter,
            phase_g=args.phase_g,
            corner=corner,
            port=port,
            light_port=light_port,
        )
    )


def declared_medium(args: argparse.Namespace) -> MediumSpec:
    """The project's `medium` of `--declare-medium` (air without it)."""
    from lightcal.io.medium_spec import MediumSpec

    if args.declare_medium is None:
        return MediumSpec()
    g = args.phase_g
    if args.declare_medium == "estimated":
        names: list[Any] = ["attenuation_per_m"]
        if args.backscatter > 0.0:
            names.append("backscatter_per_m")
        return build(lambda: MediumSpec(phase_g=g, estimate=names))
    if not (args.attenuation > 0.0 or args.backscatter > 0.0):
        raise InputError(
            "--declare-medium",
            "given: expected --attenuation C > 0 or --backscatter BETA > 0 (the medium to declare)",
        )
    return build(
        lambda: MediumSpec(
            attenuation_per_m=args.attenuation, backscatter_per_m=args.backscatter, phase_g=g
        )
    )
