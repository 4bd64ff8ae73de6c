"""The Files tab's "New project from photos": upload buttons for each kind of file, what
`lightcal init` asks besides the files (the light's half angle, its initial position and
axis, the photos' black and white levels, and in a folder the detection options and the
poses' systematic floor), what was received and what is missing, Build, and after a build
the table of the photos (accepted, or rejected with the reason), the chessboard photos'
calibration with its warnings, and the built project's zip.

The level fields are prefilled with what the first wall photo's file gives (a raw file's
metadata, else 0 and 2^bits - 1) whenever that changes, unless the user has typed into
them since the last prefill: viser's update stamp of the field is newer than the one its
last prefill left (a white level of 0 is none: float photos).

The files and the build are `PhotoService`'s (`lightcal_app.photo_service`); this panel
only passes the uploads and the clicks on, and writes the service's state into its
widgets whenever the service says it changed.
"""

from __future__ import annotations

import threading
from typing import Any

import viser

from lightcal.io.images import RAW_EXTENSIONS
from lightcal_app.controller import Controller
from lightcal_app.limits import POSITION_LIMIT_M
from lightcal_app.panels.base import Programmatic, TabPanel
from lightcal_app.photo_project import (
    DEFAULT_HALF_ANGLE_DEG,
    LABELS,
    MAX_MASK_MARGIN_PX,
    PhotoKind,
    outcomes_markdown,
    staged_markdown,
)
from lightcal_app.photo_service import PhotoFields
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
    ("Response curve (8-bit photos)", "response", ".json,.npy"),
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
            "file; for 8-bit photos (JPEG) the camera's response curve (`lightcal response`) "
            f"or the box below. One file per press, or a zip of them ({limit} per file)."
        )
        self.uploads: dict[PhotoKind, Any] = {}
        for label, kind, types in BUTTONS:
            handle = gui.add_upload_button(label, icon=viser.Icon.UPLOAD, mime_type=types)
            self.uploads[kind] = handle
            self._on_upload(handle, kind)
        self.half_angle = gui.add_number(
            LABELS["half_angle_deg"],
            DEFAULT_HALF_ANGLE_DEG,
            min=0.5,
            max=89.5,
            step=0.5,
            hint="the light's half-intensity angle (a cos^m profile), used without a light file "
            "when ticked below",
        )
        self.half_angle_known = gui.add_checkbox(
            LABELS["half_angle_known"],
            False,
            hint="without a light file: ticked, the cos^m profile of this half angle; "
            "unticked, its exponent is estimated with the pose (from 30 degrees), as "
            "lightcal init without --half-angle-deg",
        )
        limit_mm = POSITION_LIMIT_M * 1e3
        self.initial_auto = gui.add_checkbox(
            LABELS["initial_auto"],
            True,
            hint="the initial guess from the beam in the photos (initial: auto, as lightcal "
            "init without --initial-position); untick to use the position and axis below",
        )
        self.initial_position = gui.add_vector3(
            LABELS["initial_position_mm"],
            (0.0, 0.0, 0.0),
            min=(-limit_mm,) * 3,
            max=(limit_mm,) * 3,
            step=1.0,
            hint="the initial guess of the light in the camera frame (x right, y down, z "
            "forward); the Light tab changes it after the build too",
        )
        self.initial_axis = gui.add_vector3(
            LABELS["initial_axis"],
            (0.0, 0.0, 1.0),
            min=(-1.0,) * 3,
            max=(1.0,) * 3,
            step=0.01,
            hint="the initial guess of the light's axis in the camera frame (0 0 1: the "
            "optical axis)",
        )
        self.black_level = gui.add_number(
            LABELS["black_level"],
            0.0,
            min=0.0,
            step=1.0,
            hint="subtracted from the photos' values (their units); prefilled from a raw "
            "file's metadata, else 0: a PNG or TIFF does not say its sensor's black level",
        )
        self.white_level = gui.add_number(
            LABELS["white_level"],
            65535.0,
            min=0.0,
            step=1.0,
            hint="the photos' clipping level (their units; 0: none, for float photos); "
            "prefilled from a raw file's metadata, else 2^bits - 1 (a 14-bit sensor in a "
            "16-bit PNG: 16383)",
        )
        # Per level field, viser's stamp of its last prefill: a newer one is the user's.
        self.assume_linear = gui.add_checkbox(
            LABELS["assume_linear"],
            False,
            hint="8-bit photos (JPEG) are taken as linear, as lightcal init --assume-linear; "
            "only if the camera really wrote linear values (a response curve, when given, "
            "linearises them instead)",
        )
        self._prefilled = [
            Programmatic.stamp(self.black_level),
            Programmatic.stamp(self.white_level),
        ]
        self._prefill_lock = threading.Lock()
        with gui.add_folder("Detection and pose floors", expand_by_default=False):
            defaults = PhotoFields()
            self.min_markers = gui.add_number(
                LABELS["min_markers"], int(defaults.min_markers), min=1, step=1
            )
            self.mask_margin = gui.add_number(
                LABELS["mask_margin_px"],
                defaults.mask_margin_px,
                min=0.0,
                max=MAX_MASK_MARGIN_PX,
                step=0.5,
                hint="padding of the marker masks",
            )
            self.max_rms = gui.add_number(
                LABELS["max_rms_px"],
                defaults.max_rms_px,
                min=0.01,
                step=0.05,
                hint="photos whose marker reprojection RMS exceeds this are rejected",
            )
            self.pose_floor_mm = gui.add_number(
                LABELS["pose_floor_mm"],
                defaults.pose_floor_mm,
                min=0.0,
                step=0.05,
                hint="systematic error of the marker poses added to each pose's covariance, "
                "per camera centre coordinate",
            )
            self.pose_floor_deg = gui.add_number(
                LABELS["pose_floor_deg"],
                defaults.pose_floor_deg,
                min=0.0,
                step=0.01,
                hint="the same for each rotation component",
            )
        self.staged_md = gui.add_markdown("")
        self.build = gui.add_button("Build project", icon=viser.Icon.HAMMER, disabled=True)
        self.clear = gui.add_button("Clear the photos", icon=viser.Icon.TRASH)
        self.outcomes_md = gui.add_markdown("", visible=False)
        self.download = gui.add_button(
            "Download the project (zip)", icon=viser.Icon.DOWNLOAD, disabled=True
        )
        self.build.on_click(lambda e: photos.request_build(self.fields(), client=e.client))
        self.clear.on_click(lambda e: photos.clear(e.client))
        self.download.on_click(lambda e: photos.download_zip(e.client))
        photos.listeners.append(self.refresh)
        self.refresh()

    def fields(self) -> PhotoFields:
        """The build's fields as the page holds them now."""
        return PhotoFields(
            half_angle_deg=float(self.half_angle.value),
            half_angle_known=bool(self.half_angle_known.value),
            initial_position_mm=tuple(self.initial_position.value),
            initial_axis=tuple(self.initial_axis.value),
            initial_auto=bool(self.initial_auto.value),
            black_level=float(self.black_level.value),
            white_level=float(self.white_level.value),
            min_markers=self.min_markers.value,
            mask_margin_px=float(self.mask_margin.value),
            max_rms_px=float(self.max_rms.value),
            pose_floor_mm=float(self.pose_floor_mm.value),
            pose_floor_deg=float(self.pose_floor_deg.value),
            assume_linear=bool(self.assume_linear.value),
        )

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
        self.download.disabled = last is None
        # The levels the photos give, into the fields the user has not typed into since.
        new = (0.0, 65535.0) if staged.levels is None else staged.levels.fields()
        handles: tuple[Any, Any] = (self.black_level, self.white_level)
        with self._prefill_lock:
            for k, (handle, value) in enumerate(zip(handles, new, strict=True)):
                if Programmatic.stamp(handle) > self._prefilled[k]:
                    continue  # typed into since the last prefill: the user's value stays
                if handle.value != value:
                    handle.value = value
                self._prefilled[k] = Programmatic.stamp(handle)
