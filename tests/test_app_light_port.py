"""A light behind its own flat port (`lights[i].port`) in the page: the overlays render
its refracted beam, and the page's solve is `lightcal calibrate`'s (docs/model.md, "The
light's flat port")."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from lightcal_app.server import LightcalApp, build_app

from lightcal.cli.main import main
from lightcal.core.medium import Medium
from lightcal.core.problem import with_view
from lightcal.core.render import render_image
from lightcal.core.scene import Rig
from tests.app_fixtures import run_in_page
from tests.test_one_engine import _cli, _same


@pytest.fixture(scope="module")
def ported(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Synth's light behind a port (d 15 mm, t 8 mm, acrylic into sea water) in water of
    c = 0.2 /m, both declared."""
    folder = tmp_path_factory.mktemp("light_port") / "data"
    argv = ["synth", str(folder), "--views", "5", "--width", "160", "--height", "120"]
    argv += ["--light-port", "15", "8", "1.49", "1.333", "--declare-light-port"]
    argv += ["--attenuation", "0.2", "--declare-medium", "given"]
    assert main([*argv, "--seed", "4", "--quiet"]) == 0
    return folder / "project.json"


@pytest.fixture(scope="module")
def app(ported: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[LightcalApp]:
    a = build_app(ported, port=0, session_path=False, state_dir=tmp_path_factory.mktemp("s"))
    assert a.wait_idle(120.0)
    yield a
    a.close()


def test_the_overlays_render_the_refracted_beam(app: LightcalApp) -> None:
    st, overlays = app.state, app.controller.overlays
    project, display = st.project, st.display
    assert display is not None
    light = display.rig.lights[0]
    assert light.port is not None and light.port.distance_m == pytest.approx(0.015)
    camera = overlays.geo.render_camera
    view = project.views[0]
    view = with_view(view, exposure=view.exposure * display.gains[0])
    options = {
        "sensor": project.spec.sensor.model,
        "rid_subsamples": project.solver.rid_subsamples,
        "medium": Medium(0.2),
    }
    ours = overlays.render(0, display).filled(np.nan)
    through = render_image(camera, view, display.rig, **options).filled(np.nan)
    # The page's frames: the straight twin's fused image times the port's ratio, exact on
    # a node grid and cubic between (`lightcal.core.light_port_frame`; 1.4e-6 measured).
    np.testing.assert_allclose(ours, through + display.offset, rtol=5e-6, equal_nan=True)
    bare = Rig.single(light.replace(port=None))
    straight = render_image(camera, view, bare, **options).filled(np.nan)
    lit = np.isfinite(straight) & np.isfinite(through) & (through > 0.1 * np.nanmax(through))
    assert np.nanmax(np.abs(straight[lit] / through[lit] - 1.0)) > 0.2


def test_the_pages_solve_is_the_clis(app: LightcalApp, ported: Path) -> None:
    _same(run_in_page(app), _cli(ported))


def test_the_pages_downloads_carry_the_lights_port(app: LightcalApp) -> None:
    """The Files tab's export: the opencv file notes the port, Blender is refused naming
    it, as `lightcal export --project` does."""
    from lightcal_app.results import export_download

    from lightcal.errors import InputError

    result = app.state.result
    assert result is not None  # the solve above
    name, data = export_download(result, app.state.project, "opencv")
    assert name.endswith(".yaml") and b"port:" in data and b"lights[0].port" in data
    with pytest.raises(InputError, match=r"lights\[0\]\.port"):
        export_download(result, app.state.project, "blender")


def test_the_3d_views_rays_bend_where_they_leave_the_lights_port(app: LightcalApp) -> None:
    """Each ray to a wall point is two segments: emitter -> where it leaves the port's
    outer face, then straight through the water to the point, along the direction the
    port's forward trace (`FlatPort.trace`: Snell's law at both faces) gives the same ray."""
    from lightcal_app.scene3d import light_rays

    from lightcal.core.light_port import port_paths

    st = app.state
    assert st.display is not None
    light = st.display.rig.lights[0]
    port = light.port
    assert port is not None
    view = st.project.views[0]
    src, R = light.position_world(view), light.rotation_world(view)
    wall = np.array([[0.1, -0.05, 0.0], [-0.2, 0.1, 0.0], [0.0, 0.0, 0.0]])
    seg = light_rays(light, view, wall)
    assert seg.shape == (6, 2, 3)
    first, second = seg[:3], seg[3:]
    np.testing.assert_allclose(first[:, 0], np.broadcast_to(src, (3, 3)))
    np.testing.assert_allclose(second[:, 1], wall, atol=1e-12)
    np.testing.assert_allclose(first[:, 1], second[:, 0])
    air = port_paths((wall - src) @ R, port).directions_light
    exits, water, ok = port.trace(air)
    assert ok.all()
    np.testing.assert_allclose(first[:, 1], src + exits @ R.T, atol=1e-12)
    u_water = second[:, 1] - second[:, 0]
    u_water /= np.linalg.norm(u_water, axis=1)[:, None]
    np.testing.assert_allclose(u_water, water @ R.T, atol=1e-9)
    bare = light_rays(light.replace(port=None), view, wall)
    assert bare.shape == (3, 2, 3)
