"""The renderer's numbers against those recorded before its kernels were reorganised.

`tests/data/kernel_golden.npz` holds outputs of `render_image` and `shade` (values and
gradients, through every kernel path) written by `tests/make_kernel_golden.py` at commit
2ad8fa0 (the monolithic `render_kernels.py`). A refactoring of the kernels must keep them
to 1e-12 relative; gradients per pixel to 1e-12 of the gradient's norm.
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.make_kernel_golden import PATH, cases

RTOL = 1e-12


@pytest.fixture(scope="module")
def recorded() -> dict[str, np.ndarray]:
    with np.load(PATH) as data:
        return {key: data[key] for key in data.files}


@pytest.fixture(scope="module")
def current() -> dict[str, np.ndarray]:
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
        np.testing.assert_allclose(got[ok], expected[ok], rtol=RTOL, atol=0.0, err_msg=key)


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
