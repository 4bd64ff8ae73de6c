"""Report figures: round axis ticks, sizes at the print scale, legible text, masks kept."""

from __future__ import annotations

import numpy as np
import pytest

from lightcal.io.figures import (
    PRINT_SCALE,
    angle_residual_figure,
    convergence_figure,
    image_pair_figure,
    nice_ticks,
    residual_figure,
)


@pytest.mark.parametrize(
    ("lo", "hi", "count", "ticks"),
    [
        (1.0, 66.0, 5, [0.0, 20.0, 40.0, 60.0, 80.0]),
        (0.0, 6.0, 6, [0.0, 2.0, 4.0, 6.0]),
        (-0.2, 0.2, 5, [-0.2, -0.1, 0.0, 0.1, 0.2]),
        (3.0, 3.0, 5, [3.0]),
    ],
)
def test_nice_ticks_are_round_and_cover_the_range(lo, hi, count, ticks):
    assert nice_ticks(lo, hi, count) == ticks


def _ink_rows(rgb: np.ndarray, x0: int, x1: int, y0: int, y1: int) -> int:
    """How many rows of the box hold dark (text) pixels."""
    box = rgb[y0:y1, x0:x1].min(axis=2)
    return int(np.count_nonzero((box < 100).any(axis=1)))


def test_figures_are_drawn_at_the_print_scale_with_legible_text():
    assert PRINT_SCALE == 2
    fig = convergence_figure([1e9, 4e7, 8e5, 7e4, 7e4])
    assert fig.shape == (360 * PRINT_SCALE, 640 * PRINT_SCALE, 3)
    # The "iteration" label under the axis: at least 16 pixels tall (9 points at 2 px/pt);
    # before the print scale the report's text was 9-10 pixels tall.
    h, w = fig.shape[:2]
    assert _ink_rows(fig, w // 2 - 80, w // 2 + 80, h - 30 * PRINT_SCALE, h) >= 16
    small = convergence_figure([1e9, 1e5], scale=1)
    assert small.shape == (360, 640, 3)


def test_convergence_figure_without_costs_says_so():
    fig = convergence_figure([float("nan"), 0.0])
    assert fig.shape == (720, 1280, 3)
    assert (fig < 100).any()  # "no iterations" is written


def test_convergence_figure_draws_the_earlier_stage_in_grey_before_the_solve():
    """A start found by a first solve: its costs in grey at iterations 0..K-1, the solve's
    in colour from K on, one log axis for both (the earlier costs may lie above)."""

    def dots(fig: np.ndarray, colour: tuple[int, int, int]) -> np.ndarray:
        """Columns of the pixels exactly of `colour` (the dots' fill)."""
        return np.nonzero(np.all(fig == colour, axis=2))[1]

    solve = [10.0, 9.0, 8.9]
    alone = convergence_figure(solve)
    fig = convergence_figure(solve, earlier=[1e4, 300.0, 20.0, 10.5], earlier_label="first")
    grey, red = dots(fig, (115, 115, 130)), dots(fig, (178, 24, 43))
    assert grey.size and red.size and grey.max() < red.min()  # grey first, then the solve
    assert dots(alone, (115, 115, 130)).size == 0
    # The axis grew to hold 1e4 and 7 iterations: the solve's dots moved right and down.
    assert red.min() > dots(alone, (178, 24, 43)).min()


def test_residual_figure_keeps_masked_pixels_grey_and_labels_the_unit():
    residual = np.ma.masked_array(np.linspace(-5, 5, 200 * 300).reshape(200, 300))
    residual[50:60, 50:60] = np.ma.masked
    fig = residual_figure(residual, title="t", vmax=5.0, width_pt=300)
    top, pad = 30 * PRINT_SCALE, 10 * PRINT_SCALE
    body = fig[top : top + 400, pad : pad + 600]
    # The masked square, scaled 2x by nearest neighbour: one grey, not red or blue.
    square = body[100:120, 100:120].reshape(-1, 3)
    assert np.all(square == square[0]) and square[0][0] == square[0][2]
    # The ends of the scale are diverging colours: red at +5 (top right), blue at -5.
    assert body[-1, -1][0] > body[-1, -1][2] and body[0, 0][2] > body[0, 0][0]


def test_image_pair_figure_fits_its_width():
    real = np.ones((100, 4000))
    fig = image_pair_figure(real, real, title="x", width_pt=900)
    assert fig.shape[1] == 900 * PRINT_SCALE


def test_angle_figure_without_a_panel_says_too_few_pixels():
    panel = {
        "significant": False,
        "p_value": 0.5,
        "bin_edges_deg": [1.0, 20.0, 40.0, 66.0],
        "mean_relative_residual": [0.001, -0.001, 0.0],
    }
    fig = angle_residual_figure({"mirror": panel, "incidence": None}, scale=1)
    assert fig.shape == (340, 900, 3)
    right = fig[:, 450:]
    assert (right < 100).any()


def test_cause_figure_colours_findings_and_quiet_causes() -> None:
    from lightcal.io.cause_figure import _FINDING, _QUIET, _SIGNIFICANT, cause_figure

    def cause(name: str, shift: float | None, significant: bool, material: bool) -> dict:
        return {
            "cause": name,
            "shift_sigma": shift,
            "relative_effect": 0.01,
            "significant": significant,
            "material": material,
        }

    fit = {
        "causes": [
            cause("gloss", 30.0, True, True),
            cause("ambient", 3.0, True, False),
            cause("vignetting", 0.5, False, False),
            cause("images", None, True, True),
        ],
        "jackknife_ratio": 5.0,
        "floors": {"shift_sigma": 1.0},
    }
    fig = cause_figure(fit, scale=1.0)
    assert fig is not None and fig.dtype == np.uint8 and fig.shape[2] == 3

    def count(colour: tuple[int, int, int]) -> int:
        return int(np.count_nonzero(np.all(fig == np.array(colour, dtype=np.uint8), axis=2)))

    # Bars as long as their log shift: gloss and the jackknife red, ambient orange.
    assert count(_FINDING) > 2 * count(_SIGNIFICANT) > 0
    assert count(_QUIET) > 0
    assert cause_figure({"causes": []}) is None


def test_a_residual_map_is_stepped_block_means_and_its_bar_alike():
    """Each map pixel is the mean of the residuals it covers (noise of +-1 over a 4 px
    block averages to 0), shown in one of 2 RESIDUAL_STEPS + 1 colour bands."""
    from lightcal.colormap import RESIDUAL_STEPS

    checker = np.where((np.indices((400, 1200)).sum(axis=0) % 2) == 0, 1.0, -1.0)
    fig = residual_figure(checker + 3.0, title="t", vmax=5.0, width_pt=300, scale=1)
    body = fig[30 : 30 + 100, 10 : 10 + 300].reshape(-1, 3)
    assert len(np.unique(body, axis=0)) == 1  # all +3: the checker averaged out
    ramp = residual_figure(
        np.linspace(-5, 5, 300)[None, :].repeat(50, axis=0), title="t", vmax=5.0, width_pt=300
    )
    colours = np.unique(ramp[60:100, 20:620].reshape(-1, 3), axis=0)
    assert len(colours) == 2 * RESIDUAL_STEPS + 1
