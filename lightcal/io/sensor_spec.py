"""The project file's `sensor` section: how the images were recorded and are read,
the noise model, and the sensor terms estimated with the lights."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from lightcal.core.solver import SolverOptions

__all__ = ["ColourChannel", "FallOffSpec", "NoiseSpec", "SensorSpec"]

ColourChannel = Literal["R", "G", "B", "G1", "G2"]
"""A colour channel `sensor.channels` may list (the CFA's sites of a raw file, or a
developed image's channel)."""


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)


class NoiseSpec(_Model):
    """Poisson-Gaussian noise: variance = gain * signal + read_variance (pixel units)."""

    gain: float = Field(ge=0)
    read_variance: float = Field(gt=0)


_SOLVER = SolverOptions()  # the sensor's defaults are the solver's (defined once)


class FallOffSpec(_Model):
    """A radial fall-off V = 1 + c1 r^2 + ... + cK r^(2K) estimated with the lights
    (docs/model.md, "The fall-off estimated from the photos"): r is 1 at the sensor's
    corners, from the image centre; V multiplies the sensor model's values."""

    model: Literal["radial"] = "radial"
    order: int = Field(default=2, ge=1, le=3, description="K, the number of coefficients")


class SensorSpec(_Model):
    """How the images were recorded and read (docs/model.md, "The sensor")."""

    model: Literal["radiance", "cos4", "paper", "map"] = "radiance"
    vignetting: str | None = Field(default=None, description="fall-off map file for 'map'")
    channel: Literal["auto", "green_binned", "luminance", "R", "G", "G1", "G2", "B"] = "auto"
    channels: list[ColourChannel] | None = Field(
        default=None,
        min_length=2,
        max_length=4,
        description="colour channels calibrated jointly: each image read once per channel, "
        "one light pose, each channel its lights' scales, room light and medium; null: "
        "the one `channel`",
    )
    black_level: float | None = Field(default=None, ge=0, description="subtracted on load")
    white_level: float | None = Field(default=None, gt=0)
    assume_linear: bool = False
    response: str | None = Field(default=None, description="camera response curve file")
    offset: float = Field(
        default=_SOLVER.offset, description="known (or initial) offset after black level"
    )
    estimate_offset: bool = _SOLVER.estimate_offset
    estimate_ambient: bool = _SOLVER.estimate_ambient  # room light, grows with exposure
    noise: NoiseSpec | None = None
    estimate_fall_off: FallOffSpec | None = Field(
        default=None,
        description="estimate the camera's radial fall-off with the lights; null: V as "
        "the sensor model says",
    )

    @model_validator(mode="after")
    def _map_needs_file(self) -> SensorSpec:
        if self.model == "map" and self.vignetting is None:
            raise ValueError("the 'map' sensor model needs a vignetting file")
        if self.channels is not None:
            if len(set(self.channels)) != len(self.channels):
                raise ValueError(f"channels: expected each channel once, got {self.channels}")
            if self.channel != "auto":
                raise ValueError(
                    f"channel {self.channel!r} beside channels: expected one of the two"
                )
        if (
            self.black_level is not None
            and self.white_level is not None
            and not self.white_level > self.black_level
        ):
            raise ValueError(
                f"white_level {self.white_level:g} must be above black_level {self.black_level:g}"
            )
        return self
