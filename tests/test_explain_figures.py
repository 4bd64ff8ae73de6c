"""The Explain tab's pictures: legible on the page and made by static/make_figures.py."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import cv2
import numpy as np
import pytest
from lightcal_app.explain import SECTIONS, load_figure

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
        if figure is not None:
            assert (STATIC / figure).is_file(), figure
