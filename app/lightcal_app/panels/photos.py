"""The Files tab's "New project from photos": upload buttons for each kind of file, the
light's half angle and initial position, what was received and what is missing, Build,
and after a build the table of the photos (accepted, or rejected with the reason).

The files and the build are `PhotoService`'s (`lightcal_app.photo_service`); this panel
only passes the uploads and the clicks on, and writes the service's state into its
widgets whenever the service says it changed.
"""

from __future__ import annotations

from typing import Any

import viser

from lightcal.io.images import RAW_EXTENSIONS
from lightcal_app.controller import Controller
from lightcal_app.limits import POSITION_LIMIT_M
from lightcal_app.panels.base import Programmatic, TabPanel
from lightcal_app.photo_project import (
    DEFAULT_HALF_ANGLE_DEG,
    PhotoKind,
    outcomes_markdown,
    staged_markdown,
)
from lightcal_app.upload_checks import format_size

IMAGE_TYPES = ",".join(
    ["image/*", ".png", ".jpg", ".jpeg", ".tif", ".tiff", ".npy", ".exr", *sorted(RAW_EXTENSIONS)]
)
"""What the photo buttons offer in the browser's file dialog (a zip too)."""

# Button label, kind, file types offered.
BUTTONS: tuple[tuple[str, PhotoKind, str], ...] = (
    ("Wall photos", "wall", IMAGE_TYPES + ",.zip"),
    ("Camera file", "camera", ".yaml,.yml,.xml,.json,.txt,.zip"),
    ("Chessboard photos", "chessboard", IMAGE_TYPES + ",.zip"),
    ("Board file", "board", ".yaml,.yml,.json,.zip"),
    ("Light file (IES/LDT)", "light", ".ies,.ldt,.zip"),
)


class PhotosPanel(TabPanel):
    """The "New project from photos" folder (built in the current GUI container)."""

    def __init__(self, server: viser.ViserServer, ctl: Controller, flag: Programmatic) -> None:
        super().__init__(server, ctl, flag)
        gui = self.gui
        photos = ctl.photos
        limit = format_size(ctl.files.upload_limit)
        gui.add_markdown(
            "Build a project from photographs, as `lightcal init` does: photos of the wall "
            "with the printed marker board, the camera file (or photos of a chessboard for "
            "the intrinsics), the board file(s) and, if you have it, the light's IES/LDT "
            f"file. One file per press, or a zip of them ({limit} per file)."
        )
        self.uploads: dict[PhotoKind, Any] = {}
        for label, kind, types in BUTTONS:
            handle = gui.add_upload_button(label, icon=viser.Icon.UPLOAD, mime_type=types)
            self.uploads[kind] = handle
            self._on_upload(handle, kind)
        self.half_angle = gui.add_number(
            "half angle (deg)",
            DEFAULT_HALF_ANGLE_DEG,
            min=0.5,
            max=89.5,
            step=0.5,
            hint="the light's half-intensity angle (a cos^m profile), used without a light file",
        )
        limit_mm = POSITION_LIMIT_M * 1e3
        self.initial_position = gui.add_vector3(
            "initial light (mm)",
            (0.0, 0.0, 0.0),
            min=(-limit_mm,) * 3,
            max=(limit_mm,) * 3,
            step=1.0,
            hint="the initial guess of the light in the camera frame (x right, y down, z "
            "forward); the Light tab changes it after the build too",
        )
        self.staged_md = gui.add_markdown("")
        self.build = gui.add_button("Build project", icon=viser.Icon.HAMMER, disabled=True)
        self.clear = gui.add_button("Clear the photos", icon=viser.Icon.TRASH)
        self.outcomes_md = gui.add_markdown("", visible=False)
        self.build.on_click(
            lambda e: photos.request_build(
                half_angle_deg=float(self.half_angle.value),
                initial_position_mm=tuple(self.initial_position.value),
                client=e.client,
            )
        )
        self.clear.on_click(lambda e: photos.clear(e.client))
        photos.listeners.append(self.refresh)
        self.refresh()

    def _on_upload(self, handle: Any, kind: PhotoKind) -> None:
        photos = self.ctl.photos

        def cb(event: Any) -> None:
            f = handle.value
            photos.upload(kind, f.name, f.content, event.client)

        handle.on_upload(cb)

    def refresh(self) -> None:
        """Write what the staging area holds, and the last build, into the widgets."""
        photos = self.ctl.photos
        staged = photos.staged()
        self.staged_md.content = staged_markdown(staged)
        self.build.disabled = not staged.ready
        last = photos.last_build
        self.outcomes_md.content = outcomes_markdown(last) if last is not None else ""
        self.outcomes_md.visible = last is not None
