"""The Result tab: the estimate with its uncertainties, the fit test's picture, downloads."""

from __future__ import annotations

import numpy as np
import viser

from lightcal.io.cause_figure import cause_figure
from lightcal.io.figures import angle_residual_figure
from lightcal_app.controller import Controller
from lightcal_app.panels.base import Programmatic, TabPanel
from lightcal_app.results import previous_markdown, result_markdown
from lightcal_app.state import Frame


class ResultPanel(TabPanel):
    """The Result tab (built in the current GUI container)."""

    def __init__(self, server: viser.ViserServer, ctl: Controller, flag: Programmatic) -> None:
        super().__init__(server, ctl, flag)
        gui = self.gui
        self.result_md = gui.add_markdown("")
        # A finished result the user's edits replaced: shown, and one click brings it back.
        self.previous_md = gui.add_markdown("", visible=False)
        self.restore_previous = gui.add_button(
            "Restore previous result", icon=viser.Icon.ARROW_BACK_UP, visible=False
        )
        self.restore_previous.on_click(lambda e: ctl.restore_previous(e.client))
        # Residuals against the mirror / incidence angle (the fit test's picture).
        self.fit_plot = gui.add_image(
            np.full((8, 8, 3), 255, dtype=np.uint8), label="residuals vs angle", visible=False
        )
        # The candidate causes of a misfit: how far each would move the pose.
        self.cause_plot = gui.add_image(
            np.full((8, 8, 3), 255, dtype=np.uint8), label="misfit causes", visible=False
        )
        self.download_result = gui.add_button("Download result (JSON)", icon=viser.Icon.DOWNLOAD)
        self.download_report = gui.add_button("Download report (zip)", icon=viser.Icon.DOWNLOAD)
        self.report_full_size = gui.add_checkbox(
            "full-size figures",
            False,
            hint="the report's image figures at print size, as lightcal calibrate --report "
            "writes them (about 4x the download)",
        )
        # The result in other tools' formats (`lightcal export`): OpenCV, Blender, ...
        self.export_format = gui.add_dropdown(
            "export as",
            ("opencv", "blender", "mitsuba", "ies", "ldt"),
            initial_value="opencv",
            hint="OpenCV FileStorage YAML, a Blender snippet, a Mitsuba 3 scene (zip with "
            "the RID textures), or the RID as an IES / EULUMDAT file",
        )
        self.download_export = gui.add_button("Download export", icon=viser.Icon.DOWNLOAD)
        self.download_export.on_click(
            lambda e: ctl.request_download("export", e.client, str(self.export_format.value))
        )
        self.download_result.on_click(lambda e: ctl.request_download("result", e.client))
        self.download_report.on_click(
            lambda e: ctl.request_download(
                "report", e.client, full_size=bool(self.report_full_size.value)
            )
        )

    def update(self, frame: Frame) -> None:
        if not frame.dirty & {"result", "scene"}:
            return
        self.result_md.content = result_markdown(frame.result, state=frame.solver_state)
        previous = frame.previous
        self.previous_md.content = previous_markdown(previous) if previous is not None else ""
        self.previous_md.visible = self.restore_previous.visible = previous is not None
        fit = frame.result.fit if frame.result is not None else None
        if fit:
            self.fit_plot.image = angle_residual_figure(fit, size=(720, 300), scale=1)
        self.fit_plot.visible = bool(fit)
        causes = cause_figure(fit, scale=1) if fit else None
        if causes is not None:
            self.cause_plot.image = causes
        self.cause_plot.visible = causes is not None
