"""What the worker can be asked to do: one frozen dataclass per kind of request.

Callbacks (viser's thread pool) queue these with `AppState.request`; the worker
(`lightcal_app.worker`) takes them in order and hands each to the handler registered
for its type. `client` is the browser that asked (None: every browser or nobody); it
is only passed back to `notify` and downloads, never inspected. A kind with no field
of its own subclasses `FromBrowser` without the decorator (it needs none).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

from lightcal.core.solver import SolveOutcome
from lightcal.io.project import Project
from lightcal.pipeline import LoadedImages
from lightcal.pipeline.solve import Calibration

if TYPE_CHECKING:  # both import `state`, which imports this module
    from lightcal_app.session_file import SessionFile
    from lightcal_app.state import LightGuess

DownloadKind = Literal["result", "report", "session", "export"]


@dataclass(frozen=True)
class FromBrowser:
    """A request a browser made (its messages go to that browser; keyword only)."""

    client: Any = field(default=None, kw_only=True)


@dataclass(frozen=True)
class SetupChanged:
    """The guess or the selection changed: drop the solve, reselect if needed."""


@dataclass(frozen=True)
class Solve(FromBrowser):
    """Start or continue the solve: one more iteration ("step") or to the end ("run")."""

    how: Literal["step", "run"] = "step"


class Pause(FromBrowser):
    """Hold the solver after its current iteration."""


@dataclass(frozen=True)
class Finished:
    """The solver's thread ended solve `gen` with `outcome` (a Calibration: the pipeline's)."""

    gen: int
    outcome: SolveOutcome | Calibration


class Reset(FromBrowser):
    """Stop the solve and go back to the initial guess."""


@dataclass(frozen=True)
class PrepareDownload(FromBrowser):
    """Prepare a file for the browser: the result, the report or the session."""

    what: DownloadKind
    export_format: str | None = None  # with what="export": one of lightcal.io.export.FORMATS
    full_size: bool = False  # with what="report": the figures at print size (4x the bytes)


class SaveSession(FromBrowser):
    """Write the session beside the autosave and send it as a download."""


@dataclass(frozen=True)
class ApplySession(FromBrowser):
    """Restore a session (an uploaded file)."""

    session: SessionFile
    source: str


class LoadSavedSession(FromBrowser):
    """Restore the session written by `SaveSession`."""


class RestorePrevious(FromBrowser):
    """Bring back the finished result an edit replaced, with its settings (undo)."""


@dataclass(frozen=True)
class PlanViews(FromBrowser):
    """Suggest the `n` best next camera poses for the current estimate (Plan tab)."""

    n: int = 3
    wall_size_m: float = 3.0


@dataclass(frozen=True)
class SwitchProject(FromBrowser):
    """Show another project (an upload); `keep` keeps the guess and the selection."""

    project: Project
    loaded: LoadedImages
    truth: list[LightGuess] | None
    keep: bool
    note: str = ""


@dataclass(frozen=True)
class BuildPhotoProject(FromBrowser):
    """Build a project from the photos received (`lightcal_app.photo_project`) and show it.

    `half_angle_deg` is used without a light file; `initial_position_m` is the light's
    initial guess in the camera frame, m (None: from the beam in the photos)."""

    half_angle_deg: float | None = None
    initial_position_m: tuple[float, float, float] | None = None


Request = (
    SetupChanged
    | Solve
    | Pause
    | Reset
    | Finished
    | PrepareDownload
    | SaveSession
    | LoadSavedSession
    | RestorePrevious
    | ApplySession
    | SwitchProject
    | PlanViews
    | BuildPhotoProject
)

MERGED: frozenset[type] = frozenset((SetupChanged,))
"""Kinds handled once when several are queued (the first; it reads the latest state)."""


def merge(requests: list[Request]) -> list[Request]:
    """Keep the order but only the first of each merged kind."""
    seen: set[type] = set()
    out: list[Request] = []
    for req in requests:
        kind = type(req)
        if kind in MERGED:
            if kind in seen:
                continue
            seen.add(kind)
        out.append(req)
    return out


def client_of(request: Request) -> Any:
    """The browser that asked (None when none did)."""
    return getattr(request, "client", None)


_WORK: dict[type, str] = {
    SetupChanged: "selecting the pixels for the new setup",
    Solve: "solving",
    Pause: "pausing the solve",
    Reset: "going back to the initial guess",
    Finished: "testing the fit and computing the uncertainties",
    SaveSession: "saving the session",
    LoadSavedSession: "restoring the saved session",
    RestorePrevious: "restoring the previous result",
    ApplySession: "restoring the session",
    SwitchProject: "loading the project",
    PlanViews: "planning the next views",
    BuildPhotoProject: "building the project from the photos",
}


def work_of(request: Request) -> str:
    """What the worker does for `request`, in a few words (the page's busy line)."""
    if isinstance(request, PrepareDownload):
        if request.what == "report":
            return "building the report (every image rendered)"
        return f"preparing the {request.what} download"
    return _WORK.get(type(request), "working")
