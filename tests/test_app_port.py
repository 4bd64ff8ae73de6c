"""A project seen through the camera's flat port (`camera.port`) in the page: the
overlays, the 3D view's wall, `lightcal plan` and the page's refusals all go through the
port, and the page's solve is `lightcal calibrate`'s (docs/model.md, "The camera's flat
port")."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from lightcal_app.scene3d import wall_extent
from lightcal_app.server import LightcalApp, build_app

from lightcal.cli.main import main
from lightcal.core.medium import Medium
from lightcal.core.port_footprints import port_footprints
from lightcal.core.port_render import render_image_through_port
from lightcal.core.problem import with_view
from lightcal.core.render import render_image
from lightcal.errors import InputError
from lightcal.pipeline import build_model
from lightcal.pipeline.plan_candidates import PlanGrid, candidate_image, candidates
from tests.app_fixtures import run_in_page
from tests.test_one_engine import _cli, _same

ATTENUATION_PER_M = 0.2


@pytest.fixture(scope="module")
def ported(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Synth's data through a port (d 20 mm, t 10 mm, acrylic into sea water) in water
    of c = 0.2 /m, the port and the water declared."""
    folder = tmp_path_factory.mktemp("port") / "data"
    argv = ["synth", str(folder), "--views", "5", "--width", "160", "--height", "120"]
    argv += ["--port", "20", "10", "1.49", "1.333", "--declare-port"]
    argv += ["--attenuation", str(ATTENUATION_PER_M), "--declare-medium", "given"]
    assert main([*argv, "--seed", "4", "--quiet"]) == 0
    return folder / "project.json"


@pytest.fixture(scope="module")
def app(ported: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[LightcalApp]:
    a = build_app(ported, port=0, session_path=False, state_dir=tmp_path_factory.mktemp("s"))
    assert a.wait_idle(120.0)
    yield a
    a.close()


def test_the_overlays_render_through_the_port(app: LightcalApp) -> None:
    """The page's rendered image is the port's render of the same view (not the straight
    rays', which differ by tens of percent at the corners)."""
    st, overlays = app.state, app.controller.overlays
    project, display = st.project, st.display
    assert project.camera_port is not None and display is not None
    camera = overlays.geo.render_camera
    view = project.views[0]
    view = with_view(view, exposure=view.exposure * display.gains[0])
    ours = overlays.render(0, display)
    options = {
        "sensor": project.spec.sensor.model,
        "rid_subsamples": project.solver.rid_subsamples,
        "medium": Medium(ATTENUATION_PER_M),
    }
    port = render_image_through_port(camera, view, display.rig, project.camera_port, **options)
    np.testing.assert_allclose(
        ours.filled(np.nan), (port + display.offset).filled(np.nan), rtol=1e-12, equal_nan=True
    )
    straight = render_image(camera, view, display.rig, **options).filled(np.nan)
    lit = np.isfinite(straight) & np.isfinite(port.filled(np.nan))
    assert np.nanmax(np.abs(straight[lit] / port.filled(np.nan)[lit] - 1.0)) > 0.05


def test_the_3d_views_wall_is_what_the_port_sees(app: LightcalApp) -> None:
    """The wall drawn spans the images' corners seen through the port (narrower than
    the straight rays')."""
    project = app.state.project
    lo, hi = wall_extent(project, margin=0.0)
    cam = project.camera
    w, h = cam.width - 1, cam.height - 1
    corners = np.array([[0, 0], [w, 0], [w, h], [0, h]])
    xy = np.concatenate(
        [
            port_footprints(cam, v, corners, project.camera_port)
            .corners_world[..., :2]
            .reshape(-1, 2)
            for v in project.views
        ]
    )
    xy = np.concatenate([xy, [v.center_world[:2] for v in project.views]])
    np.testing.assert_allclose(lo, xy.min(axis=0), atol=1e-12)
    np.testing.assert_allclose(hi, xy.max(axis=0), atol=1e-12)


def test_a_fall_off_chosen_in_the_page_is_refused_naming_the_port(app: LightcalApp) -> None:
    """`paper` (its d and viewing angle assume straight rays), as the file refuses it."""
    settings = app.state.solve_settings
    with pytest.raises(InputError) as info:
        app.controller.set_solve_settings(dataclasses.replace(settings, fall_off="paper"))
    assert "camera.port: not modelled together with sensor.model: paper" in str(info.value)
    assert app.state.solve_settings == settings


def test_plan_candidates_are_seen_through_the_port(app: LightcalApp) -> None:
    st = app.state
    project = st.project
    model = build_model(project, st.loaded)
    x = model.layout.x0.copy()
    grid = PlanGrid(distances_m=(1.0,), tilts_deg=(0.0,), rolls_deg=(0.0,))
    centre = np.zeros(3)
    pool = candidates(project.camera, grid, centre, 1.0, port=project.camera_port)
    assert pool
    image = candidate_image(model, x, project.camera, pool[0].view, grid, port=project.camera_port)
    assert image is not None
    pixels = image.footprints.pixels
    through = port_footprints(project.camera, image.view, pixels, project.camera_port)
    np.testing.assert_array_equal(image.footprints.corners_world, through.corners_world)


def test_the_pages_solve_is_the_clis(app: LightcalApp, ported: Path) -> None:
    _same(run_in_page(app), _cli(ported))
