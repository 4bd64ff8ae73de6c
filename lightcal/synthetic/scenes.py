"""Synthetic calibration scenes with known ground truth: views, rigs and the sensor.

Everything here is numbers in memory (no files; `lightcal.synthetic.dataset` writes a
dataset), in three modules that this one gathers:

- `views`: camera poses in front of the wall (`sample_views`), exposure times, and the
  marker / SfM error of the poses (`perturb_view`);
- `rigs`: lights beside the camera with one of six angular profiles (`sample_rig`,
  `LightModel`), and the deliberately wrong start of a calibration (`initial_guess`);
- `sensor`: the expected signal in DN becomes noisy, clipped raw values (`SensorConfig`,
  `apply_sensor`, `noise_model`, `signal_scale`).

Frames and units follow docs/conventions.md: the wall is the world plane z = 0, cameras
sit at z > 0 looking at it (OpenCV camera frame), a light's +z is its axis; metres and
radians inside, degrees only in the `_deg` fields of the configurations.
"""

from __future__ import annotations

from lightcal.synthetic.light_models import LIGHT_MODELS, LightModel
from lightcal.synthetic.rigs import (
    AZIMUTH_STEP_DEG,
    TABLE_STEP_DEG,
    RigConfig,
    check_in_front,
    describe_rid,
    elliptical_beam_table,
    initial_guess,
    light_names,
    make_rid,
    sample_rig,
    symmetric_profile_table,
)
from lightcal.synthetic.sensor import (
    SensorConfig,
    apply_sensor,
    conversion_gain,
    noise_model,
    peak_signal,
    signal_scale,
    vignetting_image,
    white_level,
)
from lightcal.synthetic.views import SceneConfig, perturb_view, sample_exposure_times, sample_views

__all__ = [
    "AZIMUTH_STEP_DEG",
    "LIGHT_MODELS",
    "TABLE_STEP_DEG",
    "LightModel",
    "RigConfig",
    "SceneConfig",
    "SensorConfig",
    "apply_sensor",
    "check_in_front",
    "conversion_gain",
    "describe_rid",
    "elliptical_beam_table",
    "initial_guess",
    "light_names",
    "make_rid",
    "noise_model",
    "peak_signal",
    "perturb_view",
    "sample_exposure_times",
    "sample_rig",
    "sample_views",
    "signal_scale",
    "symmetric_profile_table",
    "vignetting_image",
    "white_level",
]
