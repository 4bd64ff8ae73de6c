"""The flat ports in a real headless Chromium: the camera's port is drawn in front of its
frustum (the pixels around it change when it is hidden) and the Light tab's text reaches
the page."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from lightcal_app.server import LightcalApp, build_app
from PIL import Image

from tests.test_app_browser import (  # noqa: F401  (the browser fixture is used by name)
    BROWSER_MARKS,
    SLOW_S,
    browser,
    open_page,
    project_to_screen,
    set_camera,
    shot,
)
from tests.test_app_port_view import ported  # noqa: F401  (a fixture)

pytestmark = BROWSER_MARKS


@pytest.fixture(scope="module")
def app(
    ported: Path,  # noqa: F811  (the fixture imported above)
    tmp_path_factory: pytest.TempPathFactory,
) -> Iterator[LightcalApp]:
    a = build_app(ported, port=0, session_path=False, state_dir=tmp_path_factory.mktemp("s"))
    assert a.wait_idle(SLOW_S)
    yield a
    a.close()


def test_the_ports_are_drawn_in_the_page(
    app: LightcalApp,
    browser: Any,  # noqa: F811  (the fixture imported above)
) -> None:
    page, client = open_page(browser, app)
    page.get_by_role("tab", name="Light").click()
    page.get_by_text("behind a flat port: 20 mm to the glass", exact=False).first.wait_for()
    # Close to the first camera, looking at its port's centre from behind and aside.
    view = app.state.project.views[0]
    R_wc, C = view.R_camera_world.T, view.center_world
    centre = C + R_wc @ np.array([0.0, 0.0, 0.025])
    set_camera(client, C + R_wc @ np.array([0.03, -0.02, -0.05]), centre, -R_wc[:, 1])
    nodes = app.server.scene._handle_from_node_name
    port_nodes = [nodes[f"/cameras/{i}/{n}"] for i in range(3) for n in ("port", "port_edges")]
    with_port = np.asarray(Image.open(shot(page, "app_port_view.png")).convert("RGB"), float)
    for node in port_nodes:
        node.visible = False
    without = np.asarray(Image.open(shot(page, "app_port_view_hidden.png")).convert("RGB"), float)
    for node in port_nodes:
        node.visible = True
    # Where the inner face's corners land on the screen: most of that box changed.
    inner = np.asarray(nodes["/cameras/0/port"].vertices)[:4]
    xy = project_to_screen(client, C + inner @ R_wc.T)
    h, w = with_port.shape[:2]
    (x0, y0), (x1, y1) = np.clip(xy.min(axis=0), 0, [w, h]), np.clip(xy.max(axis=0), 0, [w, h])
    box = (slice(int(y0), int(y1)), slice(int(x0), int(x1)))
    assert (x1 - x0) * (y1 - y0) > 2000, "the port's face is too small on the screen"
    changed = np.abs(with_port - without).max(axis=2) > 12.0
    assert changed[box].mean() > 0.5, changed[box].mean()
    assert changed.mean() < 0.5  # elsewhere the page is the same
