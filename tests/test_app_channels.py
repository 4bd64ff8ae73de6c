"""The page on a colour project (`sensor.channels`: each photo one entry per channel):
it loads with the Water folder's c and beta per channel, the typed values go into the
solved project as the file's lists and into the session file, a Run through the worker
gives `lightcal calibrate`'s numbers on the edited file, the Result tab shows each
channel's scales, water and room light, and each image's overlay renders with its
channel's."""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest
from lightcal_app.actions import Actions
from lightcal_app.panels.water import water_text
from lightcal_app.results import result_markdown
from lightcal_app.server import LightcalApp, build_app
from lightcal_app.session_file import SessionFile, apply_session, session_from_state
from lightcal_app.solve_settings import check_settings, project_for_solve, settings_of
from lightcal_app.state import AppState
from lightcal_app.text import md_prose

from lightcal.core.camera import Camera
from lightcal.core.medium import Medium
from lightcal.errors import InputError
from lightcal.io.project import load_project
from lightcal.pipeline import load_images
from lightcal.pipeline.result_text import channel_lines
from lightcal.synthetic.dataset import SynthConfig, write_dataset
from lightcal.synthetic.departures import Departures
from lightcal.synthetic.views import SceneConfig
from tests.test_one_engine import _cli, _same

C_RGB = (0.4, 0.12, 0.06)
"""The water's true attenuation per channel (/m)."""
C_FILE = [0.3, 0.1, 0.05]
"""The project file's start of each channel's c."""
C_TYPED_G = 0.15
"""The start typed for channel G's c in the page."""


def colour_project(root: Path, *, n_views: int = 4, seed: int = 5) -> Path:
    """`tests/test_channels_pipeline.py`'s colour project, small: `n_views` colour PNGs
    of 200 x 150 (three synth datasets merged, one per channel), c estimated per channel
    from the file's lists."""
    camera = Camera.from_params(fx=180.0, fy=180.0, cx=99.5, cy=74.5, width=200, height=150)
    sets = []
    for ch, c in zip("RGB", C_RGB, strict=True):
        config = SynthConfig(
            camera=camera,
            scene=SceneConfig(n_views=n_views),
            seed=seed,
            departures=Departures(attenuation_per_m=c),
        )
        sets.append(write_dataset(root / ch, config))
    for k, path in enumerate(sets[0].image_paths):
        planes = [cv2.imread(str(s.image_paths[k]), cv2.IMREAD_UNCHANGED) for s in sets]
        cv2.imwrite(str(path), np.dstack(planes[::-1]))  # B, G, R on disk
    project = sets[0].project_path
    doc = json.loads(project.read_text())
    doc["sensor"]["channels"] = ["R", "G", "B"]
    doc["medium"] = {"attenuation_per_m": C_FILE, "estimate": ["attenuation_per_m"]}
    project.write_text(json.dumps(doc))
    return project


@pytest.fixture(scope="module")
def colour(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return colour_project(tmp_path_factory.mktemp("colour"))


def _edited_file(project: Path) -> Path:
    """The project file as the page edits it below: G's c typed, g 0.8."""
    doc = json.loads(project.read_text())
    c = list(C_FILE)
    c[1] = C_TYPED_G
    doc["medium"].update(attenuation_per_m=c, backscatter_per_m=[0.0] * 3, phase_g=0.8)
    edited = project.parent / "edited.json"
    edited.write_text(json.dumps(doc))
    return edited


def _numbers(tree: object, key: str = "") -> dict[str, float]:
    """Every number in a result's `channels`, by its path."""
    if isinstance(tree, dict):
        return {
            k: v for name, sub in tree.items() for k, v in _numbers(sub, f"{key}.{name}").items()
        }
    if isinstance(tree, list):
        return {k: v for n, sub in enumerate(tree) for k, v in _numbers(sub, f"{key}.{n}").items()}
    return {key: float(tree)} if isinstance(tree, int | float) else {}


def _media(project: object) -> list[Medium]:
    return [m.initial for m in project.media]  # type: ignore[attr-defined]


def test_typed_water_goes_into_the_solved_project_and_the_session_as_lists(
    colour: Path,
) -> None:
    project = load_project(colour)
    settings = settings_of(project)
    assert settings.media == tuple(Medium(c) for c in C_FILE)
    assert project_for_solve(project, settings) is project  # its own values: itself
    state = AppState(project, load_images(project))
    actions = Actions(state, planes=list, notify=lambda *a, **k: None)
    assert state.shown_media() == tuple(Medium(c) for c in C_FILE)
    actions.set_medium(1, attenuation_per_m=C_TYPED_G)
    actions.set_medium(None, phase_g=0.8)  # g: every channel's
    solved = state.solve_project
    assert solved.spec.medium.attenuation_per_m == [C_FILE[0], C_TYPED_G, C_FILE[2]]
    assert solved.spec.medium.phase_g == 0.8
    assert solved.spec.medium.estimate == ["attenuation_per_m"]
    # The project `lightcal calibrate` reads from the edited file.
    from_file = load_project(_edited_file(colour))
    assert _media(solved) == _media(from_file)
    assert [m.estimate for m in solved.media] == [m.estimate for m in from_file.media]
    assert solved.names == from_file.names and solved.channel_of == from_file.channel_of

    # The session file keeps each channel's values.
    saved = session_from_state(state)
    assert saved.solve_settings is not None and saved.solve_settings.media is not None
    assert [m.attenuation_per_m for m in saved.solve_settings.media] == [0.3, 0.15, 0.05]
    fresh = AppState(project, state.loaded)
    again = SessionFile.model_validate_json(saved.model_dump_json())
    assert apply_session(fresh, again) == []
    assert fresh.solve_settings == state.solve_settings
    assert _media(fresh.solve_project) == _media(from_file)
    # A colour project's session from before `media` (its `medium`: the first channel's
    # own) keeps the project's values per channel.
    old = json.loads(saved.model_dump_json())
    del old["solve_settings"]["media"]
    old["solve_settings"]["medium"] = {"attenuation_per_m": 0.3, "backscatter_per_m": 0.0}
    old["solve_settings"]["medium"]["phase_g"] = 0.9
    older = AppState(project, state.loaded)
    assert apply_session(older, SessionFile.model_validate(old)) == []
    assert older.solve_settings.media == tuple(Medium(c) for c in C_FILE)

    # Refused, naming the key: a value out of range, values of another number of
    # channels, two g's, a channel the project lacks.
    with pytest.raises(InputError, match=r"medium\.attenuation_per_m: expected a number"):
        actions.set_medium(2, attenuation_per_m=20.0)
    two = dataclasses.replace(state.solve_settings, media=(Medium(0.1), Medium(0.2)))
    with pytest.raises(InputError, match=r"each channel \(R, G, B\)"):
        check_settings(project, two)
    gs = dataclasses.replace(
        state.solve_settings, media=(Medium(0.1), Medium(0.2, 0.0, 0.5), Medium(0.3))
    )
    with pytest.raises(InputError, match=r"medium\.phase_g: expected one g for every channel"):
        check_settings(project, gs)
    with pytest.raises(InputError, match=r"expected a channel of sensor\.channels"):
        actions.set_medium(3, attenuation_per_m=0.1)
    assert state.solve_project is solved  # nothing refused reached the state
    # Backscatter in one channel: the list, and the fall-off it needs checked over all.
    actions.set_medium(1, backscatter_per_m=0.2)
    assert state.solve_project.spec.medium.backscatter_per_m == [0.0, 0.2, 0.0]
    cos4 = dataclasses.replace(state.solve_settings, fall_off="cos4")
    with pytest.raises(InputError, match=r"medium\.backscatter_per_m: the backscatter is"):
        check_settings(project, cos4)


def test_water_text_names_each_channels_start() -> None:
    start = [Medium(0.3), Medium(0.15), Medium(0.05)]
    text = water_text(
        start, start, ("attenuation_per_m",), estimate_shown=True, channels=("R", "G", "B")
    )
    nb = "\u00a0"
    assert text == (
        f"Showing the solve's **estimate** of c; it started from c{nb}(R){nb}={nb}0.3, "
        f"c{nb}(G){nb}={nb}0.15, c{nb}(B){nb}={nb}0.05."
    )
    assert water_text(start, start, (), estimate_shown=False).startswith("**Given**")


@pytest.fixture(scope="module")
def app(colour: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[LightcalApp]:
    state_dir = tmp_path_factory.mktemp("state")
    a = build_app(colour, port=0, session_path=False, state_dir=state_dir)
    assert a.wait_idle(120.0)
    yield a
    a.close()


def test_the_page_loads_a_colour_project_with_water_fields_per_channel(
    app: LightcalApp,
) -> None:
    assert app.state.project.names[:4] == ["view_00[R]", "view_00[G]", "view_00[B]", "view_01[R]"]
    water = app.panels.light.water
    labels = {k: h.label for k, h in water.fields.items()}
    assert labels == {
        "attenuation_per_m[R]": "attenuation c, R (m⁻¹)",
        "attenuation_per_m[G]": "attenuation c, G (m⁻¹)",
        "attenuation_per_m[B]": "attenuation c, B (m⁻¹)",
        "backscatter_per_m[R]": "backscatter β, R (m⁻¹)",
        "backscatter_per_m[G]": "backscatter β, G (m⁻¹)",
        "backscatter_per_m[B]": "backscatter β, B (m⁻¹)",
        "phase_g": "phase g",
    }
    assert [water.fields[f"attenuation_per_m[{ch}]"].value for ch in "RGB"] == C_FILE
    assert "**estimates** c" in water.text.content
    assert not [b for t, b in app.state.messages if t.startswith("⚠")]


def test_run_in_the_page_gives_the_cli_answer_per_channel(app: LightcalApp, colour: Path) -> None:
    """Typed in the Water folder, Run through the worker: `lightcal calibrate`'s numbers
    on the edited file; the Result tab, the fields and the overlays per channel."""
    water = app.panels.light.water
    water.fields["attenuation_per_m[G]"].value = C_TYPED_G  # as a browser's edit arrives
    water.fields["phase_g"].value = 0.8
    assert app.wait_idle(120.0)
    assert not [b for t, b in app.state.messages if t.startswith("⚠")]
    app.controller.set_pace(0.0)
    app.controller.run()
    deadline = time.monotonic() + 300.0
    while app.state.solver_state not in ("converged", "not converged"):
        assert time.monotonic() < deadline, "the solve did not end"
        time.sleep(0.05)
    assert app.wait_idle(120.0)
    st = app.state
    result = st.result
    assert result is not None and result.channels is not None
    cli = _cli(_edited_file(colour))
    _same(result, cli)
    page_numbers, cli_numbers = _numbers(result.channels), _numbers(cli.channels)
    assert page_numbers.keys() == cli_numbers.keys()
    np.testing.assert_allclose(
        list(page_numbers.values()), list(cli_numbers.values()), rtol=1e-9, atol=1e-15
    )
    assert channel_lines(result.channels) == channel_lines(cli.channels)
    for ch, c in zip(result.channels, C_RGB, strict=True):
        assert ch["medium"]["attenuation_per_m"] == pytest.approx(c, rel=0.05)

    # The Result tab: each channel's line as `lightcal calibrate` prints it, each scale.
    text = app.panels.result.result_md.content
    assert text == result_markdown(result, state=st.solver_state)
    for line in channel_lines(result.channels):
        assert f"- {md_prose(line)}" in text
    for ch in result.channels:
        assert f"| scale ({ch['name']}) | {ch['scales']['light']:.5g} |" in text
    assert "Water: " not in text  # the first channel's alone: not shown

    # The Light tab names each channel's scale of the estimate.
    scales = ", ".join(f"{ch['name']} {ch['scales']['light']:.4g}" for ch in result.channels)
    assert f"scales {scales}" in app.panels.light.light_md.content

    # The Water folder shows each channel's estimate.
    for ch in result.channels:
        shown = water.fields[f"attenuation_per_m[{ch['name']}]"].value
        assert shown == round(ch["medium"]["attenuation_per_m"], 3)

    # Each image's overlay renders with its channel's lights, water and room light.
    display, overlays = st.display, app.controller.overlays
    assert display is not None and display.source == "estimate" and len(display.channels) == 3
    for i in (0, 1, 2):  # view_00 in R, G, B
        ch = st.project.channel_index(i)
        own = overlays.render(i, display)
        assert np.ma.allequal(own, overlays.render(i, display.of_channel(ch)))
        c = result.channels[ch]["medium"]["attenuation_per_m"]
        assert display.of_channel(ch).medium.attenuation_per_m == c
        first = overlays.render(i, dataclasses.replace(display, channels=()))
        assert ch == 0 or not np.ma.allclose(own, first)  # R's water would be another


def test_the_3d_view_shows_one_channels_pictures_and_clicks_land_on_them(
    app: LightcalApp,
) -> None:
    """A photo's channels share a pose (their frusta coincide): the pictures of the
    highlighted image's channel, else of the gizmo's image's; a click lands on those
    (after the Run above: the points change the selection)."""
    st, ctl, scene = app.state, app.controller, app.controller.scene
    channel_of = [st.project.channel_index(i) for i in range(len(st.project.names))]

    def pictured() -> list[int]:
        return sorted({channel_of[i] for i, h in enumerate(scene.frusta) if h.image is not None})

    assert pictured() == [0]  # the gizmo's image: view_00[R]
    plane = scene.planes[4]  # view_01[G]
    d = plane.R_world_camera @ np.array([0.1 * plane.half_width_m, 0.0, plane.depth_m])
    ctl.click(plane.center_world, d, mode="add")
    assert app.wait_idle(120.0)
    assert list(st.points) == ["view_01[R]"]  # the picture shown there
    ctl.clear_points()
    ctl.set_focus("view_01[G]")
    assert app.wait_idle(120.0)
    assert pictured() == [1]
    ctl.click(plane.center_world, d, mode="add")
    assert app.wait_idle(120.0)
    assert [k for k, v in st.points.items() if v] == ["view_01[G]"]
    ctl.clear_points()
    ctl.set_focus(None)
    assert app.wait_idle(120.0)
    assert pictured() == [0]


def test_another_project_gets_its_own_water_fields(app: LightcalApp, colour: Path) -> None:
    """From the colour project to a one-channel one (its G dataset) and back: the Water
    folder's fields follow the project's channels."""
    from lightcal_app.requests import SwitchProject

    def switch(path: Path) -> None:
        project = load_project(path)
        app.state.request(SwitchProject(project, load_images(project), None, False))
        assert app.wait_idle(120.0)
        assert app.state.project.path == path

    water = app.panels.light.water
    switch(colour.parent.parent / "G" / "project.json")
    assert list(water.fields) == ["attenuation_per_m", "backscatter_per_m", "phase_g"]
    assert water.fields["attenuation_per_m"].label == "attenuation c (m⁻¹)"
    water.fields["attenuation_per_m"].value = 0.12
    assert app.wait_idle(120.0)
    assert app.state.solve_project.spec.medium.attenuation_per_m == 0.12
    assert app.state.solve_settings.media is None
    switch(colour)
    assert len(water.fields) == 7
    assert [water.fields[f"attenuation_per_m[{ch}]"].value for ch in "RGB"] == C_FILE
    assert not [b for t, b in app.state.messages if t.startswith("⚠")]
