"""Inter-reflection on data lightcal's model did not make (issue 26): Mitsuba 3's
`interreflection` scenario (`tests/mitsuba_datasets.py`: a ceiling and a side wall of
albedo 0.8, 0.5 m deep, meeting the wall 0.7 m from the median beam centre; the path
tracer's bounces are 10-12 % of the signal) calibrated with its surroundings declared
(`surroundings:`, docs/model.md "Inter-reflection"), `bounces: 3` as the path tracer
renders (`max_depth` 5).

Measured (12 views, 1000 pixels a view, realistic sensor): 43 mm and 1.76 deg off
without the section (exit 3), 0.73 mm and 0.048 deg with it (exit 0). The bounce at the
true pose is 0.98-1.03 of Mitsuba's per view (noise-free sensor, 3000 pixels a view).

Skipped without Mitsuba (`pip install .[reference]`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("mitsuba", reason="Mitsuba 3 is not installed: pip install .[reference]")

from lightcal.io.project import load_project
from lightcal.pipeline import calibrate_project
from lightcal.synthetic.dataset import read_truth
from tests.departure_suite import errors, exit_code
from tests.mitsuba_datasets import session_dataset

#: Pixels a view: the default 100 leave a 2.3 mm pixel-noise sigma.
PIXELS = 1000


def declared_surroundings(truth: dict[str, Any]) -> dict[str, Any]:
    """The `surroundings` section a user would write for the scenario's ceiling and side
    wall (truth.json's `departures.interreflection`)."""
    t = truth["departures"]["interreflection"]
    y_c = float(t["ceiling"]["plane"].split("=")[1].split()[0])
    x_s = float(t["side_wall"]["plane"].split("=")[1].split()[0])
    x0 = t["ceiling"]["x_range_m"][0]
    y1 = t["side_wall"]["y_range_m"][1]
    depth, albedo = t["depth_m"], t["albedo"]
    return {
        "wall_albedo": albedo,
        "bounces": 3,  # the scenario's max_depth 5: 3 reflections before the wall's
        "surfaces": [
            {
                "name": "ceiling",
                "corner_m": [x0, y_c, 0.0],
                "edge_u_m": [x_s - x0, 0.0, 0.0],
                "edge_v_m": [0.0, 0.0, depth],
                "albedo": albedo,
            },
            {
                "name": "side wall",
                "corner_m": [x_s, y_c, 0.0],
                "edge_u_m": [0.0, y1 - y_c, 0.0],
                "edge_v_m": [0.0, 0.0, depth],
                "albedo": albedo,
            },
        ],
    }


def _project(
    tmp_path_factory: pytest.TempPathFactory,
    *,
    declare: bool,
    sensor: str = "realistic",
    pixels: int = PIXELS,
) -> Path:
    project = session_dataset(tmp_path_factory, "interreflection", seed=0, sensor=sensor)
    doc = json.loads(project.read_text())
    doc.setdefault("selection", {})["n_per_image"] = pixels
    if declare:
        doc["surroundings"] = declared_surroundings(read_truth(project.parent / "truth.json"))
    out = project.with_name(f"{'surroundings' if declare else 'plain'}_{pixels}.json")
    out.write_text(json.dumps(doc))
    return out


def test_declared_surroundings_remove_the_inter_reflection_error(tmp_path_factory) -> None:
    project = _project(tmp_path_factory, declare=True)
    _, _, result = calibrate_project(load_project(project))
    truth = read_truth(project.parent / "truth.json")["lights"][0]
    position, position_sigma, axis, axis_sigma = errors(result, truth)
    summary = (position, position_sigma, axis, axis_sigma, result.fit["findings"])
    assert position < 2e-3 and axis < 0.1, summary
    assert position <= 3.0 * position_sigma and axis <= 3.0 * axis_sigma, summary
    assert exit_code(result) == 0, summary


def test_without_them_the_light_is_centimetres_off(tmp_path_factory) -> None:
    project = _project(tmp_path_factory, declare=False)
    _, _, result = calibrate_project(load_project(project))
    truth = read_truth(project.parent / "truth.json")["lights"][0]
    position, _, axis, _ = errors(result, truth)
    assert position > 0.02 and axis > 0.5
    assert exit_code(result) == 3


def test_the_bounce_matches_mitsubas_at_the_true_pose(tmp_path_factory) -> None:
    """Mitsuba's bounce (its path render less its direct render, noise-free sensor) against
    the term's at the true light: within 3 % per view and 1 % overall."""
    import numpy as np

    from lightcal.core.bounce_term import BounceTerm
    from lightcal.core.render import shade
    from lightcal.core.scene import Rig
    from lightcal.pipeline.load import load_images
    from lightcal.pipeline.model import build_model
    from tests.mitsuba_datasets import truth_scene

    path = _project(tmp_path_factory, declare=True, sensor="clean", pixels=3000)
    project = load_project(path)
    assert project.surroundings is not None
    model = build_model(project, load_images(project))
    truth = truth_scene(path)
    term = BounceTerm(project.surroundings, [im.footprints for im in model.images])
    light = truth.light
    mitsuba, ours = [], []
    for i, im in enumerate(model.images):
        view = truth.views[project.names.index(im.name)]
        direct = shade(im.footprints, view, Rig.single(light)).values.filled(np.nan)
        mitsuba.append(float(np.sum(im.observed - direct)))
        ours.append(light.scale * float(term.flux(i, view, light, want_grad=False)[:, 0].sum()))
    ratio = np.array(ours) / np.array(mitsuba)
    assert np.all(np.abs(ratio - 1.0) < 0.03), ratio
    assert abs(sum(ours) / sum(mitsuba) - 1.0) < 0.01


def test_albedos_declared_wrong_are_estimated_back(tmp_path_factory) -> None:
    """Both surfaces declared at albedo 0.5 (truth 0.8) with `estimate_albedo: true`:
    measured 0.803 +- 0.004 and 0.799 +- 0.005, the light 0.79 mm / 0.042 deg off
    (sigma 1.07 mm / 0.064 deg), exit 0. Held at 0.5 the light lands 9.8 mm / 0.36 deg
    off and the fit test finds it (exit 3)."""
    project = _project(tmp_path_factory, declare=True)
    doc = json.loads(project.read_text())
    for surface in doc["surroundings"]["surfaces"]:
        surface.update(albedo=0.5, estimate_albedo=True)
    estimated = project.with_name("surroundings_estimated.json")
    estimated.write_text(json.dumps(doc))
    _, _, result = calibrate_project(load_project(estimated))
    truth = read_truth(project.parent / "truth.json")["lights"][0]
    position, position_sigma, axis, axis_sigma = errors(result, truth)
    summary = (position, axis, result.surroundings, result.fit["findings"])
    assert position < 2e-3 and axis < 0.1, summary
    assert position <= 3.0 * position_sigma and axis <= 3.0 * axis_sigma, summary
    assert exit_code(result) == 0, summary
    assert result.surroundings is not None
    assert result.surroundings["estimated"] == [0, 1]
    for k, albedo in enumerate(result.surroundings["albedos"]):
        assert albedo == pytest.approx(0.8, abs=0.02), summary
        assert 0.0 < result.surroundings["sigma"][str(k)] < 0.02
