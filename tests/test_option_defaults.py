"""Defaults are defined once: the project file's selection, sensor and solver sections
take theirs from the core options (`SelectionOptions`, `SolverOptions`), and the
pipeline's multi-start defaults from the project file's solver section."""

from __future__ import annotations

import dataclasses
import inspect

from lightcal.core.selection import SelectionOptions
from lightcal.core.solver import SolverOptions
from lightcal.io.project import SelectionSpec, SensorSpec, SolverSpec, WallSpec
from lightcal.pipeline.solve import solve


def _shared_defaults(spec_cls, options) -> list[tuple[str, object, object]]:
    """(name, spec default, options default) of every field both have."""
    fields = spec_cls.model_fields
    return [
        (f.name, fields[f.name].get_default(call_default_factory=True), getattr(options, f.name))
        for f in dataclasses.fields(options)
        if f.name in fields
    ]


def test_selection_spec_defaults_are_the_selection_options():
    shared = _shared_defaults(SelectionSpec, SelectionOptions())
    names = {name for name, _, _ in shared}
    assert names == {f.name for f in dataclasses.fields(SelectionOptions)}
    for name, spec_default, option_default in shared:
        assert spec_default == option_default, name


def test_solver_and_sensor_spec_defaults_are_the_solver_options():
    shared = _shared_defaults(SolverSpec, SolverOptions()) + _shared_defaults(
        SensorSpec, SolverOptions()
    )
    names = {name for name, _, _ in shared}
    # compress and reweight are not in the project file: always their option defaults;
    # fall_off is built from sensor.estimate_fall_off and the camera (default null: None),
    # albedo_map from wall.albedo_map (default null: None).
    assert names == {f.name for f in dataclasses.fields(SolverOptions)} - {
        "compress",
        "reweight",
        "fall_off",
        "albedo_map",
    }
    assert SensorSpec().estimate_fall_off is None and SolverOptions().fall_off is None
    assert WallSpec().albedo_map is None and SolverOptions().albedo_map is None
    for name, spec_default, option_default in shared:
        assert spec_default == option_default, name


def test_multistart_defaults_are_the_solver_spec():
    params = inspect.signature(solve).parameters
    spec = SolverSpec()
    for name in ("multistart", "multistart_position_m", "multistart_angle_deg"):
        assert params[name].default == getattr(spec, name), name


def test_app_selection_defaults_are_the_selection_options():
    """The app's selection widgets and its session file start from the core defaults."""
    from lightcal_app.session_file import SelectionModel
    from lightcal_app.state import SelectionSettings

    core = SelectionOptions()
    app_fields = [f.name for f in dataclasses.fields(SelectionSettings)]
    assert app_fields == ["strategy", "n_per_image", "grid_step", "binning", "seed"]
    settings = SelectionSettings()
    saved = SelectionModel()
    for name in app_fields:
        assert getattr(settings, name) == getattr(core, name), name
        assert getattr(saved, name) == getattr(core, name), name


def test_spec_to_options_copies_every_shared_field():
    """One method carries the file's sections into the core options: every field the
    two share arrives, with non-default values, and nothing else is invented."""
    selection = SelectionSpec(
        strategy="grid", n_per_image=7, grid_step=9, binning=3, seed=11, min_signal=2.5
    ).to_options()
    assert selection == SelectionOptions("grid", 7, 9, 3, 11, 2.5)
    sensor = SensorSpec(offset=12.0, estimate_offset=True)
    solver = SolverSpec(
        loss="cauchy",
        f_scale=2.0,
        max_iterations=5,
        estimate_gains=False,
        rid_subsamples=3,
        tolerance=1e-9,
        position_bound_m=0.5,
    ).to_options(sensor)
    expected = SolverOptions(
        loss="cauchy",
        f_scale=2.0,
        max_iterations=5,
        estimate_gains=False,
        estimate_offset=True,
        offset=12.0,
        rid_subsamples=3,
        tolerance=1e-9,
        position_bound_m=0.5,
    )
    assert solver == expected
    assert SelectionSpec().to_options() == SelectionOptions()
    assert SolverSpec().to_options(SensorSpec()) == SolverOptions()
