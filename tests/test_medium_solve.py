"""Calibrating through a medium: its attenuation estimated jointly with the light."""

from __future__ import annotations

import numpy as np
import pytest

from lightcal.core.medium import MAX_ATTENUATION_PER_M, Medium
from lightcal.core.problem import LightUnknown, MediumUnknown, WallUnknown
from lightcal.core.scene import Rig
from lightcal.core.solver import CalibrationModel, SolverOptions, run_least_squares
from lightcal.core.wall import PlasticWall
from tests.calib_scenes import (
    observe,
    pose_errors,
    small_camera,
    start_near,
    symmetric_light,
    views,
)


def _problem(medium: Medium, *, n_views: int = 10, seed: int = 3, wall=None):
    camera = small_camera()
    vs = views(n_views, seed=seed)
    truth = symmetric_light()
    kw = {} if wall is None else {"wall": wall}
    images = observe(
        camera, vs, Rig.single(truth), rng=np.random.default_rng(seed), medium=medium, **kw
    )
    return images, truth


@pytest.mark.parametrize("c", [0.0, 0.4])
def test_noise_free_attenuation_recovered(c: float) -> None:
    """Noise-free views through water, c estimated from air (c = 0): the pose to 1e-6 m
    and 1e-4 deg, c to 1e-6 /m."""
    images, truth = _problem(Medium(c))
    model = CalibrationModel(
        images,
        [LightUnknown(start_near(truth))],
        SolverOptions(),
        medium=MediumUnknown(Medium(0.0), ("attenuation_per_m",)),
    )
    out = run_least_squares(model)
    assert out.success, out.message
    dp, da = pose_errors(model.layout.rig(out.x).lights[0], truth)
    assert dp < 1e-6
    assert da < 1e-4
    assert model.layout.medium_of(out.x).attenuation_per_m == pytest.approx(c, abs=1e-6)


@pytest.mark.parametrize("wall", [None, PlasticWall(0.3, 1.5, 1.5)])
@pytest.mark.parametrize("c", [0.0, 0.3])
def test_medium_column_matches_differences(c: float, wall: PlasticWall | None) -> None:
    """The Jacobian's pose, scale, wall and attenuation columns against central
    differences of the residuals (at c = 0 too, where the factor is 1 but not its
    derivative)."""
    images, truth = _problem(Medium(0.25), n_views=3, wall=wall)
    wall_unknown = None if wall is None else WallUnknown(wall, ("roughness", "specular_weight"))
    model = CalibrationModel(
        images,
        [LightUnknown(start_near(truth))],
        SolverOptions(),
        wall_unknown,
        MediumUnknown(Medium(c), ("attenuation_per_m",)),
    )
    lay = model.layout
    assert lay.names[lay.medium] == ["medium.attenuation_per_m"]
    x = lay.x0.copy()
    J = model.jacobian(x).copy()
    assert np.abs(J[:, lay.medium.start]).max() > 0.0
    for k in range(lay.n):
        h = 1e-6 * max(1.0, abs(x[k]))
        hi, lo = x.copy(), x.copy()
        hi[k] += h
        lo[k] -= h
        if k == lay.medium.start and c == 0.0:  # one-sided at the bound: second order
            lo[k] = x[k]
            hi[k] = x[k] + h
            fd = (model.residuals(hi).copy() - model.residuals(lo).copy()) / h
            np.testing.assert_allclose(J[:, k], fd, rtol=1e-4, atol=1e-4 * np.abs(fd).max())
            continue
        fd = (model.residuals(hi).copy() - model.residuals(lo).copy()) / (2 * h)
        np.testing.assert_allclose(J[:, k], fd, rtol=1e-4, atol=1e-6 * np.abs(fd).max())


def test_medium_bounds_reach_the_solver() -> None:
    images, truth = _problem(Medium(0.2), n_views=3)
    model = CalibrationModel(
        images,
        [LightUnknown(truth)],
        SolverOptions(),
        medium=MediumUnknown(Medium(0.2), ("attenuation_per_m",)),
    )
    lo, hi = model.parameter_bounds()
    np.testing.assert_array_equal(lo[model.layout.medium], [0.0])
    np.testing.assert_array_equal(hi[model.layout.medium], [MAX_ATTENUATION_PER_M])


def test_given_medium_adds_no_parameter() -> None:
    """A medium given (not estimated) renders through it without a column."""
    images, truth = _problem(Medium(0.3), n_views=3)
    given = CalibrationModel(
        images, [LightUnknown(truth)], SolverOptions(), medium=MediumUnknown(Medium(0.3))
    )
    air = CalibrationModel(images, [LightUnknown(truth)], SolverOptions())
    assert given.layout.names == air.layout.names
    x = given.layout.x0
    assert np.abs(given.residuals(x)).max() < 1e-9 * np.abs(air.residuals(x)).max()


def test_unknown_medium_parameter_is_an_error() -> None:
    with pytest.raises(ValueError, match="medium: estimate: no parameter 'sigma_s'"):
        MediumUnknown(Medium(0.1), ("sigma_s",))
    with pytest.raises(ValueError, match="medium: estimate: expected each parameter once"):
        MediumUnknown(Medium(0.1), ("attenuation_per_m", "attenuation_per_m"))


@pytest.mark.parametrize(
    ("start", "estimate"),
    [
        # c and beta from air.
        (Medium(0.0, 0.0, 0.5), ("attenuation_per_m", "backscatter_per_m")),
        # g too, from c = 0.2, beta = 2, g = 0.6: the veil's shape tells g. Slowly: 106
        # iterations (211 from g = 0.8), beta and g trading along a curved valley.
        (Medium(0.2, 2.0, 0.6), Medium.parameter_names),
    ],
)
def test_noise_free_backscatter_recovered(start: Medium, estimate: tuple[str, ...]) -> None:
    """Murky water (c = 0.3 /m, beta = 3 /m, g = 0.5) estimated: the pose to 1e-6 m and
    1e-4 deg, the medium's estimated parameters to 1e-5 relative."""
    truth_medium = Medium(0.3, 3.0, 0.5)
    images, truth = _problem(truth_medium)
    model = CalibrationModel(
        images,
        [LightUnknown(start_near(truth))],
        SolverOptions(max_iterations=300),
        medium=MediumUnknown(start, estimate),
    )
    out = run_least_squares(model)
    assert out.success, out.message
    dp, da = pose_errors(model.layout.rig(out.x).lights[0], truth)
    assert dp < 1e-6
    assert da < 1e-4
    np.testing.assert_allclose(
        model.layout.medium_of(out.x).parameters(), truth_medium.parameters(), rtol=1e-5
    )


@pytest.mark.parametrize(
    "estimate",
    [
        ("backscatter_per_m",),
        ("attenuation_per_m", "backscatter_per_m"),
        ("attenuation_per_m", "backscatter_per_m", "phase_g"),
    ],
)
def test_backscatter_columns_match_differences(estimate: tuple[str, ...]) -> None:
    """Every column of the Jacobian with the medium's parameters estimated (g too)."""
    images, truth = _problem(Medium(0.2, 2.0, 0.6), n_views=3)
    model = CalibrationModel(
        images,
        [LightUnknown(start_near(truth))],
        SolverOptions(),
        medium=MediumUnknown(Medium(0.25, 1.5, 0.6), estimate),
    )
    lay = model.layout
    assert lay.names[lay.medium] == [f"medium.{nm}" for nm in estimate]
    x = lay.x0.copy()
    J = model.jacobian(x).copy()
    for k in range(lay.n):
        h = 1e-6 * max(1.0, abs(x[k]))
        hi, lo = x.copy(), x.copy()
        hi[k] += h
        lo[k] -= h
        fd = (model.residuals(hi).copy() - model.residuals(lo).copy()) / (2 * h)
        np.testing.assert_allclose(J[:, k], fd, rtol=1e-4, atol=1e-6 * np.abs(fd).max())
