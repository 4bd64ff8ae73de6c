"""A calibrated light in words: one unit per quantity, each with its 1-sigma.

What `lightcal calibrate` prints and the report's summary writes (the app's Result tab
shows the same quantities in a table): the position in millimetres in the camera frame
(x right, y down, z forward), the axis by the paper's roll and pitch in degrees with its
angle from the optical axis, and the scale; the medium's attenuation when there is one.
"""

from __future__ import annotations

import math

from lightcal.pipeline.results import LightResult


def sigma_text(s: float, factor: float = 1.0) -> str:
    """A 1-sigma with two significant digits, or "undetermined" (NaN: the data do not
    determine it; never "0")."""
    return f"{s * factor:.2g}" if math.isfinite(s) else "undetermined"


def position_text(light: LightResult) -> str:
    """ "+101.97 ± 0.25, -13.72 ± 0.25, +18.41 ± 0.43 mm" (camera frame)."""
    values = zip(light.pose.t_camera_light, light.sigma.t_camera_light, strict=True)
    return ", ".join(f"{v * 1e3:+.2f} ± {sigma_text(s, 1e3)}" for v, s in values) + " mm"


def axis_text(light: LightResult) -> str:
    """ "roll -3.988 ± 0.014 deg, pitch -5.992 ± 0.016 deg (7.194 ± 0.02 deg from the
    optical axis)"; empty for an isotropic light (it has no axis)."""
    if light.pose_kind == "isotropic":
        return ""
    pose, sigma = light.pose, light.sigma
    return (
        f"roll {pose.roll_deg:+.3f} ± {sigma_text(sigma.roll_deg)} deg, "
        f"pitch {pose.pitch_deg:+.3f} ± {sigma_text(sigma.pitch_deg)} deg "
        f"({pose.axis_angle_from_optical_axis_deg:.3f} ± "
        f"{sigma_text(sigma.axis_angle_from_optical_axis_deg)} deg from the optical axis)"
    )


def light_lines(light: LightResult) -> list[str]:
    """The light's name, position, axis and scale, one line each (no axis line for an
    isotropic light)."""
    lines = [
        f"{light.name} ({light.pose_kind}):",
        f"  position {position_text(light)} (camera frame)",
    ]
    axis = axis_text(light)
    if axis:
        lines.append(f"  axis     {axis}")
    lines.append(f"  scale    {light.scale:.6g} ± {sigma_text(light.scale_sigma)}")
    return lines


def medium_text(medium: dict) -> str | None:
    """The medium in words ("medium: attenuation 0.301 ± 0.004 /m (estimated), backscatter
    0.5 /m (given, g 0.9)"), or None in air with nothing estimated."""
    estimated = medium.get("estimated", [])
    parts = []
    for name, label in (("attenuation_per_m", "attenuation"), ("backscatter_per_m", "backscatter")):
        v = float(medium.get(name, 0.0))
        if v == 0.0 and name not in estimated:
            continue
        s = medium.get("sigma", {}).get(name)
        sigma = f" ± {sigma_text(math.nan if s is None else s)}" if name in estimated else ""
        how = "estimated" if name in estimated else "given"
        if name == "backscatter_per_m":
            g = float(medium.get("phase_g", 0.9))
            s_g = medium.get("sigma", {}).get("phase_g")
            if "phase_g" in estimated:
                how += f", g {g:.3g} ± {sigma_text(math.nan if s_g is None else s_g)} estimated"
            else:
                how += f", g {g:.3g}"
        parts.append(f"{label} {v:.4g}{sigma} /m ({how})")
    return "medium: " + ", ".join(parts) if parts else None


def channel_lines(channels: list[dict] | None) -> list[str]:
    """A line per channel: its lights' scales (+- 1 sigma), its medium and room light."""
    lines = []
    for ch in channels or []:
        parts = [
            f"{light} scale {s:.6g} ± {sigma_text(ch['scale_sigmas'].get(light) or math.nan)}"
            for light, s in ch["scales"].items()
        ]
        medium = medium_text(ch["medium"])
        if medium is not None:
            parts.append(medium)
        if ch["ambient"] is not None:
            sigma = sigma_text(math.nan if ch["ambient_sigma"] is None else ch["ambient_sigma"])
            parts.append(f"room light {ch['ambient']:.4g} ± {sigma}")
        lines.append(f"channel {ch['name']}: " + "; ".join(parts))
    return lines


def surroundings_text(surroundings: dict) -> str:
    """The surroundings' estimated albedos in words ("surroundings: surfaces[0] albedo
    0.79 ± 0.01 (estimated)")."""
    parts = []
    for k in surroundings["estimated"]:
        sigma = surroundings["sigma"].get(str(k))
        spread = sigma_text(math.nan if sigma is None else sigma)
        parts.append(f"surfaces[{k}] albedo {surroundings['albedos'][k]:.3g} ± {spread}")
    return "surroundings: " + ", ".join(parts) + " (estimated)"
