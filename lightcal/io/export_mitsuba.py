"""The Mitsuba 3 export: a scene XML with a sensor and a spot (point) emitter per light,
the RID as a texture beside it (see `lightcal.io.export`)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from lightcal.core.camera_frames import (
    mitsuba_from_opencv,
    mitsuba_spot_cone,
)
from lightcal.io.escaping import xml_attribute, xml_comment
from lightcal.io.export_lights import LightRID, light_rid, light_transform
from lightcal.io.result_file import ResultFile

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
    centers = (np.arange(size) + 0.5) / size
    x = (2.0 * centers[None, :] - 1.0) * math.tan(cutoff)  # x / z, per column
    y = (2.0 * centers[:, None] - 1.0) * math.tan(cutoff)  # y / z, per row
    x, y = np.broadcast_arrays(x, y)
    return cutoff, rid_values(rid, np.arctan(np.hypot(x, y)), np.arctan2(y, x))


def _png16(image: NDArray[np.float64]) -> bytes:
    import cv2

    ok, buffer = cv2.imencode(".png", np.round(np.clip(image, 0, 1) * 65535).astype(np.uint16))
    assert ok, "PNG encoding failed"
    return buffer.tobytes()


def mitsuba_files(result: ResultFile, source: str | Path, out: Path) -> dict[Path, bytes]:
    files: dict[Path, bytes] = {}
    lines = [
        '<?xml version="1.0" encoding="utf-8"?>',
        f"<!-- lightcal {xml_comment(result.lightcal_version)}: calibrated lights, camera frame.",
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
        lines.append(f'    <emitter type="{kind}" id={xml_attribute(light.name)}>')
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
                f'            <string name="filename" value={xml_attribute(name)}/>',
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
