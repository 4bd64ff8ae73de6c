"""The page's overlays add the estimated room light as the model does: through the sensor
model's fall-off (here `cos4`), so a solve's residuals in the page are the pipeline's."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
from lightcal_app.overlays import OverlayImages
from lightcal_app.solve_service import SolveService
from lightcal_app.state import AppState

from lightcal.cli.main import main
from lightcal.core.footprint import room_light_image
from lightcal.io.project import load_project
from lightcal.pipeline import load_images
from tests.app_fixtures import run_requests


def _quiet(*args: object, **kwargs: object) -> None:
    del args, kwargs


def test_the_overlays_add_the_room_light_through_cos4(tmp_path: Path) -> None:
    folder = tmp_path / "cos4"
    argv = ["synth", str(folder), "--views", "8", "--width", "480", "--height", "320"]
    assert main([*argv, "--sensor", "cos4", "--ambient", "0.1", "--seed", "2", "--quiet"]) == 0
    doc = json.loads((folder / "project.json").read_text())
    doc["sensor"]["estimate_ambient"] = True
    doc["selection"].update(strategy="all", binning=4)
    (folder / "room.json").write_text(json.dumps(doc))
    project = load_project(folder / "room.json")
    state = AppState(project, load_images(project))
    solve = SolveService(state, notify=_quiet, follow_iterations=False)
    solve.setup_changed()
    solve.start("run")
    run_requests(solve, state, timeout=300.0)
    display, model = state.display, solve.model
    assert state.result is not None and display is not None and model is not None
    assert display.ambient and display.ambient > 0.0
    x = np.asarray(state.result.x)
    overlays = OverlayImages(state.project, state.loaded, render_side=120)
    assert overlays.geo.render_binning == 4
    r = model.residuals(x)
    for k, i in enumerate(solve._model_index):
        im = model.images[k]
        u, v = im.footprints.pixels.T
        fitted = r[model.bounds[k] : model.bounds[k + 1]] * model.sigmas[k]
        rms = float(np.sqrt(np.mean(fitted**2)))
        shown = np.ma.filled(overlays.residual(i, overlays.render(i, display))[v, u], np.nan)
        assert np.max(np.abs(shown - fitted)) < 0.05 * rms, i
        # The room light's share is the level times the pixel's cos^4, not uniform (as the
        # page added it before: at the corners 10 % of the room light too much).
        dark = dataclasses.replace(display, ambient=0.0)
        room = overlays.render(i, display) - overlays.render(i, dark)
        level = state.project.views[i].exposure * display.gains[i] * display.ambient
        cos4 = room_light_image(overlays.geo.render_camera, "cos4")
        assert cos4 is not None
        np.testing.assert_allclose(np.ma.filled(room, np.nan)[v, u], level * cos4[v, u], rtol=1e-9)
