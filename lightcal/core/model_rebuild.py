"""A calibration model like another, some of its parts replaced."""

from __future__ import annotations

from lightcal.core.calibration_model import CalibrationModel

__all__ = ["model_parts", "rebuilt"]


def model_parts(model: CalibrationModel) -> dict[str, object]:
    """`model`'s constructor arguments: images, lights, options, wall, medium,
    surroundings, colour channels and their media."""
    lay = model.layout
    return {
        "images": model.images,
        "unknowns": model.unknowns,
        "options": model.options,
        "wall": lay.wall_unknown,
        "medium": lay.medium_unknown,
        "surroundings": model.surroundings,
        "channels": lay.channels,
        "media": lay.media or None,
    }


def rebuilt(model: CalibrationModel, **changes: object) -> CalibrationModel:
    """A model with `model`'s parts, those named in `changes` replaced."""
    return CalibrationModel(**(model_parts(model) | changes))  # type: ignore[arg-type]
