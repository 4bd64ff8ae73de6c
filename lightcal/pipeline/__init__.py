"""From a project file to a calibrated light: load, select, model, solve, summarise.

This is the layer the CLI and the app share. One module a step:

- `load`: the project's images as linear values, the user masks, the vignetting map;
- `select`: the pixels of an image the solver sees (`image_data`);
- `model`: the `CalibrationModel` of a project, with fitted starting scales;
- `solve`: the (multi-start) solve and `calibrate_project`, the whole pipeline;
- `diagnose`: the warnings about what the views do not determine;
- `measurements`: each image's noise (sensor model or estimated) and pose covariance;
- `fit_check`: the fit test and the covariance with its terms (noise, poses, misfit);
- `wall_choice`: mirror exclusion and the `auto` wall model choice;
- `results`: `CalibrationResult` with 1-sigma uncertainties (`summarise`).

It knows files (through `lightcal.io`) but nothing of terminals or browsers.
"""

from lightcal.pipeline.diagnose import covariance, dark_light_warnings, variety_warnings
from lightcal.pipeline.load import LoadedImages, ProgressFn, load_images, vignetting_for
from lightcal.pipeline.measurements import Measurements, measurements_for
from lightcal.pipeline.model import build_model, fit_scales, starting_lights
from lightcal.pipeline.results import CalibrationResult, LightResult, PoseSummary, summarise
from lightcal.pipeline.select import image_data, noise_floor, regions_for
from lightcal.pipeline.solve import (
    Calibration,
    calibrate,
    calibrate_project,
    perturbed_start,
    solve,
    solve_project,
)

__all__ = [
    "Calibration",
    "CalibrationResult",
    "LightResult",
    "LoadedImages",
    "Measurements",
    "PoseSummary",
    "ProgressFn",
    "build_model",
    "calibrate",
    "calibrate_project",
    "covariance",
    "dark_light_warnings",
    "fit_scales",
    "image_data",
    "load_images",
    "measurements_for",
    "noise_floor",
    "perturbed_start",
    "regions_for",
    "solve",
    "solve_project",
    "starting_lights",
    "summarise",
    "variety_warnings",
    "vignetting_for",
]
