"""The Water folder of a colour project (`sensor.channels`) in a real headless Chromium:
one c field per channel, a value typed in one goes into that channel's water alone."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from lightcal_app.server import LightcalApp, build_app

from tests.test_app_browser import (  # noqa: F401  (the browser fixture is used by name)
    BROWSER_MARKS,
    SLOW_S,
    browser,
    open_page,
    shot,
    wait_for,
)
from tests.test_app_channels import C_FILE, colour  # noqa: F401  (a fixture)

pytestmark = BROWSER_MARKS


@pytest.fixture(scope="module")
def app(
    colour: Path,  # noqa: F811  (the fixture imported above)
    tmp_path_factory: pytest.TempPathFactory,
) -> Iterator[LightcalApp]:
    a = build_app(colour, port=0, session_path=False, state_dir=tmp_path_factory.mktemp("state"))
    assert a.wait_idle(SLOW_S)
    yield a
    a.close()


def test_c_per_channel_typed_in_the_page_goes_into_that_channel(
    app: LightcalApp,
    browser: Any,  # noqa: F811  (the fixture imported above)
) -> None:
    page, _ = open_page(browser, app, size=(1280, 800))
    fields = {ch: page.get_by_label(f"attenuation c, {ch} (m⁻¹)", exact=True) for ch in "RGB"}
    assert [fields[ch].input_value() for ch in "RGB"] == [f"{c:g}" for c in C_FILE]
    page.get_by_label("phase g", exact=True).wait_for()

    fields["G"].fill("0.15")
    fields["G"].press("Enter")
    wait_for(
        lambda: app.state.solve_project.spec.medium.attenuation_per_m == [0.3, 0.15, 0.05],
        "channel G's c in the solved project",
    )
    assert app.wait_idle(SLOW_S)
    display = app.state.display
    assert display is not None
    assert [m.attenuation_per_m for _, m, _ in display.channels] == [0.3, 0.15, 0.05]
    assert [fields[ch].input_value() for ch in "RGB"] == ["0.3", "0.15", "0.05"]
    shot(page, "app_channels_water.png")
