"""The app session on disk: the user's choices and the solve's progress, as JSON.

A session file records the initial guess, the pixel selection (settings, per-image
overrides, regions, clicked pixels), what each image shows, what the solve fits (the
Solve tab's settings, the water's values, the surroundings), and the solve's history
(so the plots and the current estimate come back). The app autosaves it atomically
after every change (`<project stem>.session.json` beside the project, or in the state
folder when the project's folder is read-only) and restores it at start; the user may
also save a copy, reload it, download it and upload one.
"""

from __future__ import annotations

import contextlib
import glob
import hashlib
import json
import os
import time
from dataclasses import asdict
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from lightcal.core.medium import Medium
from lightcal.core.selection import Strategy
from lightcal.core.solver import IterationReport
from lightcal.errors import InputError, LightcalError
from lightcal.io.albedo_map_spec import AlbedoMapSpec
from lightcal.io.atomic import atomic_write_text
from lightcal.io.surroundings_spec import SurroundingsSpec
from lightcal_app.limits import (
    MAX_BINNING,
    MAX_GRID_STEP,
    MAX_INT,
    MAX_NAME_LENGTH,
    MAX_PIXELS_PER_IMAGE,
    MAX_SEED,
    POSITION_LIMIT_M,
)
from lightcal_app.solve_settings import (
    MEDIUM_BOUNDS,
    SolveSettings,
    check_settings,
    project_for_solve,
)
from lightcal_app.state import (
    AppState,
    LightGuess,
    OverlayKind,
    SelectionSettings,
    SolveEnd,
    UserRegion,
)

SESSION_FORMAT: Literal["lightcal-app-session"] = "lightcal-app-session"
# The ranges of the page's widgets (lightcal_app.limits): a session file can hold
# nothing the page refuses, so a bad autosave can be neither written nor loaded.
Metres = Annotated[float, Field(ge=-POSITION_LIMIT_M, le=POSITION_LIMIT_M)]
Position = Annotated[list[Metres], Field(min_length=3, max_length=3)]
Unit = Annotated[float, Field(ge=-1.0 - 1e-6, le=1.0 + 1e-6)]
Mat3 = Annotated[
    list[Annotated[list[Unit], Field(min_length=3, max_length=3)]],
    Field(min_length=3, max_length=3),
]
Coordinate = Annotated[float, Field(ge=-MAX_INT, le=MAX_INT)]
Point2 = Annotated[list[Coordinate], Field(min_length=2, max_length=2)]
Count = Annotated[int, Field(ge=0, le=MAX_INT)]
Pixel2 = Annotated[list[Count], Field(min_length=2, max_length=2)]
Name = Annotated[str, Field(max_length=MAX_NAME_LENGTH)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class GuessModel(_Model):
    name: Name
    position_m: Position
    R_camera_light: Mat3


class SelectionModel(_Model):
    strategy: Strategy = SelectionSettings.strategy
    n_per_image: int = Field(default=SelectionSettings.n_per_image, ge=1, le=MAX_PIXELS_PER_IMAGE)
    grid_step: int = Field(default=SelectionSettings.grid_step, ge=1, le=MAX_GRID_STEP)
    binning: int = Field(default=SelectionSettings.binning, ge=1, le=MAX_BINNING)
    seed: int = Field(default=SelectionSettings.seed, ge=0, le=MAX_SEED)


class RegionModel(_Model):
    kind: Literal["rect", "polygon"]
    points: list[Point2] = Field(min_length=2)
    include: bool = True
    image: Name | None = None


class IterationModel(_Model):
    iteration: Count
    x: list[float]
    cost: float
    gradient_norm: float
    per_image_rms: list[float | None]
    nfev: Count
    reweighted: bool = False


class SolveModel(_Model):
    parameter_names: list[Name]
    state: str
    history: list[IterationModel]
    # How a finished solve ended (files before these fields: reloaded as paused).
    status: int | None = Field(default=None, ge=-2, le=4)
    message: str = Field(default="", max_length=2000)
    time_s: float = Field(default=0.0, ge=0.0, le=1e7)
    # The parameters the result's pixel weights were rendered at (`SolveEnd.weights_at`).
    weights_at: list[float] | None = None


def _medium_value(name: str) -> Any:
    """A required field in the range the core takes for `medium.<name>`."""
    lo, hi = MEDIUM_BOUNDS[name]
    return Field(ge=lo, le=hi)


class MediumModel(_Model):
    """The water's values (`Medium`), in the core's ranges."""

    attenuation_per_m: float = _medium_value("attenuation_per_m")
    backscatter_per_m: float = _medium_value("backscatter_per_m")
    phase_g: float = _medium_value("phase_g")


class SolveSettingsModel(_Model):
    """What the solve fits (`lightcal_app.solve_settings.SolveSettings`)."""

    wall_model: str = Field(max_length=40)
    exclude_mirror_deg: float = Field(ge=0.0, lt=90.0)
    estimate_offset: bool
    fall_off: str = Field(max_length=40)
    estimate_rid: list[Annotated[str, Field(max_length=40)]] = Field(max_length=64)
    # Files before these fields: off, as the project file's defaults.
    estimate_ambient: bool = False
    estimate_fall_off: int = Field(default=0, ge=0, le=3)
    medium_estimate: list[Annotated[str, Field(max_length=40)]] = Field(
        default_factory=list, max_length=3
    )
    # None (and files before this field): the project's values.
    medium: MediumModel | None = None
    # `wall.albedo_map`; None (and files before this field): off.
    albedo_map: AlbedoMapSpec | None = None
    # `surroundings`, as the page edits them; None: none. Files before this field (the
    # key absent, `model_fields_set`): the project's.
    surroundings: SurroundingsSpec | None = None
    # With `sensor.channels`: each channel's water (`medium` the first's); None (and
    # files before this field): `medium` in every channel.
    media: list[MediumModel] | None = Field(default=None, max_length=8)


class SessionFile(_Model):
    """One app session (version 1)."""

    format: Literal["lightcal-app-session"] = SESSION_FORMAT
    version: Literal[1] = 1
    project: str
    saved_at: str
    lights: list[GuessModel]
    selection: SelectionModel
    selection_per_image: dict[Name, SelectionModel] = Field(default_factory=dict)
    regions: list[RegionModel] = Field(default_factory=list)
    points: dict[Name, list[Pixel2]] = Field(default_factory=dict)
    overlay_default: OverlayKind = "real"
    overlay_per_image: dict[Name, OverlayKind] = Field(default_factory=dict)
    show_selection: bool = True
    show_albedo: bool = True
    rays_image: Name = "none"
    ref_image: Count = 0
    # Files before this field: the project's own settings.
    solve_settings: SolveSettingsModel | None = None
    solve: SolveModel | None = None


def default_session_path(project_path: Path, state_dir: Path) -> Path:
    """`<stem>.session.json` beside the project, or in `state_dir` if that is read-only."""
    folder = project_path.parent
    if os.access(folder, os.W_OK):
        return folder / f"{project_path.stem}.session.json"
    digest = hashlib.sha1(str(project_path.resolve()).encode()).hexdigest()[:10]
    return state_dir / "sessions" / f"{project_path.stem}-{digest}.session.json"


def _selection_model(s: SelectionSettings) -> SelectionModel:
    return SelectionModel(
        strategy=s.strategy,
        n_per_image=s.n_per_image,
        grid_step=s.grid_step,
        binning=s.binning,
        seed=s.seed,
    )


def _settings(m: SelectionModel) -> SelectionSettings:
    return SelectionSettings(m.strategy, m.n_per_image, m.grid_step, m.binning, m.seed)


def _finite_or_none(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


def session_from_state(state: AppState) -> SessionFile:
    """The session file of the current state (call under `state.lock`)."""
    names = [u.initial.name for u in state.project.lights]
    solve = None
    if state.history:
        solve = SolveModel(
            parameter_names=list(state.parameter_names),
            state=state.solver_state,
            status=state.result.status if state.result is not None else None,
            message=state.result.message if state.result is not None else "",
            time_s=state.result.time_s if state.result is not None else 0.0,
            weights_at=(
                None
                if state.result is None or state.result_weights_at is None
                else [float(v) for v in state.result_weights_at]
            ),
            history=[
                IterationModel(
                    iteration=r.iteration,
                    x=[float(v) for v in r.x],
                    cost=float(r.cost),
                    gradient_norm=float(r.gradient_norm),
                    per_image_rms=[_finite_or_none(v) for v in r.per_image_rms],
                    nfev=int(r.nfev),
                    reweighted=bool(r.reweighted),
                )
                for r in state.history
            ],
        )
    return SessionFile(
        project=str(state.project.path),
        saved_at=time.strftime("%Y-%m-%d %H:%M:%S"),
        lights=[
            GuessModel(
                name=n,
                position_m=g.t_camera_light.tolist(),  # the file's name for it
                R_camera_light=g.R_camera_light.tolist(),
            )
            for n, g in zip(names, state.guess, strict=True)
        ],
        selection=_selection_model(state.selection),
        selection_per_image={k: _selection_model(v) for k, v in state.selection_per_image.items()},
        regions=[
            RegionModel(
                kind=r.kind, points=[list(p) for p in r.points], include=r.include, image=r.image
            )
            for r in state.regions
        ],
        points={k: [list(p) for p in v] for k, v in state.points.items() if v},
        overlay_default=state.overlay_default,
        overlay_per_image=dict(state.overlay_per_image),
        show_selection=state.show_selection,
        show_albedo=state.show_albedo,
        solve_settings=SolveSettingsModel.model_validate(asdict(state.solve_settings)),
        rays_image=state.rays_image,
        ref_image=state.ref_image,
        solve=solve,
    )


def session_json(session: SessionFile) -> str:
    """The file's text."""
    return session.model_dump_json(indent=1) + "\n"


def write_session(session: SessionFile, path: Path) -> None:
    """Write a session file atomically (its folder is created)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, session_json(session))


def remove_stale_temps(path: Path) -> None:
    """Remove what a killed atomic write of `path` left behind (`.<name>.<hex>.tmp`)."""
    with contextlib.suppress(OSError):
        for temp in path.parent.glob(f".{glob.escape(path.name)}.*.tmp"):
            with contextlib.suppress(OSError):
                temp.unlink()


def parse_session(text: str | bytes, source: str | Path) -> SessionFile:
    """Validate a session file's content; InputError naming the field on any problem."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(source, f"not valid JSON: {exc.msg}", line=exc.lineno) from exc
    except UnicodeDecodeError as exc:
        raise InputError(source, "not a text file: expected a lightcal session JSON") from exc
    if not isinstance(data, dict) or data.get("format") != SESSION_FORMAT:
        raise InputError(source, f"expected a lightcal session file (format {SESSION_FORMAT!r})")
    try:
        return SessionFile.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        loc = ".".join(str(p) for p in err["loc"]) or "(top level)"
        raise InputError(source, f"{loc}: {err['msg']}") from exc


def read_session(path: Path) -> SessionFile:
    """Read a session file; InputError naming it on any problem."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError as exc:
        raise InputError(path, "session file not found") from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, f"cannot read the session file ({exc})") from exc
    return parse_session(text, path)


def apply_session(state: AppState, session: SessionFile) -> list[str]:
    """Put a session's choices into the state (call under `state.lock`).

    Choices naming images or lights the project does not have are skipped.

    Returns:
        warnings about what was skipped.
    """
    warnings: list[str] = []
    names = set(state.project.names)
    light_names = [u.initial.name for u in state.project.lights]
    by_name = {g.name: g for g in session.lights}
    guess = list(state.guess)
    for j, name in enumerate(light_names):
        g = by_name.get(name)
        if g is None:
            warnings.append(f"the session has no light named {name!r}; kept the project's")
            continue
        R = np.array(g.R_camera_light, dtype=np.float64)
        if abs(np.linalg.det(R) - 1.0) > 1e-4 or np.abs(R.T @ R - np.eye(3)).max() > 1e-4:
            warnings.append(f"light {name!r}: R_camera_light is not a rotation; kept the project's")
            continue
        guess[j] = LightGuess(np.array(g.position_m, dtype=np.float64), R)
    state.guess = guess
    state.selection = _settings(session.selection)

    def known(name: str | None, what: str) -> bool:
        if name is None or name in names:
            return True
        warnings.append(f"{what}: the project has no image named {name!r}; skipped")
        return False

    state.selection_per_image = {
        k: _settings(v) for k, v in session.selection_per_image.items() if known(k, "selection")
    }
    state.regions = [
        UserRegion(r.kind, tuple((float(p[0]), float(p[1])) for p in r.points), r.include, r.image)
        for r in session.regions
        if known(r.image, "region")
    ]
    state.points = {
        k: [(int(p[0]), int(p[1])) for p in v]
        for k, v in session.points.items()
        if known(k, "points")
    }
    state.overlay_default = session.overlay_default
    state.overlay_per_image = {
        k: v for k, v in session.overlay_per_image.items() if known(k, "overlay")
    }
    state.show_selection = session.show_selection
    state.show_albedo = session.show_albedo
    if session.rays_image in ("none", "all") or session.rays_image in names:
        state.rays_image = session.rays_image
    if session.ref_image < len(state.project.names):
        state.ref_image = session.ref_image
    if session.solve_settings is not None:
        saved = session.solve_settings
        media = (
            None if saved.media is None else tuple(Medium(**m.model_dump()) for m in saved.media)
        )
        if media is None and saved.medium is not None and state.project.channels:
            # A colour project's file before `media`: its `medium` was the first channel's
            # (kept per channel when that is the project's own).
            first = Medium(**saved.medium.model_dump())
            own = tuple(m.initial for m in state.project.media)
            media = own if first == own[0] else None
        settings = SolveSettings(
            saved.wall_model,
            saved.exclude_mirror_deg,
            saved.estimate_offset,
            saved.fall_off,
            tuple(saved.estimate_rid),
            saved.estimate_ambient,
            saved.estimate_fall_off,
            tuple(saved.medium_estimate),
            None if saved.medium is None else Medium(**saved.medium.model_dump()),
            saved.albedo_map,
            (
                saved.surroundings
                if "surroundings" in saved.model_fields_set
                else state.project.spec.surroundings
            ),
            media,
        )
        try:
            check_settings(state.project, settings)
            state.solve_project = project_for_solve(state.project, settings)
            state.solve_settings = settings
        except LightcalError as exc:
            warnings.append(f"what the solve fits: {exc}; kept the project's")
    if session.solve is not None and session.solve.history:
        state.parameter_names = list(session.solve.parameter_names)
        state.history = [
            IterationReport(
                h.iteration,
                np.array(h.x, dtype=np.float64),
                h.cost,
                h.gradient_norm,
                np.array([np.nan if v is None else v for v in h.per_image_rms]),
                h.nfev,
                h.reweighted,
            )
            for h in session.solve.history
        ]
        solve = session.solve
        if solve.state in ("converged", "not converged") and solve.status is not None:
            weights = None if solve.weights_at is None else np.array(solve.weights_at)
            state.resume_end = SolveEnd(
                solve.state,  # type: ignore[arg-type]
                solve.status,
                solve.message,
                solve.time_s,
                weights,
            )
    return warnings
