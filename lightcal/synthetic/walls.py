"""The true wall of a synthetic dataset from its kind and parameters (`lightcal synth
--wall`): the defaults filled in, a parameter of another kind refused rather than ignored.
Errors name the parameter (`roughness`, `ior`, `albedo`, `sigma_deg`)."""

from __future__ import annotations

import math

from lightcal.core.wall import LAMBERTIAN, OrenNayarWall, PlasticWall, WallReflectance
from lightcal.errors import InputError

WALL_PARAMETERS: dict[str, dict[str, float]] = {
    "plastic": {"roughness": 0.3, "ior": 1.5, "albedo": 0.8},
    "oren_nayar": {"sigma_deg": 20.0},
}
"""The parameters of each kind of wall with their defaults (the others take none)."""


def true_wall(kind: str, given: dict[str, float | None]) -> WallReflectance:
    """The wall of `kind` ("lambertian", "plastic", "oren_nayar").

    Args:
        kind: The kind of wall.
        given: Parameters by name (`WALL_PARAMETERS`); None: the default.

    Raises:
        InputError: A parameter of another kind of wall, or out of its range.
    """
    values = dict(WALL_PARAMETERS.get(kind, {}))
    for other, parameters in WALL_PARAMETERS.items():
        for name in parameters:
            if given.get(name) is None:
                continue
            if other != kind:
                raise InputError(name, f"applies to the {other} wall only, got the {kind} wall")
            values[name] = float(given[name])  # type: ignore[arg-type]
    if kind == "oren_nayar":
        low, high = (math.degrees(b) for b in OrenNayarWall.parameter_bounds[0])
        sigma = values["sigma_deg"]
        if not (math.isfinite(sigma) and low <= sigma <= high):
            raise InputError(
                "sigma_deg", f"expected a value in [{low:g}, {high:g}] degrees, got {sigma:g}"
            )
        return OrenNayarWall(math.radians(sigma))
    if kind == "plastic":
        try:
            return PlasticWall.from_albedo(values["roughness"], values["ior"], values["albedo"])
        except ValueError as exc:  # "plastic wall: <parameter>: expected ..."
            _, name, detail = [*str(exc).split(": ", 2), "", ""][:3]
            if name in values and detail:
                raise InputError(name, detail) from exc
            raise InputError("wall", str(exc)) from exc
    return LAMBERTIAN
