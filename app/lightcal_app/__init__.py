"""The interactive calibration web app (`lightcal app`), built on viser.

Layers, from the bottom (nothing imports upwards; the first six import no viser):

- `state`: the shared state, its lock, the dirty flags; `requests`: the typed requests
  the worker handles;
- `solve_service` (selection, model via `lightcal.pipeline`, stepping, results) and
  `files_service` (uploads, downloads, sessions, autosave), with `pixel_selection`,
  `results`, `uploads`, `session_file`, `demo_truth`;
- `worker`: the one thread that takes the requests in order and draws;
- `actions`: what a user can do (state changes and queued requests);
- `overlays`, `picking`: pictures on the frusta, clicks and rectangles to pixels;
- `controller` (actions + services + worker + messages), `redraw` (one redraw inside
  `server.atomic()`), `scene3d` and `panels/` (one class per tab): what browsers see;
- `server`: `build_app`, the server and its guards.
"""

from __future__ import annotations

__all__ = ["build_app", "default_project_path"]


def __getattr__(name: str):  # lazy: importing `app` must not start viser
    if name in __all__:
        from lightcal_app import server

        return getattr(server, name)
    raise AttributeError(name)
