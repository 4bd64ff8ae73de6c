"""The surroundings' albedos estimated with the light (`Surroundings.estimate_albedo`):
d L / d a_k through the radiosity solve and its truncated series, the Jacobian's albedo
columns against central differences, and a calibration that recovers the light and a
ceiling's albedo declared wrong."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from lightcal.core.medium import Medium
from lightcal.core.problem import LightUnknown, MediumUnknown
from lightcal.core.solver import CalibrationModel, SolverOptions, run_least_squares
from lightcal.core.surroundings import Surroundings
from tests.calib_scenes import assert_columns_match_differences, pose_errors, start_near
from tests.test_bounce import _light_and_view
from tests.test_bounce_water import _calibration_data, _room, _term


@pytest.mark.parametrize("bounces", [None, 3])
@pytest.mark.parametrize("c", [0.0, 0.4])
def test_albedo_slopes_match_central_differences(bounces: int | None, c: float) -> None:
    """d bounce / d a_k of each surface (every bounce and 3 bounces, air and water)
    against central differences of the term at the surfaces' albedos +- 1e-6."""
    light, view = _light_and_view()
    term = _term(bounces)
    s = term.map.surroundings
    term.estimated = (0, 1)
    base = s.albedos()
    got = term.flux(
        0, view, light, want_grad=False, medium=Medium(c), albedos=base, albedo_surfaces=(0, 1)
    )
    for k in (0, 1):
        step = np.zeros_like(base)
        step[k] = 1e-6
        hi = term.flux(0, view, light, want_grad=False, medium=Medium(c), albedos=base + step)
        lo = term.flux(0, view, light, want_grad=False, medium=Medium(c), albedos=base - step)
        fd = (hi[:, 0] - lo[:, 0]) / 2e-6
        assert np.abs(fd).max() > 0.0
        np.testing.assert_allclose(got[:, 1 + k], fd, rtol=1e-5, atol=1e-8 * np.abs(fd).max())
    # The declared albedos given explicitly are the map as built.
    plain = term.flux(0, view, light, want_grad=False, medium=Medium(c))
    np.testing.assert_allclose(got[:, 0], plain[:, 0], rtol=1e-12)


def _estimating(room: Surroundings, start: float) -> Surroundings:
    """`room` with its ceiling's albedo declared as `start` and estimated."""
    surfaces = (dataclasses.replace(room.surfaces[0], albedo=start), *room.surfaces[1:])
    return dataclasses.replace(room, surfaces=surfaces, estimate_albedo=(0,))


def test_the_albedo_column_matches_differences() -> None:
    """Every Jacobian column (pose, scale, c and the ceiling's albedo) of a model in water
    with the ceiling's albedo estimated, against central differences of its residuals."""
    images, truth = _calibration_data(0.3, _room())
    model = CalibrationModel(
        images[:3],
        [LightUnknown(start_near(truth))],
        SolverOptions(),
        medium=MediumUnknown(Medium(0.25), ("attenuation_per_m",)),
        surroundings=_estimating(_room(), 0.6),
    )
    lay = model.layout
    assert lay.names[lay.surface_albedo] == ["surroundings.surfaces[0].albedo"]
    J = assert_columns_match_differences(model, lay.x0.copy())
    assert np.abs(J[:, lay.surface_albedo.start]).max() > 0.0


def test_a_wrong_ceiling_albedo_is_estimated_back() -> None:
    """Noise-free, the model's own render with the room's ceiling at 0.8: declared at 0.5
    and estimated, the light comes back to 1e-6 m and the albedo to 1e-5; declared at 0.5
    and held, the light lands off by more than 0.1 mm."""
    room = _room()
    images, truth = _calibration_data(0.0, room)

    def solve(surroundings: Surroundings) -> tuple[CalibrationModel, np.ndarray]:
        model = CalibrationModel(
            images, [LightUnknown(start_near(truth))], SolverOptions(), surroundings=surroundings
        )
        out = run_least_squares(model)
        assert out.success, out.message
        return model, out.x

    model, x = solve(_estimating(room, 0.5))
    dp, da = pose_errors(model.layout.rig(x).lights[0], truth)
    assert dp < 1e-6 and da < 1e-4
    assert x[model.layout.surface_albedo][0] == pytest.approx(0.8, abs=1e-5)
    held = dataclasses.replace(_estimating(room, 0.5), estimate_albedo=())
    model, x = solve(held)
    dp, _ = pose_errors(model.layout.rig(x).lights[0], truth)
    assert dp > 1e-4


def test_bad_estimate_albedo_is_refused() -> None:
    room = _room()
    with pytest.raises(ValueError) as err:
        dataclasses.replace(room, estimate_albedo=(0, 2))
    assert str(err.value) == (
        "surroundings: estimate_albedo: expected distinct surfaces among 0-1, got [0, 2]"
    )
    assert _term().estimated == ()


def test_a_project_estimates_the_albedos_it_marks() -> None:
    """`estimate_albedo: true` on a surface of the sample project: the core's
    surroundings estimate that surface's albedo, the spec written back keeps the mark,
    and the result's summary and words name it."""
    import json

    from lightcal.io.project import parse_project, project_from_spec
    from lightcal.io.surroundings_spec import surroundings_spec
    from lightcal.pipeline.result_text import surroundings_text
    from tests.test_bounce_water import SAMPLE

    source = SAMPLE / "project.json"
    doc = json.loads(source.read_text())
    ceiling = {"corner_m": [-1, -0.5, 0], "edge_u_m": [2, 0, 0], "edge_v_m": [0, 0, 0.5]}
    side = {"corner_m": [1, -0.5, 0], "edge_u_m": [0, 1, 0], "edge_v_m": [0, 0, 0.5]}
    doc["surroundings"] = {
        "surfaces": [
            {**ceiling, "albedo": 0.6, "estimate_albedo": True},
            {**side, "albedo": 0.7},
        ]
    }
    project = project_from_spec(parse_project(doc, source), source)
    assert project.surroundings is not None
    assert project.surroundings.estimate_albedo == (0,)
    spec = surroundings_spec(project.surroundings)
    assert [s.estimate_albedo for s in spec.surfaces] == [True, False]
    summary = {"albedos": [0.79, 0.7], "estimated": [0], "sigma": {"0": 0.004}}
    assert surroundings_text(summary) == "surroundings: surfaces[0] albedo 0.79 ± 0.004 (estimated)"
