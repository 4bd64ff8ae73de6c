"""The departure options of `lightcal synth` (`lightcal.cli.synth` documents them), and
`--dark-frames`: a light-off photo per view when the room light is on."""

from __future__ import annotations

import argparse

__all__ = ["register_departures"]


def register_departures(p: argparse.ArgumentParser) -> None:
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
        default=0.0,
        metavar="C",
        help="a medium (clear water): each value x exp(-C (d_light + d_camera)), C in 1/m (0)",
    )
    g.add_argument(
        "--dark-frames",
        action="store_true",
        help="with --ambient: also write a light-off photo of each view (the room light "
        "alone, same exposure, its own noise) as images/view_NN_dark, declared as the "
        "image's dark in the project, which then subtracts it",
    )
