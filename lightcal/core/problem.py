"""The calibration problem: observed pixels, unknowns and their parameter vector.

The solver minimises sum_pixels rho(((m_obs - m_render(x)) / sigma)^2) over x, the
concatenation of, for every light, its pose parameters (3, 5 or 6, `lightcal.core.pose`),
the log of its scale and optionally its RID parameters; then optionally one log-gain per
image but the first (the first image's gain is fixed: a global gain is the lights'
scales), optionally the offset b, the wall model's estimated parameters
(`WallUnknown`), the fall-off's coefficients (`lightcal.core.fall_off`), the room
light's level a (`ParameterLayout.ambient_index`) and last the medium's
(`MediumUnknown`).

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

from lightcal.core.fall_off import FallOffUnknown, apply_fall_off
from lightcal.core.footprint import Footprints
from lightcal.core.medium import Medium, MediumUnknown
from lightcal.core.pose import PoseKind, PoseParameterization, pose_parameterization
from lightcal.core.rid import RID, CosPowerRID, IsotropicRID, SymmetricTableRID
from lightcal.core.scene import Light, Rig, View
from lightcal.core.wall import LAMBERTIAN, WallReflectance

RidEstimate = Literal["none", "cos_power", "curve"]
Loss = Literal["linear", "huber", "soft_l1", "cauchy"]


def poisson_gaussian_sigma(signal: np.ndarray, noise: tuple[float, float]) -> np.ndarray:
    """(N,) noise sigma of values whose `signal` (N,) above the offset is given.

    sigma = sqrt(gain * max(signal, 0) + read_variance), noise = (gain, read_variance).
    """
    gain, read_variance = noise
    return np.sqrt(gain * np.maximum(signal, 0.0) + read_variance)


@dataclass(frozen=True, eq=False)
class ImageData:
    """The selected pixels of one image.

    Attributes:
        name: image label (file name).
        view: camera pose and exposure.
        footprints: footprints of the N selected pixels (all valid).
        observed: (N,) measured linear pixel values.
        sigma: (N,) noise standard deviation of each value (1 when unweighted).
        noise: (gain, read_variance) of a Poisson-Gaussian sensor, in the units of
            `observed`: variance = gain * (value - offset) + read_variance. When given, the
            solver re-weights from rendered values (`SolverOptions.reweight`).
    """

    name: str
    view: View
    footprints: Footprints
    observed: np.ndarray
    sigma: np.ndarray
    noise: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        n = len(self.footprints)
        for label, arr in (("observed", self.observed), ("sigma", self.sigma)):
            a = np.asarray(arr, dtype=np.float64)
            if a.shape != (n,):
                raise ValueError(f"{self.name}: {label}: expected shape ({n},), got {a.shape}")
            if not np.all(np.isfinite(a)):
                raise ValueError(f"{self.name}: {label}: expected finite values, got NaN or inf")
            object.__setattr__(self, label, a)
        if np.any(self.sigma <= 0.0):
            raise ValueError(f"{self.name}: sigma: expected values > 0")
        if not np.all(self.footprints.valid):
            raise ValueError(f"{self.name}: expected only valid footprints (select valid pixels)")
        if self.noise is not None:
            gain, read_variance = (float(v) for v in self.noise)
            if not (math.isfinite(gain) and gain >= 0.0):
                raise ValueError(f"{self.name}: noise: expected a finite gain >= 0, got {gain}")
            if not (math.isfinite(read_variance) and read_variance > 0.0):
                raise ValueError(
                    f"{self.name}: noise: expected a finite read variance > 0, got {read_variance}"
                )
            object.__setattr__(self, "noise", (gain, read_variance))

    def subset(self, rows: np.ndarray) -> ImageData:
        """The same image with only rows (k,) (indices or a boolean mask) of its pixels."""
        return ImageData(
            self.name,
            self.view,
            self.footprints.subset(rows),
            self.observed[rows],
            self.sigma[rows],
            self.noise,
        )


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


def curve_rid(theta_max_rad: float, q: np.ndarray) -> SymmetricTableRID:
    """The monotone "curve" RID of `q` (K,) free parameters on [0, theta_max]."""
    k = q.shape[0]
    theta = np.linspace(0.0, theta_max_rad, k + 1)
    values = np.concatenate([[1.0], np.exp(-np.cumsum(np.exp(np.clip(q, -700.0, 6.0))))])
    return SymmetricTableRID(theta, values)


def curve_params_from_rid(rid: RID, theta_max_rad: float, k: int) -> np.ndarray:
    """Initial "curve" parameters (K,) that follow `rid` at the knots (a table's exact
    interpolation, not its rendering grid: a curve's own parameters come back exactly)."""
    theta = np.linspace(0.0, theta_max_rad, k + 1)
    f = np.clip(rid.value_and_derivatives(theta, exact=True)[0], 1e-6, None)
    f = np.minimum.accumulate(f)
    ratio = np.clip(f[1:] / f[:-1], 1e-12, 1.0 - 1e-6)
    return np.log(-np.log(ratio))


@dataclass
class _LightBlock:
    """Where one light's parameters sit in x."""

    unknown: LightUnknown
    param: PoseParameterization
    pose: slice
    log_scale: int
    rid: slice
    curve_theta_max: float


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
    ) -> ParameterLayout:
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
            x0.append(math.log(light.scale))
            names.append(f"{light.name}.log_scale")
            theta_max = 0.0
            if u.estimate_rid == "cos_power":
                m = light.rid.m if isinstance(light.rid, CosPowerRID) else _fit_cos_power(light.rid)
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
            blocks.append(_LightBlock(u, param, pose, log_scale, rid_slice, theta_max))
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
        if estimate_ambient:  # a dark room to start
            ambient_index = len(x0)
            x0.append(0.0)
            names.append("ambient")
        medium = medium if medium is not None else MediumUnknown()
        start = len(x0)
        p0 = medium.initial.parameters()
        for k, nm in zip(medium.indices, medium.estimate, strict=True):
            x0.append(float(p0[k]))
            names.append(f"medium.{nm}")
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
            slice(start, len(x0)),
        )

    def rid_of(self, block: _LightBlock, x: np.ndarray) -> RID:
        u = block.unknown
        if u.estimate_rid == "cos_power":
            return CosPowerRID(_exp(float(x[block.rid][0])))
        if u.estimate_rid == "curve":
            return curve_rid(block.curve_theta_max, x[block.rid])
        return u.initial.rid

    def light_of(self, block: _LightBlock, x: np.ndarray, *, rid: RID | None = None) -> Light:
        R, t = block.param.to_pose(x[block.pose])
        return Light(
            rid if rid is not None else self.rid_of(block, x),
            t,
            R,
            scale=_exp(float(x[block.log_scale])),
            name=block.unknown.initial.name,
        )

    def rig(self, x: np.ndarray) -> Rig:
        return Rig(tuple(self.light_of(b, x) for b in self.blocks))

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

    def ambient(self, x: np.ndarray) -> float:
        """The room light's level a at x (value units at exposure and gain 1; 0 when not
        estimated)."""
        return float(x[self.ambient_index]) if self.ambient_index is not None else 0.0

    def sensor_values(
        self, values: np.ndarray, footprints: Footprints, x: np.ndarray, exposure_gain: float
    ) -> np.ndarray:
        """(N,) the sensor terms on the lights' values above the offset `values` (N,) at
        x: (values + g e a V_s) V (V_s `Footprints.room_light_factor`), g e `exposure_gain`."""
        if self.ambient_index is not None:
            room = footprints.room_light_factor
            level = exposure_gain * self.ambient(x)
            values = values + (level if room is None else level * room)
        v = self.fall_off_factor(footprints.pixels, x)
        return values if v is None else values * v

    def image_values(
        self, values: np.ma.MaskedArray, image: ImageData, x: np.ndarray, gain: float
    ) -> np.ndarray:
        """(N,) `image`'s rendered values above the offset at x from its lights' shaded
        `values` (N,) (NaN where masked) and its gain g: g (values + e a) V."""
        lights = gain * values.filled(np.nan)
        return self.sensor_values(lights, image.footprints, x, gain * float(image.view.exposure))

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
        if self.ambient_index is not None:
            exposure = float(image.view.exposure)
            room = image.footprints.room_light_factor  # the sensor's fall-off, or None: 1
            d_ambient = exposure if room is None else exposure * room
            total += d_ambient * self.ambient(x)
            A[:, self.ambient_index] = gain * d_ambient
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

    def medium_of(self, x: np.ndarray) -> Medium:
        """The medium at x (its estimated parameters taken from x)."""
        return _estimated(self.medium_unknown, x[self.medium])

    def medium_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Box bounds (k,) of the estimated medium parameters."""
        return _box(Medium.parameter_bounds, self.medium_unknown.indices)


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


def _fit_cos_power(rid: RID) -> float:
    """The cos^m exponent with the same half-intensity angle as `rid`."""
    half = rid.half_angle_rad
    if not 0.0 < half < math.pi / 2:
        return 1.0
    return -math.log(2.0) / math.log(math.cos(half))


def with_view(view: View, **changes: object) -> View:
    """A copy of a view with some fields replaced."""
    fields: dict[str, object] = {
        "R_camera_world": view.R_camera_world,
        "t_camera_world": view.t_camera_world,
        "exposure": view.exposure,
    }
    fields.update(changes)
    return View(**fields)  # type: ignore[arg-type]


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
