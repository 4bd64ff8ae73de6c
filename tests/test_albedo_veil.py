"""The albedo map beside the water's veil: every renderer of the model's values scales the
wall's light by the map and leaves the backscatter as it is (`lightcal.core.albedo_systems`
in the solver's systems, `albedo_map.with_albedo` elsewhere), so they agree."""

from __future__ import annotations

import numpy as np
import pytest

from lightcal.cli.main import main
from lightcal.core.albedo_map import with_albedo
from lightcal.core.medium import Medium
from lightcal.io.project import load_project
from lightcal.pipeline.fit_check import _renderer
from lightcal.pipeline.load import load_images
from lightcal.pipeline.model import build_model


@pytest.fixture(scope="module")
def veiled_model(tmp_path_factory):
    """6 views of a +-10 % textured wall in water (c 0.2, beta 0.5 /m, both estimated),
    the model away from its start: c and beta set, the light moved."""
    folder = tmp_path_factory.mktemp("veil") / "data"
    argv = ["synth", str(folder), "--views", "6", "--width", "320", "--height", "240"]
    argv += ["--albedo-texture", "0.1", "--declare-albedo-map", "--attenuation", "0.2"]
    argv += ["--backscatter", "0.5", "--declare-medium", "estimated", "--seed", "2", "--quiet"]
    assert main(argv) == 0
    project = load_project(folder / "project.json")
    model = build_model(project, load_images(project))
    x = model.layout.x0.copy()
    x[:3] += [0.01, -0.005, 0.0]
    x[model.layout.medium] = [0.2, 0.5]
    return model, x


def test_the_solvers_values_are_the_fit_tests(veiled_model) -> None:
    """The values the projected systems fit (observed - r sigma) are those the fit test's
    renderer draws, the map scaling the wall's light and not the veil (measured: 1e-12)."""
    model, x = veiled_model
    r = model.residuals(x)
    albedo = model.albedo_map(x)
    assert albedo is not None and np.ptp(albedo.delta) > 0.05  # a real map, not 1
    render = _renderer(model, x)
    for i, im in enumerate(model.images):
        fitted = im.observed - r[model.bounds[i] : model.bounds[i + 1]] * model.sigmas[i]
        drawn = render(i, im.view, im.footprints)
        np.testing.assert_allclose(drawn, fitted, rtol=1e-9, atol=1e-9 * np.abs(fitted).max())


def test_the_veil_is_not_scaled_by_the_albedo() -> None:
    """with_albedo: the wall's part times a, the veil as it is; in clear water all of it
    times a."""
    calls: list[float] = []

    def render(medium: Medium) -> np.ndarray:
        calls.append(medium.backscatter_per_m)
        wall = np.array([10.0, 20.0])
        return wall + (np.array([1.0, 2.0]) if medium.scatters else 0.0)

    a = np.array([0.5, 2.0])
    np.testing.assert_allclose(with_albedo(render, Medium(0.1, 0.3), a), [6.0, 42.0])
    assert calls == [0.3, 0.0]
    np.testing.assert_allclose(with_albedo(render, Medium(0.1, 0.0), a), [5.0, 40.0])
    assert calls == [0.3, 0.0, 0.0]
