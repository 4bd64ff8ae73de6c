"""A new project from photos in the app, without a browser: uploads into the staging area
(`lightcal_app.photo_project`), the build on the worker, the switch to the new project.

Uploads are checked in the callback that received them (a refusal is a message to that
browser); **Build project** queues `BuildPhotoProject`, whose handler runs on the worker:
it says each step in the page's busy line ("building the project: image 3 of 12"), then
shows the new project through `FilesService.switch_project` (as an uploaded project)
and writes a message naming every rejected photo with its reason. The panel is told of
every change through `listeners`.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Sequence
from typing import Any

from lightcal.errors import LightcalError
from lightcal_app.files_service import FilesService, received_or_refused
from lightcal_app.limits import check_position_m
from lightcal_app.photo_project import (
    PhotoBuild,
    PhotoKind,
    PhotoOptions,
    PhotoStaging,
    Staged,
    check_half_angle,
)
from lightcal_app.requests import BuildPhotoProject, SwitchProject
from lightcal_app.solve_service import Notify

log = logging.getLogger("lightcal.app")

PHOTOS_FOLDER = "photos"
"""The staging areas' folder under the app's state folder."""


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

    def request_build(
        self, *, half_angle_deg: float, initial_position_mm: Sequence[float], client: Any = None
    ) -> None:
        """Queue the build (refused at once when something is missing or a value is out
        of range)."""
        try:
            half = check_half_angle(half_angle_deg)
            position = check_position_m([float(v) / 1000.0 for v in initial_position_mm])
        except (LightcalError, TypeError, ValueError) as exc:
            self.notify(client, "Value refused", str(exc), error=True)
            return
        staged = self.staging.staged()
        if staged.missing:
            self.notify(client, "Not ready to build", "Missing: " + "; ".join(staged.missing) + ".")
            return
        x, y, z = (float(v) for v in position)
        self.files.state.request(BuildPhotoProject(half, (x, y, z), client=client))

    # ------------------------------------------------------------------ worker

    def build(self, req: BuildPhotoProject) -> None:
        """Build the project, show it, and name the rejected photos (worker)."""
        options = PhotoOptions(
            half_angle_deg=req.half_angle_deg, initial_position_m=req.initial_position_m
        )

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
