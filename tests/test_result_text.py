"""A calibrated light in words: millimetres and degrees, each with its 1-sigma."""

from __future__ import annotations

import numpy as np

from lightcal.core.pose import rotation_from_axis
from lightcal.pipeline.result_text import axis_text, light_lines, position_text
from lightcal.pipeline.results import LightResult, PoseSummary


def _light(kind: str) -> LightResult:
    axis = np.array([0.1, 0.0, 1.0]) / np.hypot(0.1, 1.0)
    pose = PoseSummary.of_pose(rotation_from_axis(axis), np.array([0.10197, -0.01372, 0.01841]))
    sigma = PoseSummary(
        t_camera_light=np.array([0.00025, 0.00025, 0.00043]),
        R_camera_light=np.zeros((3, 3)),
        quaternion_wxyz=np.zeros(4),
        axis_camera=np.zeros(3),
        roll_deg=0.014,
        pitch_deg=0.016,
        axis_angle_from_optical_axis_deg=0.02,
    )
    return LightResult("led", pose, sigma, 9902.51, 4.0, kind, None)


def test_position_in_millimetres_with_sigma() -> None:
    assert position_text(_light("symmetric")) == ("+101.97 ± 0.25, -13.72 ± 0.25, +18.41 ± 0.43 mm")


def test_axis_by_roll_and_pitch_with_sigma_and_its_angle_from_the_optical_axis() -> None:
    light = _light("symmetric")
    tilt = np.degrees(np.arctan(0.1))  # 5.711 deg from +z
    text = axis_text(light)
    roll, pitch = light.pose.roll_deg, light.pose.pitch_deg
    assert text.startswith(f"roll {roll:+.3f} ± 0.014 deg, pitch {pitch:+.3f} ± 0.016 deg")
    assert text.endswith(f"({tilt:.3f} ± 0.02 deg from the optical axis)")


def test_an_isotropic_light_has_no_axis_line() -> None:
    assert axis_text(_light("isotropic")) == ""
    assert light_lines(_light("isotropic")) == [
        "led (isotropic):",
        "  position +101.97 ± 0.25, -13.72 ± 0.25, +18.41 ± 0.43 mm (camera frame)",
        "  scale    9902.51 ± 4",
    ]
    assert len(light_lines(_light("general"))) == 4


def test_the_medium_in_words_with_its_phase_estimated_or_given() -> None:
    from lightcal.pipeline.result_text import medium_text

    air = {"attenuation_per_m": 0.0, "backscatter_per_m": 0.0, "phase_g": 0.9, "estimated": []}
    assert medium_text(air) is None
    water = {
        "attenuation_per_m": 0.301,
        "backscatter_per_m": 0.5,
        "phase_g": 0.82,
        "estimated": ["attenuation_per_m", "backscatter_per_m", "phase_g"],
        "sigma": {"attenuation_per_m": 0.004, "backscatter_per_m": 0.01, "phase_g": 0.03},
    }
    assert medium_text(water) == (
        "medium: attenuation 0.301 ± 0.004 /m (estimated), backscatter 0.5 ± 0.01 /m "
        "(estimated, g 0.82 ± 0.03 estimated)"
    )
    given = {**water, "estimated": [], "sigma": {}}
    assert medium_text(given) == (
        "medium: attenuation 0.301 /m (given), backscatter 0.5 /m (given, g 0.82)"
    )
