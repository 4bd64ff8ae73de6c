"""Keys a project file gives that lightcal would not use: an error naming each, never
silently ignored.

A key left at its default says nothing (`save_project` writes every default, such as
`camera.dist: []` beside `camera.path`); a key given another value where the rest of the
file makes lightcal ignore it is a mistake the user should hear about (a `dist` beside
a camera file's `path` would not distort anything). The cases:

| key | ignored when |
|---|---|
| `camera.dist`, `camera.skew` | `camera.path` is given (the camera file's intrinsics are used) |
| `camera.camera_id` | no `camera.path` (it picks a camera of a COLMAP file) |
| `sensor.vignetting` | `sensor.model` is not `map` |
| `lights[j].rid.m`, `.sigma_deg`, `.half_angle_deg`, `.profile`, `.path` | its type takes none |
| `lights[j].curve_knots`, `.curve_max_angle_deg` | `estimate_rid` is not `curve` |

(`rid.profile` is the `half_angle` type's.)

(The other sections' pydantic models refuse unknown keys, and the wall model its
parameters, by themselves.) Checked when a project file is read (`load_project`); a spec
built in memory (the app's edits) is not: the app's RID upload keeps the earlier type's
fields beside the new type and path.
"""

from __future__ import annotations

from pathlib import Path

from pydantic import BaseModel

from lightcal.errors import InputError
from lightcal.io.project_spec import ProjectFile

__all__ = ["check_no_ignored_keys", "ignored_keys"]

_RID_KEY_OF_TYPE = {
    "cos_power": {"m"},
    "gaussian": {"sigma_deg"},
    "half_angle": {"half_angle_deg", "profile"},
    "table": {"path"},
    "ies": {"path"},
    "ldt": {"path"},
    "isotropic": set(),
}


def _given(model: BaseModel, keys: tuple[str, ...], used: set[str]) -> list[str]:
    """The keys of `model` not in `used` that hold another value than their default."""
    fields = type(model).model_fields
    return [
        k
        for k in keys
        if k not in used and getattr(model, k) != fields[k].get_default(call_default_factory=True)
    ]


def ignored_keys(spec: ProjectFile) -> list[tuple[str, str]]:
    """(key, why it is not used) for every key `spec` gives that lightcal would ignore."""
    out: list[tuple[str, str]] = []
    camera = spec.camera
    if camera.path is not None:
        why = "beside camera.path: the camera file's intrinsics are used (give them there)"
        out += [(f"camera.{k}", why) for k in _given(camera, ("dist", "skew"), set())]
    elif camera.camera_id is not None:
        out.append(("camera.camera_id", "without camera.path (it picks a COLMAP camera)"))
    if spec.sensor.model != "map" and spec.sensor.vignetting is not None:
        out.append(("sensor.vignetting", f"with sensor.model {spec.sensor.model!r} (map uses it)"))
    for j, light in enumerate(spec.lights):
        rid = light.rid
        keys = ("m", "sigma_deg", "half_angle_deg", "profile", "path")
        for k in _given(rid, keys, _RID_KEY_OF_TYPE.get(rid.type, set(keys))):
            out.append((f"lights[{j}].rid.{k}", f"with rid.type {rid.type!r}"))
        if light.estimate_rid != "curve":
            curve = ("curve_knots", "curve_max_angle_deg")
            for k in _given(light, curve, set()):
                why = f"with estimate_rid {light.estimate_rid!r} (a 'curve' RID's)"
                out.append((f"lights[{j}].{k}", why))
    return out


def check_no_ignored_keys(spec: ProjectFile, source: str | Path) -> None:
    """Raises InputError naming the first key `spec` gives that lightcal would ignore
    (and how many more there are)."""
    found = ignored_keys(spec)
    if found:
        key, why = found[0]
        more = f" (and {len(found) - 1} more such keys)" if len(found) > 1 else ""
        raise InputError(source, f"{key}: given but not used {why}; remove it{more}")
