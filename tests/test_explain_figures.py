"""The Explain tab's pictures: legible on the page and made by static/make_figures.py."""

from __future__ import annotations

import importlib.util
import math
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
from lightcal_app.explain import (
    PROJECT_FIGURES,
    SECTIONS,
    load_figure,
    project_views_figure,
    view_geometry,
)

from lightcal.core.scene import View
from lightcal.io.project import load_project

STATIC = Path(__file__).resolve().parents[1] / "static"
PANEL_PX = 360
"""About how wide the panel shows a picture (control_width "large")."""


def _script():
    spec = importlib.util.spec_from_file_location("make_figures", STATIC / "make_figures.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def script():
    return _script()


def test_text_is_about_12_pixels_on_the_page(script) -> None:
    (_, height), _ = cv2.getTextSize("Hg", script.FONT, script.S * script.TEXT, script.S)
    shown = height * PANEL_PX / (script.W * script.S)
    assert 11.0 <= shown <= 16.0, shown


@pytest.mark.parametrize("name", sorted(script_name for script_name in _script().FIGURES))
def test_each_stored_picture_is_the_scripts(script, name: str) -> None:
    stored = load_figure(name)
    assert stored is not None, name
    drawn = script.FIGURES[name]()
    assert stored.shape == drawn.shape == (script.H * script.S, script.W * script.S, 3)
    # Regenerated after every change of the script (PNG is lossless: equal pixels).
    assert np.mean(np.abs(stored.astype(int) - drawn.astype(int))) < 0.05, name


def test_every_section_picture_exists() -> None:
    for _, _, figure in SECTIONS:
        if figure is not None and figure not in PROJECT_FIGURES:
            assert (STATIC / figure).is_file(), figure


def test_the_views_figure_places_each_view_by_distance_and_tilt() -> None:
    project = load_project(Path(__file__).resolve().parents[1] / "sample_data" / "project.json")
    square = View.looking_at(np.array([0.1, -0.2, 1.5]), np.array([0.1, -0.2, 0.0]))
    a = math.radians(25.0)  # 25 deg off the normal, 2 m along the axis
    tilted = View.looking_at(2.0 * np.array([math.sin(a), 0.0, math.cos(a)]), np.zeros(3))
    two = replace(project, views=[square, tilted], names=["square", "tilted"])
    distance, tilt = view_geometry(two)
    np.testing.assert_allclose(distance, [1.5, 2.0 * math.cos(a)], rtol=1e-12)
    np.testing.assert_allclose(tilt, [0.0, 25.0], atol=1e-9)
    fig = project_views_figure(project)
    assert fig.shape == (420, 600, 3) and fig.dtype == np.uint8
    # The sample's 12 views are drawn as 12 red dots (the figure's _DOT colour).
    red = np.all(np.abs(fig.astype(int) - np.array([178, 24, 43])) < 30, axis=-1)
    n, _ = cv2.connectedComponents(red.astype(np.uint8))
    assert n - 1 >= 6  # 12 dots, some may touch
