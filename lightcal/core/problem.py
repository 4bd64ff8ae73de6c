"""The calibration problem: observed pixels, unknowns and their parameter vector.

The solver minimises sum_pixels rho(((m_obs - m_render(x)) / sigma)^2) over x, the
concatenation of, for every light, its pose parameters (3, 5 or 6, `lightcal.core.pose`),
the log of its scale (one per colour channel) and optionally its RID parameters; then
optionally one log-gain per image but the first (the first image's gain is fixed: a
global gain is the lights' scales), optionally the offset b, the wall model's estimated
parameters (`WallUnknown`), the fall-off's coefficients (`lightcal.core.fall_off`), the
room light's level a (`ParameterLayout.ambient_index`; one per channel), the medium's
(`MediumUnknown`; channel after channel) and last the albedos of the surroundings'
surfaces it estimates (`Surroundings.estimate_albedo`).

Colour channels solved jointly (`channels`): every image (`ImageData.channel`) shares
the lights' poses, RIDs, the gains, offset, wall and fall-off; each channel has its own
lights' scales, room light and medium (the water's attenuation depends on the
wavelength).

Room light (ambient) is a uniform radiance on the wall: image i records it as
g_i e_i a (its gain and exposure: the room's light grows with the exposure time as the
beam's does) through the estimated fall-off V, unlike the offset b, which is the same in
every image whatever its exposure. With equal exposures the two are one column: then
the offset, when estimated, is the room light too, and a is not a parameter
(`ambient_estimated`).

RID estimation (the paper's future work), for symmetric lights:
- ``cos_power``: f = cos^m(theta) with x holding log m;
- ``curve``: a monotone decreasing profile on K + 1 knots theta_k = k theta_max / K,
  f_0 = 1 and f_k = f_(k-1) exp(-exp(q_k)), interpolated by PCHIP, with x holding q.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np

from lightcal.core.channels import channel_media
from lightcal.core.fall_off import FallOffUnknown, apply_fall_off
from lightcal.core.footprint import Footprints
from lightcal.core.image_data import ImageData, poisson_gaussian_sigma
from lightcal.core.medium import Medium, MediumUnknown
from lightcal.core.pose import PoseKind, PoseParameterization, pose_parameterization
from lightcal.core.rid import RID, CosPowerRID, IsotropicRID
from lightcal.core.rid_curve import curve_params_from_rid, curve_rid, fit_cos_power
from lightcal.core.scene import Light, Rig, with_view
from lightcal.core.surroundings import Surroundings
from lightcal.core.wall import LAMBERTIAN, WallReflectance

__all__ = [
    "LOG_CLIP",
    "ImageData",
    "LightUnknown",
    "Loss",
    "MediumUnknown",
    "ParameterLayout",
    "RidEstimate",
    "WallUnknown",
    "curve_params_from_rid",
    "curve_rid",
    "poisson_gaussian_sigma",
    "with_curve_range",
    "with_view",
]

RidEstimate = Literal["none", "cos_power", "curve"]
Loss = Literal["linear", "huber", "soft_l1", "cauchy"]


@dataclass(frozen=True, eq=False)
class LightUnknown:
    """A light to calibrate: its initial guess and what is estimated about it.

    Args:
        initial: the initial light (RID, pose, scale).
        pose_kind: "isotropic", "symmetric" or "general"; the default follows the RID's symmetry.
        estimate_rid: also estimate its RID ("cos_power" or "curve"; symmetric lights only).
        curve_knots: K, the number of free knots of a "curve" RID.
        curve_max_angle_rad: theta_max of a "curve" RID; default: where the initial RID
            falls to 1 %, at most 89 degrees.
    """

    initial: Light
    pose_kind: PoseKind | None = None
    estimate_rid: RidEstimate = "none"
    curve_knots: int = 6
    curve_max_angle_rad: float | None = None

    def kind(self) -> PoseKind:
        if self.pose_kind is not None:
            return self.pose_kind
        if isinstance(self.initial.rid, IsotropicRID) and self.estimate_rid == "none":
            return "isotropic"  # orientation unobservable
        return "symmetric" if self.initial.rid.symmetric else "general"


@dataclass(frozen=True, eq=False)
class WallUnknown:
    """The wall's reflectance model and which of its parameters to estimate.

    Args:
        initial: the model with its initial (or fixed) parameter values.
        estimate: names of the parameters to estimate (a subset of its parameter_names).
    """

    initial: WallReflectance = LAMBERTIAN
    estimate: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "estimate", tuple(self.estimate))
        names = self.initial.parameter_names
        for nm in self.estimate:
            if nm not in names:
                expected = ", ".join(names) or "none"
                raise ValueError(
                    f"wall: estimate: {self.initial.name} has no parameter {nm!r}; "
                    f"expected {expected}"
                )
        if len(set(self.estimate)) != len(self.estimate):
            raise ValueError("wall: estimate: expected each parameter once")

    @property
    def indices(self) -> list[int]:
        """Positions of the estimated parameters in the model's parameter vector."""
        return [self.initial.parameter_names.index(nm) for nm in self.estimate]


#: Log-parameters (scales, the cos^m exponent) are clipped to +-LOG_CLIP before exp.
LOG_CLIP = 300.0


def _exp(v: float) -> float:
    """exp(v) with v clipped to +-300: finite for any parameter the solver tries, and
    small enough (1e130) that trf's sum of squared residuals of a wild trial step stays
    finite (with +-700 it overflowed, with a RuntimeWarning, before being rejected)."""
    return math.exp(min(max(v, -LOG_CLIP), LOG_CLIP))


@dataclass
class _LightBlock:
    """Where one light's parameters sit in x."""

    unknown: LightUnknown
    param: PoseParameterization
    pose: slice
    log_scale: int
    rid: slice
    curve_theta_max: float
    log_scales: tuple[int, ...] = ()  # per channel (the first is `log_scale`)

    def log_scale_of(self, channel: int) -> int:
        """The index of its log-scale in `channel`."""
        return self.log_scales[channel] if self.log_scales else self.log_scale


@dataclass
class ParameterLayout:
    """Maps the solver's x onto lights, gains and offset.

    Build it with `ParameterLayout.build`; `x0` is the initial vector.
    """

    blocks: list[_LightBlock]
    n_images: int
    estimate_gains: bool
    estimate_offset: bool
    offset0: float
    gains: slice
    offset_index: int | None
    n: int
    names: list[str]
    x0: np.ndarray = field(repr=False)
    wall_unknown: WallUnknown = field(default_factory=WallUnknown)
    wall: slice = field(default_factory=lambda: slice(0, 0))
    fall_off_unknown: FallOffUnknown | None = None
    fall_off: slice = field(default_factory=lambda: slice(0, 0))
    ambient_index: int | None = None
    medium_unknown: MediumUnknown = field(default_factory=MediumUnknown)
    medium: slice = field(default_factory=lambda: slice(0, 0))
    channels: tuple[str, ...] = ()
    media: tuple[MediumUnknown, ...] = ()
    ambient_indices: tuple[int, ...] = ()
    surface_albedo: slice = field(default_factory=lambda: slice(0, 0))
    surroundings: Surroundings | None = None

    @property
    def n_channels(self) -> int:
        """How many colour channels are solved jointly (1 without `channels`)."""
        return max(1, len(self.channels))

    @classmethod
    def build(
        cls,
        unknowns: list[LightUnknown],
        n_images: int,
        *,
        estimate_gains: bool,
        estimate_offset: bool,
        offset0: float,
        wall: WallUnknown | None = None,
        fall_off: FallOffUnknown | None = None,
        estimate_ambient: bool = False,
        medium: MediumUnknown | None = None,
        channels: Sequence[str] = (),
        media: Sequence[MediumUnknown] | None = None,
        surroundings: Surroundings | None = None,
    ) -> ParameterLayout:
        """The layout; with `channels` (names, 2 or more) each channel has its lights'
        scales, its room light and its medium: `media` one per channel (default: `medium`
        in every channel), all estimating the same parameters."""
        channels = tuple(channels)
        media_list = channel_media(channels, medium, media)
        medium = media_list[0]
        blocks: list[_LightBlock] = []
        names: list[str] = []
        x0: list[float] = []
        for j, u in enumerate(unknowns):
            light = u.initial
            kind = u.kind()
            if u.estimate_rid != "none" and not light.rid.symmetric:
                raise ValueError(
                    f"light {light.name}: RID estimation ({u.estimate_rid}) needs a "
                    "rotationally symmetric light"
                )
            R_ref = light.R_camera_light if kind == "general" else None
            param = pose_parameterization(kind, R_ref_camera_light=R_ref)
            start = len(x0)
            x0.extend(param.from_pose(light.R_camera_light, light.t_camera_light))
            names.extend(f"{light.name}.{nm}" for nm in param.names)
            pose = slice(start, len(x0))
            log_scale = len(x0)
            log_scales = tuple(range(log_scale, log_scale + max(1, len(channels))))
            x0.extend([math.log(light.scale)] * len(log_scales))
            if channels:
                names.extend(f"{light.name}.log_scale.{ch}" for ch in channels)
            else:
                names.append(f"{light.name}.log_scale")
            theta_max = 0.0
            if u.estimate_rid == "cos_power":
                m = light.rid.m if isinstance(light.rid, CosPowerRID) else fit_cos_power(light.rid)
                rid_slice = slice(len(x0), len(x0) + 1)
                x0.append(math.log(max(m, 1e-3)))
                names.append(f"{light.name}.log_m")
            elif u.estimate_rid == "curve":
                theta_max = u.curve_max_angle_rad or min(
                    math.radians(89.0), light.rid.angle_at_level_rad(0.01)
                )
                q = curve_params_from_rid(light.rid, theta_max, u.curve_knots)
                rid_slice = slice(len(x0), len(x0) + q.size)
                x0.extend(q)
                names.extend(f"{light.name}.curve_q{i + 1}" for i in range(q.size))
            else:
                rid_slice = slice(len(x0), len(x0))
            blocks.append(_LightBlock(u, param, pose, log_scale, rid_slice, theta_max, log_scales))
            del j
        gains = slice(len(x0), len(x0))
        if estimate_gains and n_images > 1:
            gains = slice(len(x0), len(x0) + n_images - 1)
            x0.extend([0.0] * (n_images - 1))
            names.extend(f"image{i}.log_gain" for i in range(1, n_images))
        offset_index = None
        if estimate_offset:
            offset_index = len(x0)
            x0.append(offset0)
            names.append("offset")
        wall = wall if wall is not None else WallUnknown()
        start = len(x0)
        p0 = wall.initial.parameters()
        for k, nm in zip(wall.indices, wall.estimate, strict=True):
            x0.append(float(p0[k]))
            names.append(f"wall.{nm}")
        wall_slice = slice(start, len(x0))
        if fall_off is not None:  # V = 1 to start: the coefficients 0
            x0.extend([0.0] * fall_off.order)
            names.extend(fall_off.names)
        fall_off_slice = slice(wall_slice.stop, len(x0))
        ambient_index = None
        ambient_indices: tuple[int, ...] = ()
        if estimate_ambient:  # a dark room to start
            ambient_index = len(x0)
            ambient_indices = tuple(range(len(x0), len(x0) + max(1, len(channels))))
            x0.extend([0.0] * len(ambient_indices))
            names.extend([f"ambient.{ch}" for ch in channels] if channels else ["ambient"])
        start = len(x0)
        for ch, unknown in zip(channels or ("",), media_list, strict=True):
            p0 = unknown.initial.parameters()
            for k, nm in zip(unknown.indices, unknown.estimate, strict=True):
                x0.append(float(p0[k]))
                names.append(f"medium.{ch}.{nm}" if ch else f"medium.{nm}")
        medium_slice = slice(start, len(x0))
        surfaces = () if surroundings is None else surroundings.surfaces
        for k in () if surroundings is None else surroundings.estimate_albedo:
            x0.append(surfaces[k].albedo)
            names.append(f"surroundings.surfaces[{k}].albedo")
        return cls(
            blocks,
            n_images,
            estimate_gains,
            estimate_offset,
            offset0,
            gains,
            offset_index,
            len(x0),
            names,
            np.array(x0, dtype=np.float64),
            wall,
            wall_slice,
            fall_off,
            fall_off_slice,
            ambient_index,
            medium,
            medium_slice,
            channels,
            tuple(media_list) if channels else (),
            ambient_indices,
            slice(medium_slice.stop, len(x0)),
            surroundings,
        )

    def rid_of(self, block: _LightBlock, x: np.ndarray) -> RID:
        u = block.unknown
        if u.estimate_rid == "cos_power":
            return CosPowerRID(_exp(float(x[block.rid][0])))
        if u.estimate_rid == "curve":
            return curve_rid(block.curve_theta_max, x[block.rid])
        return u.initial.rid

    def light_of(
        self, block: _LightBlock, x: np.ndarray, *, rid: RID | None = None, channel: int = 0
    ) -> Light:
        """The light at x, its scale that of `channel`."""
        R, t = block.param.to_pose(x[block.pose])
        return block.unknown.initial.replace(  # its name and port kept
            rid=rid if rid is not None else self.rid_of(block, x),
            t_camera_light=t,
            R_camera_light=R,
            scale=_exp(float(x[block.log_scale_of(channel)])),
        )

    def rig(self, x: np.ndarray, channel: int = 0) -> Rig:
        """The lights at x, their scales those of `channel`."""
        return Rig(tuple(self.light_of(b, x, channel=channel) for b in self.blocks))

    def gain_factors(self, x: np.ndarray) -> np.ndarray:
        """(n_images,) multiplicative gains on top of each image's exposure."""
        g = np.ones(self.n_images)
        if self.gains.stop > self.gains.start:
            g[1:] = np.exp(x[self.gains])
        return g

    def offset(self, x: np.ndarray) -> float:
        return float(x[self.offset_index]) if self.offset_index is not None else self.offset0

    def wall_of(self, x: np.ndarray) -> WallReflectance:
        """The wall model at x (its estimated parameters taken from x)."""
        return _estimated(self.wall_unknown, x[self.wall])

    def fall_off_factor(self, pixels: np.ndarray, x: np.ndarray) -> np.ndarray | None:
        """(N,) the estimated fall-off V at x of (binned) `pixels` (N, 2); None when the
        fall-off is not estimated (V = 1)."""
        f = self.fall_off_unknown
        return None if f is None else f.factor(pixels, x[self.fall_off])

    def ambient_index_of(self, channel: int) -> int | None:
        """The index of `channel`'s room light level in x (None when not estimated)."""
        if self.ambient_index is None:
            return None
        return self.ambient_indices[channel] if self.ambient_indices else self.ambient_index

    def ambient(self, x: np.ndarray, channel: int = 0) -> float:
        """`channel`'s room light level a at x (value units at exposure and gain 1; 0 when
        not estimated)."""
        k = self.ambient_index_of(channel)
        return float(x[k]) if k is not None else 0.0

    def sensor_values(
        self,
        values: np.ndarray,
        footprints: Footprints,
        x: np.ndarray,
        exposure_gain: float,
        channel: int = 0,
    ) -> np.ndarray:
        """(N,) the sensor terms on the lights' values above the offset `values` (N,) at
        x: (values + g e a V_s) V (V_s `Footprints.room_light_factor`), g e `exposure_gain`,
        a that of `channel`."""
        if self.ambient_index is not None:
            room = footprints.room_light_factor
            level = exposure_gain * self.ambient(x, channel)
            values = values + (level if room is None else level * room)
        v = self.fall_off_factor(footprints.pixels, x)
        return values if v is None else values * v

    def image_values(
        self, values: np.ma.MaskedArray, image: ImageData, x: np.ndarray, gain: float
    ) -> np.ndarray:
        """(N,) `image`'s rendered values above the offset at x from its lights' shaded
        `values` (N,) (NaN where masked) and its gain g: g (values + e a) V."""
        lights = gain * values.filled(np.nan)
        exposure_gain = gain * float(image.view.exposure)
        return self.sensor_values(lights, image.footprints, x, exposure_gain, image.channel)

    def apply_sensor_terms(
        self,
        A: np.ndarray,
        total: np.ndarray,
        image: ImageData,
        x: np.ndarray,
        gain: float,
        fluxes: list[np.ndarray] | None,
    ) -> None:
        """The room light and the fall-off at x on one image's system, in place: total
        (N,) (sum over lights of scale * flux) gains e a V_s and its column of A (N, n + 1)
        d m / d a = g e V_s (V_s the sensor model's fall-off); then A's columns, total and
        each light's flux (N,) in `fluxes` (when given) are multiplied by V
        (`lightcal.core.fall_off.apply_fall_off`). Nothing when neither is estimated."""
        k = self.ambient_index_of(image.channel)
        if k is not None:
            exposure = float(image.view.exposure)
            room = image.footprints.room_light_factor  # the sensor's fall-off, or None: 1
            d_ambient = exposure if room is None else exposure * room
            total += d_ambient * float(x[k])
            A[:, k] = gain * d_ambient
        f = self.fall_off_unknown
        if f is None:
            return
        powers = f.powers(image.footprints.pixels)
        v = apply_fall_off(A, total, self.n, powers, x[self.fall_off], self.fall_off, gain)
        if fluxes is not None:
            fluxes[:] = [flux * v for flux in fluxes]

    def wall_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Box bounds (k,) of the estimated wall parameters."""
        return _box(self.wall_unknown.initial.parameter_bounds, self.wall_unknown.indices)

    def medium_columns(self, channel: int = 0) -> slice:
        """The columns of `channel`'s estimated medium parameters."""
        k = len(self.medium_unknown.estimate)
        start = self.medium.start + channel * k
        return slice(start, start + k)

    def medium_of(self, x: np.ndarray, channel: int = 0) -> Medium:
        """`channel`'s medium at x (its estimated parameters taken from x)."""
        unknown = self.media[channel] if self.media else self.medium_unknown
        return _estimated(unknown, x[self.medium_columns(channel)])

    def surface_albedos(self, x: np.ndarray) -> np.ndarray | None:
        """(S,) the surroundings' albedos at x, the estimated from x; None when none is
        estimated (the declared hold)."""
        s = self.surroundings
        if s is None or not s.estimate_albedo:
            return None
        albedos = s.albedos()
        albedos[list(s.estimate_albedo)] = x[self.surface_albedo]
        return albedos

    def medium_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Box bounds (k,) of the estimated medium parameters (every channel's)."""
        lo, hi = _box(Medium.parameter_bounds, self.medium_unknown.indices)
        return np.tile(lo, self.n_channels), np.tile(hi, self.n_channels)


def _estimated(unknown: WallUnknown | MediumUnknown, values: np.ndarray) -> Any:
    """The unknown's model (a wall, a medium) with its estimated parameters set to
    `values` (k,); its initial model when nothing of it is estimated."""
    if not unknown.estimate:
        return unknown.initial
    p = unknown.initial.parameters()
    p[unknown.indices] = values
    return unknown.initial.with_parameters(p)


def _box(
    bounds: Sequence[tuple[float, float]], indices: list[int]
) -> tuple[np.ndarray, np.ndarray]:
    """(lower (k,), upper (k,)) of the parameters `indices` of a model's `bounds`."""
    return np.array([bounds[k][0] for k in indices]), np.array([bounds[k][1] for k in indices])


def with_curve_range(unknown: LightUnknown, images: list[ImageData]) -> LightUnknown:
    """A "curve" RID without a set range spans the angles the selected pixels are seen
    at from the initial light (knots beyond them would be unobservable)."""
    if unknown.estimate_rid != "curve" or unknown.curve_max_angle_rad is not None:
        return unknown
    light = unknown.initial
    largest = 0.0
    for im in images:
        L = light.position_world(im.view)
        axis = light.rotation_world(im.view)[:, 2]
        w = im.footprints.corners_world.mean(axis=(1, 2)) - L
        cos = (w @ axis) / np.linalg.norm(w, axis=1)
        largest = max(largest, float(np.arccos(np.clip(cos.min(), -1.0, 1.0))))
    # 1 % margin keeps the seen pixels off the last knot, where f drops to 0; knots far
    # beyond the angles the pixels are seen at are unobservable and
    # make the solve wander (measured: 1.05 and 1.15 x fail to converge on tests).
    theta_max = min(math.radians(89.0), 1.01 * largest) if largest > 0 else None
    return replace(unknown, curve_max_angle_rad=theta_max)
