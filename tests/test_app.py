"""In-process tests of the calibration app: drive the GUI handles as a browser would.

Setting `handle.value` fires the handle's callbacks with `client None` (a button:
`button.value = True` is a click). Each app is built on port 0 on a small synthetic
project (`tests/app_fixtures.py`) and waits for its worker to finish (`wait_idle`).
"""

from __future__ import annotations

import dataclasses
import gc
import io
import json
import math
import re
import threading
import time
import zipfile
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from lightcal_app.beam_shapes import cone_lines, cone_mesh
from lightcal_app.demo_truth import read_truth_lights
from lightcal_app.overlays import (
    OUTLINE_FRACTION,
    OverlayImages,
    display_geometry,
    full_to_display,
    legend_picture,
)
from lightcal_app.panels.base import Programmatic
from lightcal_app.panels.light import pose_angles_deg, rotation_from_angles_deg
from lightcal_app.panels.solve import status_text
from lightcal_app.picking import frustum_plane, frustum_scale_for_depth, pick, ray_hit, screen_ray
from lightcal_app.server import LightcalApp, build_app
from lightcal_app.session_file import (
    apply_session,
    parse_session,
    read_session,
    session_from_state,
    session_json,
)
from lightcal_app.state import Display
from lightcal_app.text import md
from viser import _messages
from viser._gui_handles import GuiEvent, UploadedFile
from viser.infra import ClientId

from lightcal.cli import collector
from lightcal.core.pose import describe_pose, rotation_from_axis
from lightcal.core.rotations import matrix_from_rotvec, quaternion_wxyz_from_matrix
from lightcal.core.scene import Rig
from lightcal.core.solver import IterationReport
from lightcal.errors import InputError
from lightcal.io.ies import write_ies
from lightcal.io.photometric_table import PhotometricTable
from lightcal.pipeline import image_data
from tests.app_fixtures import TRUE_POSITION_M, SyntheticProject, make_project


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory: pytest.TempPathFactory) -> SyntheticProject:
    return make_project(tmp_path_factory.mktemp("proj"), n_views=4, width=160, height=120)


def _build(project: SyntheticProject, tmp: Path, **kw) -> LightcalApp:
    kw.setdefault("session_path", tmp / "autosave.session.json")
    return build_app(project.path, port=0, state_dir=tmp / "state", **kw)


@pytest.fixture
def app(synthetic: SyntheticProject, tmp_path: Path):
    a = _build(synthetic, tmp_path)
    assert a.wait_idle()
    yield a
    a.close()


def _set(handle: Any, value: Any) -> None:
    """Assign a widget's value as a browser would (fires its callbacks, client None)."""
    handle.value = value


def _upload(handle: Any, name: str, content: bytes) -> None:
    """What viser does when a browser's upload completes (with no browser: client None)."""
    handle._impl.value = UploadedFile(name, content)
    for cb in handle._impl.update_cb:
        cb(GuiEvent(client=None, client_id=None, target=handle))


def _idle(a: LightcalApp, timeout: float = 60.0) -> None:
    assert a.wait_idle(timeout), "the app did not settle"


# ---------------------------------------------------------------------------- pure parts


def test_picking_hits_the_pixel_a_ray_goes_through() -> None:
    # A frustum 0.2 m deep, 1.6 x 1.2 aspect; a ray from the camera centre through the
    # picture's point (x, y) must give u = (x / hw + 1) W / 2 - 1/2.
    fov = 2 * math.atan(0.5)
    R = matrix_from_rotvec(np.array([0.1, -0.2, 0.3]))
    c = np.array([0.3, -0.1, 1.2])
    scale = frustum_scale_for_depth(0.2, fov_y_rad=fov, aspect=4 / 3)
    plane = frustum_plane(
        R, c, fov_y_rad=fov, aspect=4 / 3, scale=scale, width_px=160, height_px=120
    )
    assert plane.depth_m == pytest.approx(0.2)
    assert plane.half_height_m == pytest.approx(0.1)
    assert plane.half_width_m == pytest.approx(0.2 * 0.5 * 4 / 3)
    # The picture's centre is between pixels 79 and 80: u = 79.5, v = 59.5.
    hit = ray_hit(plane, c, R @ np.array([0.0, 0.0, 1.0]))
    assert hit is not None
    u, v, t = hit
    assert (u, v) == pytest.approx((79.5, 59.5))
    assert t == pytest.approx(0.2)
    # The top-left corner of the picture is pixel coordinate (-1/2, -1/2).
    inside = 1 - 1e-9
    corner = ray_hit(
        plane, c, R @ np.array([-plane.half_width_m * inside, -plane.half_height_m * inside, 0.2])
    )
    assert corner is not None
    u, v, _ = corner
    assert (u, v) == pytest.approx((-0.5, -0.5), abs=1e-3)
    assert ray_hit(plane, c, R @ np.array([0.0, 0.0, -1.0])) is None  # behind
    assert ray_hit(plane, c, R @ np.array([1.0, 0.0, 0.1])) is None  # beside
    # A browser camera at the frustum's apex with the same field of view: the screen
    # point (0.25, 0.75) is pixel (0.25 W - 1/2, 0.75 H - 1/2).
    o, d = screen_ray(
        c, quaternion_wxyz_from_matrix(R), fov_y_rad=fov, aspect=4 / 3, screen_xy=(0.25, 0.75)
    )
    assert pick([plane], o, d) == pytest.approx((0, 39.5, 89.5))


def test_pose_angles_round_trip() -> None:
    rng = np.random.default_rng(5)
    for _ in range(20):
        R = matrix_from_rotvec(rng.normal(scale=0.6, size=3))
        a, b, roll = pose_angles_deg(R)
        np.testing.assert_allclose(rotation_from_angles_deg(a, b, roll), R, atol=1e-12)
    # Hand cases in the paper's angles (as the result file gives them): the axis tilted
    # by 10 degrees towards +x is a pitch of 10; towards -y, a roll of 10; no spin.
    R = rotation_from_axis(np.array([math.sin(math.radians(10)), 0.0, math.cos(math.radians(10))]))
    assert pose_angles_deg(R) == pytest.approx((0.0, 10.0, 0.0), abs=1e-9)
    R = rotation_from_axis(np.array([0.0, -math.sin(math.radians(10)), math.cos(math.radians(10))]))
    assert pose_angles_deg(R) == pytest.approx((10.0, 0.0, 0.0), abs=1e-9)
    # The same numbers as the result's roll_deg / pitch_deg.
    R = matrix_from_rotvec(np.array([0.2, -0.1, 0.3]))
    pose = describe_pose(R, np.zeros(3))
    roll, pitch, _ = pose_angles_deg(R)
    assert (roll, pitch) == pytest.approx((pose["roll_deg"], pose["pitch_deg"]), abs=1e-12)


def test_cone_lines_outline_the_cone() -> None:
    segs = cone_lines(math.radians(45), 1.0, n_ring=8, n_generators=4)
    assert segs.shape == (12, 2, 3)
    ends = segs.reshape(-1, 3)
    ends = ends[np.linalg.norm(ends, axis=1) > 0]
    np.testing.assert_allclose(np.linalg.norm(ends, axis=1), 1.0)
    np.testing.assert_allclose(ends[:, 2], math.cos(math.radians(45)))


def test_cone_mesh_has_the_requested_angle() -> None:
    v, f = cone_mesh(math.radians(30), 2.0, n=12)
    assert v.shape == (13, 3) and f.shape == (12, 3)
    ring = v[1:]
    np.testing.assert_allclose(np.linalg.norm(ring, axis=1), 2.0)
    np.testing.assert_allclose(
        np.degrees(np.arctan2(np.hypot(ring[:, 0], ring[:, 1]), ring[:, 2])), 30.0
    )


def test_display_geometry_and_pixel_mapping() -> None:
    from lightcal.core.camera import Camera

    cam = Camera.from_params(fx=900, fy=900, cx=399.5, cy=299.5, width=800, height=600)
    geo = display_geometry(cam, max_side=640, render_side=200)
    assert (geo.width, geo.height, geo.render_binning) == (640, 480, 4)
    assert (geo.render_camera.width, geo.render_camera.height) == (200, 150)
    # Pixel edges map to picture edges: -1/2 -> -1/2, W - 1/2 -> W_d - 1/2.
    np.testing.assert_allclose(
        full_to_display(np.array([[-0.5, -0.5], [799.5, 599.5]]), geo),
        [[-0.5, -0.5], [639.5, 479.5]],
    )


def test_rendered_overlay_matches_the_real_image_at_the_true_light(
    synthetic: SyntheticProject,
) -> None:
    from lightcal.io.project import load_project
    from lightcal.pipeline import load_images

    project = load_project(synthetic.path)
    loaded = load_images(project)
    ov = OverlayImages(project, loaded, render_side=40)
    assert ov.geo.render_binning == 4
    # The images were rendered with scale 1 then multiplied by a gain: fit it per image.
    for i in range(len(project.names)):
        display = Display(
            Rig.single(synthetic.true_light), (1.0,) * len(project.names), 0.0, "guess", 0
        )
        r = ov.render(i, display)
        real = ov.real_binned[i]
        ok = ~np.ma.getmaskarray(r) & np.isfinite(real)
        gain = float(np.sum(real[ok] * r[ok]) / np.sum(r[ok] ** 2))
        rel = np.abs(real[ok] - gain * r[ok]) / real[ok].max()
        assert rel.max() < 5e-3  # rounding to 16 bits and the binned-camera approximation


def test_a_dense_selection_is_drawn_as_an_outline_over_the_picture(
    synthetic: SyntheticProject,
) -> None:
    """Every pixel selected (`all`): only the selection's outline is green, the picture
    inside it is untouched; a sparse selection is drawn as dots."""
    from lightcal.io.project import load_project
    from lightcal.pipeline import load_images

    project = load_project(synthetic.path)
    ov = OverlayImages(project, load_images(project), render_side=40)
    h, w = ov.geo.camera.height, ov.geo.camera.width
    v, u = np.mgrid[h // 4 : 3 * h // 4, w // 4 : 3 * w // 4]
    dense = np.stack([u.ravel(), v.ravel()], axis=1)
    base = np.full((ov.geo.height, ov.geo.width, 3), 128, np.uint8)
    rgb = ov.draw_selection(base.copy(), 0, selected=dense, binning=1, regions=(), points=())
    mask = ov.mask_display[0]
    green = (rgb[..., 1] > 180) & (rgb[..., 0] < 100) & ~mask
    H, W = ov.geo.height, ov.geo.width
    centre = (slice(H // 2 - 2, H // 2 + 3), slice(W // 2 - 2, W // 2 + 3))
    assert not green[centre].any() and (rgb[centre][~mask[centre]] == 128).all()
    assert green.any() and green.mean() < 0.5 * (dense.shape[0] / (h * w))
    sparse = dense[:: max(1, len(dense) // 50)]
    rgb = ov.draw_selection(base.copy(), 0, selected=sparse, binning=1, regions=(), points=())
    dots = (rgb[..., 1] > 180) & (rgb[..., 0] < 100) & ~mask
    assert 0 < dots.mean() < OUTLINE_FRACTION


def test_legend_picture_shows_both_ends() -> None:
    img = legend_picture(2.5)
    assert img.shape == (56, 320, 3)
    bar = img[14, 14:306]
    assert bar[0, 2] > bar[0, 0]  # blue end (negative)
    assert bar[-1, 0] > bar[-1, 2]  # red end (positive)


class _Widget:
    """What `Programmatic` uses of a viser handle: its value and viser's stamp of it."""

    def __init__(self, value: str) -> None:
        self._value = value
        self.update_timestamp = 0.0
        self.clock = 0.0

    @property
    def value(self) -> str:
        return self._value

    @value.setter
    def value(self, value: str) -> None:  # a panel's write, or a browser's value
        self.clock += 1.0
        self._value, self.update_timestamp = value, self.clock


def test_a_redraw_leaves_alone_a_widget_a_user_edited_until_its_callback_ends() -> None:
    flag = Programmatic()
    w = _Widget("real")
    flag.assign(w, "real")
    w.value = "residual"  # a browser's value, stamped by viser before its callback runs
    assert flag.pending(w)
    flag.assign(w, "real")  # a redraw from the state as it was before the edit
    assert w.value == "residual"
    stamp = flag.begin(w)  # its callback starts ...
    assert stamp is not None
    flag.done(w, stamp)  # ... and ends (here: the value was refused)
    assert not flag.pending(w)
    flag.assign(w, "real")
    assert w.value == "real"
    flag.assign(w, "depth")  # the state changed: written
    assert w.value == "depth"
    other = _Widget("real")  # every widget has its own record
    flag.assign(other, "residual")
    assert other.value == "residual" and w.value == "depth"
    # A second callback of an edit applied already has nothing to do.
    w.value = "real"
    stamp = flag.begin(w)
    assert stamp is not None
    flag.done(w, stamp)
    assert flag.begin(w) is None
    # The callback of an older edit ends while a newer one is on its way: left alone.
    w.value = "residual"
    older = flag.begin(w)
    assert older is not None
    w.value = "depth"
    flag.done(w, older)
    flag.assign(w, "residual")
    assert w.value == "depth"
    newer = flag.begin(w)
    assert newer is not None and newer > older
    flag.done(w, newer)
    flag.assign(w, "real")  # that edit was refused: the state's value again
    assert w.value == "real"


def test_an_edit_back_to_the_written_value_is_still_an_edit() -> None:
    """A, B, A: the user changes a widget and changes it back before any callback ran.
    Its value equals the panels' last write, yet it is an edit (newer stamp): a redraw
    from a state that took B meanwhile must not overwrite it, and its callback applies A.
    Comparing values, as before, lost this edit."""
    flag = Programmatic()
    w = _Widget("real")
    flag.assign(w, "real")
    w.value = "residual"  # edit 1
    first = flag.begin(w)  # edit 1's callback applies "residual" to the state ...
    w.value = "real"  # ... while edit 2 arrives
    assert first is not None
    flag.done(w, first)
    flag.assign(w, "residual")  # the redraw of the state edit 1 made
    assert w.value == "real"  # edit 2 is left alone
    assert flag.begin(w) is not None  # and its callback has an edit to apply


def test_truth_file_errors(tmp_path: Path) -> None:
    p = tmp_path / "truth.json"
    p.write_text(json.dumps({"lights": [{"position_m": [0, 0]}]}))
    with pytest.raises(InputError, match=r"lights\[0\]: position_m: expected 3 finite numbers"):
        read_truth_lights(p)
    p.write_text(json.dumps({"lights": [{"position_m": [0, 0, 0], "axis_camera": [0, 0, 1]}]}))
    (g,) = read_truth_lights(p)
    np.testing.assert_allclose(g.R_camera_light, np.eye(3))
    with pytest.raises(InputError, match="truth file not found"):
        read_truth_lights(tmp_path / "missing.json")
    # The sample data's form: one "light" with R_camera_light.
    R = rotation_from_axis(np.array([0.6, 0.0, 0.8]))
    p.write_text(json.dumps({"light": {"position_m": [0.1, 0, 0], "R_camera_light": R.tolist()}}))
    (g,) = read_truth_lights(p)
    np.testing.assert_allclose(g.R_camera_light, R)
    p.write_text(json.dumps({"views": []}))
    with pytest.raises(InputError, match=r"lights: expected a non-empty list"):
        read_truth_lights(p)


def test_session_file_errors() -> None:
    with pytest.raises(InputError, match=r"s.json:1: not valid JSON"):
        parse_session("{", "s.json")
    with pytest.raises(InputError, match="expected a lightcal session file"):
        parse_session("{}", "s.json")
    bad = {
        "format": "lightcal-app-session",
        "project": "p",
        "saved_at": "now",
        "lights": [],
        "selection": {"strategy": "random", "n_per_image": 0},
    }
    with pytest.raises(
        InputError, match=r"selection.n_per_image: Input should be greater than or equal to 1"
    ):
        parse_session(json.dumps(bad), "s.json")


# ---------------------------------------------------------------------------- the app


def test_app_binds_localhost_without_share_tunnel(app: LightcalApp) -> None:
    assert app.server.get_host() == "127.0.0.1"
    assert app.url == f"http://127.0.0.1:{app.server.get_port()}"
    handlers = app.server._websock_server._incoming_handlers
    assert _messages.ShareUrlRequest not in handlers
    with pytest.raises(RuntimeError, match="share tunnel is disabled"):
        app.server.request_share_url()


def test_selection_is_what_calibrate_would_use(
    app: LightcalApp, synthetic: SyntheticProject
) -> None:
    st = app.state
    for i in range(len(st.project.names)):
        expected = image_data(st.project, st.loaded, i).footprints.pixels
        np.testing.assert_array_equal(st.selected[i], expected)
        assert len(expected) == 60
    assert "240 pixels" in app.panels.pixels.selection_text.handle.content


def test_step_adds_an_iteration_to_the_cost_plot(app: LightcalApp) -> None:
    _set(app.panels.solve.step_button, True)
    _idle(app)
    st = app.state
    assert [h.iteration for h in st.history] == [0, 1]
    assert st.history[1].cost < st.history[0].cost
    it, cost = app.panels.solve.cost_plot.data
    np.testing.assert_array_equal(it, [0, 1])
    np.testing.assert_allclose(cost, np.log10([h.cost for h in st.history]))  # log10 axis
    assert st.solver_state == "paused"
    assert st.result is not None and "paused after iteration 1" in st.result.message
    # The position plot shows the estimate in mm.
    data = app.panels.solve.position_plot.data
    assert data[1][-1] == pytest.approx(st.history[-1].x[0] * 1e3)
    _set(app.panels.solve.step_button, True)
    _idle(app)
    assert [h.iteration for h in st.history] == [0, 1, 2]
    assert len(app.panels.solve.cost_plot.data[0]) == 3


def test_run_finds_the_true_light_and_reports_it(app: LightcalApp, tmp_path: Path) -> None:
    _set(app.panels.solve.run_button, True)
    _idle(app, 120)
    st = app.state
    assert st.solver_state == "converged"
    res = st.result
    assert res is not None and res.converged
    np.testing.assert_allclose(res.lights[0].pose.t_camera_light, TRUE_POSITION_M, atol=2e-4)
    md = app.panels.result.result_md.content
    assert md.startswith("**converged**")
    x_mm = re.search(r"\| position x \(mm\) \| ([-+0-9.]+) \| ([0-9.e-]+) \|", md)
    assert x_mm is not None and float(x_mm.group(1)) == pytest.approx(100.0, abs=0.05)
    assert float(x_mm.group(2)) == pytest.approx(
        res.lights[0].sigma.t_camera_light[0] * 1e3, rel=0.03
    )
    # The gizmo followed the estimate.
    np.testing.assert_allclose(
        app.controller.scene.gizmos[0].position, res.lights[0].pose.t_camera_light, atol=1e-6
    )
    # Step after the end asks for a reset instead of starting a second solve.
    _set(app.panels.solve.step_button, True)
    _idle(app)
    assert st.messages[-1][0] == "The solve has ended"
    # Downloads: the result JSON and the zipped report.
    _set(app.panels.result.download_result, True)
    _idle(app)
    d = st.downloads[-1]
    assert d.name == "project.result.json"
    data = json.loads(d.content)
    np.testing.assert_allclose(data["lights"][0]["position_m"], TRUE_POSITION_M, atol=2e-4)
    # The same result in other tools' formats (`lightcal export`).
    _set(app.panels.result.export_format, "opencv")
    _set(app.panels.result.download_export, True)
    _idle(app)
    d = st.downloads[-1]
    assert d.name == "project.opencv.yaml"
    import cv2

    yaml_path = tmp_path / d.name
    yaml_path.write_bytes(d.content)
    fs = cv2.FileStorage(str(yaml_path), cv2.FILE_STORAGE_READ)
    T = fs.getNode("lights").at(0).getNode("T_camera_light").mat()
    fs.release()
    np.testing.assert_allclose(T[:3, 3], data["lights"][0]["position_m"], atol=1e-12)
    _set(app.panels.result.export_format, "mitsuba")
    _set(app.panels.result.download_export, True)
    _idle(app)
    d = st.downloads[-1]
    assert d.name == "project.mitsuba.zip"
    assert "project.mitsuba.xml" in zipfile.ZipFile(io.BytesIO(d.content)).namelist()
    _set(app.panels.result.download_report, True)
    _idle(app, 120)
    d = st.downloads[-1]
    assert d.name == "project.report.zip"
    # "Preparing the report" is replaced when it is done, with the file's size.
    assert st.messages[-2][0] == "Preparing the report"
    assert st.messages[-1][0] == "Report ready"
    assert st.messages[-1][1].startswith("project.report.zip (")
    report = zipfile.ZipFile(io.BytesIO(d.content))
    names = report.namelist()
    assert "report/summary.md" in names and "report/result.json" in names
    assert sum(n.startswith("report/residual_") for n in names) == 4
    # Screen-size figures by default; "full-size figures" gives the CLI's print size.
    small = cv2.imdecode(np.frombuffer(report.read("report/residual_v00.png"), np.uint8), 1)
    _set(app.panels.result.report_full_size, True)
    _set(app.panels.result.download_report, True)
    _idle(app, 120)
    full = zipfile.ZipFile(io.BytesIO(st.downloads[-1].content)).read("report/residual_v00.png")
    big = cv2.imdecode(np.frombuffer(full, np.uint8), 1)
    assert big.shape[1] > 1.9 * small.shape[1]  # twice the map, the bar a little less
    _set(app.panels.result.report_full_size, False)
    # Reset goes back to the initial guess.
    _set(app.panels.solve.reset_button, True)
    _idle(app)
    assert st.history == [] and st.result is None and st.solver_state == "idle"
    np.testing.assert_allclose(app.controller.scene.gizmos[0].position, [0.05, 0.0, 0.0])
    # The converged result is kept, shown in the Result tab, and one click restores it.
    panel = app.panels.result
    assert panel.restore_previous.visible and panel.previous_md.visible
    assert panel.previous_md.content.startswith("**Previous result** (converged, ")
    x_solved = res.x.copy()
    _set(panel.restore_previous, True)
    _idle(app, 60)
    assert st.solver_state == "converged" and st.result is not None
    np.testing.assert_array_equal(st.result.x, x_solved)
    assert not panel.restore_previous.visible
    _set(app.panels.solve.reset_button, True)
    _idle(app)


def test_gizmo_drag_changes_rendered_overlay_and_numbers(app: LightcalApp) -> None:
    _set(app.panels.view.overlay_all, "rendered")
    _idle(app)
    frustum = app.controller.scene.frusta[0]
    before = frustum.image.copy()
    gizmo = app.controller.scene.gizmos[0]
    R = rotation_from_axis(np.array([0.2, 0.0, 1.0]) / math.hypot(0.2, 1.0))
    event = SimpleNamespace(
        target=SimpleNamespace(
            position=np.array([0.12, -0.02, 0.0]), wxyz=quaternion_wxyz_from_matrix(R)
        ),
        client=None,
    )
    for cb in gizmo._impl_aux.update_cb:
        cb(event)
    _idle(app)
    after = frustum.image
    assert np.abs(after.astype(int) - before.astype(int)).mean() > 1.0
    np.testing.assert_allclose(app.state.guess[0].t_camera_light, [0.12, -0.02, 0.0])
    w = app.panels.light.light_widgets[0]
    assert w["position"].value == pytest.approx((120.0, -20.0, 0.0))
    assert w["axis"].value[1] == pytest.approx(math.degrees(math.atan(0.2)), abs=1e-3)  # pitch


def test_typed_numbers_move_the_gizmo_without_fighting_a_solve(app: LightcalApp) -> None:
    w = app.panels.light.light_widgets[0]
    _set(w["position"], (80.0, 10.0, 5.0))
    _idle(app)
    np.testing.assert_allclose(app.state.guess[0].t_camera_light, [0.08, 0.01, 0.005])
    np.testing.assert_allclose(app.controller.scene.gizmos[0].position, [0.08, 0.01, 0.005])
    _set(w["axis"], (5.0, -3.0))
    _idle(app)
    roll, pitch, _ = pose_angles_deg(app.state.guess[0].R_camera_light)
    assert (roll, pitch) == pytest.approx((5.0, -3.0))
    # A step writes the estimate into the widgets; those writes are not user edits.
    _set(app.panels.solve.step_button, True)
    _idle(app)
    gen = app.state.session_gen
    assert len(app.state.history) == 2
    assert w["position"].value[0] == pytest.approx(app.state.history[-1].x[0] * 1e3, abs=0.01)
    assert app.state.session_gen == gen and app.state.solver_state == "paused"
    # A user edit now starts over from the edited estimate.
    _set(w["position"], (90.0, 0.0, 0.0))
    _idle(app)
    assert app.state.history == [] and app.state.session_gen > gen


def test_rectangle_on_an_image_changes_its_selection(app: LightcalApp) -> None:
    st = app.state
    view = st.project.views[1]
    R_wc = view.R_camera_world.T
    fov = st.project.camera.fov_y_rad
    before = [s.copy() for s in st.selected]
    # A browser camera at camera 1's centre, with its orientation: the screen's middle
    # fifth maps to the middle of the image.
    region = app.controller.rect(
        (0.4, 0.4),
        (0.6, 0.6),
        camera_position=view.center_world,
        camera_wxyz=quaternion_wxyz_from_matrix(R_wc),
        fov_y_rad=fov,
        aspect=st.project.camera.aspect,
        include=True,
    )
    assert region is not None and region.image == st.project.names[1]
    poly = np.array(region.points)
    # With the same field of view: u = 0.4 W - 1/2 .. 0.6 W - 1/2.
    np.testing.assert_allclose(poly.min(axis=0), [0.4 * 160 - 0.5, 0.4 * 120 - 0.5], atol=1e-6)
    np.testing.assert_allclose(poly.max(axis=0), [0.6 * 160 - 0.5, 0.6 * 120 - 0.5], atol=1e-6)
    _idle(app)
    sel = st.selected[1]
    assert 0 < len(sel) <= 60
    assert np.all(
        (sel[:, 0] >= 63.5) & (sel[:, 0] <= 95.5) & (sel[:, 1] >= 47.5) & (sel[:, 1] <= 71.5)
    )
    for i in (0, 2, 3):
        np.testing.assert_array_equal(st.selected[i], before[i])
    # An exclude region over the same area on image 1 empties it.
    app.controller.rect(
        (0.3, 0.3),
        (0.7, 0.7),
        camera_position=view.center_world,
        camera_wxyz=quaternion_wxyz_from_matrix(R_wc),
        fov_y_rad=fov,
        aspect=st.project.camera.aspect,
        include=False,
    )
    _idle(app)
    assert len(st.selected[1]) == 0
    # A rectangle over no image is refused with a message.
    assert (
        app.controller.rect(
            (0.0, 0.0),
            (0.1, 0.1),
            camera_position=np.array([0.0, 0.0, -5.0]),
            camera_wxyz=np.array([1.0, 0.0, 0.0, 0.0]),
            fov_y_rad=1.0,
            aspect=1.0,
            include=True,
        )
        is None
    )
    assert st.messages[-1][0] == "No image under the rectangle"
    _set(app.panels.pixels.clear_regions, True)
    _idle(app)
    for i in range(4):
        np.testing.assert_array_equal(st.selected[i], before[i])


def test_clicks_add_pixels_and_per_image_strategy(app: LightcalApp) -> None:
    st = app.state
    scene = app.controller.scene
    plane = scene.planes[2]
    # A ray from the camera centre through pixel (30, 40) of image 2.
    hw, hh = plane.half_width_m, plane.half_height_m
    x = ((30 + 0.5) / 160 * 2 - 1) * hw
    y = ((40 + 0.5) / 120 * 2 - 1) * hh
    d = plane.R_world_camera @ np.array([x, y, plane.depth_m])
    _set(app.panels.pixels.click_mode, "adds a pixel")
    app.controller.click(plane.center_world, d, mode="add")
    _idle(app)
    assert st.points[st.project.names[2]] == [(30, 40)]
    assert (st.selected[2] == [30, 40]).all(axis=1).any()
    assert len(st.selected[2]) == 61
    app.controller.click(plane.center_world, d, mode="remove")
    _idle(app)
    assert st.points[st.project.names[2]] == []
    # One image gets its own strategy: a grid of step 20 -> (160 / 20) x (120 / 20) nodes.
    _set(app.panels.pixels.sel_target, st.project.names[3])
    _set(app.panels.pixels.strategy, "grid")
    _set(app.panels.pixels.grid_step, 20)
    _idle(app)
    grid = st.selected[3]
    assert np.all(grid % 20 == 10)
    assert len(grid) <= 48 and len(st.selected[0]) == 60
    _set(app.panels.pixels.clear_override, True)
    _idle(app)
    assert len(st.selected[3]) == 60


def test_residual_overlay_and_legend(app: LightcalApp) -> None:
    _set(app.panels.view.overlay_image, app.state.project.names[0])
    _set(app.panels.view.overlay_one, "residual")
    _idle(app)
    assert app.state.overlay_of(0) == "residual" and app.state.overlay_of(1) == "real"
    assert "pixel values" in app.panels.view.legend_text.handle.content
    img = app.controller.scene.frusta[0].image.astype(int)
    # Diverging colours: the light is off, so the residual has both signs, red and blue.
    assert (img[..., 0] - img[..., 2] > 60).any() and (img[..., 2] - img[..., 0] > 60).any()
    grey = app.controller.scene.frusta[1].image.astype(int)
    assert np.abs(grey[..., 0] - grey[..., 2]).max() < 60  # grey, green marks only


def _solver_threads() -> int:
    return sum(t.name == "lightcal-solver" for t in threading.enumerate())


def test_concurrent_clicks_run_one_solve(app: LightcalApp) -> None:
    # Solver threads of earlier tests' sessions (in this process) may still be ending.
    before = _solver_threads()
    solver_threads: list[int] = []
    stop = threading.Event()

    def watch() -> None:
        while not stop.is_set():
            solver_threads.append(_solver_threads())
            time.sleep(0.001)

    watcher = threading.Thread(target=watch)
    watcher.start()
    buttons = [
        app.panels.solve.step_button,
        app.panels.solve.run_button,
        app.panels.solve.pause_button,
    ] * 4
    threads = [threading.Thread(target=_set, args=(b, True)) for b in buttons]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    _set(app.panels.solve.run_button, True)
    _idle(app, 120)
    stop.set()
    watcher.join()
    assert max(solver_threads) <= before + 1
    its = [h.iteration for h in app.state.history]
    assert its == list(range(len(its)))  # one solve, no iteration twice
    assert app.state.solver_state == "converged"


def test_reset_while_running_ends_the_solve(app: LightcalApp) -> None:
    st = app.state
    before = _solver_threads()  # earlier tests' solver threads may still be ending
    app.controller.solve.follow_timeout_s = 30.0
    with st.lock:  # hold the redraw: the solver waits for each iteration to be drawn
        _set(app.panels.solve.run_button, True)
        time.sleep(0.3)
        _set(app.panels.solve.reset_button, True)
    _idle(app)
    assert st.solver_state == "idle" and st.history == [] and st.result is None
    assert _solver_threads() <= before
    _set(app.panels.solve.step_button, True)
    _idle(app)
    assert [h.iteration for h in st.history] == [0, 1]


def test_bad_uploads_get_a_message_and_the_server_keeps_working(
    app: LightcalApp, tmp_path: Path
) -> None:
    st = app.state
    _upload(app.panels.files.upload_project, "broken.zip", b"not a zip at all")
    assert st.messages[-1] == ("⚠ Upload rejected: broken.zip", "broken.zip: not a valid zip file")
    _upload(app.panels.files.upload_rid, "lamp.ies", b"IESNA:LM-63-2002\nnonsense\n")
    assert st.messages[-1][0] == "⚠ Upload rejected: lamp.ies"
    assert "lamp.ies" in st.messages[-1][1]
    _upload(app.panels.files.upload_image, "other.png", b"\x89PNG....")
    assert "no project image has this file name" in st.messages[-1][1]
    evil = io.BytesIO()
    with zipfile.ZipFile(evil, "w") as zf:
        zf.writestr("../escape.json", "{}")
    _upload(app.panels.files.upload_project, "evil.zip", evil.getvalue())
    assert "unsafe path in the zip: '../escape.json'" in st.messages[-1][1]
    assert not (tmp_path / "escape.json").exists()
    _set(app.panels.solve.step_button, True)
    _idle(app)
    assert len(st.history) == 2


def test_uploads_over_the_limit_are_dropped(synthetic: SyntheticProject, tmp_path: Path) -> None:
    a = _build(synthetic, tmp_path, upload_limit_bytes=1000)
    try:
        _idle(a)
        _upload(a.panels.files.upload_session, "s.json", b"x" * 10)  # small: parsed
        assert "not valid JSON" in a.state.messages[-1][1]
        _upload(a.panels.files.upload_project, "big.zip", b"x" * 2000)
        assert a.state.messages[-1] == (
            "⚠ Upload rejected: big.zip",
            "big.zip: the file is 2.0 kB; uploads are limited to 1.0 kB per file",
        )
        # The transfer guard drops an upload announced too large before its data arrives.
        gui = a.server.gui
        uuid = a.panels.files.upload_project._impl.uuid
        msg = _messages.FileTransferStartUpload(
            source_component_uuid=uuid,
            transfer_uuid="t1",
            filename="huge.zip",
            mime_type="application/zip",
            part_count=3,
            size_bytes=5000,
        )
        for handler in a.server._websock_server._incoming_handlers[
            _messages.FileTransferStartUpload
        ]:
            handler(ClientId(0), msg)
        assert "t1" not in gui._current_file_upload_states
        assert a.state.messages[-1] == (
            "⚠ Upload rejected: huge.zip",
            "huge.zip: the file is 5.0 kB; uploads are limited to 1.0 kB per file",
        )
        small = _messages.FileTransferStartUpload(
            source_component_uuid=uuid,
            transfer_uuid="t2",
            filename="ok.zip",
            mime_type="application/zip",
            part_count=1,
            size_bytes=500,
        )
        for handler in a.server._websock_server._incoming_handlers[
            _messages.FileTransferStartUpload
        ]:
            handler(ClientId(0), small)
        assert "t2" in gui._current_file_upload_states
    finally:
        a.close()


def test_project_and_rid_uploads_switch_the_project(
    app: LightcalApp, synthetic: SyntheticProject, tmp_path: Path
) -> None:
    buf = io.BytesIO()
    folder = synthetic.path.parent
    with zipfile.ZipFile(buf, "w") as zf:
        for p in sorted(folder.rglob("*")):
            if p.is_file() and p.suffix in (".json", ".yaml", ".png") and "session" not in p.name:
                zf.write(p, f"myproj/{p.relative_to(folder)}")
    _upload(app.panels.files.upload_project, "myproj.zip", buf.getvalue())
    _idle(app)
    st = app.state
    assert st.project.path.parent.name == "myproj"
    assert st.project.path.is_relative_to(app.controller.files.upload_root)
    assert st.messages[-1][0] == "Project updated"
    assert len(app.controller.scene.frusta) == 4
    # The Files tab names the new project's autosave, not the old one's.
    autosave = app.controller.files.session_path
    assert autosave is not None and autosave.name == "project.session.json"
    assert f"(as {md(autosave.name)})" in app.panels.files.autosave_md.content
    assert "autosave" not in app.panels.files.autosave_md.content.split("(as ")[1]
    # An IES file becomes the light's RID; the guess is kept.
    _set(app.panels.light.light_widgets[0]["position"], (70.0, 0.0, 0.0))
    _idle(app)
    gamma = np.arange(0.0, 91.0, 5.0)
    table = PhotometricTable(
        gamma,
        np.array([0.0]),
        (1000 * np.cos(np.radians(gamma)) ** 3)[None, :],
        "lamp.ies",
        "axial",
    )
    write_ies(tmp_path / "lamp.ies", table)
    figure_before = app.panels.rid_figure.image.copy()
    _upload(app.panels.files.upload_rid, "lamp.ies", (tmp_path / "lamp.ies").read_bytes())
    _idle(app)
    assert st.project.spec.lights[0].rid.type == "ies"
    # The Explain tab's RID figure is the project's light, redrawn with its new RID.
    assert not np.array_equal(app.panels.rid_figure.image, figure_before)
    np.testing.assert_allclose(st.guess[0].t_camera_light, [0.07, 0.0, 0.0])
    assert "now uses the RID of lamp.ies" in st.messages[-1][1]
    # The project as saved then loads again: no field of the old RID type is left over.
    from lightcal.io.project import load_project

    reloaded = load_project(st.project.path)
    assert reloaded.spec.lights[0].rid.model_dump(exclude_none=True) == {
        "type": "ies",
        "profile": "cos_power",
        "path": st.project.spec.lights[0].rid.path,
    }


def test_a_browser_edit_survives_a_redraw_before_its_callback(app: LightcalApp) -> None:
    handle = app.panels.view.overlay_all
    assert handle.value == "real"
    # viser stores a browser's value, then queues the widget's callbacks on a worker
    # thread: a redraw can come in between, from the state as it was before the edit.
    handle._impl.value = "residual"
    handle._impl.update_timestamp = time.time()  # viser stamps it on its event loop
    app.state.mark("widgets")
    _idle(app)
    assert handle.value == "residual"
    for cb in handle._impl.update_cb:
        cb(GuiEvent(client=None, client_id=None, target=handle))
    _idle(app)
    assert app.state.overlay_default == "residual" and handle.value == "residual"


def test_edits_in_quick_succession_build_on_each_other_not_on_an_old_estimate(
    app: LightcalApp,
) -> None:
    """With an estimate shown, an edit of the position and then one of the spin, before
    the worker has replaced the estimate: the spin's edit keeps the new position (the
    estimate is out of date after the first edit; it was taken for the base pose)."""
    ctl, st = app.controller, app.state
    ctl.step(None)
    _idle(app)
    with st.lock:
        assert st.display is not None and st.display.source == "estimate"
        estimate = st.display.rig.lights[0]
    w = app.panels.light.light_widgets[0]
    new_position_mm = (12.0, -3.0, 7.0)
    with st.lock:  # the worker waits: neither edit has been handled when the next comes
        _set(w["position"], new_position_mm)
        _set(w["spin"], float(w["spin"].value) + 5.0)
        guess = st.guess[0]
        assert not st.display.current(st)
    np.testing.assert_allclose(guess.t_camera_light, np.array(new_position_mm) / 1e3)
    assert not np.allclose(guess.t_camera_light, estimate.t_camera_light)
    _idle(app)
    assert tuple(w["position"].value) == new_position_mm  # and the widget shows it


def test_a_widget_the_panels_changed_beside_a_redraw_is_not_taken_for_an_edit(
    app: LightcalApp,
) -> None:
    rays, shown = app.panels.view.rays, app.state.rays_image
    assert rays.value == shown != "all"
    with app.panels.flag.writing():  # as viser does when new options drop the old value
        rays.value = "all"
    app.state.mark("widgets")
    _idle(app)
    assert rays.value == shown == app.state.rays_image  # written from the state again


def test_autosave_restores_after_a_restart(synthetic: SyntheticProject, tmp_path: Path) -> None:
    a = _build(synthetic, tmp_path)
    try:
        _idle(a)
        # Edits one after the other, while the redraws of the earlier ones run.
        _set(a.panels.light.light_widgets[0]["position"], (60.0, -5.0, 1.0))
        _set(a.panels.pixels.n_per_image, 40)
        a.controller.add_point(1, 50, 60)
        _set(a.panels.view.overlay_all, "residual")
        _set(a.panels.solve.step_button, True)
        _idle(a)
        path = tmp_path / "autosave.session.json"
        deadline = time.monotonic() + 30.0  # written by the worker after the changes
        while time.monotonic() < deadline:
            saved = read_session(path) if path.is_file() else None
            if saved is not None and saved.solve is not None and len(saved.solve.history) == 2:
                break
            time.sleep(0.05)
        assert saved is not None
        assert saved.selection.n_per_image == 40
        assert saved.points == {a.state.project.names[1]: [[50, 60]]}
        assert saved.solve is not None and len(saved.solve.history) == 2
        assert not list(tmp_path.glob(".autosave*.tmp"))  # atomic: no leftovers
        x_last = a.state.history[-1].x.copy()
    finally:
        a.controller.files.session_path = None  # like a crash: no final write
        a.close()
    b = _build(synthetic, tmp_path)
    try:
        _idle(b)
        st = b.state
        np.testing.assert_allclose(st.guess[0].t_camera_light, [0.06, -0.005, 0.001])
        assert st.selection.n_per_image == 40 and st.overlay_default == "residual"
        assert len(st.selected[0]) == 40 and len(st.selected[1]) == 41
        assert [h.iteration for h in st.history] == [0, 1]
        assert st.solver_state == "paused"
        assert b.controller.startup_notes[0][0] == "Session restored"
        np.testing.assert_allclose(b.controller.scene.gizmos[0].position, x_last[:3])
        # Continuing picks up at iteration 2.
        _set(b.panels.solve.step_button, True)
        _idle(b)
        assert [h.iteration for h in st.history] == [0, 1, 2]
        assert st.history[2].cost <= st.history[1].cost
    finally:
        b.close()
    c = _build(synthetic, tmp_path, restore=False)
    try:
        _idle(c)
        assert c.state.selection.n_per_image == 60
    finally:
        c.close()


def test_save_and_reload_session(app: LightcalApp) -> None:
    st = app.state
    _set(app.panels.pixels.seed, 7)
    _idle(app)
    _set(app.panels.files.save_session, True)
    _idle(app)
    path = app.controller.files.saved_session_path()
    assert read_session(path).selection.seed == 7
    assert st.downloads[-1].name == path.name
    _set(app.panels.pixels.seed, 3)
    _idle(app)
    _set(app.panels.files.reload_session, True)
    _idle(app)
    assert st.selection.seed == 7 and app.panels.pixels.seed.value == 7
    assert st.messages[-1][0] == "Session restored"


def test_session_keeps_which_iterations_were_reweighted(app: LightcalApp) -> None:
    st = app.state
    n = len(st.parameter_names) or 6
    rms = np.ones(len(st.project.names))
    st.history = [
        IterationReport(0, np.zeros(n), 2.0, 1.0, rms, 1),
        IterationReport(1, np.zeros(n), 1.5, 0.1, rms, 2, reweighted=True),
    ]
    text = session_json(session_from_state(st))
    st.history = []
    apply_session(st, parse_session(text, "s.json"))
    assert [h.reweighted for h in st.history] == [False, True]
    assert "re-weighted" in status_text(
        SimpleNamespace(history=st.history, solver_state="converged", solver_message="")
    )


def test_demo_mode_shows_the_true_light(synthetic: SyntheticProject, tmp_path: Path) -> None:
    a = _build(synthetic, tmp_path, demo=True)
    try:
        _idle(a)
        node = a.server.scene.get_handle_by_name("/cameras/2/truth0")
        assert node is not None
        np.testing.assert_allclose(node.position, TRUE_POSITION_M)
    finally:
        a.close()
    (tmp_path / "p2").mkdir()
    proj = make_project(tmp_path / "p2", n_views=3, width=64, height=48)
    proj.truth_path.unlink()
    with pytest.raises(InputError, match="truth file not found"):
        build_app(proj.path, port=0, demo=True, session_path=False, state_dir=tmp_path / "state")


def test_a_demo_starts_from_the_guess_and_keeps_the_users_session(tmp_path: Path) -> None:
    """`--demo` with the default autosave: a solved session beside the project is neither
    reopened nor overwritten; the demo autosaves to its own file."""
    proj = make_project(tmp_path / "p", n_views=3, width=64, height=48)
    own = proj.path.with_name(f"{proj.path.stem}.session.json")
    a = build_app(proj.path, port=0, state_dir=tmp_path / "state")
    try:
        _idle(a)
        _set(a.panels.solve.run_button, True)
        _idle(a, 120)
        assert a.state.solver_state == "converged"
        a.controller.save_session()
        _idle(a)
    finally:
        a.close()
    saved = own.read_bytes()
    assert b'"converged"' in saved
    demo = build_app(proj.path, port=0, demo=True, state_dir=tmp_path / "state")
    try:
        _idle(demo)
        assert demo.state.history == [] and demo.state.solver_state == "idle"
        _set(demo.panels.solve.step_button, True)
        _idle(demo)
        demo.controller.save_session()
        _idle(demo)
    finally:
        demo.close()
    assert own.read_bytes() == saved
    assert proj.path.with_name(f"{proj.path.stem}.demo-session.json").is_file()


def test_fresh_keeps_the_earlier_session_aside(tmp_path: Path) -> None:
    """`--fresh` does not restore the autosave, and does not let the next autosave
    replace it either: it is renamed beside it, and the page says where."""
    proj = make_project(tmp_path / "p", n_views=3, width=64, height=48)
    session = tmp_path / "state" / "autosave.session.json"
    session.parent.mkdir()
    session.write_text("{}")  # what it holds does not matter: it is not read
    a = build_app(
        proj.path, port=0, state_dir=tmp_path / "state", session_path=session, restore=False
    )
    try:
        _idle(a)
        kept = sorted(session.parent.glob("autosave.session.*.json"))
        assert len(kept) == 1 and kept[0].read_text() == "{}"
        assert not session.exists() or session.read_text() != "{}"
        notes = dict(a.controller.startup_notes)
        assert notes["Session kept"] == (
            f"The earlier session was not restored; it is kept as {kept[0].name}."
        )
    finally:
        a.close()


def test_explanation_panel_has_pictures() -> None:
    from lightcal_app.explain import PROJECT_FIGURES, SECTIONS, load_figure

    from lightcal.io.project import load_project

    project = load_project(Path(__file__).resolve().parents[1] / "sample_data" / "project.json")
    for _, _, figure in SECTIONS:
        assert figure is not None
        drawn = PROJECT_FIGURES.get(figure)  # drawn from the project shown
        img = drawn(project) if drawn is not None else load_figure(figure)
        assert img is not None and img.ndim == 3 and img.shape[2] == 3


def test_cli_without_sample_project_says_how_to_make_it(
    monkeypatch, capsys, tmp_path: Path
) -> None:
    import lightcal_app.server as server_module

    from lightcal.cli.main import main

    monkeypatch.setattr(
        server_module, "default_project_path", lambda: tmp_path / "sample_data" / "project.json"
    )
    assert main(["app"]) == 2
    err = capsys.readouterr().err
    assert "project.json: the sample project is missing" in err
    assert "lightcal app PROJECT" in err


def test_cli_warns_when_exposed(
    monkeypatch, capsys, synthetic: SyntheticProject, tmp_path: Path
) -> None:
    import lightcal_app.server as server_module

    from lightcal.cli.main import main

    served = []

    def serve(a: LightcalApp, on_ready: Callable[[], None] | None = None) -> None:
        served.append(a.url)
        if on_ready is not None:
            on_ready()
        a.close()

    monkeypatch.setattr(server_module, "serve_forever", serve)
    frozen = gc.get_freeze_count()
    gc.set_threshold(*collector.COMMAND_THRESHOLDS)  # as `lightcal` sets it for any command
    try:
        rc = main(
            [
                "app",
                str(synthetic.path),
                "--host",
                "0.0.0.0",
                "--port",
                "0",
                "--session",
                str(tmp_path / "s.json"),
                "--state-dir",
                str(tmp_path / "state"),
            ]
        )
        # Served as a long-running process: the start-up's objects frozen, Python's own
        # thresholds back.
        assert gc.get_freeze_count() > frozen
        assert gc.get_threshold() == collector.PYTHON_THRESHOLDS
    finally:
        gc.unfreeze()
        gc.set_threshold(*collector.PYTHON_THRESHOLDS)
    assert rc == 0
    out = capsys.readouterr()
    assert "warning: --host 0.0.0.0 exposes the app" in out.err
    assert f"open {served[0]} in your browser" in out.out


@pytest.fixture(scope="module")
def satin(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A glossy (plastic, roughness 0.2) wall from `lightcal synth`, its project Lambertian."""
    from lightcal.cli.main import main as cli_main

    folder = tmp_path_factory.mktemp("satin") / "data"
    argv = ["synth", str(folder), "--wall", "plastic", "--roughness", "0.2", "--quiet"]
    assert cli_main([*argv, "--views", "8", "--width", "320", "--height", "240"]) == 0
    return folder


def _result_text_after_run(project: Path, state: Path) -> tuple[str, bool]:
    """Open `project` in the app, Run to the end: the Result tab's text and whether the
    residual-vs-angle plot shows."""
    a = build_app(project, port=0, state_dir=state, session_path=state / "autosave.json")
    try:
        _idle(a)
        _set(a.panels.solve.run_button, True)
        _idle(a, 120)
        panel = a.panels.result
        # Both pictures of the fit test show with a tested result.
        assert bool(panel.cause_plot.visible) == bool(panel.fit_plot.visible)
        return panel.result_md.content, bool(panel.fit_plot.visible)
    finally:
        a.close()


def test_app_shows_the_misfit_and_the_wall_model(satin: Path, tmp_path: Path) -> None:
    md, plot = _result_text_after_run(satin / "project.json", tmp_path / "s")
    assert "#### Wall: lambertian" in md
    assert "Fit: **⚠ a misfit moves the pose beyond its statistical sigma**" in md
    assert "it looks glossy (a correction of" in md
    assert "; try `wall: {model: plastic}` (or `auto`)" in md
    assert "- systematic: the shift the gloss cause accounts for" in md
    assert plot
    doc = json.loads((satin / "project.json").read_text())
    doc["wall"] = {"model": "plastic"}
    (satin / "plastic.json").write_text(json.dumps(doc))
    md, _ = _result_text_after_run(satin / "plastic.json", tmp_path / "t")
    assert "#### Wall: plastic" in md
    rough = re.search(r"\| roughness \| ([0-9.]+) \| [0-9.e-]+ \|", md)
    assert rough is not None and float(rough.group(1)) == pytest.approx(0.2, abs=0.02)
    assert "| ior | 1.5 | fixed |" in md
    assert "Fit: **explained by the noise**" in md


def test_the_view_tab_explains_every_mark_of_the_scene(app: LightcalApp) -> None:
    from lightcal_app.panels.view import SCENE_LEGEND

    text = app.panels.view.scene_legend.content
    assert text == SCENE_LEGEND
    for mark in (
        "**wall**",
        "**camera's frustum**",
        "carries the light\n  gizmo",
        "**light**",
        "**cones**",
        "**gizmo**",
        "**rays**",
        "**true light**",
        "**selected pixels**",
        "**masked**",
        "**regions**",
        "clicked pixels",
    ):
        assert mark in text, mark


def test_the_page_says_it_is_loading_until_the_scene_is_drawn(
    synthetic: SyntheticProject, tmp_path: Path
) -> None:
    """Built but not yet drawn: a loading message names the work; the first redraw of
    the scene hides it. The terminal is told each step (`say`)."""
    said: list[str] = []
    a = build_app(
        synthetic.path,
        port=0,
        session_path=False,
        state_dir=tmp_path / "state",
        say=said.append,
    )
    try:
        assert said[0] == f"reading the 4 images of {synthetic.path.name}"
        assert said[1].startswith("images read (") and said[1].endswith("building the scene")
        assert said[2].endswith("the first pictures render now")
        assert a.wait_idle()
        assert not a.panels.loading_md.visible
        assert a.panels.loading_md.content.startswith(
            "**Loading**: rendering the pictures of the 4"
        )
    finally:
        a.close()


def test_the_explain_tab_draws_the_projects_own_lights(synthetic: SyntheticProject) -> None:
    import math

    from lightcal_app.explain import project_rid_figure, rid_curves

    from lightcal.core.rid import Table2DRID
    from lightcal.core.scene import Light
    from lightcal.io.project import load_project

    project = load_project(synthetic.path)
    rid = project.lights[0].initial.rid
    ((label, angles, values),) = rid_curves(project)
    half = math.degrees(rid.half_angle_rad)
    assert label == f"{project.lights[0].initial.name} (half at {half:.1f} deg)"
    np.testing.assert_array_equal(values, rid(np.radians(angles)))
    assert angles[0] == 0.0 and angles[-1] == 90.0
    fig = project_rid_figure(project)
    assert fig.shape == (420, 600, 3)  # 300 x 210 points at 2 px per point
    # A light without rotational symmetry: its profile at two azimuths.
    theta = np.radians([0.0, 30.0, 60.0, 90.0])
    phi = np.radians([0.0, 90.0, 180.0, 270.0])
    table = Table2DRID(theta, phi, np.array([[1.0, 0.8, 0.3, 0.0], [1.0, 0.5, 0.1, 0.0]] * 2))
    u = project.lights[0]
    light = Light(table, u.initial.t_camera_light, u.initial.R_camera_light, scale=1.0)
    other = dataclasses.replace(
        project, lights=[dataclasses.replace(u, initial=light.replace(name="spot"))]
    )
    labels = [c[0] for c in rid_curves(other)]
    assert labels == ["spot, azimuth 0 deg", "spot, azimuth 90 deg"]


def test_each_picture_carries_its_images_name(app: LightcalApp) -> None:
    """The names are written on the pictures (labels floating beside the frusta
    collided): a white box with dark text in the top-left corner of each frustum."""
    from lightcal_app.overlays import draw_name

    blank = np.full((240, 320, 3), 128, np.uint8)
    named = draw_name(blank.copy(), "view_00")
    box = named[:6, :40]
    assert (box == 255).all(axis=-1).mean() > 0.5  # the white box
    assert (named[:20, :80] < 60).any()  # dark ink
    assert (named[120:] == 128).all()  # the rest untouched
    frame = app.controller.scene.frusta[0].image
    assert (frame[:4, :30] == 255).all(axis=-1).mean() > 0.5


def test_looking_through_an_image_turns_the_rays_off(app: LightcalApp) -> None:
    _set(app.panels.view.rays, "all")
    _idle(app)
    assert app.state.rays_image == "all"
    _set(app.panels.view.look_through, True)
    _idle(app)
    assert app.state.rays_image == "none"
    assert app.panels.view.rays.value == "none"


def test_the_busy_line_keeps_its_place(app: LightcalApp) -> None:
    """Working or idle, the busy line is one visible line: the panel does not jump."""
    from lightcal_app.panels import IDLE_LINE

    line = app.panels.work_md
    app.panels.show_work("rendering the overlays")
    assert line.visible and line.content == "**Working**: rendering the overlays..."
    app.panels.show_work("")
    assert line.visible and line.content == IDLE_LINE


def test_the_light_tab_guesses_the_light_from_its_beam(app: LightcalApp) -> None:
    """The Light tab's "Guess from the beam in the photos": the guess moves onto the beam
    (what `initial: auto` does) and the page says from how many spots."""
    from lightcal.core.light_axis import axis_from_angles
    from tests.app_fixtures import TRUE_AXIS_ANGLES_RAD

    st = app.state
    _set(app.panels.light.beam_guess, True)
    _idle(app)
    with st.lock:
        guess = st.guess[0]
    truth_axis = axis_from_angles(*TRUE_AXIS_ANGLES_RAD)
    cos = float(guess.R_camera_light[:, 2] @ truth_axis)
    # A 30-degree beam's spots lean towards the wall's nearer parts: 18 degrees here.
    assert math.degrees(math.acos(min(cos, 1.0))) < 25.0
    title, body = st.messages[-1]
    assert title == "Guess from the beam" and " mm from 4 spots: " in body
    _set(app.panels.solve.run_button, True)  # and the solve from it finds the light
    _idle(app, 120)
    assert st.result is not None and st.result.converged
    found = st.result.lights[0].pose.t_camera_light
    np.testing.assert_allclose(found, TRUE_POSITION_M, atol=1e-3)
