"""Export a calibration result (`lightcal.io.result_file`) to other tools' formats.

| format | file | holds |
|---|---|---|
| `opencv` | FileStorage YAML | per light: 4x4 `T_camera_light`, position, axis, sigmas, RID |
| `blender` | Python snippet | a spot (point) light per light, parented to the scene camera |
| `mitsuba` | Mitsuba 3 scene XML | a sensor, a spot (point) emitter per light, RID textures |
| `ies` | IES LM-63-2002 | the estimated RID of one light (`lightcal.io.ies`) |
| `ldt` | EULUMDAT | the estimated RID of one light (`lightcal.io.eulumdat`) |

All poses are the result's `T_camera_light` (OpenCV camera frame: x right, y down, z
forward; metres), converted to Blender's and Mitsuba's camera conventions as
`lightcal.core.camera_frames` documents. A light's RID is known to the result only when
the calibration estimated it (`rid` in the result, tabulated at `theta_deg`; a 2-D table
also has `phi_deg` and `values` of shape (n_phi, n_theta)); without it the opencv file
has no RID table, Blender and Mitsuba get a 180 degree cone, and ies/ldt refuse
(`with_given_rids` fills in a project's given RIDs). With
it, a Mitsuba spot gets the RID as a texture: a 16-bit PNG beside the XML
(`<stem>_rid_<k>.png`, `spot_texture`), looked up by Mitsuba along each direction.
Photometric files hold the relative RID as candela (1 cd on the axis, absolute
photometry); azimuths follow docs/conventions.md (C = -phi).
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal
from xml.sax.saxutils import escape, quoteattr

import numpy as np
from numpy.typing import NDArray

from lightcal import __version__
from lightcal.core.camera_frames import (
    blender_from_opencv,
    blender_spot_cone,
    mitsuba_from_opencv,
    mitsuba_spot_cone,
    transform_camera_light,
)
from lightcal.core.rid import RID, IsotropicRID, SymmetricTableRID, Table2DRID
from lightcal.errors import InputError
from lightcal.io.atomic import atomic_create_bytes, atomic_write_bytes
from lightcal.io.photometric_table import PhotometricTable
from lightcal.io.result_file import LightResultModel, ResultFile

__all__ = [
    "FORMATS",
    "ExportFormat",
    "LightRID",
    "export_files",
    "export_result",
    "given_rid_description",
    "light_rid",
    "light_transform",
    "rid_photometric_table",
    "rid_values",
    "spot_texture",
    "with_given_rids",
]

ExportFormat = Literal["opencv", "blender", "mitsuba", "ies", "ldt"]
FORMATS: tuple[ExportFormat, ...] = ("opencv", "blender", "mitsuba", "ies", "ldt")

FRAME_NOTE = (
    "OpenCV camera frame: x right, y down, z forward; metres; T_camera_light maps light to camera"
)


@dataclass(frozen=True)
class LightRID:
    """A light's RID as the result tabulates it.

    Attributes:
        model: The estimated model ("cos_power", "curve", ...).
        theta_rad: (n_t,) angles from the light axis, radians, from 0.
        values: (n_t,) relative intensities, or (n_p, n_t) for a 2-D table.
        phi_rad: (n_p,) azimuths in the light frame for a 2-D table, else None.
        half_angle_rad: The half-intensity angle.
    """

    model: str
    theta_rad: NDArray[np.float64]
    values: NDArray[np.float64]
    phi_rad: NDArray[np.float64] | None
    half_angle_rad: float


def light_transform(light: LightResultModel) -> NDArray[np.float64]:
    """(4, 4) `T_camera_light` of a result's light (OpenCV camera frame, metres)."""
    return transform_camera_light(light.R_camera_light, light.position_m)


def light_rid(light: LightResultModel, source: str | Path) -> LightRID | None:
    """The light's tabulated RID, or None when the result holds none.

    Raises:
        InputError: naming `source` and the light: the table is malformed.
    """
    rid: dict[str, Any] | None = light.rid
    if not rid:
        return None
    where = f"lights[{light.name}].rid"
    try:
        theta = np.radians(np.asarray(rid["theta_deg"], dtype=np.float64))
        values = np.asarray(rid["values"], dtype=np.float64)
        phi = np.radians(np.asarray(rid["phi_deg"], dtype=np.float64)) if "phi_deg" in rid else None
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(
            source, f"{where}: expected theta_deg and values (and phi_deg for a 2-D table): {exc}"
        ) from None
    shape = (theta.size,) if phi is None else (phi.size, theta.size)
    if theta.ndim != 1 or theta.size < 2 or values.shape != shape:
        raise InputError(
            source, f"{where}: expected values of shape {shape} for {theta.size} angles"
        )
    if not (np.all(np.isfinite(values)) and np.all(np.isfinite(theta))):
        raise InputError(source, f"{where}: expected finite angles and values")
    if theta[0] != 0.0 or np.any(np.diff(theta) <= 0.0) or np.any(values[..., 0] <= 0.0):
        raise InputError(
            source, f"{where}: expected increasing angles from 0 and positive values on the axis"
        )
    if phi is not None and (
        phi[0] < 0.0 or phi[-1] >= 2.0 * math.pi or np.any(np.diff(phi) <= 0.0)
    ):
        raise InputError(source, f"{where}: expected phi_deg increasing within [0, 360)")
    if "half_angle_deg" in rid:
        half = math.radians(float(rid["half_angle_deg"]))
    else:
        mean = values if phi is None else values.mean(axis=0)
        below = np.nonzero(mean <= 0.5 * mean[0])[0]
        if below.size == 0:
            half = float(theta[-1])
        else:  # linear between the samples either side of the half level
            k = max(int(below[0]), 1)
            f0, f1 = mean[k - 1] / mean[0], mean[k] / mean[0]
            half = float(theta[k - 1] + (theta[k] - theta[k - 1]) * (f0 - 0.5) / (f0 - f1))
    return LightRID(str(rid.get("model", "table")), theta, values, phi, half)


def given_rid_description(rid: RID) -> dict[str, Any] | None:
    """A project's given RID in the result's `rid` form (None for an isotropic light).

    Tables keep their own samples; analytic profiles are sampled every degree to 90.
    """
    if isinstance(rid, IsotropicRID):
        return None
    phi: NDArray[np.float64] | None = None
    if isinstance(rid, Table2DRID):
        theta, phi, values = rid.theta_rad, rid.phi_rad, rid.values
    elif isinstance(rid, SymmetricTableRID):
        theta, values = rid.theta_rad, rid.values
    else:
        theta = np.radians(np.arange(91.0))
        values = rid(theta)
    description: dict[str, Any] = {
        "model": f"given ({type(rid).__name__})",
        "theta_deg": np.degrees(theta).tolist(),
        "values": np.asarray(values).tolist(),
        "half_angle_deg": math.degrees(rid.half_angle_rad),
    }
    if phi is not None:
        description["phi_deg"] = np.degrees(phi).tolist()
    return description


def with_given_rids(result: ResultFile, rids: dict[str, RID]) -> ResultFile:
    """`result` with each light that has no estimated RID given the project's, by name."""
    lights = [
        light.model_copy(update={"rid": given_rid_description(rids[light.name])})
        if not light.rid and light.name in rids
        else light
        for light in result.lights
    ]
    return result.model_copy(update={"lights": lights})


# ----------------------------------------------------------------------------- opencv


def _opencv_yaml(result: ResultFile, source: str | Path) -> bytes:
    import cv2

    fs = cv2.FileStorage(
        "export.yaml",
        cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY | cv2.FILE_STORAGE_FORMAT_YAML,
    )
    fs.write("lightcal_version", result.lightcal_version)
    fs.write("frame", FRAME_NOTE)
    fs.write("lights_count", len(result.lights))
    fs.startWriteStruct("lights", cv2.FileNode_SEQ)
    for light in result.lights:
        sigma = light.sigma
        fs.startWriteStruct("", cv2.FileNode_MAP)
        fs.write("name", light.name)
        fs.write("pose_kind", light.pose_kind)
        fs.write("T_camera_light", light_transform(light))
        fs.write("position_m", np.array(light.position_m, dtype=np.float64).reshape(3, 1))
        fs.write("axis_camera", np.array(light.axis_camera, dtype=np.float64).reshape(3, 1))
        fs.write("scale", float(light.scale))
        fs.write("sigma_position_m", np.array(sigma.position_m, dtype=np.float64).reshape(3, 1))
        fs.write("sigma_axis_camera", np.array(sigma.axis_camera, dtype=np.float64).reshape(3, 1))
        fs.write("sigma_R_camera_light", np.array(sigma.R_camera_light, dtype=np.float64))
        fs.write("sigma_roll_deg", float(sigma.roll_deg))
        fs.write("sigma_pitch_deg", float(sigma.pitch_deg))
        fs.write("sigma_axis_angle_deg", float(sigma.axis_angle_from_optical_axis_deg))
        fs.write("sigma_scale", float(light.scale_sigma))
        rid = light_rid(light, source)
        if rid is not None:
            fs.write("rid_model", rid.model)
            fs.write("rid_half_angle_rad", rid.half_angle_rad)
            if rid.phi_rad is None:
                # (n, 2): theta_rad, relative intensity
                fs.write("rid_table", np.column_stack([rid.theta_rad, rid.values]))
            else:
                fs.write("rid_theta_rad", rid.theta_rad.reshape(-1, 1))
                fs.write("rid_phi_rad", rid.phi_rad.reshape(-1, 1))
                fs.write("rid_grid", rid.values)  # (n_phi, n_theta)
        fs.endWriteStruct()
    fs.endWriteStruct()
    return fs.releaseAndGetString().encode("utf-8")


# ---------------------------------------------------------------------------- blender

_BLENDER_TEMPLATE = '''"""Calibrated lights from lightcal {version} for Blender.

Run it in Blender's Python console or Text Editor. Each light is added as a child of
the camera CAMERA_NAME (the scene's active camera when None), its matrix_local given in
Blender's camera frame: the camera looks down -Z with +Y up, a spot shines along its -Z.
That is matrix_local = F @ T_camera_light @ F, F = diag(1, -1, -1, 1), T_camera_light
the pose lightcal calibrated in the OpenCV camera frame (x right, y down, z forward;
metres). Without a camera the lights are placed in world coordinates equal to Blender's
camera frame. Spot size and blend approximate the RID: the blend's middle sits at its
half-intensity angle.
"""

import bpy
from mathutils import Matrix

CAMERA_NAME = None

LIGHTS = {lights}


def add_lights(lights=LIGHTS, camera_name=CAMERA_NAME):
    scene = bpy.context.scene
    camera = bpy.data.objects[camera_name] if camera_name else scene.camera
    added = []
    for spec in lights:
        data = bpy.data.lights.new(name=spec["name"], type=spec["type"])
        if spec["type"] == "SPOT":
            data.spot_size = spec["spot_size"]
            data.spot_blend = spec["spot_blend"]
        obj = bpy.data.objects.new(spec["name"], data)
        scene.collection.objects.link(obj)
        if camera is not None:
            obj.parent = camera
            obj.matrix_parent_inverse = Matrix.Identity(4)
        obj.matrix_local = Matrix(spec["matrix_blendercam_light"])
        added.append(obj)
    return added


add_lights()
'''


def _blender_snippet(result: ResultFile, source: str | Path) -> bytes:
    specs = []
    for light in result.lights:
        rid = light_rid(light, source)
        spec: dict[str, Any] = {
            "name": light.name,
            "type": "POINT" if light.pose_kind == "isotropic" else "SPOT",
        }
        if spec["type"] == "SPOT":
            size, blend = blender_spot_cone(rid.half_angle_rad if rid else math.pi / 2)
            spec["spot_size"] = size
            spec["spot_blend"] = blend
        M = blender_from_opencv(light_transform(light))
        spec["matrix_blendercam_light"] = tuple(tuple(float(v) for v in row) for row in M)
        specs.append(spec)
    lights = "[\n" + "".join(f"    {spec!r},\n" for spec in specs) + "]"
    return _BLENDER_TEMPLATE.format(version=result.lightcal_version, lights=lights).encode()


# ---------------------------------------------------------------------------- mitsuba


def _matrix_attribute(M: NDArray[np.float64]) -> str:
    """A Mitsuba `<matrix value=...>`: 16 numbers, row-major, shortest exact text."""
    return " ".join(repr(float(v)) for v in M.ravel())


TEXTURE_SIZE = 256
"""Pixels per side of a Mitsuba spot's RID texture."""

_TEXTURE_CUTOFF_LEVEL = 1e-3
"""The texture's cone ends where the RID stays below this (or where its table ends)."""

_TEXTURE_MAX_CUTOFF_DEG = 80.0
"""Widest texture cone: the texture is a tangent-plane projection (tan of the angle)."""


def rid_values(rid: LightRID, theta_rad: NDArray, phi_rad: NDArray) -> NDArray[np.float64]:
    """The tabulated RID at directions (any shape), linear between samples, 0 beyond.

    Args:
        rid: The table.
        theta_rad: angles from the light axis, radians.
        phi_rad: azimuths in the light frame (from +x towards +y), radians; same shape.
    """
    theta = np.asarray(theta_rad, dtype=np.float64).ravel()
    if rid.phi_rad is None:
        out = np.interp(theta, rid.theta_rad, rid.values, right=0.0)
    else:
        rows = np.stack([np.interp(theta, rid.theta_rad, v, right=0.0) for v in rid.values])
        knots = np.append(rid.phi_rad, rid.phi_rad[0] + 2.0 * math.pi)
        phi = np.mod(np.asarray(phi_rad, dtype=np.float64).ravel() - knots[0], 2.0 * math.pi)
        phi += knots[0]
        k = np.clip(np.searchsorted(knots, phi, side="right") - 1, 0, rid.phi_rad.size - 1)
        w = (phi - knots[k]) / (knots[k + 1] - knots[k])
        columns = np.arange(theta.size)
        nxt = (k + 1) % rid.phi_rad.size
        out = (1.0 - w) * rows[k, columns] + w * rows[nxt, columns]
    return np.clip(out, 0.0, None).reshape(np.shape(theta_rad))


def spot_texture(rid: LightRID, size: int = TEXTURE_SIZE) -> tuple[float, NDArray[np.float64]]:
    """A Mitsuba spot's cutoff angle and RID texture.

    Mitsuba's `spot` looks its texture up at uv = 1/2 + (x, y) / (2 z tan(cutoff)) for a
    direction (x, y, z) in its frame (= the light frame), row 0 at v = 0; pixel (i, j)
    has its centre at uv = ((j + 1/2) / size, (i + 1/2) / size).

    Returns:
        cutoff_rad: The cone's half angle: where the RID stays below 1e-3 of the axis or
            its table ends, at most 80 degrees.
        texture: (size, size) the relative intensity of each pixel's direction.
    """
    level = rid.values if rid.phi_rad is None else rid.values.max(axis=0)
    above = np.nonzero(level >= _TEXTURE_CUTOFF_LEVEL)[0]
    last = min(int(above[-1]) + 1, rid.theta_rad.size - 1) if above.size else 1
    cutoff = min(float(rid.theta_rad[last]), math.radians(_TEXTURE_MAX_CUTOFF_DEG))
    centres = (np.arange(size) + 0.5) / size
    x = (2.0 * centres[None, :] - 1.0) * math.tan(cutoff)  # x / z, per column
    y = (2.0 * centres[:, None] - 1.0) * math.tan(cutoff)  # y / z, per row
    x, y = np.broadcast_arrays(x, y)
    return cutoff, rid_values(rid, np.arctan(np.hypot(x, y)), np.arctan2(y, x))


def _png16(image: NDArray[np.float64]) -> bytes:
    import cv2

    ok, buffer = cv2.imencode(".png", np.round(np.clip(image, 0, 1) * 65535).astype(np.uint16))
    assert ok, "PNG encoding failed"
    return buffer.tobytes()


def _mitsuba_files(result: ResultFile, source: str | Path, out: Path) -> dict[Path, bytes]:
    files: dict[Path, bytes] = {}
    lines = [
        '<?xml version="1.0" encoding="utf-8"?>',
        f"<!-- lightcal {escape(result.lightcal_version)}: calibrated lights, camera frame.",
        "     The sensor sits at the origin in Mitsuba's camera convention (looking down +z,",
        "     +y up, +x to the image's left); each emitter's to_world is",
        "     diag(-1, -1, 1, 1) @ T_camera_light (OpenCV frame: x right, y down, z forward;",
        "     metres). In a scene whose sensor has to_world S, use S @ (the matrix below).",
        "     A spot's texture (16-bit PNG beside this file) is its RID over the cone;",
        "     without one the cone's falloff approximates a 90 degree half angle. -->",
        '<scene version="3.0.0">',
        '    <sensor type="perspective" id="camera">',
        '        <transform name="to_world"><matrix value="'
        + _matrix_attribute(np.eye(4))
        + '"/></transform>',
        "    </sensor>",
    ]
    for index, light in enumerate(result.lights):
        rid = light_rid(light, source)
        M = mitsuba_from_opencv(light_transform(light))
        kind = "point" if light.pose_kind == "isotropic" else "spot"
        lines.append(f'    <emitter type="{kind}" id={quoteattr(light.name)}>')
        intensity = 1.0
        if kind == "spot" and rid is not None:
            cutoff_rad, texture = spot_texture(rid)
            intensity = max(float(texture.max()), 1.0)  # a batwing's peak is off the axis
            name = f"{out.stem}_rid_{index}.png"
            files[out.parent / name] = _png16(texture / intensity)
            cutoff_deg = math.degrees(cutoff_rad)
            lines += [
                f'        <float name="cutoff_angle" value="{cutoff_deg!r}"/>',
                f'        <float name="beam_width" value="{cutoff_deg!r}"/>',
                '        <texture type="bitmap" name="texture">',
                f'            <string name="filename" value={quoteattr(name)}/>',
                '            <boolean name="raw" value="true"/>',
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
        lines.append("    </emitter>")
    lines.append("</scene>")
    return {out: ("\n".join(lines) + "\n").encode("utf-8"), **files}


# ------------------------------------------------------------------------ photometric


def rid_photometric_table(light: LightResultModel, source: str | Path) -> PhotometricTable:
    """The light's estimated RID as a type C table (1 cd on the axis, absolute photometry).

    Raises:
        InputError: naming `source`: the result holds no RID for this light.
    """
    rid = light_rid(light, source)
    if rid is None:
        raise InputError(
            source,
            f"light {light.name!r} has no estimated RID: expected a result of a calibration "
            "with estimate_rid (cos_power or curve)",
        )
    values = np.clip(rid.values, 0.0, None)
    written = light.rid or {}
    theta_deg = np.asarray(written["theta_deg"], dtype=np.float64)  # as written, exactly
    if theta_deg[-1] < 90.0:  # LM-63 type C tables end at 90 or 180; the RID is 0 beyond
        theta_deg = np.append(theta_deg, 90.0)
        values = np.concatenate([values, np.zeros((*values.shape[:-1], 1))], axis=-1)
    if rid.phi_rad is None:
        return PhotometricTable(
            theta_deg,
            np.zeros(1),
            values[None, :],
            source=str(source),
            symmetry="axial",
            luminaire=light.name,
        )
    phi_deg = np.asarray(written["phi_deg"], dtype=np.float64)
    c_deg = np.mod(-phi_deg, 360.0)  # C = -phi (docs/conventions.md)
    order = np.argsort(c_deg)
    return PhotometricTable(
        theta_deg,
        c_deg[order],
        values[order],
        source=str(source),
        symmetry="none",
        luminaire=light.name,
    )


def _select_light(result: ResultFile, source: str | Path, name: str | None) -> LightResultModel:
    if name is not None:
        for light in result.lights:
            if light.name == name:
                return light
        names = ", ".join(repr(light.name) for light in result.lights)
        raise InputError(source, f"no light named {name!r}: expected one of {names}")
    with_rid = [light for light in result.lights if light.rid]
    if len(result.lights) == 1:
        return result.lights[0]
    if len(with_rid) == 1:
        return with_rid[0]
    raise InputError(source, f"{len(result.lights)} lights: name the one to export (--light NAME)")


def _photometric_bytes(
    writer: Callable[[Path, PhotometricTable], None], suffix: str
) -> Callable[[ResultFile, str | Path, str | None], bytes]:
    def render(result: ResultFile, source: str | Path, light_name: str | None) -> bytes:
        table = rid_photometric_table(_select_light(result, source, light_name), source)
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / f"light{suffix}"
            writer(path, table)
            return path.read_bytes()

    return render


def _write_ies(path: Path, table: PhotometricTable) -> None:
    from lightcal.io.ies import write_ies

    write_ies(path, table, keywords={"TEST": f"lightcal {__version__} estimated RID"})


def _write_ldt(path: Path, table: PhotometricTable) -> None:
    from lightcal.io.eulumdat import write_ldt

    write_ldt(path, table)


# ---------------------------------------------------------------------------- entry


def export_files(
    result: ResultFile,
    fmt: str,
    out: str | Path,
    *,
    source: str | Path,
    light_name: str | None = None,
) -> dict[Path, bytes]:
    """The exported files' contents: `out` first, then any it refers to (Mitsuba textures).

    Args:
        result: The result read with `read_result`.
        fmt: One of `FORMATS`.
        out: The main file's path (textures go beside it).
        source: The result's path, for error messages.
        light_name: The light to export as ies/ldt (needed when several have a RID).

    Raises:
        InputError: an unknown format, or the result lacks what the format needs.
    """
    out = Path(out)
    whole: dict[str, Callable[[ResultFile, str | Path], bytes]] = {
        "opencv": _opencv_yaml,
        "blender": _blender_snippet,
    }
    if fmt in whole:
        return {out: whole[fmt](result, source)}
    if fmt == "mitsuba":
        return _mitsuba_files(result, source, out)
    if fmt == "ies":
        return {out: _photometric_bytes(_write_ies, ".ies")(result, source, light_name)}
    if fmt == "ldt":
        return {out: _photometric_bytes(_write_ldt, ".ldt")(result, source, light_name)}
    raise InputError("--format", f"unknown format {fmt!r}: expected one of {', '.join(FORMATS)}")


def export_result(
    result: ResultFile,
    fmt: str,
    out: str | Path,
    *,
    source: str | Path,
    light_name: str | None = None,
    force: bool = False,
) -> list[Path]:
    """Write `export_files` atomically, each; existing files only with `force`.

    Returns:
        The files written, `out` first.

    Raises:
        InputError: `export_files`' errors; a file exists (without `force`; then nothing
            is written) or the folder does not.
    """
    files = export_files(result, fmt, out, source=source, light_name=light_name)
    out = Path(out)
    if not out.parent.is_dir():
        raise InputError(out, f"cannot write: folder {str(out.parent)!r} does not exist")
    if not force:
        for path in files:
            if path.exists():
                raise InputError(path, "the file exists: expected a new path, or --force")
    for path, data in reversed(files.items()):  # what `out` refers to first
        try:
            if force:
                atomic_write_bytes(path, data)
            else:
                atomic_create_bytes(path, data)
        except FileExistsError:
            raise InputError(path, "the file exists: expected a new path, or --force") from None
    return list(files)
