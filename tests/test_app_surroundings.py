"""The surroundings a project declares (`surroundings:`) are drawn in the page's 3D view:
each surface a translucent rectangle at its corners, labelled with its name and albedo."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from lightcal_app.server import build_app

from lightcal.cli.main import main
from lightcal.io.project import load_project


def test_the_declared_surfaces_are_drawn_where_they_are(tmp_path: Path) -> None:
    folder = tmp_path / "corner"
    argv = ["synth", str(folder), "--views", "4", "--width", "320", "--height", "240"]
    argv += ["--corner", "0.7", "0.5", "0.8", "--declare-surroundings", "--quiet"]
    assert main(argv) == 0
    project = load_project(folder / "project.json")
    assert project.surroundings is not None
    surfaces = project.surroundings.surfaces
    app = build_app(folder / "project.json", port=0, session_path=None, state_dir=tmp_path)
    try:
        assert app.wait_idle()  # the scene is drawn
        nodes = app.server.scene._handle_from_node_name
        for k, surface in enumerate(surfaces):
            mesh = nodes[f"/surroundings/{k}"]
            np.testing.assert_allclose(mesh.vertices, surface.corners_world, atol=1e-6)
            label = nodes[f"/surroundings/{k}_label"]
            assert label.text == f"{surface.name} (albedo {surface.albedo:.2g})"
        assert f"/surroundings/{len(surfaces)}" not in nodes
    finally:
        app.close()
