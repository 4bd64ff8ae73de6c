"""The Mitsuba 3 export: a scene XML with a sensor and a spot (point) emitter per light,
the RID as a texture beside it (see `lightcal.io.export`).

What a Mitsuba render of the exported scene reproduces (`tests/test_export_mitsuba_render.py`
renders it with a wall and compares with lightcal's `render_image` of the same view):

- **The sensor** (given the project's camera): the film's width and height, the field of
  view along y from fy (fov = 2 atan(height / (2 fy))), and the principal point as
  Mitsuba's `principal_point_offset_x/y` (fractions of the film's size, from its
  centre). Mitsuba's `perspective` has one focal length (fx is taken as fy), no skew and
  no lens distortion: compare with undistorted images (the XML's comment says the
  numbers). Pixel centres: OpenCV's at integers, Mitsuba's at half-integers, which the
  offset accounts for. A box pixel filter, so a pixel is the mean over its square, as
  lightcal's footprint is.
- **The light's scale**: the emitter's intensity is the result's `scale` (times the RID
  texture's peak when that is off the axis), so several lights keep their relative
  brightness. A Lambertian wall of albedo rho then renders rho / pi times lightcal's
  `radiance` value.
- **The RID**: a 16-bit PNG over the spot's cone, evaluated with lightcal's own table
  interpolation (`SymmetricTableRID` / `Table2DRID` of the result's samples) and sized so
  that Mitsuba's bilinear lookup stays within `TEXTURE_STEP_DEG` of the axis
  (`texture_size`).
- **The medium** (a result calibrated in water, `lightcal.io.export_medium`): a
  `homogeneous` medium that the sensor and every emitter reference, so that the camera's
  rays, the wall's shadow rays and the emitters are all in it, sigma_t = c, albedo
  sigma_s / c with sigma_s = beta rho / pi (0 without backscatter), a Henyey-Greenstein
  phase of g, and the `volpath` integrator with `max_depth` a parameter of the file
  default -1; `max_depth=2` is lightcal's single scattering). A result in air writes
  none of it: the scene is byte for byte what it was.
- **The camera's flat port** (`port`, the project's `camera.port`,
  `lightcal.io.export_port`): its two faces as dielectric rectangles in front of the
  sensor, which then sits in the housing's air (the medium, if any, is the outer face's
  interior and the emitters'); a `path` integrator (`volpath` in water) with `max_depth`
  a parameter of the file, since `direct` does not follow a ray through a dielectric.
- **The lights' flat ports** (`light_ports`, the project's `lights[i].port`,
  `lightcal.io.export_light_port`): each ported light's two faces as dielectric
  disks in front of its emitter, and Mitsuba's particle tracer (`ptracer`); refused
  in water and with a camera port (`ptracer` has no media; its connection to the sensor
  is a shadow ray the camera's port would block).
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from lightcal.core.camera import Camera
from lightcal.core.camera_frames import (
    mitsuba_from_opencv,
    mitsuba_spot_cone,
)
from lightcal.core.flat_port import FlatPort
from lightcal.core.rid import RID, SymmetricTableRID, Table2DRID
from lightcal.errors import InputError
from lightcal.io.escaping import xml_attribute, xml_comment
from lightcal.io.export_light_port import (
    MITSUBA_CAMERA_PORT_REFUSAL,
    MITSUBA_WATER_REFUSAL,
    LightPort,
    mitsuba_light_port_lines,
    ptracer_lines,
)
from lightcal.io.export_lights import LightRID, light_rid, light_transform
from lightcal.io.export_medium import ExportMedium, export_medium
from lightcal.io.export_port import mitsuba_port_lines
from lightcal.io.result_file import ResultFile

__all__ = [
    "TEXTURE_MAX_SIZE",
    "TEXTURE_MIN_SIZE",
    "TEXTURE_STEP_DEG",
    "medium_id",
    "mitsuba_files",
    "rid_values",
    "sensor_numbers",
    "spot_texture",
    "texture_size",
]


def _matrix_attribute(M: NDArray[np.float64]) -> str:
    """A Mitsuba `<matrix value=...>`: 16 numbers, row-major, shortest exact text."""
    return " ".join(repr(float(v)) for v in M.ravel())


TEXTURE_STEP_DEG = 0.4
"""Largest angle between neighbouring texture pixels on the light's axis (where the
tangent-plane projection is coarsest), within `TEXTURE_MIN_SIZE..TEXTURE_MAX_SIZE`."""

TEXTURE_MIN_SIZE = 512
TEXTURE_MAX_SIZE = 4096
"""Pixels per side of a Mitsuba spot's RID texture: the bounds of `texture_size`."""

_TEXTURE_CUTOFF_LEVEL = 1e-3
"""The texture's cone ends where the RID stays below this (or where its table ends)."""

_TEXTURE_MAX_CUTOFF_DEG = 80.0
"""Widest texture cone: the texture is a tangent-plane projection (tan of the angle)."""

NEAR_CLIP_M = 1e-5
"""The sensor's near clip in water: Mitsuba starts a camera ray there, so the default
1 cm would leave the ray's first centimetre out of the medium (3e-3 of the value at
c = 0.3 /m)."""

SAMPLES_PER_PIXEL = 16
"""The exported sensor's `multijitter` samples per pixel (a delta light: only the pixel's
area is sampled)."""


def _table_rid(rid: LightRID) -> RID:
    """The result's RID samples as lightcal interpolates a table (PCHIP in theta)."""
    if rid.phi_rad is None:
        return SymmetricTableRID(rid.theta_rad, np.clip(rid.values, 0.0, None))
    return Table2DRID(rid.theta_rad, rid.phi_rad, np.clip(rid.values, 0.0, None))


def rid_values(rid: LightRID, theta_rad: NDArray, phi_rad: NDArray) -> NDArray[np.float64]:
    """The tabulated RID at directions (any shape), 0 beyond its last angle.

    Interpolated as lightcal renders a table RID (its knots' PCHIP in theta, Catmull-Rom
    in phi: `RID.value_and_derivatives(exact=True)`), relative to the axis (f(0) = 1).

    Args:
        rid: The table.
        theta_rad: angles from the light axis, radians.
        phi_rad: azimuths in the light frame (from +x towards +y), radians; same shape.
    """
    theta = np.asarray(theta_rad, dtype=np.float64)
    phi = np.asarray(phi_rad, dtype=np.float64)
    values = _table_rid(rid).value_and_derivatives(theta, phi, exact=True)[0]
    return np.clip(np.asarray(values, dtype=np.float64), 0.0, None).reshape(theta.shape)


def _cutoff_rad(rid: LightRID) -> float:
    level = rid.values if rid.phi_rad is None else rid.values.max(axis=0)
    level = level / (level[0] if rid.phi_rad is None else rid.values[:, 0].mean())
    above = np.nonzero(level >= _TEXTURE_CUTOFF_LEVEL)[0]
    last = min(int(above[-1]) + 1, rid.theta_rad.size - 1) if above.size else 1
    return min(float(rid.theta_rad[last]), math.radians(_TEXTURE_MAX_CUTOFF_DEG))


def texture_size(cutoff_rad: float) -> int:
    """Pixels per side for a cone of half angle `cutoff_rad`: a power of two whose pixels
    on the axis are at most `TEXTURE_STEP_DEG` apart, within the size bounds."""
    needed = 2.0 * math.tan(cutoff_rad) / math.radians(TEXTURE_STEP_DEG)
    size = 2 ** math.ceil(math.log2(max(needed, 1.0)))
    return int(min(max(size, TEXTURE_MIN_SIZE), TEXTURE_MAX_SIZE))


def spot_texture(rid: LightRID, size: int | None = None) -> tuple[float, NDArray[np.float64]]:
    """A Mitsuba spot's cutoff angle and RID texture.

    Mitsuba's `spot` looks its texture up at uv = 1/2 + (x, y) / (2 z tan(cutoff)) for a
    direction (x, y, z) in its frame (= the light frame), row 0 at v = 0; pixel (i, j)
    has its centre at uv = ((j + 1/2) / size, (i + 1/2) / size).

    Args:
        rid: The table.
        size: Pixels per side; None: `texture_size` of the cone.

    Returns:
        cutoff_rad: The cone's half angle: where the RID stays below 1e-3 of the axis or
            its table ends, at most 80 degrees.
        texture: (size, size) the relative intensity of each pixel's direction.
    """
    cutoff = _cutoff_rad(rid)
    n = texture_size(cutoff) if size is None else int(size)
    centers = (np.arange(n) + 0.5) / n
    x = (2.0 * centers[None, :] - 1.0) * math.tan(cutoff)  # x / z, per column
    y = (2.0 * centers[:, None] - 1.0) * math.tan(cutoff)  # y / z, per row
    x, y = np.broadcast_arrays(x, y)
    return cutoff, rid_values(rid, np.arctan(np.hypot(x, y)), np.arctan2(y, x))


def sensor_numbers(camera: Camera) -> dict[str, float]:
    """Mitsuba's `perspective` settings for `camera` (see the module docstring).

    Returns:
        fov_deg: the field of view along y, from fy; principal_point_offset_x/y: the
        principal point's offset from the film's centre as fractions of its width and
        height (OpenCV's image centre is ((width - 1) / 2, (height - 1) / 2)).
    """
    fy = float(camera.K[1, 1])
    return {
        "fov_deg": math.degrees(2.0 * math.atan(camera.height / (2.0 * fy))),
        "principal_point_offset_x": ((camera.width - 1) / 2 - float(camera.K[0, 2])) / camera.width,
        "principal_point_offset_y": ((camera.height - 1) / 2 - float(camera.K[1, 2]))
        / camera.height,
    }


def _png16(image: NDArray[np.float64]) -> bytes:
    import cv2

    ok, buffer = cv2.imencode(".png", np.round(np.clip(image, 0, 1) * 65535).astype(np.uint16))
    assert ok, "PNG encoding failed"
    return buffer.tobytes()


def _sensor_lines(camera: Camera | None, inside: list[str]) -> list[str]:
    """The sensor's lines, `inside` (the medium's reference) before its end."""
    head = [
        '    <sensor type="perspective" id="camera">',
        '        <transform name="to_world"><matrix value="'
        + _matrix_attribute(np.eye(4))
        + '"/></transform>',
    ]
    if camera is None:
        return [
            "    <!-- No project was given: the sensor has Mitsuba's default film and field",
            "         of view (give the export the project for its camera's). -->",
            *head,
            *inside,
            "    </sensor>",
        ]
    numbers = sensor_numbers(camera)
    fx, fy = float(camera.K[0, 0]), float(camera.K[1, 1])
    dist = [float(c) for c in camera.dist[: camera.n_dist]]
    distortion = (
        "none" if not any(dist) else ", ".join(f"{c:.6g}" for c in dist) + " (NOT modelled)"
    )
    return [
        f"    <!-- The project's camera: {camera.width} x {camera.height} px, fy {fy:.6g} px (the",
        f"         field of view along y), principal point ({float(camera.K[0, 2]):.6g},",
        f"         {float(camera.K[1, 2]):.6g}) px (OpenCV: pixel centres at integers) as an",
        "         offset from the film's centre. Mitsuba's perspective sensor has one focal",
        f"         length (fx {fx:.6g} px is taken as fy: ratio {fx / fy:.8f}), no skew",
        f"         (here {camera.skew:.3g}) and no lens distortion: distortion {distortion}.",
        "         Compare its renders with undistorted images (cv2.undistort). -->",
        *head,
        '        <string name="fov_axis" value="y"/>',
        f'        <float name="fov" value="{numbers["fov_deg"]!r}"/>',
        '        <float name="principal_point_offset_x" value="'
        f'{numbers["principal_point_offset_x"]!r}"/>',
        '        <float name="principal_point_offset_y" value="'
        f'{numbers["principal_point_offset_y"]!r}"/>',
        '        <film type="hdrfilm">',
        f'            <integer name="width" value="{camera.width}"/>',
        f'            <integer name="height" value="{camera.height}"/>',
        '            <rfilter type="box"/>',
        "        </film>",
        '        <sampler type="multijitter">',
        f'            <integer name="sample_count" value="{SAMPLES_PER_PIXEL}"/>',
        "        </sampler>",
        *inside,
        "    </sensor>",
    ]


def medium_id(result: ResultFile) -> str:
    """The medium's id in the XML: `lightcal_medium`, made unlike every emitter's id."""
    names = {light.name for light in result.lights}
    ident = "lightcal_medium"
    while ident in names:
        ident += "_"
    return ident


def _medium_lines(
    medium: ExportMedium, wall_albedo: float | None, ident: str, *, port: bool = False
) -> list[str]:
    """The `homogeneous` medium and the `volpath` integrator (module docstring); behind
    the camera's `port` the sensor is in the housing's air."""
    albedo = medium.albedo(wall_albedo)
    sigma_s = medium.scattering_per_m(wall_albedo)
    if medium.scatters:
        how = (
            f"sigma_s = beta rho / pi = {sigma_s!r} /m with the wall's albedo rho = "
            f"{wall_albedo!r}: give the wall that albedo (a wall of albedo rho renders rho / pi "
            "times lightcal's value, and the water's veil sigma_s / beta times lightcal's)."
        )
    else:
        how = "no scattering (backscatter_per_m 0): albedo 0, a purely absorbing medium."
    where = (
        "that the emitters sit in and the camera's port's outer face opens into (the sensor "
        "is in the housing's air), so that every ray in the water is in it"
        if port
        else "that the sensor and the emitters sit in, so that every ray of the scene is in it"
    )
    ports = (
        "The camera's port is below; not modelled: refraction at the light's port."
        if port
        else "The sensor's near_clip is 1e-5 m: a camera ray starts there, in the water. Not "
        "modelled: refraction at the camera's and the light's ports."
    )
    text = (
        f"The calibration's medium: {medium.text()}. A homogeneous medium (docs/model.md, "
        f'"Medium") {where}: sigma_t = c (attenuation_per_m), albedo sigma_s / c, '
        "a Henyey-Greenstein "
        "phase of g (phase_g). The result's backscatter beta = sigma_s pi / rho is relative "
        f"to the wall's albedo rho: {how} lightcal's model is single scattering: "
        "mi.load_file(path, max_depth=2) renders it (direct light and one scattering); the "
        f"default max_depth -1 follows every order. {ports}"
    )
    comment = textwrap.wrap(xml_comment(text, max_chars=4000), 84)
    return [
        f"    <!-- {comment[0]}",
        *(f"         {line}" for line in comment[1:-1]),
        f"         {comment[-1]} -->",
        '    <default name="max_depth" value="-1"/>',
        '    <integrator type="volpath">',
        '        <integer name="max_depth" value="$max_depth"/>',
        "    </integrator>",
        f'    <medium type="homogeneous" id="{ident}">',
        f'        <float name="sigma_t" value="{medium.attenuation_per_m!r}"/>',
        f'        <float name="albedo" value="{albedo!r}"/>',
        '        <phase type="hg">',
        f'            <float name="g" value="{medium.phase_g!r}"/>',
        "        </phase>",
        "    </medium>",
    ]


def mitsuba_files(
    result: ResultFile,
    source: str | Path,
    out: Path,
    *,
    camera: Camera | None = None,
    wall_albedo: float | None = None,
    port: FlatPort | None = None,
    light_ports: Mapping[str, LightPort] | None = None,
) -> dict[Path, bytes]:
    """The scene XML (`out`) and the RID textures beside it.

    Args:
        result: The result (with the project's given RIDs filled in, `with_given_rids`).
        source: The result's path, for error messages.
        out: The XML's path; textures are named `<stem>_rid_<k>.png` beside it.
        camera: The project's camera, for the sensor's film and field of view.
        wall_albedo: rho, for the scattering coefficient of a medium that scatters
            (`lightcal.io.export_medium`).
        port: The project's camera port, or None (`lightcal.io.export_port`).
        light_ports: The project's lights' ports by name (`lightcal.io.export_light_port`).

    Raises:
        InputError: the medium scatters and `wall_albedo` is None, or its sigma_s > c;
            naming `lights[i].port`: a light port in water or with a camera port.
    """
    files: dict[Path, bytes] = {}
    medium = export_medium(result, source)
    ident = medium_id(result)
    behind = port is not None
    water = [] if medium is None else _medium_lines(medium, wall_albedo, ident, port=behind)
    inside = [] if medium is None else [f'        <ref name="medium" id="{ident}"/>']
    clip = [f'        <float name="near_clip" value="{NEAR_CLIP_M!r}"/>']
    sensor_inside = [] if medium is None else [*clip, *inside]
    port_lines: list[str] = []
    if port is not None:  # the sensor in the housing's air, its rays through the port
        sensor_inside = clip
        port_lines = mitsuba_port_lines(port, camera, None if medium is None else ident)
        if medium is None:
            water = [
                '    <default name="max_depth" value="-1"/>',
                '    <integrator type="path">',
                '        <integer name="max_depth" value="$max_depth"/>',
                "    </integrator>",
            ]
    names = {light.name for light in result.lights}
    ported = {k: v for k, v in (light_ports or {}).items() if k in names}
    if ported:  # a point light behind a port: only the particle tracer reaches it
        first = next(iter(ported.values())).key
        if medium is not None:
            raise InputError(first, MITSUBA_WATER_REFUSAL)
        if port is not None:
            raise InputError(first, MITSUBA_CAMERA_PORT_REFUSAL)
        water = ptracer_lines()
    lines = [
        '<?xml version="1.0" encoding="utf-8"?>',
        f"<!-- lightcal {xml_comment(result.lightcal_version)}: calibrated lights, camera frame.",
        "     The sensor sits at the origin in Mitsuba's camera convention (looking down +z,",
        "     +y up, +x to the image's left); each emitter's to_world is",
        "     diag(-1, -1, 1, 1) @ T_camera_light (OpenCV frame: x right, y down, z forward;",
        "     metres). In a scene whose sensor has to_world S, use S @ (the matrix below).",
        "     Each emitter's intensity is the light's calibrated scale (times its texture's",
        "     peak): a Lambertian wall of albedo rho renders rho / pi times lightcal's value.",
        "     A spot's texture (16-bit PNG beside this file) is its RID over the cone;",
        "     without one the cone's falloff approximates a 90 degree half angle. -->",
        '<scene version="3.0.0">',
        *water,
        *_sensor_lines(camera, sensor_inside),
        *port_lines,
    ]
    for index, light in enumerate(result.lights):
        rid = light_rid(light, source)
        M = mitsuba_from_opencv(light_transform(light))
        kind = "point" if light.pose_kind == "isotropic" else "spot"
        lines.append(f'    <emitter type="{kind}" id={xml_attribute(light.name)}>')
        intensity = float(light.scale)
        cutoff_rad = math.pi / 2
        if kind == "spot" and rid is not None:
            cutoff_rad, texture = spot_texture(rid)
            peak = max(float(texture.max()), 1.0)  # a batwing's peak is off the axis
            intensity *= peak
            name = f"{out.stem}_rid_{index}.png"
            files[out.parent / name] = _png16(texture / peak)
            cutoff_deg = math.degrees(cutoff_rad)
            lines += [
                f'        <float name="cutoff_angle" value="{cutoff_deg!r}"/>',
                f'        <float name="beam_width" value="{cutoff_deg!r}"/>',
                '        <texture type="bitmap" name="texture">',
                f'            <string name="filename" value={xml_attribute(name)}/>',
                '            <boolean name="raw" value="true"/>',
                '            <string name="wrap_mode" value="clamp"/>',
                "        </texture>",
            ]
        elif kind == "spot":
            cutoff_deg, beam_deg = mitsuba_spot_cone(math.pi / 2)
            lines.append(f'        <float name="cutoff_angle" value="{cutoff_deg!r}"/>')
            lines.append(f'        <float name="beam_width" value="{beam_deg!r}"/>')
        lines.append(f'        <rgb name="intensity" value="{intensity!r}"/>')
        lines.append(
            '        <transform name="to_world"><matrix value="'
            + _matrix_attribute(M)
            + '"/></transform>'
        )
        lines += inside
        lines.append("    </emitter>")
        if light.name in ported:
            lines += mitsuba_light_port_lines(
                light.name, ported[light.name], light_transform(light), cutoff_rad, camera
            )
    lines.append("</scene>")
    return {out: ("\n".join(lines) + "\n").encode("utf-8"), **files}
