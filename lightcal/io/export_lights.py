"""The lights of a calibration result as the exporters need them: pose and RID.

`light_transform` gives a light's 4x4 `T_camera_light`; `light_rid` its RID as a table
(`LightRID`) when the result holds one; `with_given_rids` fills in a project's given
RIDs. Used by `lightcal.io.export` and `lightcal.io.export_mitsuba`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lightcal import __version__
from lightcal.core.camera_frames import (
    transform_camera_light,
)
from lightcal.core.rid import RID, IsotropicRID, SymmetricTableRID, Table2DRID
from lightcal.errors import InputError
from lightcal.io.escaping import plain_line
from lightcal.io.result_file import LightResultModel, ResultFile

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


def clean_degrees(values: Any) -> NDArray[np.float64]:
    """Angles in degrees without the noise of a radian round trip (3.0000000000000004 ->
    3.0): rounded to 1e-9 degrees, far below any table's precision."""
    return np.asarray(np.round(np.asarray(values, dtype=np.float64), 9) + 0.0, dtype=np.float64)


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
        "theta_deg": clean_degrees(np.degrees(theta)).tolist(),
        "values": np.asarray(values).tolist(),
        "half_angle_deg": math.degrees(rid.half_angle_rad),
    }
    if phi is not None:
        description["phi_deg"] = clean_degrees(np.degrees(phi)).tolist()
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


def rid_origin(light: LightResultModel) -> str:
    """Where the light's RID comes from, for a photometric file's header: given to the
    calibration (a project's profile, `with_given_rids`) or estimated by it."""
    model = plain_line((light.rid or {}).get("model", "table"))
    if model.startswith("given"):
        return f"lightcal {__version__}: the given RID {model[len('given') :].strip()}"
    return f"lightcal {__version__}: the RID estimated by the calibration ({model})"
