"""The interactive calibration web app (`lightcal app`), built on viser.

Layers: `state` (the shared state and its lock), `actions` (what a user can do: state
changes and queued requests), `controller` (the one worker thread: selection, solve,
files), `redraw` (one redraw inside `server.atomic()`), `scene3d` and `panels` (what
the browsers see), `overlays` (pictures on the frusta), `picking` (clicks and
rectangles to image pixels), `pixel_selection`, `results`, `uploads`, `session_file`,
`demo_truth`, `explain`, and `server` (`build_app`).
"""

from __future__ import annotations

__all__ = ["build_app", "default_project_path"]


def __getattr__(name: str):  # lazy: importing `app` must not start viser
    if name in __all__:
        from lightcal_app import server

        return getattr(server, name)
    raise AttributeError(name)
