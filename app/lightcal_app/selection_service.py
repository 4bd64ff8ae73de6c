"""The pixels the page's solve uses, selected as the user set them (`pixel_selection`):
per project image its `ImageData` (or None where the selection failed), on the worker
thread, for `SolveService`. No viser."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from lightcal.core.problem import ImageData
from lightcal.errors import LightcalError
from lightcal_app.pixel_selection import footprint_centers, select_image
from lightcal_app.state import AppState

Notify = Callable[..., None]
"""`notify(client, title, body, *, error=False)`: a message in the page."""


class SelectionService:
    """Each image's selected pixels for the state's project (the one solved).

    Args:
        state: the shared state.
        notify: shows a message in the page (`notify(client, title, body, error=...)`).
    """

    def __init__(self, state: AppState, *, notify: Notify) -> None:
        self.state = state
        self.notify = notify
        self._image_data: list[ImageData | None] = [None] * len(state.project.names)
        self._selection_done = -1

    def stale(self) -> bool:
        """The state's selection changed since the last `compute`."""
        with self.state.lock:
            return self.state.selection_rev != self._selection_done

    def forget(self) -> None:
        """Another project: nothing selected yet."""
        with self.state.lock:
            self._image_data = [None] * len(self.state.project.names)
            self._selection_done = -1

    def compute(self) -> None:
        """Select every image's pixels with the user's settings, regions and clicks."""
        st = self.state
        with st.lock:
            project, loaded = st.solve_project, st.loaded
            rev = st.selection_rev
            settings = [st.selection_of(i) for i in range(len(project.names))]
            regions = list(st.regions)
            points = [list(st.points.get(n, [])) for n in project.names]
        datas: list[ImageData | None] = []
        for i in range(len(project.names)):
            try:
                datas.append(select_image(project, loaded, i, settings[i], regions, points[i]))
            except LightcalError as exc:
                datas.append(None)
                self.notify(None, f"Selection failed for {project.names[i]}", str(exc), error=True)
        with st.lock:
            if st.solve_project is not project:
                return
            self._image_data = datas
            self._selection_done = rev
            st.selected = [
                d.footprints.pixels if d is not None else np.zeros((0, 2), np.int64) for d in datas
            ]
            st.selected_binning = [s.binning if s.strategy == "all" else 1 for s in settings]
            st.selected_wall_points = [
                footprint_centers(d) if d is not None else np.zeros((0, 3)) for d in datas
            ]
            st.mark("selection", "light", "status")

    def usable(self) -> tuple[list[ImageData], list[int]]:
        """The selected images with pixels, and their project indices."""
        datas, index = [], []
        for i, d in enumerate(self._image_data):
            if d is not None and len(d.observed) > 0:
                datas.append(d)
                index.append(i)
        return datas, index
