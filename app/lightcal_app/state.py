"""The app's shared state: one lock, the user's choices, the solve as last reported.

Every browser sees and edits this one state. GUI and scene callbacks (viser's thread
pool) change it only through `AppState` methods under `lock`, mark what must be redrawn
(`dirty`) and queue requests for the worker (`lightcal app`'s one worker thread, see
`lightcal_app.worker`), then `notify()`. Exact values live here; the scene only shows them.
"""

from __future__ import annotations

import dataclasses
import threading
from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

import numpy as np

from lightcal.core.albedo_map import AlbedoMap
from lightcal.core.footprint import SensorModel
from lightcal.core.medium import AIR, Medium
from lightcal.core.scene import Rig
from lightcal.core.selection import SelectionOptions, Strategy
from lightcal.core.solver import IterationReport
from lightcal.core.surroundings import Surroundings
from lightcal.core.wall import LAMBERTIAN, WallReflectance
from lightcal.io.project import Project
from lightcal.pipeline import CalibrationResult, LoadedImages
from lightcal.pipeline.auto_start import with_auto_initial
from lightcal.pipeline.plan import PlannedView, Sigmas
from lightcal_app.requests import Request, SetupChanged
from lightcal_app.solve_settings import SolveSettings, settings_of

if TYPE_CHECKING:  # session_file imports this module
    from lightcal_app.session_file import SessionFile

OverlayKind = Literal["real", "rendered", "residual"]
OVERLAY_KINDS: tuple[OverlayKind, ...] = ("real", "rendered", "residual")
SolverState = Literal["idle", "running", "paused", "converged", "not converged"]
"""One vocabulary for the solve (the reason in plain words is `solver_message`)."""

# What a redraw may have to refresh.
Dirt = Literal[
    "scene", "overlays", "light", "selection", "plots", "status", "result", "widgets", "plan"
]
ALL_DIRT: frozenset[Dirt] = frozenset(
    ("scene", "overlays", "light", "selection", "plots", "status", "result", "widgets", "plan")
)


DEFAULT_ITERATION_S = 0.5
"""Run's default pace in the app: at least half a second per iteration, readable."""
MAX_ITERATION_S = 5.0
"""The slowest pace the Solve tab offers."""

EstimateKey = tuple[int, int, int, str]
"""Which estimate a number was computed for: (setup_rev, session_gen, iteration, solver
state); any change of the guess, the selection or the solve changes it."""


@dataclass(frozen=True)
class LightGuess:
    """The pose of one light the user set (camera frame).

    Attributes:
        t_camera_light: (3,) emitter position in the camera frame, m (the library's name,
            `lightcal.core.scene.Light.t_camera_light`).
        R_camera_light: (3, 3) rotation light -> camera.
    """

    t_camera_light: np.ndarray
    R_camera_light: np.ndarray


@dataclass(frozen=True)
class SelectionSettings:
    """How pixels are chosen (the editable part of `SelectionOptions`, its defaults)."""

    strategy: Strategy = SelectionOptions.strategy
    n_per_image: int = SelectionOptions.n_per_image
    grid_step: int = SelectionOptions.grid_step
    binning: int = SelectionOptions.binning
    seed: int = SelectionOptions.seed


@dataclass(frozen=True)
class SolveEnd:
    """How a finished solve ended, kept in a saved session so that a reload shows it.

    Attributes:
        state: "converged" or "not converged".
        status: the solver's status code (`SolveOutcome.status`).
        message: the solver's own message (`stop_reason` puts it in plain words).
        time_s: the solver's time (pauses excluded), s.
        weights_at: (n,) the parameters its pixel weights were rendered at (the solve's
            re-weighting; `CalibrationModel.set_weights_at`), None: the data's sigmas.
    """

    state: Literal["converged", "not converged"]
    status: int
    message: str
    time_s: float
    weights_at: np.ndarray | None = None


@dataclass(frozen=True)
class PreviousResult:
    """A finished result the user's edits replaced by a new draft, kept for undo.

    Attributes:
        session: the settings and the solve as they were when it finished (restoring it
            brings back both).
        result: the result, for the page to show.
        state: "converged" or "not converged".
    """

    session: SessionFile
    result: CalibrationResult
    state: SolverState


@dataclass(frozen=True)
class Readout:
    """The pose's 1-sigma uncertainty at an estimate (the Plan tab's live read-out).

    Attributes:
        sigmas: per light, position (m) and axis (deg) sigmas, and the D-criterion.
        light_names: one per light.
        where: the estimate, in words ("the initial guess", "iteration 4", ...).
        noise: where s^2 (the pixel noise) came from, in words.
        key: the estimate it belongs to (`AppState.estimate_key`).
    """

    sigmas: Sigmas
    light_names: tuple[str, ...]
    where: str
    noise: str
    key: EstimateKey


@dataclass(frozen=True)
class PlanShown:
    """The next views suggested for an estimate (`lightcal.pipeline.plan`).

    Attributes:
        now: the read-out of the estimate planned for.
        views: the chosen views, best first, each with its sigmas before and after.
    """

    now: Readout
    views: tuple[PlannedView, ...]


@dataclass(frozen=True)
class UserRegion:
    """An include/exclude region drawn in the app.

    Attributes:
        kind: "rect" (2 opposite corners) or "polygon" (>= 3 vertices).
        points: (K, 2) vertices (u, v) in full-resolution pixel coordinates.
        include: include (True) or exclude (False).
        image: the image name it applies to; None for every image.
    """

    kind: Literal["rect", "polygon"]
    points: tuple[tuple[float, float], ...]
    include: bool
    image: str | None


@dataclass(frozen=True)
class Display:
    """What the rendered overlays and the light show.

    Attributes:
        rig: the lights (estimate while solving, else the initial guess with fitted scale).
        gains: per project image, the gain on top of its exposure.
        offset: the offset added to every value.
        source: "guess" or "estimate".
        setup_rev: the state's `setup_rev` of the guess and selection it was made from;
            after an edit of either (a newer `setup_rev`) it is out of date until the
            worker replaces it, and the widgets show the state's guess instead.
        wall: the wall's reflectance the overlays render with (the estimate's: a
            plastic wall `auto` chose renders its highlight).
        fall_off: the camera's fall-off model they render with (`sensor.model` of the
            project solved); None: the loaded project's.
        medium: the medium between the rig and the wall they render through (the
            estimate's when its attenuation is estimated).
        fall_off_coeffs: (K,) the estimated radial fall-off's c_1..c_K
            (`sensor.estimate_fall_off`; `lightcal.core.fall_off`); empty: none.
        ambient: the estimated room light a (value at exposure and gain 1; 0: none).
        albedo: the estimated albedo map of the wall (`wall.albedo_map`); None: an
            even wall.
        surroundings: the surfaces whose bounce light they add (the project solved's
            `surroundings`, as the page edits them); None: none.
        channels: per colour channel solved jointly (`sensor.channels`), its (lights,
            medium, room light); `rig`, `medium` and `ambient` are the first's. Empty:
            one channel.
        surface_albedos: the surroundings' surfaces' albedos the solve estimates (empty:
            the declared).
    """

    rig: Rig
    gains: tuple[float, ...]
    offset: float
    source: Literal["guess", "estimate"]
    setup_rev: int
    wall: WallReflectance = LAMBERTIAN
    fall_off: SensorModel | None = None
    medium: Medium = AIR
    fall_off_coeffs: tuple[float, ...] = ()
    ambient: float = 0.0
    albedo: AlbedoMap | None = None
    surroundings: Surroundings | None = None
    channels: tuple[tuple[Rig, Medium, float], ...] = ()
    surface_albedos: tuple[float, ...] = ()

    def of_channel(self, channel: int) -> Display:
        """The display of one colour channel's images: its lights' scales, medium and
        room light (itself without channels)."""
        if not self.channels:
            return self
        rig, medium, ambient = self.channels[channel]
        return dataclasses.replace(self, rig=rig, medium=medium, ambient=ambient)

    def current(self, state: AppState) -> bool:
        """Made from the guess and selection the state holds now (call under the lock)."""
        return self.setup_rev == state.setup_rev


@dataclass
class Download:
    """A file prepared for one browser (tests read it when no browser asked)."""

    name: str
    content: bytes


class AppState:
    """Everything the browsers share. Use `lock` for every access.

    Args:
        project: the project shown.
        loaded: its images.
    """

    def __init__(self, project: Project, loaded: LoadedImages) -> None:
        self.lock = threading.RLock()
        self.cond = threading.Condition(self.lock)
        self.closing = False
        self.requests: deque[Request] = deque()
        self.dirty: set[Dirt] = set(ALL_DIRT)
        self.messages: list[tuple[str, str]] = []  # (title, body) shown in the page
        self.downloads: list[Download] = []
        self.load_project(project, loaded)

    # -- project --------------------------------------------------------------------------

    def load_project(self, project: Project, loaded: LoadedImages) -> None:
        """Show a (new) project: every choice back to the project's defaults. A light
        whose file says `initial: auto` starts on its beam, as `lightcal calibrate` does
        (InputError when no image shows it)."""
        project = with_auto_initial(project, loaded)
        self.project = project
        self.loaded = loaded
        self.guess: list[LightGuess] = [
            LightGuess(u.initial.t_camera_light.copy(), u.initial.R_camera_light.copy())
            for u in project.lights
        ]
        sel = project.selection
        self.selection = SelectionSettings(
            sel.strategy, sel.n_per_image, sel.grid_step, sel.binning, sel.seed
        )
        self.selection_per_image: dict[str, SelectionSettings] = {}
        # What the solve fits (the Solve tab), and the project it solves (the loaded one
        # with those keys set: `solve_settings.project_for_solve`).
        self.solve_settings: SolveSettings = settings_of(project)
        self.solve_project: Project = project
        self.regions: list[UserRegion] = []
        self.points: dict[str, list[tuple[int, int]]] = {}
        self.overlay_default: OverlayKind = "real"
        self.overlay_per_image: dict[str, OverlayKind] = {}
        self.show_selection = True
        self.show_albedo = True  # the estimated albedo map on the wall (View tab)
        self.rays_image: str = project.names[0]
        self.focus_image: str | None = None  # highlighted, the others dimmed (View tab)
        self.ref_image = 0
        # Selection as computed by the worker: per project image, the (N, 2) chosen
        # (super-)pixels, their binning, and the footprint centres (N, 3) on the wall.
        self.selected: list[np.ndarray] = [np.zeros((0, 2), np.int64) for _ in project.names]
        self.selected_binning: list[int] = [1 for _ in project.names]
        self.selected_wall_points: list[np.ndarray] = [np.zeros((0, 3)) for _ in project.names]
        self.selection_rev_done = -1
        self.setup_rev = 0  # bumped by every change of guess or selection
        self.selection_rev = 0  # bumped by every change of the selection only
        self.session_gen = 0  # bumped whenever the solve is thrown away
        self.solver_state: SolverState = "idle"
        self.solver_message = ""
        self.history: list[IterationReport] = []
        self.parameter_names: list[str] = []
        self.result: CalibrationResult | None = None
        self.display: Display | None = None
        self.resume_x: np.ndarray | None = None
        self.resume_end: SolveEnd | None = None  # a restored solve that had finished
        # The parameters the finished result's pixel weights were rendered at (its model's
        # `weights_at`), kept in the session so that a restored result is computed alike.
        self.result_weights_at: np.ndarray | None = None
        # The settings and solve at the end of the last finished solve (a SessionFile),
        # and the finished result an edit or a reset replaced (kept, with undo).
        self.finished_snapshot: SessionFile | None = None
        self.previous: PreviousResult | None = None
        # Run's pace in a page: each iteration stays at least this long (0: as fast as
        # drawn); only a solve followed by a page waits (SolveService.follow_iterations).
        self.min_iteration_s = DEFAULT_ITERATION_S
        self.drawn: tuple[int, int] = (-1, -1)  # (session_gen, iteration) last drawn
        # Capture planning (Plan tab): the last plan, the live read-out, the ghost frusta.
        self.plan: PlanShown | None = None
        self.readout: Readout | None = None
        self.show_plan = True
        self.changed = True  # something worth autosaving happened
        self.dirty = set(ALL_DIRT)

    # -- requests -------------------------------------------------------------------------

    def request(self, request: Request) -> None:
        """Queue a request for the worker (call with or without the lock held)."""
        with self.cond:
            self.requests.append(request)
            self.cond.notify_all()

    def mark(self, *dirt: Dirt, changed: bool = False) -> None:
        """Mark parts of the page for redrawing; `changed`: worth autosaving."""
        with self.cond:
            self.dirty.update(dirt)
            self.changed = self.changed or changed
            self.cond.notify_all()

    def setup_changed(self, *, selection: bool) -> None:
        """The initial guess or the selection changed: the solve starts over."""
        with self.cond:
            self.setup_rev += 1
            if selection:
                self.selection_rev += 1
            self.request(SetupChanged())
            self.mark("light", "overlays", "selection", "widgets", "status", changed=True)

    def estimate_key(self) -> EstimateKey:
        """The estimate shown now (call under the lock): see `EstimateKey`."""
        it = self.history[-1].iteration if self.history else -1
        return (self.setup_rev, self.session_gen, it, self.solver_state)

    def shown_estimate(self) -> Display | None:
        """The display of the solve's estimate of the guess and selection held now, if
        there is one (call under the lock): what the Light tab's fields show."""
        d = self.display
        return d if d is not None and d.source == "estimate" and d.current(self) else None

    def shown_medium(self) -> Medium:
        """The water's values the page shows (call under the lock): the solve's estimate
        of the setup held now, else the values the solve starts from."""
        estimate = self.shown_estimate()
        return estimate.medium if estimate is not None else self.solve_project.medium.initial

    def shown_media(self) -> tuple[Medium, ...]:
        """`shown_medium` of each colour channel (`sensor.channels`; call under the lock):
        one without channels."""
        estimate = self.shown_estimate()
        if estimate is not None and estimate.channels:
            return tuple(medium for _, medium, _ in estimate.channels)
        if estimate is not None or not self.solve_project.media:
            return (self.shown_medium(),)
        return tuple(m.initial for m in self.solve_project.media)

    def image_index(self, name: str) -> int:
        """Index of an image by name (ValueError naming it when unknown)."""
        try:
            return self.project.names.index(name)
        except ValueError:
            raise ValueError(
                f"image: expected one of {', '.join(self.project.names)}, got {name!r}"
            ) from None

    def overlay_of(self, index: int) -> OverlayKind:
        """What the frustum of image `index` shows."""
        return self.overlay_per_image.get(self.project.names[index], self.overlay_default)

    def selection_of(self, index: int) -> SelectionSettings:
        """The selection settings of image `index` (its own, else the global ones)."""
        return self.selection_per_image.get(self.project.names[index], self.selection)

    def regions_of(self, index: int) -> list[UserRegion]:
        """The user regions that apply to image `index`."""
        name = self.project.names[index]
        return [r for r in self.regions if r.image is None or r.image == name]


@dataclass(frozen=True)
class Frame:
    """A consistent copy of what one redraw shows (taken under the lock).

    Attributes:
        dirty: what to refresh.
        session_gen, iteration: the solve and iteration shown.
        display: lights, gains, offset to render with (None: not computed yet).
        guess: the user's guess per light.
        overlay: per image what its frustum shows.
        selected, selected_binning, wall_points: the selection per image.
        regions: per image the user regions that apply.
        points: per image the clicked pixels.
        show_selection: draw the selection on the images.
        show_albedo: draw the estimated albedo map on the wall.
        rays_image: image whose rays are drawn ("all", "none" or a name).
        ref_image: the image whose camera carries the gizmo.
        solver_state, solver_message, history, parameter_names, result: the solve.
        plan, readout, show_plan: the Plan tab's suggested views and read-out.
        estimate_key: the estimate shown (stale plans and read-outs differ from it).
        focus_image: the image highlighted (the others dimmed), None: none.
    """

    dirty: frozenset[Dirt]
    session_gen: int
    iteration: int
    display: Display | None
    guess: tuple[LightGuess, ...]
    overlay: tuple[OverlayKind, ...]
    selected: tuple[np.ndarray, ...]
    selected_binning: tuple[int, ...]
    wall_points: tuple[np.ndarray, ...]
    regions: tuple[tuple[UserRegion, ...], ...]
    points: tuple[tuple[tuple[int, int], ...], ...]
    show_selection: bool
    rays_image: str
    ref_image: int
    solver_state: SolverState
    solver_message: str
    history: tuple[IterationReport, ...]
    parameter_names: tuple[str, ...]
    result: CalibrationResult | None
    selection_summary: tuple[int, ...] = field(default=())
    previous: PreviousResult | None = None
    plan: PlanShown | None = None
    readout: Readout | None = None
    show_plan: bool = True
    estimate_key: EstimateKey = (0, 0, -1, "idle")
    focus_image: int | None = None
    show_albedo: bool = True


def take_frame(state: AppState) -> Frame:
    """Copy what a redraw needs and clear the dirty flags (call under `state.lock`)."""
    names = state.project.names
    n = len(names)
    it = state.history[-1].iteration if state.history else -1
    frame = Frame(
        dirty=frozenset(state.dirty),
        session_gen=state.session_gen,
        iteration=it,
        display=state.display,
        guess=tuple(state.guess),
        overlay=tuple(state.overlay_of(i) for i in range(n)),
        selected=tuple(state.selected),
        selected_binning=tuple(state.selected_binning),
        wall_points=tuple(state.selected_wall_points),
        regions=tuple(tuple(state.regions_of(i)) for i in range(n)),
        points=tuple(tuple(state.points.get(nm, [])) for nm in names),
        show_selection=state.show_selection,
        rays_image=state.rays_image,
        ref_image=state.ref_image,
        solver_state=state.solver_state,
        solver_message=state.solver_message,
        previous=state.previous,
        history=tuple(state.history),
        parameter_names=tuple(state.parameter_names),
        result=state.result,
        selection_summary=tuple(len(s) for s in state.selected),
        plan=state.plan,
        readout=state.readout,
        show_plan=state.show_plan,
        estimate_key=state.estimate_key(),
        focus_image=None if state.focus_image is None else names.index(state.focus_image),
        show_albedo=state.show_albedo,
    )
    state.dirty.clear()
    return frame
