"""A new project from photos in the app, without a browser: uploads into the staging area
(`lightcal_app.photo_project`), the build on the worker, the switch to the new project.

Uploads are checked in the callback that received them (a refusal is a message to that
browser); **Build project** queues `BuildPhotoProject`, whose handler runs on the worker:
it says each step in the page's busy line ("building the project: image 3 of 12"), then
shows the new project through `FilesService.switch_project` (as an uploaded project)
and writes a message naming every rejected photo with its reason. The panel is told of
every change through `listeners`.

The page's fields (`PhotoFields`: levels, initial guess, `lightcal init`'s detection
options and pose floors) are checked when Build is pressed (`check_fields`: the checks
of `lightcal.capture.init_checks`, each refusal naming the field as the page labels it).
**Download the project (zip)** sends the last build with every file it reads
(`photo_build.project_zip_bytes`).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

from lightcal.capture.init_checks import (
    POSE_FLOOR_DEG,
    POSE_FLOOR_M,
    axis_problem,
    check_detection,
    check_levels,
    check_pose_floor,
    vector3,
)
from lightcal.errors import InputError, LightcalError
from lightcal_app.files_service import FilesService, received_or_refused
from lightcal_app.limits import check_position_m
from lightcal_app.photo_build import project_zip_bytes
from lightcal_app.photo_project import (
    DEFAULT_HALF_ANGLE_DEG,
    LABELS,
    MAX_MASK_MARGIN_PX,
    FileLevels,
    PhotoBuild,
    PhotoKind,
    PhotoOptions,
    PhotoStaging,
    Staged,
    check_half_angle,
)
from lightcal_app.requests import BuildPhotoProject, SwitchProject
from lightcal_app.solve_service import Notify
from lightcal_app.upload_checks import format_size

log = logging.getLogger("lightcal.app")

PHOTOS_FOLDER = "photos"
"""The staging areas' folder under the app's state folder."""

ZIP_NAME = "project-from-photos.zip"


@dataclass(frozen=True)
class PhotoFields:
    """The page's fields of a build as typed (`check_fields` makes the options of them).

    The levels are prefilled with the photos' own (`FileLevels.fields`); a white level
    of 0 (or None) is none (float photos). The other names and units are `lightcal init`'s
    options (`LABELS`: the page's label of each).
    """

    half_angle_deg: float = DEFAULT_HALF_ANGLE_DEG
    half_angle_known: bool = False
    initial_position_mm: Sequence[float] = (0.0, 0.0, 0.0)
    initial_axis: Sequence[float] = (0.0, 0.0, 1.0)
    initial_auto: bool = True
    black_level: float | None = None
    white_level: float | None = None
    min_markers: int | float = 4
    mask_margin_px: float = 3.0
    max_rms_px: float = 1.0
    pose_floor_mm: float = POSE_FLOOR_M * 1e3
    pose_floor_deg: float = POSE_FLOOR_DEG
    assume_linear: bool = False


T = TypeVar("T")


def _as_field(check: Callable[[], T], names: dict[str, str]) -> T:
    """`check()`, its refusal naming the page's field (`names`: the library's name -> it)."""
    try:
        return check()
    except InputError as exc:
        detail = exc.detail
        for name, label in names.items():  # "above black_level (512)": the page's words
            detail = detail.replace(name, label)
        raise InputError(names.get(exc.source, exc.source), detail) from exc


def check_fields(fields: PhotoFields, levels: FileLevels | None = None) -> PhotoOptions:
    """The build's options of the page's fields, with `lightcal init`'s checks
    (`lightcal.capture.init_checks`).

    A level equal to the files' own (`levels`) is passed as None: the reader then applies
    the file's own (a raw file's per colour channel), as `lightcal init` without the option.

    Raises:
        InputError: naming the field as the page labels it.
    """
    half = check_half_angle(fields.half_angle_deg)
    position = _as_field(
        lambda: check_position_m([float(v) / 1e3 for v in fields.initial_position_mm]),
        {"light position": LABELS["initial_position_mm"]},
    )
    axis = vector3(LABELS["initial_axis"], fields.initial_axis)
    if (problem := axis_problem(axis)) is not None:
        shown = ", ".join(f"{v:g}" for v in axis)
        raise InputError(LABELS["initial_axis"], f"{problem}, got ({shown})")
    black = None if fields.black_level is None else float(fields.black_level)
    white = None if fields.white_level in (None, 0) else float(fields.white_level)
    _as_field(lambda: check_levels(black, white), LABELS)
    if levels is not None and (black is None) != (white is None):
        # One level typed: it must suit the other, the photos' own.
        low = levels.black if black is None else black
        high = levels.white if white is None else white
        if high is not None and not high > low:
            key, other, bound = (
                ("black_level", "white", high) if white is None else ("white_level", "black", low)
            )
            side = "below" if key == "black_level" else "above"
            got = black if white is None else white
            raise InputError(
                LABELS[key],
                f"expected a value {side} the photos' {other} level ({bound:g}), got {got:g}",
            )
    if levels is not None:
        black = None if black == levels.black else black
        white = None if white == levels.white else white
    value = fields.min_markers
    if isinstance(value, bool) or not (isinstance(value, int) or float(value).is_integer()):
        raise InputError(LABELS["min_markers"], f"expected an integer >= 1, got {value!r}")
    markers = int(value)
    margin, rms = float(fields.mask_margin_px), float(fields.max_rms_px)
    _as_field(lambda: check_detection(markers, margin, rms), LABELS)
    if not margin <= MAX_MASK_MARGIN_PX:
        raise InputError(
            LABELS["mask_margin_px"],
            f"expected a padding of 0 to {MAX_MASK_MARGIN_PX:g} pixels, got {margin:g}",
        )
    floor_mm, floor_deg = float(fields.pose_floor_mm), float(fields.pose_floor_deg)
    check_pose_floor(floor_mm, floor_deg, (LABELS["pose_floor_mm"], LABELS["pose_floor_deg"]))
    x, y, z = (float(v) for v in position)
    ax, ay, az = axis
    return PhotoOptions(
        half_angle_deg=half if fields.half_angle_known else None,
        initial_position_m=None if fields.initial_auto else (x, y, z),
        initial_axis_camera=None if fields.initial_auto else (ax, ay, az),
        black_level=black,
        white_level=white,
        min_markers=markers,
        mask_margin_px=margin,
        max_rms_px=rms,
        pose_floor_m=floor_mm / 1e3,
        pose_floor_deg=floor_deg,
        assume_linear=bool(fields.assume_linear),
    )


class PhotoService:
    """The staging area of a new project and its build.

    Args:
        files: the files service (its state folder, the folders the project shown reads,
            the project switch).
        notify: shows a message in the page.
        show_work: the page's busy line.
    """

    def __init__(
        self, files: FilesService, *, notify: Notify, show_work: Callable[[str], None]
    ) -> None:
        self.files = files
        self.notify = notify
        self.show_work = show_work
        self.staging = PhotoStaging(
            files.state_dir / PHOTOS_FOLDER, limit=files.upload_limit, keep=files.kept_folders
        )
        self.listeners: list[Callable[[], None]] = []
        self._lock = threading.Lock()
        self._last: PhotoBuild | None = None
        self._options: dict[int, tuple[BuildPhotoProject, PhotoOptions]] = {}

    @property
    def last_build(self) -> PhotoBuild | None:
        """The last project built (None before the first)."""
        with self._lock:
            return self._last

    def staged(self) -> Staged:
        return self.staging.staged()

    def _changed(self) -> None:
        for listener in list(self.listeners):
            try:
                listener()
            except Exception:  # the panel is a courtesy: never fail an upload for it
                log.debug("photo panel refresh failed", exc_info=True)

    # ------------------------------------------------------------------ callbacks

    def upload(self, kind: PhotoKind, name: str, content: bytes, client: Any = None) -> None:
        """A file (or a zip) for the new project; a refusal is said in the page."""
        try:
            received = received_or_refused(
                self.notify, client, name, lambda: self.staging.receive(kind, name, content)
            )
        finally:
            self._changed()
        if received is None:
            return
        if received.ignored or len(received.placed) > 1:  # a zip: say what it held
            self.notify(client, f"{name} unpacked", received.text())

    def clear(self, client: Any = None) -> None:
        """Forget the files received."""
        try:
            self.staging.clear()
        except LightcalError as exc:
            self.notify(client, "Not cleared", str(exc), error=True)
            return
        with self._lock:
            self._last = None
        self._changed()

    def request_build(self, fields: PhotoFields, client: Any = None) -> None:
        """Queue the build (refused at once when something is missing or a field's value
        is not one `lightcal init` takes, the refusal naming the field)."""
        staged = self.staging.staged()
        try:
            options = check_fields(fields, staged.levels)
        except (LightcalError, TypeError, ValueError) as exc:
            self.notify(client, "Value refused", str(exc), error=True)
            return
        if staged.missing:
            self.notify(client, "Not ready to build", "Missing: " + "; ".join(staged.missing) + ".")
            return
        req = BuildPhotoProject(options.half_angle_deg, options.initial_position_m, client=client)
        with self._lock:
            # The request carries the half angle and position; the other options wait
            # here for it (by identity: the request is the key's owner).
            self._options[id(req)] = (req, options)
        self.files.state.request(req)

    def _options_of(self, req: BuildPhotoProject) -> PhotoOptions:
        with self._lock:
            entry = self._options.pop(id(req), None)
        if entry is not None and entry[0] is req:
            return entry[1]
        return PhotoOptions(
            half_angle_deg=req.half_angle_deg, initial_position_m=req.initial_position_m
        )

    def project_zip(self) -> tuple[str, bytes]:
        """The last build as a zip (`photo_build.project_zip_bytes`) and its file name.

        Raises:
            InputError: no project built yet, or its files are gone.
        """
        built = self.last_build
        if built is None:
            raise InputError("new project", "no project built yet: press Build project first")
        try:
            return ZIP_NAME, project_zip_bytes(built)
        except OSError as exc:
            raise InputError(
                "new project", f"its files are gone ({type(exc).__name__}): build it again"
            ) from exc

    def download_zip(self, client: Any = None) -> None:
        """Send the last build as a zip to the browser that asked."""
        try:
            name, content = self.project_zip()
        except LightcalError as exc:
            self.notify(client, "No project to download", str(exc), error=True)
            return
        if client is not None:
            self.files.deliver(client, name, content)
        self.notify(
            client,
            "Project zip ready",
            f"{name} ({format_size(len(content))}) sent as a download: unzip it and run "
            "lightcal calibrate project.json in its folder.",
        )

    def build(self, req: BuildPhotoProject) -> None:
        """Build the project, show it, and name the rejected photos (worker)."""
        options = self._options_of(req)

        def progress(text: str) -> None:
            try:
                self.show_work(f"building the project: {text}")
            except Exception:  # the busy line is a courtesy
                log.debug("busy line failed", exc_info=True)

        try:
            built = self.staging.build(progress, options)
        except LightcalError as exc:
            self.notify(req.client, "Project not built", str(exc), error=True)
            return
        finally:
            self._changed()
        with self._lock:
            self._last = built
        n_ok, n = len(built.accepted), len(built.photos)
        note = (
            f"Project built from the photos: {n_ok} of {n} accepted; camera: {built.camera.text()}."
        )
        note += "".join(f"\n- chessboard photos: {w}" for w in built.camera.warnings)
        note += "".join(f"\n- {w}" for w in built.warnings)
        progress("drawing the new project")
        self.files.switch_project(
            SwitchProject(built.project, built.loaded, None, False, note, client=req.client)
        )
        rejected = built.rejected
        if rejected:
            body = "; ".join(f"{p.name}: {p.reason}" for p in rejected)
            self.notify(
                req.client,
                f"{len(rejected)} of {n} photos rejected",
                body,
                error=True,
            )
        self._changed()
