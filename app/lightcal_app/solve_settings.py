"""What the solve fits, as the page sets it: the project-file keys a user would otherwise
edit by hand before `lightcal calibrate`.

`SolveSettings` holds the wall model (`wall.model`, `auto` included), the mirror
exclusion (`selection.exclude_mirror_deg`), the offset (`sensor.estimate_offset`: a
black level left in the images), the room light (`sensor.estimate_ambient`), the
camera's fall-off (`sensor.model`) and the radial one estimated with the light
(`sensor.estimate_fall_off`), each light's RID estimate (`lights[].estimate_rid`), the
water's values (`medium.attenuation_per_m`, `backscatter_per_m`, `phase_g`: the Light
tab's Water folder; with `sensor.channels` c and beta per channel, lists in the file),
what is estimated of them (`medium.estimate`), the wall's
albedo map (`wall.albedo_map`) and the surroundings (`surroundings`: the Light tab's
Surroundings folder, `lightcal_app.surroundings_settings`).
`project_for_solve` makes the project the solve uses: the loaded project with those
keys set, built by `lightcal.io.project.project_from_spec` exactly as a project file
with them would be, so the page solves what `lightcal calibrate` solves on the edited
file.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Literal, get_args

from pydantic import ValidationError

from lightcal.core.fall_off import FALL_OFF_MAX_ORDER
from lightcal.core.medium import MAX_PHASE_G, Medium
from lightcal.core.solver import CalibrationModel
from lightcal.errors import InputError
from lightcal.io.albedo_map_spec import AlbedoMapSpec
from lightcal.io.project import Project, project_from_spec
from lightcal.io.project_spec import FallOffSpec, WallModelName, WallSpec
from lightcal.io.surroundings_spec import SurroundingsSpec
from lightcal.pipeline.wall_choice import candidate_named
from lightcal_app.surroundings_settings import check_mesh, check_surroundings

FallOff = Literal["radiance", "cos4", "paper", "map"]
RidEstimate = Literal["none", "cos_power", "curve"]

WALL_MODELS: tuple[str, ...] = get_args(WallModelName)
FALL_OFFS: tuple[str, ...] = get_args(FallOff)
RID_ESTIMATES: tuple[str, ...] = get_args(RidEstimate)
FALL_OFF_ORDERS: tuple[str, ...] = ("off", "r^2", "r^2, r^4", "r^2, r^4, r^6")
"""The Solve tab's words for `sensor.estimate_fall_off`'s order 0 (off) to 3."""
MEDIUM_ESTIMATES: dict[str, tuple[str, ...]] = {
    "none": (),
    "attenuation": ("attenuation_per_m",),
    "backscatter": ("backscatter_per_m",),
    "attenuation, backscatter": ("attenuation_per_m", "backscatter_per_m"),
    "backscatter, g": ("backscatter_per_m", "phase_g"),
    "attenuation, backscatter, g": ("attenuation_per_m", "backscatter_per_m", "phase_g"),
    "g": ("phase_g",),
    "attenuation, g": ("attenuation_per_m", "phase_g"),
}
"""The Solve tab's words for `medium.estimate`: each set of `Medium.parameter_names`, in
their order (g alone or with c: beside a given backscatter, which it shapes)."""
MEDIUM_WORDS: dict[tuple[str, ...], str] = {v: k for k, v in MEDIUM_ESTIMATES.items()}
"""`medium.estimate` -> the Solve tab's words for it."""
MEDIUM_BOUNDS: dict[str, tuple[float, float]] = {
    **dict(zip(Medium.parameter_names, Medium.parameter_bounds, strict=True)),
    "phase_g": (-MAX_PHASE_G, MAX_PHASE_G),
}
"""The water's values the page takes (`medium.<name>`): (lowest, highest), the core's."""


@dataclass(frozen=True)
class SolveSettings:
    """The project keys the Solve tab edits (see the module docstring).

    Attributes:
        wall_model: `wall.model`.
        exclude_mirror_deg: `selection.exclude_mirror_deg`; 0: off (null in the file).
        estimate_offset: `sensor.estimate_offset`.
        fall_off: `sensor.model` ("map" only for a project with a vignetting file).
        estimate_rid: per light, `lights[j].estimate_rid`.
        estimate_ambient: `sensor.estimate_ambient`.
        estimate_fall_off: the order of `sensor.estimate_fall_off`; 0: off (null).
        medium_estimate: `medium.estimate` (a value of `MEDIUM_ESTIMATES`).
        medium: the water's values (`medium.attenuation_per_m`, `backscatter_per_m`,
            `phase_g`): given, or the start of those estimated; None: the project's. With
            `sensor.channels`: the first channel's (`media` has each).
        media: with `sensor.channels`, each channel's water (its c and beta, lists in the
            file; g the same in each); None: `medium` in every channel (the project's
            when that is None too). Without channels: None.
        albedo_map: `wall.albedo_map` (its spacing and prior); None: off.
        surroundings: `surroundings` (the surfaces whose bounce light the model adds);
            None: none.
    """

    wall_model: str
    exclude_mirror_deg: float
    estimate_offset: bool
    fall_off: str
    estimate_rid: tuple[str, ...]
    estimate_ambient: bool = False
    estimate_fall_off: int = 0
    medium_estimate: tuple[str, ...] = ()
    medium: Medium | None = None
    albedo_map: AlbedoMapSpec | None = None
    surroundings: SurroundingsSpec | None = None
    media: tuple[Medium, ...] | None = None


def settings_of(project: Project) -> SolveSettings:
    """The settings as the project file has them."""
    spec = project.spec
    return SolveSettings(
        wall_model=spec.wall.model,
        exclude_mirror_deg=float(spec.selection.exclude_mirror_deg or 0.0),
        estimate_offset=spec.sensor.estimate_offset,
        fall_off=spec.sensor.model,
        estimate_rid=tuple(ls.estimate_rid for ls in spec.lights),
        estimate_ambient=spec.sensor.estimate_ambient,
        estimate_fall_off=(
            0 if spec.sensor.estimate_fall_off is None else spec.sensor.estimate_fall_off.order
        ),
        medium_estimate=tuple(n for n in Medium.parameter_names if n in spec.medium.estimate),
        medium=project.medium.initial,
        albedo_map=spec.wall.albedo_map,
        surroundings=spec.surroundings,
        media=tuple(m.initial for m in project.media) if project.channels else None,
    )


def settings_media(project: Project, settings: SolveSettings) -> tuple[Medium, ...]:
    """The water the settings give each channel (one without `sensor.channels`)."""
    if settings.media is not None:
        return settings.media
    n = max(1, len(project.channels))
    return (project.medium.initial if settings.medium is None else settings.medium,) * n


def check_media(project: Project, media: object) -> None:
    """InputError naming the key when `media` (`SolveSettings.media`) is not one water
    per channel of the project's `sensor.channels` with one g."""
    if media is None:
        return
    channels = project.channels
    if not channels:
        raise InputError(
            "medium",
            f"values per colour channel need sensor.channels; expected one water, got {media!r}",
        )
    if (
        not isinstance(media, tuple)
        or len(media) != len(channels)
        or not all(isinstance(m, Medium) for m in media)
    ):
        raise InputError(
            "medium",
            f"expected the water's values of each channel ({', '.join(channels)}), got {media!r}",
        )
    for m in media:  # each value in the core's range
        medium_with(m, {nm: getattr(m, nm) for nm in MEDIUM_BOUNDS})
    if len({m.phase_g for m in media}) > 1:
        raise InputError(
            "medium.phase_g",
            "expected one g for every channel, got " + ", ".join(f"{m.phase_g:g}" for m in media),
        )


def medium_with(base: Medium, values: Mapping[str, object]) -> Medium:
    """`base` with some of its values replaced by ones typed in a page (`medium.<name>`
    -> value); InputError naming the key when a value is not a number in the core's
    range (`MEDIUM_BOUNDS`)."""
    for name, value in values.items():
        if name not in MEDIUM_BOUNDS:
            raise InputError("medium", f"expected one of {', '.join(MEDIUM_BOUNDS)}, got {name!r}")
        lo, hi = MEDIUM_BOUNDS[name]
        if isinstance(value, bool) or not isinstance(value, int | float):
            got = repr(value)
        elif math.isfinite(value) and lo <= value <= hi:
            continue
        else:
            got = f"{value:g}"
        unit = "" if name == "phase_g" else " (1/m)"
        raise InputError(
            f"medium.{name}", f"expected a number from {lo:g} to {hi:g}{unit}, got {got}"
        )
    return replace(base, **{name: float(v) for name, v in values.items()})  # type: ignore[arg-type]


def check_settings(project: Project, settings: SolveSettings) -> SolveSettings:
    """`settings` when each value is one the project accepts; InputError naming the
    project key otherwise (values come from a page)."""
    if settings.wall_model not in WALL_MODELS:
        raise InputError("wall.model", f"expected one of {', '.join(WALL_MODELS)}")
    mirror = settings.exclude_mirror_deg
    if not (isinstance(mirror, int | float) and math.isfinite(mirror) and 0 <= mirror < 90):
        raise InputError(
            "selection.exclude_mirror_deg",
            f"expected an angle in degrees from 0 (off) to below 90, got {mirror}",
        )
    if settings.fall_off not in FALL_OFFS:
        raise InputError("sensor.model", f"expected one of {', '.join(FALL_OFFS)}")
    if settings.fall_off == "map" and project.vignetting_path is None:
        raise InputError(
            "sensor.model", "'map' needs the project's vignetting file (sensor.vignetting)"
        )
    order = settings.estimate_fall_off
    if (
        isinstance(order, bool)
        or not isinstance(order, int)
        or not 0 <= order <= FALL_OFF_MAX_ORDER
    ):
        raise InputError(
            "sensor.estimate_fall_off.order",
            f"expected 0 (off) to {FALL_OFF_MAX_ORDER}, got {order!r}",
        )
    if tuple(settings.medium_estimate) not in MEDIUM_ESTIMATES.values():
        raise InputError(
            "medium.estimate",
            f"expected one of {', '.join(map(repr, MEDIUM_ESTIMATES))}, got "
            f"{settings.medium_estimate!r}",
        )
    medium = project.medium.initial if settings.medium is None else settings.medium
    if not isinstance(medium, Medium):
        raise InputError("medium", f"expected the water's values, got {medium!r}")
    check_media(project, settings.media)
    scatters = any(m.scatters for m in settings_media(project, settings))
    if settings.fall_off != "radiance" and (
        scatters or "backscatter_per_m" in settings.medium_estimate
    ):
        # The core's renderer refuses it: its backscatter is a radiance.
        raise InputError(
            "medium.backscatter_per_m",
            "the backscatter is modelled with the camera fall-off radiance (sensor.model) "
            f"only, not {settings.fall_off!r}: set backscatter to 0 or the fall-off to radiance",
        )
    if "phase_g" in settings.medium_estimate and not (
        scatters or "backscatter_per_m" in settings.medium_estimate
    ):
        raise InputError(
            "medium.estimate",
            "g shapes the backscatter: expected a backscatter above 0 (Light tab, Water) "
            "or estimated with g",
        )
    check_albedo_map(project, settings)
    if settings.surroundings is not None and not isinstance(
        settings.surroundings, SurroundingsSpec
    ):
        raise InputError("surroundings", f"expected its surfaces, got {settings.surroundings!r}")
    check_mesh(project, check_surroundings(settings.surroundings))
    if len(settings.estimate_rid) != len(project.lights):
        raise InputError(
            "lights.estimate_rid",
            f"expected one per light ({len(project.lights)}), got {len(settings.estimate_rid)}",
        )
    for j, value in enumerate(settings.estimate_rid):
        if value not in RID_ESTIMATES:
            raise InputError(
                f"lights.{j}.estimate_rid", f"expected one of {', '.join(RID_ESTIMATES)}"
            )
        light = project.lights[j].initial
        if value != "none" and not light.rid.symmetric:
            raise InputError(
                f"lights.{j}.estimate_rid",
                f"light {light.name!r} has an RID without rotational symmetry: its RID "
                "cannot be estimated (expected none)",
            )
    return settings


def albedo_map_spec(spacing_mm: float, variation: float, smoothness: float) -> AlbedoMapSpec:
    """The `wall.albedo_map` of values typed in a page; InputError naming the key of a
    value out of the project file's range."""
    try:
        return AlbedoMapSpec(spacing_mm=spacing_mm, variation=variation, smoothness=smoothness)
    except ValidationError as exc:
        err = exc.errors()[0]
        key = ".".join(str(part) for part in err["loc"])
        words = str(err["msg"]).replace("Input should be", "expected a number")
        raise InputError(f"wall.albedo_map.{key}", words) from exc


def check_albedo_map(project: Project, settings: SolveSettings) -> None:
    """InputError (key `wall.albedo_map`) when the settings' albedo map is not one the
    project takes: not an `AlbedoMapSpec`, or with a robust loss (the map is solved by
    linear least squares)."""
    albedo = settings.albedo_map
    if albedo is None:
        return
    if not isinstance(albedo, AlbedoMapSpec):
        raise InputError("wall.albedo_map", f"expected its spacing and prior, got {albedo!r}")
    loss = project.spec.solver.loss
    if loss != "linear":
        raise InputError(
            "wall.albedo_map",
            f"the albedo map needs the linear loss; the project's solver.loss is {loss!r} "
            "(set it to linear in the project file)",
        )


def project_for_solve(project: Project, settings: SolveSettings) -> Project:
    """The project with the settings' keys set (the project itself when they are its
    own); InputError when the edited project is refused (an RID estimate of a light
    that has no axis, ...), naming the key as the project file would."""
    if settings == settings_of(project):
        return project
    spec = project.spec
    wall = spec.wall
    if settings.wall_model != wall.model:
        # Another model: its default parameters (a model's own do not carry over).
        wall = WallSpec(
            model=settings.wall_model,  # type: ignore[arg-type]
            flatness_mm=wall.flatness_mm,
            mesh=wall.mesh,
        )
    wall = wall.model_copy(update={"albedo_map": settings.albedo_map})
    edited = spec.model_copy(
        update={
            "wall": wall,
            "selection": spec.selection.model_copy(
                update={"exclude_mirror_deg": settings.exclude_mirror_deg or None}
            ),
            "sensor": spec.sensor.model_copy(
                update={
                    "estimate_offset": settings.estimate_offset,
                    "model": settings.fall_off,
                    "estimate_ambient": settings.estimate_ambient,
                    "estimate_fall_off": (
                        FallOffSpec(order=settings.estimate_fall_off)
                        if settings.estimate_fall_off
                        else None
                    ),
                }
            ),
            "lights": [
                ls.model_copy(update={"estimate_rid": value})
                for ls, value in zip(spec.lights, settings.estimate_rid, strict=True)
            ],
            "medium": spec.medium.model_copy(
                update={
                    "estimate": list(settings.medium_estimate),
                    **_medium_keys(settings),
                }
            ),
            "surroundings": settings.surroundings,
        }
    )
    return project_from_spec(edited, project.path)


def _medium_keys(settings: SolveSettings) -> dict[str, object]:
    """The `medium` keys of the settings' water values: per channel c and beta as lists
    (`media`), else one value each (`medium`); none when the project's."""
    if settings.media is not None:
        return {
            "attenuation_per_m": [m.attenuation_per_m for m in settings.media],
            "backscatter_per_m": [m.backscatter_per_m for m in settings.media],
            "phase_g": settings.media[0].phase_g,
        }
    if settings.medium is None:
        return {}
    return {nm: getattr(settings.medium, nm) for nm in MEDIUM_BOUNDS}


def restored_wall(
    project: Project, model: CalibrationModel, names: list[str]
) -> tuple[Project, CalibrationModel]:
    """The project and model a restored solve with parameters `names` continues: a
    `wall: auto` solve ended on the wall it chose (plastic, oren_nayar), whose parameters
    the project's first model lacks; that wall's project and model then. Otherwise the
    ones given."""
    chosen = candidate_named(model, names) if project.spec.wall.model == "auto" else None
    if chosen is None or names == list(model.layout.names):
        return project, model
    settings = replace(settings_of(project), wall_model=chosen.layout.wall_unknown.initial.name)
    return project_for_solve(project, settings), chosen
