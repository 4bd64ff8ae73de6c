"""The bounce light over whole images (`lightcal.core.bounce_image`): what the report's
rendered images and the page's overlays add for declared surroundings, as the model adds
it to the selected pixels."""

from __future__ import annotations

import numpy as np
import pytest

from lightcal.cli.main import main
from lightcal.core.bounce_image import MAX_PIXELS, BounceImages
from lightcal.core.medium import Medium
from lightcal.io.project import load_project
from lightcal.pipeline.load import load_images
from lightcal.pipeline.model import build_model
from lightcal.report import render_views


@pytest.fixture(scope="module")
def corner(tmp_path_factory: pytest.TempPathFactory):
    """A corner 0.7 m from where 4 views of 240 x 160 look, declared; the model at the
    truth's neighbourhood (its start)."""
    out = tmp_path_factory.mktemp("corner") / "data"
    argv = ["synth", str(out), "--corner", "0.7", "0.5", "0.8", "--declare-surroundings"]
    assert main([*argv, "--views", "4", "--width", "240", "--height", "160", "--quiet"]) == 0
    project = load_project(out / "project.json")
    loaded = load_images(project)
    return project, loaded, build_model(project, loaded)


def test_the_reports_images_hold_the_models_bounce(corner) -> None:
    """At the selected pixels the report's rendered values are the model's (observed - r
    sigma), the bounce in: without it they would be off by the bounce itself (measured:
    about 1 % of the bounce, the report's map covering the whole images and the model's
    its selected pixels, on grids of their own)."""
    project, loaded, model = corner
    x = model.layout.x0
    rig = model.layout.rig(x)
    r = model.residuals(x)
    images = render_views(project, loaded, rig, offset=model.layout.offset(x))
    for k, im in enumerate(model.images):
        u, v = im.footprints.pixels.T
        fitted = im.observed - r[model.bounds[k] : model.bounds[k + 1]] * model.sigmas[k]
        shown = np.ma.filled(images[k][v, u], np.nan)
        assert model.bounce is not None
        bounce = model.bounce.values(k, im.view, rig)
        assert np.median(bounce / fitted) > 0.02  # the corner's light is there to see
        error = np.abs(shown - fitted)
        assert np.nanmedian(error / bounce) < 0.03, k
        assert np.nanmax(error / bounce) < 0.15, k


def test_the_lattice_interpolates_the_exact_term(corner) -> None:
    """Every 4th pixel computed exactly and the rest interpolated, against every pixel
    exactly, in water too (measured: median 1e-4, 95th percentile 2e-3 of the term)."""
    project, _, model = corner
    view = project.views[0]
    rig = model.layout.rig(model.layout.x0)
    assert project.surroundings is not None
    for medium in (Medium(), Medium(0.3, 0.0)):
        exact, coarse = (
            BounceImages(project.camera, [view], project.surroundings, max_pixels=most).image(
                0, view, rig, medium
            )
            for most in (MAX_PIXELS, 2400)
        )
        seen = exact > 0.0
        relative = np.abs(coarse - exact)[seen] / exact[seen]
        assert np.median(relative) < 2e-3 and np.percentile(relative, 95) < 2e-2
