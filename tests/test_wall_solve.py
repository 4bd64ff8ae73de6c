"""Calibrating on glossy walls: the wall's parameters estimated jointly with the light."""

from __future__ import annotations

import numpy as np
import pytest

from lightcal.core.problem import LightUnknown, WallUnknown
from lightcal.core.scene import Rig
from lightcal.core.solver import CalibrationModel, SolverOptions, run_least_squares
from lightcal.core.wall import OrenNayarWall, PlasticWall
from tests.calib_scenes import (
    observe,
    pose_errors,
    small_camera,
    start_near,
    symmetric_light,
    views,
)


def _problem(wall, *, n_views: int = 10, seed: int = 3):
    camera = small_camera()
    vs = views(n_views, seed=seed)
    truth = symmetric_light()
    images = observe(camera, vs, Rig.single(truth), rng=np.random.default_rng(seed), wall=wall)
    return images, truth


@pytest.mark.parametrize("roughness", [0.2, 0.5])
def test_noise_free_plastic_wall_recovered(roughness: float) -> None:
    """Noise-free plastic walls, wall model estimated: position < 1e-6 m, axis < 1e-4 deg."""
    truth_wall = PlasticWall.from_albedo(roughness, 1.5, 0.8)
    images, truth = _problem(truth_wall)
    start_wall = PlasticWall(0.35, 1.5, 1.0)
    model = CalibrationModel(
        images,
        [LightUnknown(start_near(truth))],
        SolverOptions(),
        WallUnknown(start_wall, ("roughness", "specular_weight")),
    )
    out = run_least_squares(model)
    assert out.success, out.message
    est = model.layout.rig(out.x).lights[0]
    dp, da = pose_errors(est, truth)
    assert dp < 1e-6
    assert da < 1e-4
    wall = model.layout.wall_of(out.x)
    np.testing.assert_allclose(
        wall.parameters()[[0, 2]], truth_wall.parameters()[[0, 2]], rtol=1e-5
    )


@pytest.mark.parametrize(
    ("wall", "estimate"),
    [
        (PlasticWall(0.3, 1.5, 1.5), ("roughness", "ior", "specular_weight")),
        (OrenNayarWall(0.4), ("sigma",)),
    ],
)
def test_wall_columns_match_differences(wall, estimate) -> None:
    images, truth = _problem(wall, n_views=3)
    model = CalibrationModel(
        images, [LightUnknown(start_near(truth))], SolverOptions(), WallUnknown(wall, estimate)
    )
    x = model.layout.x0.copy()
    J = model.jacobian(x).copy()
    cols = range(model.layout.wall.start, model.layout.wall.stop)
    assert len(cols) == len(estimate)
    for k in [*range(model.layout.n - len(estimate)), *cols]:
        h = 1e-6 * max(1.0, abs(x[k]))
        hi, lo = x.copy(), x.copy()
        hi[k] += h
        lo[k] -= h
        fd = (model.residuals(hi).copy() - model.residuals(lo).copy()) / (2 * h)
        np.testing.assert_allclose(J[:, k], fd, rtol=1e-4, atol=1e-6 * np.abs(fd).max())


def test_wall_bounds_reach_the_solver() -> None:
    wall = PlasticWall(0.3, 1.5, 1.5)
    images, truth = _problem(wall, n_views=3)
    model = CalibrationModel(
        images,
        [LightUnknown(truth)],
        SolverOptions(),
        WallUnknown(wall, ("roughness", "specular_weight")),
    )
    lo, hi = model.parameter_bounds()
    np.testing.assert_array_equal(lo[model.layout.wall], [0.02, 0.0])
    np.testing.assert_array_equal(hi[model.layout.wall], [1.0, 100.0])
    assert model.layout.names[model.layout.wall] == ["wall.roughness", "wall.specular_weight"]


def test_unknown_wall_parameter_is_an_error() -> None:
    with pytest.raises(ValueError, match="wall: estimate: plastic has no parameter 'alpha'"):
        WallUnknown(PlasticWall(), ("alpha",))
