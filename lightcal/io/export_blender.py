"""The Blender export: a Python snippet that adds each light to the scene, driven by its RID
through Cycles' IES Texture node, and gives the scene camera the project's intrinsics.

What a Cycles render of the exported scene reproduces (`tests/test_export_blender_render.py`
renders it with a wall in `bpy` and compares with lightcal's `render_image` of the view):

- **The pose**: each light is a child of the camera, `matrix_local = F T_camera_light F`,
  F = diag(1, -1, -1, 1) (`lightcal.core.camera_frames`).
- **The RID**: a point light of radius 0 whose node tree feeds an IES Texture node (the
  IES text embedded in the snippet, a Blender text block) into its Emission strength.
  Cycles' reading of IES data (Blender 5.0, `intern/cycles/util/ies.cpp` and
  `intern/cycles/kernel/svm/ies.h`): the candela values are multiplied by the file's
  multipliers and by `CYCLES_WATTS_PER_CANDELA` = 4 pi / 177.83 (its candela-to-watt
  factor, which the node's Strength `IES_STRENGTH` undoes); the lookup direction is the
  light's outgoing direction in the light object's frame (x, y, z), at vertical angle
  acos(-z) and horizontal angle atan2(x, y) + 180 degrees, which is lightcal's phi - 90
  degrees (the light frame's y and z are Blender's -y and -z), not the C = -phi of
  docs/conventions.md: the embedded table is written in Cycles' angles and is not for
  other tools (`lightcal export --format ies` is). Between the table's angles Cycles
  interpolates with uniform Catmull-Rom splines in the angles' indices (whatever their
  spacing), reflecting the column across the pole at 0 degrees, zero beyond the last
  vertical angle. The table is therefore lightcal's own interpolation of the RID
  (`rid_values`) sampled finely enough (`IES_THETA_STEP_DEG`; `IES_THETA_STEP_2D_DEG` and
  `IES_PHI_STEP_DEG` for a light without rotational symmetry) that Cycles' cubics between
  the samples stay within 1e-4 of it.
- **The scale**: the light's power is 4 pi `scale` W. Cycles gives a point light of power
  P (radius 0) the intensity P / (4 pi) W/sr times its emission strength
  (`intern/cycles/scene/light.cpp`: eval_fac = 1 / (pi area), area 4 for radius 0), so
  the light's intensity is `scale` times the RID, as Mitsuba's intensity, and several
  lights keep their relative brightness. A Lambertian wall of albedo rho renders rho / pi
  times lightcal's `radiance` value.
- **The camera** (given the project's camera): the render's resolution, a horizontal
  sensor fit with lens = fx sensor_width / width, the pixel aspect fy / fx (Blender's
  pixel_aspect_x / pixel_aspect_y, each >= 1) and the principal point as the shift
  shift_x = ((width - 1) / 2 - cx) / width, shift_y = (cy - (height - 1) / 2) fx / (fy
  width) (OpenCV's pixel centres at integers, Blender's at half-integers; both shifts in
  units of the width). No skew and no lens distortion: compare with undistorted images.
- **The medium** (a result calibrated in water, `lightcal.io.export_medium`): `set_water`,
  appended to the snippet, makes it the volume of the scene's world (a new, black world
  if there is none), where Cycles puts the camera, the lights and every ray: a Volume
  Absorption (black) of density c - sigma_s plus a Volume Scatter (white) of density
  sigma_s = beta rho / pi with Henyey-Greenstein anisotropy g, so that the extinction is
  c (densities per Blender unit: one unit a metre, as for the poses). Cycles renders it as
  lightcal does with its Volume bounces 0 (single scattering), the veil included
  (`tests/test_export_blender_render.py`). A result in air appends nothing.

What is left, and what a user's scene must keep: Cycles' spline over the last vertical
interval takes a zero beyond the table, so between 89.75 and 90 degrees it differs from
the RID by up to 0.5 x^2 (1 - x) times the RID at 90 degrees (at most 7 % of that value;
nothing for a RID that is 0 there; a constant table, 1 at 90 degrees, reads up to 14.8 %
high over a coarse table's last interval). A light of radius > 0 (Blender gives a new
light 0.25 m) looks the table up along the normal of the point it samples on its sphere,
which blurs the RID and lowered a constant one by 1.5 % at 2 m: the snippet sets radius 0.
Blender's default pixel filter (Blackman-Harris, 1.5 px) and denoising smooth the beam;
lightcal's pixel is the mean over its square (Cycles' box filter of 1 px).
"""

from __future__ import annotations

import math
import tempfile
import textwrap
from pathlib import Path
from typing import Any

import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.camera_frames import blender_from_opencv, blender_spot_cone
from lightcal.io.escaping import plain_line
from lightcal.io.export_lights import LightRID, light_rid, light_transform, rid_origin
from lightcal.io.export_medium import ExportMedium, export_medium
from lightcal.io.export_mitsuba import rid_values
from lightcal.io.photometric_table import PhotometricTable
from lightcal.io.result_file import LightResultModel, ResultFile

__all__ = [
    "CYCLES_WATTS_PER_CANDELA",
    "IES_PHI_STEP_DEG",
    "IES_STRENGTH",
    "IES_THETA_STEP_2D_DEG",
    "IES_THETA_STEP_DEG",
    "SENSOR_WIDTH_MM",
    "blender_camera_numbers",
    "blender_snippet",
    "blender_water_numbers",
    "cycles_ies_table",
    "cycles_ies_text",
]

CYCLES_WATTS_PER_CANDELA = 4.0 * math.pi / 177.83
"""Cycles' factor from an IES file's candela to its node's output (0.0706650768394 in
`intern/cycles/util/ies.cpp`: 4 pi over D65's luminous efficacy, 177.83 lm/W)."""

IES_STRENGTH = 1.0 / CYCLES_WATTS_PER_CANDELA
"""The IES Texture node's Strength: its output is then the table's value, the relative RID."""

IES_THETA_STEP_DEG = 0.25
"""Vertical angle step of the embedded table of a rotationally symmetric light (from 0 to
90 degrees, or 180 for a RID beyond 90)."""

IES_THETA_STEP_2D_DEG = 0.5
IES_PHI_STEP_DEG = 2.0
"""Vertical and horizontal angle steps of the embedded table of a light without rotational
symmetry (350 kB of text; Cycles' interpolation of it is within 1e-4 of the RID)."""

SENSOR_WIDTH_MM = 36.0
"""The exported camera's sensor width (Blender's default); the lens follows from fx."""


def cycles_ies_table(rid: LightRID, name: str) -> PhotometricTable:
    """The RID as the table the snippet embeds, in Cycles' angles (module docstring).

    Args:
        rid: The light's tabulated RID.
        name: The light's name (the table's luminaire).

    Returns:
        A type C table of the relative RID (1 on the axis) from 0 to 90 degrees (180 when
        the RID's table goes beyond 90), zero beyond the RID's last angle: axially
        symmetric every `IES_THETA_STEP_DEG` for a 1-D RID, else every
        `IES_THETA_STEP_2D_DEG` and every `IES_PHI_STEP_DEG` of Cycles' horizontal angle
        C = phi - 90 degrees.
    """
    end_deg = 90.0 if rid.theta_rad[-1] <= math.pi / 2 + 1e-12 else 180.0
    step = IES_THETA_STEP_DEG if rid.phi_rad is None else IES_THETA_STEP_2D_DEG
    n_theta = round(end_deg / step) + 1
    theta_deg = np.linspace(0.0, end_deg, n_theta)
    theta = np.radians(theta_deg)
    if rid.phi_rad is None:
        values = rid_values(rid, theta, np.zeros_like(theta))[None, :]
        c_deg = np.zeros(1)
    else:
        c_deg = np.arange(0.0, 360.0, IES_PHI_STEP_DEG)
        phi = np.radians(c_deg + 90.0)  # Cycles' C = phi - 90 degrees
        tt, pp = np.meshgrid(theta, phi)
        values = rid_values(rid, tt, pp)
    return PhotometricTable(
        theta_deg,
        c_deg,
        values,
        source=name,
        symmetry="axial" if rid.phi_rad is None else "none",
        luminaire=name,
    )


def cycles_ies_text(table: PhotometricTable, origin: str) -> str:
    """The IES LM-63-2002 text of `table` the snippet embeds (header `[TEST]` `origin`)."""
    from lightcal.io.ies import write_ies

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "light.ies"
        keywords = {"TEST": origin, "OTHER": "Cycles' angles: C = phi - 90 degrees (lightcal)"}
        write_ies(path, table, keywords=keywords, digits=7)
        return path.read_text()


def blender_camera_numbers(camera: Camera) -> dict[str, float | int]:
    """The Blender camera and render settings for `camera` (see the module docstring)."""
    fx, fy = float(camera.K[0, 0]), float(camera.K[1, 1])
    width, height = int(camera.width), int(camera.height)
    return {
        "width": width,
        "height": height,
        "sensor_width_mm": SENSOR_WIDTH_MM,
        "lens_mm": fx * SENSOR_WIDTH_MM / width,
        "shift_x": ((width - 1) / 2 - float(camera.K[0, 2])) / width,
        "shift_y": (float(camera.K[1, 2]) - (height - 1) / 2) * fx / (fy * width),
        "pixel_aspect_x": max(fy / fx, 1.0),
        "pixel_aspect_y": max(fx / fy, 1.0),
    }


def _light_spec(light: LightResultModel, source: str | Path) -> dict[str, Any]:
    rid = light_rid(light, source)
    kind = "SPOT" if light.pose_kind != "isotropic" and rid is None else "POINT"
    spec: dict[str, Any] = {"name": light.name, "type": kind}
    M = blender_from_opencv(light_transform(light))
    spec["matrix_blendercam_light"] = tuple(tuple(float(v) for v in row) for row in M)
    spec["power_w"] = 4.0 * math.pi * float(light.scale)
    if kind == "SPOT":  # no RID known: a 180 degree cone
        spec["spot_size"], spec["spot_blend"] = blender_spot_cone(math.pi / 2)
    if light.pose_kind != "isotropic" and rid is not None:
        spec["ies"] = cycles_ies_text(cycles_ies_table(rid, light.name), rid_origin(light))
    return spec


def _camera_note(camera: Camera | None) -> str:
    if camera is None:
        return (
            "No project was given: the scene camera keeps its settings (give the export the\n"
            "project for its camera's)."
        )
    fx, fy = float(camera.K[0, 0]), float(camera.K[1, 1])
    dist = [float(c) for c in camera.dist[: camera.n_dist]]
    distortion = (
        "none" if not any(dist) else ", ".join(f"{c:.6g}" for c in dist) + " (NOT modelled)"
    )
    return (
        f"The project's camera: {camera.width} x {camera.height} px, fx {fx:.6g} px, fy "
        f"{fy:.6g} px, principal point ({float(camera.K[0, 2]):.6g}, "
        f"{float(camera.K[1, 2]):.6g}) px\n"
        "(OpenCV: pixel centres at integers) as Blender's lens, pixel aspect and shift.\n"
        f"Blender's camera has no skew (here {camera.skew:.3g}) and no lens distortion:\n"
        f"distortion {distortion}. Compare its renders with undistorted images."
    )


# The world's volume: appended to the snippet of a result in water (nothing in air).
_WATER_CODE = """

WATER = {water}


def set_water(scene, numbers=WATER):
    \"\"\"The calibration's medium as the world's volume (see the docstring at the top).\"\"\"
    world = scene.world
    made = world is None
    if made:  # a black world, as none is: the water only
        world = bpy.data.worlds.new("lightcal water")
        scene.world = world
    if world.node_tree is None:  # Blender < 5 (World.use_nodes goes in Blender 6)
        world.use_nodes = True
    tree = world.node_tree
    if made:
        tree.nodes.clear()
    output = next((node for node in tree.nodes if node.type == "OUTPUT_WORLD"), None)
    if output is None:
        output = tree.nodes.new("ShaderNodeOutputWorld")
    absorption = tree.nodes.new("ShaderNodeVolumeAbsorption")
    absorption.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    absorption.inputs["Density"].default_value = numbers["absorption_per_m"]
    scatter = tree.nodes.new("ShaderNodeVolumeScatter")
    if hasattr(scatter, "phase"):  # Blender 4.3 and later
        scatter.phase = "HENYEY_GREENSTEIN"
    scatter.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    scatter.inputs["Density"].default_value = numbers["scattering_per_m"]
    scatter.inputs["Anisotropy"].default_value = numbers["phase_g"]
    both = tree.nodes.new("ShaderNodeAddShader")
    tree.links.new(absorption.outputs["Volume"], both.inputs[0])
    tree.links.new(scatter.outputs["Volume"], both.inputs[1])
    tree.links.new(both.outputs["Shader"], output.inputs["Volume"])
    return world


set_water(bpy.context.scene)
"""


def blender_water_numbers(medium: ExportMedium, wall_albedo: float | None) -> dict[str, float]:
    """The world volume's densities (1/m: one Blender unit a metre) and anisotropy:
    Volume Absorption (black) of c - sigma_s plus Volume Scatter (white) of sigma_s, so
    that the extinction is c (`lightcal.io.export_medium` for sigma_s)."""
    sigma_s = medium.scattering_per_m(wall_albedo)
    return {
        "attenuation_per_m": medium.attenuation_per_m,
        "absorption_per_m": medium.attenuation_per_m - sigma_s,
        "scattering_per_m": sigma_s,
        "phase_g": medium.phase_g,
    }


def _water_note(medium: ExportMedium, numbers: dict[str, float], wall_albedo: float | None) -> str:
    if medium.scatters:
        how = (
            f"sigma_s = beta rho / pi = {numbers['scattering_per_m']!r} /m with the wall's "
            f"albedo rho = {wall_albedo!r}: give the wall that albedo (a wall of albedo rho "
            "renders rho / pi times lightcal's value and the veil sigma_s / beta times it)."
        )
    else:
        how = "no scattering (backscatter_per_m 0): a purely absorbing medium."
    text = (
        f"The calibration's medium: {medium.text()}. set_water makes it the volume of the "
        "scene's world (a new, black world if the scene has none), which Cycles puts the "
        "camera, the lights and every ray in: a Volume Absorption of density c - sigma_s "
        "(black) plus a Volume Scatter of density sigma_s (white, Henyey-Greenstein "
        "anisotropy g), so that the extinction is c; densities per Blender unit, one unit a "
        "metre (unit scale 1, as the lights' positions are). The backscatter beta = sigma_s "
        f"pi / rho is relative to the wall's albedo rho: {how} lightcal's model is single "
        "scattering: Cycles' Volume bounces 0 (its default), the volume's direct light only. "
        "A Cycles render of it matches lightcal's in water, veil included "
        "(tests/test_export_blender_render.py); EEVEE renders no world volume. Not "
        "modelled: refraction at the camera's and the light's ports."
    )
    return "\n\n" + "\n".join(textwrap.wrap(text, 88))


def blender_snippet(
    result: ResultFile,
    source: str | Path,
    template: str,
    *,
    camera: Camera | None,
    wall_albedo: float | None = None,
) -> bytes:
    """The snippet's text: `template` with the version, camera and lights filled in, and
    in water the world's volume (`_WATER_CODE`) after it.

    Args:
        result: The result (with the project's given RIDs filled in).
        source: The result's path, for error messages.
        template: The snippet's code with `{version}`, `{camera_note}`, `{camera}`,
            `{ies_strength}` and `{lights}` to fill.
        camera: The project's camera, or None.
        wall_albedo: rho, for the scattering coefficient of a medium that scatters.

    Raises:
        InputError: the medium scatters and `wall_albedo` is None, or its sigma_s > c.
    """
    medium = export_medium(result, source)
    water = None if medium is None else blender_water_numbers(medium, wall_albedo)
    specs = [_light_spec(light, source) for light in result.lights]
    lights = "[\n" + "".join(f"    {spec!r},\n" for spec in specs) + "]"
    numbers = None if camera is None else blender_camera_numbers(camera)
    note = _camera_note(camera)
    if medium is not None and water is not None:
        note += _water_note(medium, water, wall_albedo)
    text = template.format(
        version=repr(plain_line(result.lightcal_version)),
        camera_note=note,
        camera=repr(numbers),
        ies_strength=repr(IES_STRENGTH),
        lights=lights,
    )
    if water is not None:
        text += _WATER_CODE.format(water=repr(water))
    return text.encode()
