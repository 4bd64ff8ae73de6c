"""Capture planning (lightcal.pipeline.plan): the predicted covariance, the greedy choice,
`lightcal plan`. Small synthetic problems (~150 pixels per image) from tests/calib_scenes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from lightcal.core.problem import LightUnknown
from lightcal.core.solver import CalibrationModel, SolverOptions
from lightcal.pipeline.plan import (
    InformationState,
    PlanGrid,
    candidate_image,
    candidate_view,
    greedy_plan,
    plan_views,
)
from tests import calib_scenes as cs

GRID = PlanGrid(pixels_per_view=150, distances_m=(0.9, 1.8), tilts_deg=(0.0, 30.0))


def _problem(n_views: int = 3, *, estimate_gains: bool = False):
    camera = cs.small_camera()
    light = cs.symmetric_light()
    images = cs.observe(
        camera, cs.views(n_views, seed=3), cs.Rig((light,)), n_per_image=150,
        rng=np.random.default_rng(0),
    )
    # Noise-free values with the noise model's sigma: s^2 = 1 is exact.
    images = [
        cs.ImageData(im.name, im.view, im.footprints, im.observed, np.sqrt(im.observed + 4.0))
        for im in images
    ]
    model = CalibrationModel(
        images, [LightUnknown(light)], SolverOptions(estimate_gains=estimate_gains)
    )
    return camera, light, model, model.layout.x0.copy()


@pytest.mark.parametrize("estimate_gains", [False, True])
def test_predicted_covariance_is_the_solvers_after_adding_the_view(estimate_gains):
    camera, light, model, x = _problem(estimate_gains=estimate_gains)
    state = InformationState(model, x)
    view = candidate_view(1.3, 30.0, 45.0, 90.0, np.zeros(3)).view
    image = candidate_image(model, x, camera, view, GRID)
    assert image is not None
    predicted = np.linalg.inv(state.view_information(image))
    bigger = CalibrationModel(model.images + [image], model.unknowns, model.options)
    x_big = np.concatenate([x, [0.0]]) if estimate_gains else x
    # The extended layout orders gains before the pose? Map by names.
    names = bigger.layout.names
    order = [*model.layout.names, *[nm for nm in names if nm not in model.layout.names]]
    x_big = np.array([dict(zip(order, x_big, strict=True))[nm] for nm in names])
    assert np.abs(bigger.residuals(x_big)).max() < 1e-9  # the data at the truth
    actual = np.linalg.inv(bigger.normal_matrix(x_big))
    idx = [order.index(nm) for nm in names]
    predicted = predicted[np.ix_(idx, idx)]
    pose = np.arange(5)
    rel = np.abs(predicted[np.ix_(pose, pose)] - actual[np.ix_(pose, pose)]).max()
    assert rel / np.abs(actual[np.ix_(pose, pose)]).max() < 1e-6
    assert state.sigmas(state.view_information(image)).position_m[0] < state.sigmas().position_m[0]
