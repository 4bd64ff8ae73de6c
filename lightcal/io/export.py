"""Export a calibration result (`lightcal.io.result_file`) to other tools' formats.

| format | file | holds |
|---|---|---|
| `opencv` | FileStorage YAML | per light: 4x4 `T_camera_light`, rvec/tvec, 6x6 covariance, RID |
| `blender` | Python snippet | camera intrinsics, a point light per light driven by its RID |
| `mitsuba` | Mitsuba 3 scene XML | sensor (project's intrinsics), spot per light, RID textures |
| `ros` | ROS 2 launch XML + URDF | a static transform and a fixed joint per light |
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

A result calibrated in water (its `medium`, `lightcal.io.export_medium`) gives Mitsuba a
`homogeneous` medium the sensor and emitters sit in (and `volpath`), Blender the world's
volume, the opencv file a `medium` map of c, beta, g and their sigmas and the ROS launch
file a comment; ies/ldt cannot hold it (`lightcal export` says so on stderr). The
renderers need the scattering coefficient sigma_s = beta rho / pi: `wall_albedo` rho.
In air the files are what they were before media, byte for byte.

A project whose camera looked through a flat port (`port`, its `camera.port`) gives
Mitsuba the port's two dielectric faces, the opencv file a `camera_port` map and the ROS
launch file a note (the camera frame and intrinsics are the housing's, in air, behind
the port); Blender is refused (`lightcal.io.export_port`). A project whose lights shine
through flat ports (`light_ports`, their `lights[i].port`) gives Mitsuba each port's two
faces in front of its emitter and the particle tracer (refused in water and with a camera
port), the opencv file a `port` map in the light's entry, the ROS launch file a note and
an ies/ldt file's origin text a word (the pose is the emitter's behind its port, the RID
the emitter's in air); Blender is refused (`lightcal.io.export_light_port`).
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Literal

import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.flat_port import FlatPort
from lightcal.errors import InputError
from lightcal.io.atomic import atomic_create_bytes, atomic_write_bytes
from lightcal.io.export_blender import blender_snippet
from lightcal.io.export_light_port import BLENDER_LIGHT_REFUSAL, LightPort, origin_suffix
from lightcal.io.export_lights import (
    LightRID,
    clean_degrees,
    given_rid_description,
    light_rid,
    light_transform,
    rid_origin,
    with_given_rids,
)
from lightcal.io.export_medium import check_wall_albedo
from lightcal.io.export_mitsuba import mitsuba_files, rid_values, spot_texture
from lightcal.io.export_opencv import opencv_yaml
from lightcal.io.export_port import BLENDER_REFUSAL
from lightcal.io.export_ros import ros_files
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
    "select_light",
    "spot_texture",
    "with_given_rids",
]

ExportFormat = Literal["opencv", "blender", "mitsuba", "ros", "ies", "ldt"]
FORMATS: tuple[ExportFormat, ...] = ("opencv", "blender", "mitsuba", "ros", "ies", "ldt")

# ---------------------------------------------------------------------------- blender

# Strings from the result reach the snippet only as `repr` literals (LIGHTCAL_VERSION,
# LIGHTS, whose IES texts hold the names too): never inside the docstring or a comment.
_BLENDER_TEMPLATE = '''"""Calibrated lights from lightcal (version: LIGHTCAL_VERSION) for Blender.

Made for Cycles. Run it in Blender's Python console or Text Editor (or `exec` it with
`bpy`). Each light is added as a child of the camera CAMERA_NAME (the scene's active
camera when None), its matrix_local given in Blender's camera frame: the camera looks
down -Z with +Y up, a light's axis is its -Z. That is matrix_local = F @ T_camera_light @ F,
F = diag(1, -1, -1, 1), T_camera_light the pose lightcal calibrated in the OpenCV camera
frame (x right, y down, z forward; metres). Without a camera the lights are placed in
world coordinates equal to Blender's camera frame.

A light with a RID is a point light of radius 0 whose Emission strength is an IES Texture
node reading the RID (a text block, in Cycles' angles: C = phi - 90 degrees) with the
node's Strength IES_STRENGTH, which undoes Cycles' candela-to-watt factor 4 pi / 177.83:
the node gives the relative RID, 1 on the axis. Its power is 4 pi times the calibrated
scale, so its intensity is the scale times the RID (W/sr in Cycles' units) and several
lights keep their relative brightness; a Lambertian wall of albedo rho renders rho / pi
times lightcal's radiance value. A light without a known RID is a spot with a 180 degree
cone. The IES node is Cycles' only: EEVEE shows the lights without their RID.

{camera_note}
"""

import bpy
from mathutils import Matrix

LIGHTCAL_VERSION = {version}
CAMERA_NAME = None
CAMERA = {camera}
IES_STRENGTH = {ies_strength}

LIGHTS = {lights}


def set_camera(camera, scene, numbers=CAMERA):
    """The project's intrinsics on `camera`'s data and the scene's render size."""
    if camera is None or numbers is None:
        return
    data = camera.data
    data.type = "PERSP"
    data.sensor_fit = "HORIZONTAL"
    data.sensor_width = numbers["sensor_width_mm"]
    data.lens_unit = "MILLIMETERS"
    data.lens = numbers["lens_mm"]
    data.shift_x = numbers["shift_x"]
    data.shift_y = numbers["shift_y"]
    render = scene.render
    render.resolution_x = numbers["width"]
    render.resolution_y = numbers["height"]
    render.resolution_percentage = 100
    render.pixel_aspect_x = numbers["pixel_aspect_x"]
    render.pixel_aspect_y = numbers["pixel_aspect_y"]


def drive_by_ies(data, spec):
    """The light's Emission strength from an IES Texture node holding its RID."""
    text = bpy.data.texts.new(spec["name"] + ".ies")
    text.write(spec["ies"])
    data.use_nodes = True
    tree = data.node_tree
    emission = next(node for node in tree.nodes if node.type == "EMISSION")
    ies = tree.nodes.new("ShaderNodeTexIES")
    ies.mode = "INTERNAL"
    ies.ies = text
    ies.inputs["Strength"].default_value = IES_STRENGTH
    tree.links.new(ies.outputs["Fac"], emission.inputs["Strength"])


def add_lights(lights=LIGHTS, camera_name=CAMERA_NAME):
    scene = bpy.context.scene
    camera = bpy.data.objects[camera_name] if camera_name else scene.camera
    set_camera(camera, scene)
    added = []
    for spec in lights:
        data = bpy.data.lights.new(name=spec["name"], type=spec["type"])
        data.energy = spec["power_w"]
        data.shadow_soft_size = 0.0
        if spec["type"] == "SPOT":
            data.spot_size = spec["spot_size"]
            data.spot_blend = spec["spot_blend"]
        if "ies" in spec:
            drive_by_ies(data, spec)
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


def _blender_snippet(
    result: ResultFile, source: str | Path, camera: Camera | None, wall_albedo: float | None
) -> bytes:
    return blender_snippet(
        result, source, _BLENDER_TEMPLATE, camera=camera, wall_albedo=wall_albedo
    )


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
    theta_deg = clean_degrees(written["theta_deg"])
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
    phi_deg = clean_degrees(written["phi_deg"])
    c_deg = clean_degrees(np.mod(-phi_deg, 360.0))  # C = -phi (docs/conventions.md)
    order = np.argsort(c_deg)
    return PhotometricTable(
        theta_deg,
        c_deg[order],
        values[order],
        source=str(source),
        symmetry="none",
        luminaire=light.name,
    )


def select_light(result: ResultFile, source: str | Path, name: str | None) -> LightResultModel:
    """The light an ies/ldt export writes: the one named, the only one, or the only one
    with a RID (`InputError` naming `source` otherwise)."""
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
    writer: Callable[[Path, PhotometricTable, str], None], suffix: str
) -> Callable[[ResultFile, str | Path, str | None, Mapping[str, LightPort]], bytes]:
    def render(
        result: ResultFile,
        source: str | Path,
        light_name: str | None,
        light_ports: Mapping[str, LightPort],
    ) -> bytes:
        light = select_light(result, source, light_name)
        table = rid_photometric_table(light, source)
        origin = rid_origin(light)
        if light.name in light_ports:
            origin += origin_suffix(light_ports[light.name])
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / f"light{suffix}"
            writer(path, table, origin)
            return path.read_bytes()

    return render


def _write_ies(path: Path, table: PhotometricTable, origin: str) -> None:
    from lightcal.io.ies import write_ies

    write_ies(path, table, keywords={"TEST": origin})


def _write_ldt(path: Path, table: PhotometricTable, origin: str) -> None:
    from lightcal.io.eulumdat import write_ldt

    write_ldt(path, table, report=origin)


# ---------------------------------------------------------------------------- entry


def export_files(
    result: ResultFile,
    fmt: str,
    out: str | Path,
    *,
    source: str | Path,
    light_name: str | None = None,
    camera: Camera | None = None,
    wall_albedo: float | None = None,
    port: FlatPort | None = None,
    light_ports: Mapping[str, LightPort] | None = None,
) -> dict[Path, bytes]:
    """The exported files' contents: `out` first, then any it refers to (Mitsuba textures).

    Args:
        result: The result read with `read_result`.
        fmt: One of `FORMATS`.
        out: The main file's path (textures go beside it).
        source: The result's path, for error messages.
        light_name: The light to export as ies/ldt (needed when several have a RID).
        camera: The project's camera (Mitsuba's sensor, Blender's camera: film size,
            field of view, principal point).
        wall_albedo: rho, the wall's diffuse reflectance, in (0, 1]: Mitsuba's and
            Blender's scattering coefficient sigma_s = beta rho / pi of a result whose
            medium scatters (`lightcal.io.export_medium`).
        port: The project's camera port (`camera.port`), or None.
        light_ports: The project's lights' ports by the lights' names
            (`lightcal.io.export_light_port.light_ports_of`), or None.

    Raises:
        InputError: an unknown format, the result lacks what the format needs, or its
            medium scatters and the format needs `wall_albedo`; naming `camera.port`:
            the Blender export of a camera behind a port; naming `lights[i].port`: the
            Blender export of a light behind one, the Mitsuba export of one in water or
            with a camera port.
    """
    out = Path(out)
    check_wall_albedo(wall_albedo)
    if result.undetermined:
        raise InputError(
            source,
            f"the result is undetermined ({result.undetermined[0]}): there is no pose to "
            "export; fix the project and calibrate again",
        )
    names = {light.name for light in result.lights}
    ported = {k: v for k, v in (light_ports or {}).items() if k in names}
    if fmt == "opencv":
        return {out: opencv_yaml(result, source, port, ported)}
    if fmt == "blender":
        if port is not None:
            raise InputError("camera.port", BLENDER_REFUSAL)
        if ported:
            raise InputError(next(iter(ported.values())).key, BLENDER_LIGHT_REFUSAL)
        return {out: _blender_snippet(result, source, camera, wall_albedo)}
    if fmt == "mitsuba":
        return mitsuba_files(
            result, source, out, camera=camera, wall_albedo=wall_albedo, port=port,
            light_ports=ported,
        )  # fmt: skip
    if fmt == "ros":
        return ros_files(result, out, source, port, ported)
    if fmt == "ies":
        return {out: _photometric_bytes(_write_ies, ".ies")(result, source, light_name, ported)}
    if fmt == "ldt":
        return {out: _photometric_bytes(_write_ldt, ".ldt")(result, source, light_name, ported)}
    raise InputError("--format", f"unknown format {fmt!r}: expected one of {', '.join(FORMATS)}")


def export_result(
    result: ResultFile,
    fmt: str,
    out: str | Path,
    *,
    source: str | Path,
    light_name: str | None = None,
    camera: Camera | None = None,
    wall_albedo: float | None = None,
    port: FlatPort | None = None,
    light_ports: Mapping[str, LightPort] | None = None,
    force: bool = False,
) -> list[Path]:
    """Write `export_files` atomically, each; existing files only with `force`.

    Returns:
        The files written, `out` first.

    Raises:
        InputError: `export_files`' errors; a file exists (without `force`; then nothing
            is written) or the folder does not.
    """
    files = export_files(
        result,
        fmt,
        out,
        source=source,
        light_name=light_name,
        camera=camera,
        wall_albedo=wall_albedo,
        port=port,
        light_ports=light_ports,
    )
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
