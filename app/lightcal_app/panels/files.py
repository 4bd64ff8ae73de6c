"""The Files tab: sessions (save, reload, upload), uploads of a project, an image or a
light's RID file, and a new project from photos (`lightcal_app.panels.photos`). The files
themselves are handled by `FilesService` (and `PhotoService`)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import viser

from lightcal.io.project import Project
from lightcal_app.controller import Controller
from lightcal_app.panels.base import Programmatic, TabPanel
from lightcal_app.panels.photos import PhotosPanel
from lightcal_app.text import md
from lightcal_app.upload_checks import format_size


def autosave_text(session_path: Path | None) -> str:
    """What the Files tab says of the autosave (its file name, never its folder)."""
    if session_path is None:
        return "The session is **not autosaved** (no writable place for it)."
    return (
        "The session (guess, selection, regions, solve) is **autosaved** after every change "
        f"(as {md(session_path.name)}) and restored at start."
    )


class FilesPanel(TabPanel):
    """The Files tab (built in the current GUI container)."""

    def __init__(self, server: viser.ViserServer, ctl: Controller, flag: Programmatic) -> None:
        super().__init__(server, ctl, flag)
        gui = self.gui
        files = ctl.files
        self.autosave_md = gui.add_markdown(autosave_text(files.session_path))
        self.save_session = gui.add_button("Save session", icon=viser.Icon.DEVICE_FLOPPY)
        self.reload_session = gui.add_button("Reload saved session")
        self.upload_session = gui.add_upload_button("Load a session file", mime_type=".json")
        gui.add_markdown(
            f"**Uploads** (at most {format_size(files.upload_limit)} per file; a zip may unpack "
            "to 500 MB): "
            "a project (zip of project.json, camera file and images, or a project file), "
            "an image replacing the project image of the same file name, or an IES/LDT file "
            "as a light's RID. Every upload is checked with the project readers first."
        )
        self.upload_project = gui.add_upload_button(
            "Upload a project", mime_type=".zip,.json,.yaml,.yml"
        )
        self.upload_image = gui.add_upload_button(
            "Upload an image", mime_type="image/*,.tif,.tiff,.npy,.exr,.dng"
        )
        names = [u.initial.name for u in ctl.state.project.lights]
        self.rid_light = gui.add_dropdown("RID file for light", names, initial_value=names[0])
        self.upload_rid = gui.add_upload_button("Upload an IES/LDT file", mime_type=".ies,.ldt")
        with gui.add_folder("New project from photos"):
            self.photos = PhotosPanel(server, ctl, flag)
        self.save_session.on_click(lambda e: ctl.save_session(e.client))
        self.reload_session.on_click(lambda e: ctl.load_saved_session(e.client))
        self._on_upload(self.upload_session, files.upload_session)
        self._on_upload(self.upload_project, files.upload_project)
        self._on_upload(self.upload_image, files.upload_image)
        self._on_upload(
            self.upload_rid,
            lambda name, content, client: files.upload_rid(
                name, content, self.rid_light.value, client
            ),
        )

    @staticmethod
    def _on_upload(handle: Any, receive: Callable[[str, bytes, Any], None]) -> None:
        def cb(event: Any) -> None:
            f = handle.value
            receive(f.name, f.content, event.client)

        handle.on_upload(cb)

    def set_project(self, project: Project) -> None:
        self.rid_light.options = [u.initial.name for u in project.lights]
        # Another project autosaves elsewhere: name the file it saves to now.
        self.autosave_md.content = autosave_text(self.ctl.files.session_path)
