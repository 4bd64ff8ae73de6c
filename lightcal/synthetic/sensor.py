"""The synthetic sensor (`SensorConfig`, `apply_sensor`, `noise_model`).

The expected signal in DN above the black level becomes photo-electrons (signal / gain),
gets Poisson shot noise and Gaussian read noise, goes back to DN, gets the black level, is
rounded and clipped at the white level 2^bits - 1 (saturation).

The light scale k of docs/model.md (`Light.scale`) is expressed in DN: rendering with the true
rig gives the expected pixel value above the black level, at the exposure of the first
image. `signal_scale` picks k so that the brightest expected pixel of a dataset sits at
`SensorConfig.exposure_target` of the usable range (white - black).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from lightcal.core.camera import Camera
from lightcal.core.footprint import SensorModel
from lightcal.core.render import render_image, render_pixels
from lightcal.core.scene import Rig, View
from lightcal.core.vignetting import RadialVignetting
from lightcal.errors import InputError

MAX_FULL_WELL_E = 1e7
"""Largest full well, electrons (real sensors: 1e3 to 1e6)."""

MAX_EXPOSURE_TARGET = 10.0
"""Largest `exposure_target`: ten times the usable range already saturates most pixels."""


@dataclass(frozen=True)
class SensorConfig:
    """The camera's sensor.

    Attributes:
        bit_depth: Bits per sample (10, 12, 14 or 16); white level 2^bits - 1.
        full_well_e: Electrons that fill the usable range (white - black).
        read_noise_e: Standard deviation of the read noise, electrons.
        black_level_dn: Black level, DN; None: 2^(bits - 5) (512 for 14 bits).
        exposure_target: The brightest expected pixel sits at this fraction of the usable
            range (values > 1 saturate on purpose).
        noise: False: no shot or read noise (values are only rounded).
        model: Fall-off model of docs/model.md the images follow ("radiance", "cos4", "paper",
            "map").
        vignetting_coeffs: c_1, c_2, ... of a centred `RadialVignetting`; required for
            (and only for) model "map".
    """

    bit_depth: int = 14
    full_well_e: float = 20000.0
    read_noise_e: float = 3.0
    black_level_dn: float | None = None
    exposure_target: float = 0.7
    noise: bool = True
    model: SensorModel = "radiance"
    vignetting_coeffs: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if self.bit_depth not in (10, 12, 14, 16):
            raise InputError("bit_depth", f"expected 10, 12, 14 or 16, got {self.bit_depth!r}")
        if not (math.isfinite(self.full_well_e) and self.full_well_e > 0.0):
            raise InputError("full_well_e", f"expected a value > 0, got {self.full_well_e!r}")
        if not (math.isfinite(self.read_noise_e) and self.read_noise_e >= 0.0):
            raise InputError("read_noise_e", f"expected a value >= 0, got {self.read_noise_e!r}")
        white = 2**self.bit_depth - 1
        if self.black_level_dn is not None and not (0.0 <= self.black_level_dn < white):
            raise InputError(
                "black_level_dn",
                f"expected a value in [0, {white}) for {self.bit_depth} bits, "
                f"got {self.black_level_dn!r}",
            )
        if not (math.isfinite(self.exposure_target) and self.exposure_target > 0.0):
            raise InputError(
                "exposure_target", f"expected a value > 0, got {self.exposure_target!r}"
            )
        if self.full_well_e > MAX_FULL_WELL_E:
            raise InputError(
                "full_well_e",
                f"expected at most {MAX_FULL_WELL_E:g} electrons, got {self.full_well_e:g}",
            )
        if self.read_noise_e > self.full_well_e:
            raise InputError(
                "read_noise_e",
                f"expected at most the full well ({self.full_well_e:g} electrons), "
                f"got {self.read_noise_e:g}",
            )
        if self.exposure_target > MAX_EXPOSURE_TARGET:
            raise InputError(
                "exposure_target",
                f"expected at most {MAX_EXPOSURE_TARGET:g} (values above 1 saturate), "
                f"got {self.exposure_target:g}",
            )
        if self.model not in ("radiance", "cos4", "paper", "map"):
            raise InputError("model", f"expected radiance, cos4, paper or map, got {self.model!r}")
        if (self.model == "map") != (self.vignetting_coeffs is not None):
            raise InputError(
                "vignetting_coeffs",
                "expected radial vignetting coefficients with the 'map' sensor model and "
                f"none with the others, got model {self.model!r} and "
                f"coefficients {self.vignetting_coeffs!r}",
            )
        if self.vignetting_coeffs is not None and (
            len(self.vignetting_coeffs) == 0
            or not all(math.isfinite(c) for c in self.vignetting_coeffs)
        ):
            raise InputError(
                "vignetting_coeffs",
                f"expected one or more finite coefficients, got {self.vignetting_coeffs!r}",
            )

    @property
    def black_level(self) -> float:
        """The black level in DN (the default filled in)."""
        if self.black_level_dn is None:
            return float(2 ** (self.bit_depth - 5))
        return float(self.black_level_dn)


def white_level(config: SensorConfig) -> float:
    """2^bits - 1, DN."""
    return float(2**config.bit_depth - 1)


def conversion_gain(config: SensorConfig) -> float:
    """DN per photo-electron: the full well fills the range above the black level."""
    return (white_level(config) - config.black_level) / config.full_well_e


def noise_model(config: SensorConfig) -> tuple[float, float]:
    """The Poisson-Gaussian noise of black-subtracted values, variance = gain m + read_variance.

    Returns:
        gain: DN per electron (0 without noise).
        read_variance: (DN per electron x read noise)^2 + 1/12 (quantisation), DN^2;
            1/12 alone without noise.
    """
    if not config.noise:
        return 0.0, 1.0 / 12.0
    g = conversion_gain(config)
    return g, (g * config.read_noise_e) ** 2 + 1.0 / 12.0


def signal_scale(peak: float, config: SensorConfig) -> float:
    """The light scale k (DN per unit of the rendered signal) putting `peak` at the target.

    Args:
        peak: The brightest rendered value of the dataset with unit (relative) scales.
        config: The sensor.

    Returns:
        exposure_target x (white - black) / peak.
    """
    if not (math.isfinite(peak) and peak > 0.0):
        raise InputError(
            "lights",
            f"the lights illuminate nothing the camera sees (peak signal {peak!r}); "
            "expected lights in front of the wall pointing at it",
        )
    return config.exposure_target * (white_level(config) - config.black_level) / peak


def vignetting_image(config: SensorConfig, camera: Camera) -> NDArray[np.float64] | None:
    """(H, W) the radial fall-off of the "map" model (centred, 1 at the centre), else None."""
    if config.vignetting_coeffs is None:
        return None
    model = RadialVignetting.centered(
        np.array(config.vignetting_coeffs), width=camera.width, height=camera.height
    )
    values = model.image()
    if not np.all(values > 0.0):
        raise InputError(
            "vignetting_coeffs",
            f"the fall-off reaches {float(values.min()):.3g} inside the image; expected V > 0",
        )
    return values


def peak_signal(
    camera: Camera,
    views: list[View],
    rig: Rig,
    *,
    sensor: SensorModel = "radiance",
    vignetting: NDArray[np.float64] | None = None,
    max_pixels: int = 100_000,
) -> float:
    """The brightest rendered value over the views (exposures included).

    Images of at most `max_pixels` pixels are rendered whole (the exact maximum); larger
    ones on a regular grid of about `max_pixels` pixels: a smooth beam's maximum is then
    found to a fraction of a percent, at a fraction of the cost of a render.

    Returns:
        The maximum value (0 when nothing is lit).
    """
    n_pixels = camera.width * camera.height
    pixels = None
    if n_pixels > max_pixels:
        stride = math.ceil(math.sqrt(n_pixels / max_pixels))
        vv, uu = np.mgrid[0 : camera.height : stride, 0 : camera.width : stride]
        pixels = np.stack([uu.ravel(), vv.ravel()], axis=1)
    peak = 0.0
    for view in views:
        if pixels is None:
            values = render_image(camera, view, rig, sensor=sensor, vignetting=vignetting)
        else:
            values = render_pixels(camera, view, rig, pixels, sensor=sensor, vignetting=vignetting)
        if values.count() > 0:
            peak = max(peak, float(values.max()))
    return peak


def apply_sensor(
    signal_dn: np.ma.MaskedArray | NDArray[np.float64],
    config: SensorConfig,
    rng: np.random.Generator,
    *,
    gamma: float = 1.0,
) -> tuple[NDArray[np.uint16], NDArray[np.bool_]]:
    """Turn the expected signal into raw sensor values.

    photo-electrons ~ Poisson(signal / gain), plus N(0, read_noise_e^2) electrons; back to
    DN (x gain), plus the black level, rounded to integers and clipped to
    [0, 2^bits - 1]. Masked (invalid) pixels have no signal: black level plus read noise.
    Without noise the value is round(signal + black).

    With `gamma` G != 1 a tone curve acts on the (noisy) linear value x above black
    before rounding: x -> W (max(x, 0) / W)^(1/G), W = white - black the usable range, so
    the black and white levels stay where they are (the `gamma` departure).

    Args:
        signal_dn: (H, W) expected value above the black level, DN (masked where invalid).
        config: The sensor.
        rng: Randomness (unused without noise).
        gamma: G > 0 of the response curve (1: linear).

    Returns:
        dn: (H, W) uint16 raw values.
        saturated: (H, W) True where the value was clipped at the white level.
    """
    signal = np.ma.filled(np.ma.masked_invalid(signal_dn), 0.0).astype(np.float64)
    if signal.ndim != 2:
        raise InputError("signal_dn", f"expected an (H, W) image, got shape {signal.shape}")
    signal = np.clip(signal, 0.0, None)
    white = white_level(config)
    black = config.black_level
    if config.noise:
        g = conversion_gain(config)
        electrons = rng.poisson(signal / g).astype(np.float64)
        electrons += rng.normal(0.0, config.read_noise_e, size=signal.shape)
        raw = electrons * g + black
    else:
        raw = signal + black
    if gamma != 1.0:
        usable = white - black
        raw = black + usable * (np.clip(raw - black, 0.0, None) / usable) ** (1.0 / gamma)
    raw = np.rint(raw)
    saturated = raw >= white
    dn = np.clip(raw, 0.0, white).astype(np.uint16)
    return dn, saturated
