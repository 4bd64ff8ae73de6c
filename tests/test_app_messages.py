"""Values from a page are checked before they touch the state; names are shown, never
rendered (issue 10); many edits arriving as viser delivers them are none of them lost."""

from __future__ import annotations

import json
import math
import random
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from lightcal_app.limits import check_position_m
from lightcal_app.server import LightcalApp, build_app
from lightcal_app.session_file import read_session
from lightcal_app.text import md, md_prose, public
from viser._gui_handles import GuiEvent
from viser.infra import ClientId

from lightcal.errors import InputError
from tests.app_fixtures import SyntheticProject, make_project


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory: pytest.TempPathFactory) -> SyntheticProject:
    return make_project(tmp_path_factory.mktemp("msg"), n_views=4, width=96, height=72)


@pytest.fixture
def app(synthetic: SyntheticProject, tmp_path: Path):
    a = build_app(
        synthetic.path,
        port=0,
        state_dir=tmp_path / "state",
        session_path=tmp_path / "s.session.json",
    )
    assert a.wait_idle()
    yield a
    a.close()


def _refusals(a: LightcalApp) -> list[str]:
    return [body for title, body in a.state.messages if title == "⚠ Value refused"]


def test_a_nan_or_a_short_position_is_refused_and_the_guess_kept(app: LightcalApp) -> None:
    before = [g.t_camera_light.copy() for g in app.state.guess]
    widget = app.panels.light.light_widgets[0]["position"]
    widget.value = (float("nan"), 0.0, 0.0)
    assert app.wait_idle()
    assert _refusals(app) == [
        "light position: expected 3 finite numbers within +-10000 mm, got (nan, 0, 0)"
    ]
    assert all(
        np.array_equal(g.t_camera_light, b) for g, b in zip(app.state.guess, before, strict=True)
    )
    # The widget shows the kept guess again (in mm).
    assert np.allclose(widget.value, before[0] * 1e3, atol=0.01)
    with pytest.raises(InputError, match=r"^light position: expected 3 finite numbers"):
        app.controller.set_guess(0, t_camera_light=np.array([0.1, 0.2]))
    with pytest.raises(InputError, match=r"^light position: expected 3 finite numbers"):
        app.controller.set_guess(0, t_camera_light=np.array([1e308, 0.0, 0.0]))


def test_a_24_digit_seed_is_refused_and_never_saved(app: LightcalApp, tmp_path: Path) -> None:
    before = app.state.selection
    app.panels.pixels.seed.value = 10**24
    assert app.wait_idle()
    assert _refusals(app) == [
        "seed: expected an integer from 0 to 4294967295, got 1000000000000000000000000"
    ]
    assert app.state.selection == before
    app.controller.files.autosave(force=True)  # whatever is saved must load again
    session = read_session(tmp_path / "s.session.json")
    assert session.selection.seed == before.seed


def test_session_files_outside_the_widgets_ranges_are_refused(
    app: LightcalApp, tmp_path: Path
) -> None:
    app.controller.files.autosave(force=True)
    good = json.loads((tmp_path / "s.session.json").read_text())
    for edit, field in [
        (lambda d: d["selection"].__setitem__("seed", 10**24), "selection.seed"),
        (lambda d: d["lights"][0].__setitem__("position_m", [0.1, 0.2]), "lights.0.position_m"),
        (lambda d: d["lights"][0].__setitem__("position_m", [math.nan, 0, 0]), "position_m"),
    ]:
        data = json.loads(json.dumps(good))
        edit(data)
        path = tmp_path / "bad.session.json"
        path.write_text(json.dumps(data).replace("NaN", "NaN"))
        with pytest.raises(InputError, match=field.split(".")[0]):
            read_session(path)


def test_names_reach_markdown_as_text() -> None:
    hostile = '<img src="https://evil.example/x.png" onerror=alert(1)>'
    assert "<img" not in md(hostile) and "&lt;img" in md(hostile)
    assert "![" not in md("![x](https://evil.example/p.png)")
    assert "<script" not in md_prose("see `view_01` and <script>alert(1)</script>")
    assert public("cannot read /srv/data/secret/key.png (denied)") == (
        "cannot read key.png (denied)"
    )


def test_a_light_named_with_html_is_shown_as_text(
    synthetic: SyntheticProject, tmp_path: Path
) -> None:
    project = json.loads(synthetic.path.read_text())
    project["lights"][0]["name"] = '<img src="https://evil.example/x.png">'
    path = synthetic.path.parent / "html-name.json"
    path.write_text(json.dumps(project))
    a = build_app(path, port=0, state_dir=tmp_path / "state", session_path=False)
    try:
        assert a.wait_idle()
        text = a.panels.light.light_md.content
        assert "&lt;img" in text and "<img" not in text
    finally:
        a.close()
        path.unlink()


def test_position_limit_is_in_metres() -> None:
    assert np.array_equal(check_position_m([0.1, -0.2, 9.9]), [0.1, -0.2, 9.9])
    with pytest.raises(InputError):
        check_position_m([0.1, -0.2, 10.1])


def test_a_choice_that_is_not_offered_is_refused(app: LightcalApp) -> None:
    before = app.state.ref_image
    app.panels.light.ref_image._impl.value = "../../etc/passwd"  # what a forged message sets
    app.panels.light.ref_image._impl.update_timestamp = time.time()  # (stamped by viser)
    for cb in app.panels.light.ref_image._impl.update_cb:
        cb(GuiEvent(client=None, client_id=None, target=app.panels.light.ref_image))
    assert app.wait_idle()
    assert _refusals(app)[-1] == "'../../etc/passwd' is not a value this control takes"
    assert app.state.ref_image == before
    assert app.panels.light.ref_image.value == app.state.project.names[before]  # shown again


# ---------------------------------------------------------------- before viser takes them


def _send(a: LightcalApp, handle: Any, updates: dict[str, Any]) -> None:
    """A page's widget message, as the websocket hands it to the server (no browser)."""
    import asyncio

    from viser import _messages

    ws = a.server._websock_server
    message = _messages.GuiUpdateMessage(handle._impl.uuid, updates)
    for handler in list(ws._incoming_handlers[_messages.GuiUpdateMessage]):
        asyncio.run(handler(ClientId(12345), message))


def test_values_are_checked_before_viser_stores_or_broadcasts_them(
    app: LightcalApp, tmp_path: Path
) -> None:
    pixels, light = app.panels.pixels, app.panels.light.light_widgets[0]
    app.controller.files.autosave(force=True)
    saved = (tmp_path / "s.session.json").read_bytes()
    before = (app.state.selection, [g.t_camera_light.copy() for g in app.state.guess])
    widgets = (pixels.seed.value, light["position"].value, pixels.strategy.value)
    cases = [
        (
            pixels.seed,
            {"value": 1e24},
            "seed: expected an integer from 0 to 4.29497e+09, got 1e+24",
        ),
        (pixels.seed, {"value": -1}, "seed: expected an integer from 0 to 4.29497e+09, got -1"),
        (pixels.seed, {"value": 2.5}, "seed: expected an integer from 0 to 4.29497e+09, got 2.5"),
        (pixels.seed, {"value": "7"}, "seed: expected a number, got '7'"),
        (
            pixels.n_per_image,
            {"value": math.nan},
            "pixels per image (random): expected an integer from 1 to 1e+06, got nan",
        ),
        (
            light["position"],
            {"value": [1.0, 2.0]},
            "position (mm): expected 3 numbers, got [1.0, 2.0]",
        ),
        (
            light["position"],
            {"value": [math.nan, 0, 0]},
            "position (mm): expected a number from -10000 to 10000, got nan",
        ),
        (
            light["position"],
            {"value": [1e308, 0, 0]},
            "position (mm): expected a number from -10000 to 10000, got 1e+308",
        ),
        (
            light["axis"],
            {"value": [math.inf, 0.0]},
            "axis roll, pitch (deg): expected a number from -180 to 180, got inf",
        ),
        (
            light["axis"],
            {"value": [0.0, 91.0]},
            "axis roll, pitch (deg): expected a number from -90 to 90, got 91",
        ),
        (
            pixels.strategy,
            {"value": "<img src=x>"},
            "strategy: expected one of the choices offered, got '<img src=x>'",
        ),
        (
            pixels.show_selection,
            {"value": 1},
            "show selection and masks on the images: expected true or false, got '1'",
        ),
        (pixels.seed, {"value": 3, "label": "x"}, "seed: only the value may change"),
    ]
    for handle, updates, reason in cases:
        _send(app, handle, updates)
        assert app.wait_idle()
        assert _refusals(app)[-1] == reason, updates
    # Nothing reached viser's widgets, the state or the autosave.
    assert (pixels.seed.value, light["position"].value, pixels.strategy.value) == widgets
    assert app.state.selection == before[0]
    assert all(
        np.array_equal(g.t_camera_light, p) for g, p in zip(app.state.guess, before[1], strict=True)
    )
    app.controller.files.autosave(force=True)
    assert (tmp_path / "s.session.json").read_bytes() == saved
    # A value that fits is passed on to viser as the widget's type.
    _send(app, pixels.seed, {"value": 42.0})
    assert pixels.seed.value == 42 and isinstance(pixels.seed.value, int)


def test_messages_show_no_server_folder(app: LightcalApp, tmp_path: Path) -> None:
    app.controller.files.upload_image("v00.png", b"\x89PNG\r\n\x1a\n not an image")
    app.controller.notify(None, "Read failed", f"cannot read {tmp_path}/secret/key.png (denied)")
    assert app.wait_idle()
    bodies = [body for _, body in app.state.messages]
    assert bodies[-1] == "cannot read key.png (denied)"
    assert bodies[-2].startswith("v00.png") and "/" not in bodies[-2], bodies[-2]
    assert str(tmp_path) not in app.panels.messages_md.content


def test_a_failing_autosave_is_reported_once_and_never_retriggers_itself(
    app: LightcalApp, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import lightcal_app.files_service as files_service

    app.controller.files.autosave(force=True)
    path = tmp_path / "s.session.json"
    good = path.read_bytes()
    attempts: list[int] = []
    real = files_service.session_from_state

    def counted(state: Any) -> Any:
        attempts.append(1)
        return real(state)

    monkeypatch.setattr(files_service, "session_from_state", counted)
    monkeypatch.setattr(files_service, "AUTOSAVE_INTERVAL_S", 0.0)
    st = app.state
    with st.lock:  # a state no check lets in (a 2-number position), as a bug might leave
        guess = list(st.guess)
        guess[0] = type(guess[0])(np.array([0.1, 0.2]), guess[0].R_camera_light)
        st.guess = guess
        st.mark("status", changed=True)
    deadline = time.monotonic() + 2.0  # about 8 turns of the worker's loop
    while time.monotonic() < deadline:
        assert app.wait_idle()
        time.sleep(0.1)
    failures = [m for m in st.messages if m[0] == "⚠ Autosave failed"]
    assert len(failures) == 1 and len(attempts) == 1
    # Each later change tries once more, silently; the last good file stays.
    for k in range(2):
        app.controller.set_show_selection(k % 2 == 0)
        assert app.wait_idle()
        time.sleep(0.3)
        assert app.wait_idle()
    assert len([m for m in st.messages if m[0] == "⚠ Autosave failed"]) == 1
    assert len(attempts) == 3
    assert path.read_bytes() == good


def test_scene_messages_are_checked_before_they_touch_the_state(app: LightcalApp) -> None:
    ctl, st = app.controller, app.state
    before = [(g.t_camera_light.copy(), g.R_camera_light.copy()) for g in st.guess]
    points = dict(st.points)
    one = np.array([1.0, 0.0, 0.0, 0.0])
    assert ctl.on_gizmo(0, np.array([math.nan, 0.0, 0.0]), one, None) is None
    assert ctl.on_gizmo(0, np.array([0.1, 0.2]), one, None) is None
    assert ctl.on_gizmo(0, np.array([0.1, 0.0, 0.0]), np.array([0.0, 0.0, 0.0, 0.0]), None) is None
    ctl.click(np.array([0.0, math.inf, 0.0]), np.array([0.0, 0.0, 1.0]), mode="add")
    ctl.click(np.zeros(3), np.array([0.0, 1.0]), mode="add")
    region = ctl.rect(
        (0.1, math.nan),
        (0.5, 0.5),
        camera_position=np.zeros(3),
        camera_wxyz=one,
        fov_y_rad=1.0,
        aspect=1.5,
        include=True,
    )
    assert app.wait_idle()
    assert region is None and st.regions == [] and st.points == points
    assert all(
        np.array_equal(g.t_camera_light, p) and np.array_equal(g.R_camera_light, R)
        for g, (p, R) in zip(st.guess, before, strict=True)
    )
    refusals = _refusals(app)
    assert len(refusals) == 6
    assert refusals[0].startswith("light position: expected 3 finite numbers")
    assert refusals[3].startswith("click ray origin")
    assert refusals[4].startswith("click ray direction")
    assert refusals[5].startswith("rectangle corner")
    # The gizmo is back at the kept guess.
    np.testing.assert_allclose(ctl.scene.gizmos[0].position, before[0][0])
    # A good drag is taken.
    taken = ctl.on_gizmo(0, np.array([0.07, 0.0, 0.01]), one, None)
    assert taken is not None and np.allclose(st.guess[0].t_camera_light, [0.07, 0.0, 0.01])


def test_session_files_hold_only_what_the_page_accepts(app: LightcalApp, tmp_path: Path) -> None:
    from lightcal_app.session_file import parse_session

    app.controller.files.autosave(force=True)
    path = tmp_path / "s.session.json"
    text = path.read_text()
    good = json.loads(text)
    name = next(iter(app.state.project.names))
    cases = [
        (
            ("lights", 0, "position_m"),
            [11.0, 0.0, 0.0],
            "lights.0.position_m.0: Input should be less than or equal to 10",
        ),
        (
            ("lights", 0, "R_camera_light"),
            [[5.0, 0, 0], [0, 1, 0], [0, 0, 1]],
            "lights.0.R_camera_light.0.0: Input should be less than or equal to 1.000001",
        ),
        (
            ("lights", 0, "name"),
            "x" * 201,
            "lights.0.name: String should have at most 200 characters",
        ),
        (
            ("points",),
            {name: [[2**60, 0]]},
            f"points.{name}.0.0: Input should be less than or equal to 9007199254740992",
        ),
        (
            ("ref_image",),
            2**60,
            "ref_image: Input should be less than or equal to 9007199254740992",
        ),
        (
            ("regions",),
            [{"kind": "rect", "points": [[0, 0], [1e300, 1]]}],
            "regions.0.points.1.0: Input should be less than or equal to 9007199254740992",
        ),
        (
            ("selection", "n_per_image"),
            0,
            "selection.n_per_image: Input should be greater than or equal to 1",
        ),
    ]
    for where, value, message in cases:
        data = json.loads(text)
        target = data
        for key in where[:-1]:
            target = target[key]
        target[where[-1]] = value
        with pytest.raises(InputError) as exc:
            parse_session(json.dumps(data), "s.session.json")
        assert str(exc.value) == f"s.session.json: {message}", where
    assert parse_session(json.dumps(good), "s.session.json").lights
    # Nor can one be written: a state no check lets in makes the save fail, the file stays.
    with app.state.lock:
        app.state.selection = type(app.state.selection)(seed=10**24)
        app.state.mark("status", changed=True)
    app.controller.files.autosave(force=True)
    assert path.read_text() == text
    assert [m[0] for m in app.state.messages].count("⚠ Autosave failed") == 1


def test_an_image_named_with_html_is_shown_as_text(
    synthetic: SyntheticProject, tmp_path: Path
) -> None:
    project = json.loads(synthetic.path.read_text())
    hostile = '<img src="https://evil.example/x.png">'
    project["images"][0]["name"] = hostile
    path = synthetic.path.parent / "html-image.json"
    path.write_text(json.dumps(project))
    a = build_app(path, port=0, state_dir=tmp_path / "state", session_path=False)
    try:
        assert a.wait_idle()
        a.controller.run()
        assert a.wait_idle(120)
        for text in (
            a.panels.pixels.selection_text.handle.content,
            a.panels.result.result_md.content,
        ):
            assert "&lt;img" in text and "<img" not in text, text
    finally:
        a.close()
        path.unlink()


# -------------------------------------------------- many edits, as viser delivers them
# viser stores a browser's value, then runs the widget's callbacks on its thread pool,
# where they may start late and out of order; meanwhile the worker redraws the widgets
# from the state after every edit. Whatever the interleaving, each widget and the state
# must end with the last value sent (`panels.base.Programmatic`).


_POSITION_RANGES_MM = ((-80.0, 80.0), (-80.0, 80.0), (1.0, 20.0))


def _widgets(app: LightcalApp) -> dict[str, tuple[Any, Callable[[random.Random], Any]]]:
    """The edited widgets and, for each, a random value a browser could send."""
    p = app.panels
    names = list(app.state.project.names)
    return {
        "overlay": (p.view.overlay_all, lambda r: r.choice(["real", "rendered", "residual"])),
        "rays": (p.view.rays, lambda r: r.choice(["none", "all", *names])),
        "n_per_image": (p.pixels.n_per_image, lambda r: r.randint(20, 200)),
        "seed": (p.pixels.seed, lambda r: r.randint(0, 1000)),
        "show_selection": (p.pixels.show_selection, lambda r: r.random() < 0.5),
        "position": (
            p.light.light_widgets[0]["position"],
            lambda r: tuple(round(r.uniform(lo, hi), 2) for lo, hi in _POSITION_RANGES_MM),
        ),
    }


def _state_values(app: LightcalApp) -> dict[str, Any]:
    st = app.state
    with st.lock:
        return {
            "overlay": st.overlay_default,
            "rays": st.rays_image,
            "n_per_image": st.selection.n_per_image,
            "seed": st.selection.seed,
            "show_selection": st.show_selection,
            "position": tuple(round(float(v) * 1e3, 2) for v in st.guess[0].t_camera_light),
        }


@pytest.mark.parametrize("seed", [1, 2])
def test_late_callbacks_never_lose_the_last_edit(app: LightcalApp, seed: int) -> None:
    r = random.Random(seed)
    widgets = _widgets(app)
    last: dict[str, Any] = {}
    pending = []
    with ThreadPoolExecutor(4) as pool:  # viser's pool, busy: callbacks start 0-50 ms late

        def late(cb: Callable[[Any], None], handle: Any, delay_s: float) -> None:
            time.sleep(delay_s)
            cb(GuiEvent(client=None, client_id=None, target=handle))

        for k in range(150):
            key = r.choice(sorted(widgets))
            handle, value_of = widgets[key]
            handle._impl.value = value_of(r)  # what viser stores from the message,
            handle._impl.update_timestamp = time.time()  # stamped on its event loop
            last[key] = handle._impl.value
            for cb in handle._impl.update_cb:
                pending.append(pool.submit(late, cb, handle, r.uniform(0.0, 0.05)))
            if k % 30 == 29:
                app.controller.step(None)  # estimates redraw the light widgets
            time.sleep(r.uniform(0.0, 0.01))
        for f in pending:
            f.result()
    assert app.wait_idle(120)
    state = _state_values(app)
    with app.state.lock:
        estimate_shown = bool(app.state.history)
    for key, sent in last.items():
        assert state[key] == sent, (key, "state", state[key], "last sent", sent)
        if key == "position" and estimate_shown:
            continue  # after a Step the light widgets show the estimate
        assert widgets[key][0].value == sent, (key, "widget", widgets[key][0].value, sent)
