"""The renderer's numbers against those recorded before its kernels were reorganised.

`tests/data/kernel_golden.npz` holds outputs of `render_image` and `shade` (values and
gradients, through every kernel path) written by `tests/make_kernel_golden.py` at commit
2ad8fa0 (the monolithic `render_kernels.py`). A refactoring of the kernels must keep them
to 1e-12 relative; gradients per pixel to 1e-12 of the gradient's norm. The table RIDs
are compared so through their exact interpolation (`RID.exact_data`, what was recorded);
rendered from their grids (`lightcal.core.rid_tabulate`, what lightcal renders with) they
stay within GRID_RTOL of the recorded values and GRID_GRAD_RTOL of the gradients' norms
(measured: 4.3e-5 and 6.7e-3, the 2-D table's; the symmetric table's 7.3e-8 and 8.8e-5).

The images of the high-resolution crop (`image__crop_*`) are held to CROP_RTOL: since
issue 12 the corner grid is no longer bit for bit `pixels_to_normalized` (round-off apart:
both stop at a residual of 1e-15 relative, so corners may differ by ~4e-15 in normalised
coordinates, 2e-11 of a crop pixel 1/5400 wide), and a `paper` value scales with its
footprint's area (measured: 2.0e-12 for `image__crop_paper`, 1.8e-15 for the others).
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.make_kernel_golden import PATH, cases

RTOL = 1e-12
CROP_RTOL = 5e-11
GRID_RTOL = 1e-4
GRID_GRAD_RTOL = 1.5e-2


@pytest.fixture(scope="module")
def recorded() -> dict[str, np.ndarray]:
    with np.load(PATH) as data:
        return {key: data[key] for key in data.files}


@pytest.fixture(scope="module")
def current() -> dict[str, np.ndarray]:
    return dict(cases(exact_tables=True))


@pytest.fixture(scope="module")
def on_grids() -> dict[str, np.ndarray]:
    return dict(cases())


def test_the_same_cases_are_recorded(
    recorded: dict[str, np.ndarray], current: dict[str, np.ndarray]
) -> None:
    assert sorted(current) == sorted(recorded)


def test_values_match_the_recorded_ones(
    recorded: dict[str, np.ndarray], current: dict[str, np.ndarray]
) -> None:
    for key, expected in recorded.items():
        if key.endswith("__grad"):
            continue
        got = current[key]
        assert got.shape == expected.shape, key
        np.testing.assert_array_equal(np.isnan(got), np.isnan(expected), err_msg=key)
        ok = ~np.isnan(expected)
        assert np.count_nonzero(expected[ok]) > 0, key
        rtol = CROP_RTOL if key.startswith("image__crop_") else RTOL
        np.testing.assert_allclose(got[ok], expected[ok], rtol=rtol, atol=0.0, err_msg=key)


def test_gradients_match_the_recorded_ones(
    recorded: dict[str, np.ndarray], current: dict[str, np.ndarray]
) -> None:
    for key, expected in recorded.items():
        if not key.endswith("__grad"):
            continue
        got = current[key]
        assert got.shape == expected.shape, key
        for part in (slice(0, 3), slice(3, 6)):
            norm = np.linalg.norm(expected[:, part], axis=1)
            err = np.linalg.norm(got[:, part] - expected[:, part], axis=1)
            assert np.all(err <= RTOL * norm), (key, np.max(err / np.maximum(norm, 1e-300)))


def test_table_grids_stay_close_to_the_recorded_values(
    recorded: dict[str, np.ndarray], current: dict[str, np.ndarray], on_grids: dict[str, np.ndarray]
) -> None:
    changed = 0
    for key, expected in recorded.items():
        got = on_grids[key]
        ok = ~np.isnan(expected)
        np.testing.assert_array_equal(np.isnan(got), ~ok, err_msg=key)
        if not np.array_equal(got[ok], current[key][ok]):
            changed += 1
        if key.endswith("__grad"):
            for part in (slice(0, 3), slice(3, 6)):
                norm = np.linalg.norm(expected[:, part], axis=1)
                err = np.linalg.norm(got[:, part] - expected[:, part], axis=1)
                assert np.all(err <= GRID_GRAD_RTOL * norm), key
        else:
            np.testing.assert_allclose(got[ok], expected[ok], rtol=GRID_RTOL, atol=0.0, err_msg=key)
    # Only the cases with a table differ: the others are the same numbers.
    assert changed == sum(
        1
        for key in recorded
        if "table" in key
        or key.startswith(("image__radiance", "image__cos4", "image__paper_b", "image__map"))
    )
