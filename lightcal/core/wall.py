"""Reflectance models of the calibration wall: one interface, three models.

The renderer computes each pixel's footprint irradiance exactly (docs/model.md); the wall
model turns irradiance into radiance. A Lambertian wall of albedo rho reflects
L_r = rho E / pi whatever the directions; a real (painted) wall reflects L_r = f_r(l, v) E
with l the direction to the light and v the direction to the camera. Every model here is
written as its BRDF relative to a Lambertian one,

    B(l, v) = f_r(l, v) / k_d,    k_d the model's diffuse level / pi,

so that the light's scale keeps absorbing I0, the albedo and the sensor gain, and
B = 1 for the Lambertian wall (the renderer then skips the factor: bit-for-bit the
Lambertian numbers). Models:

- `LambertianWall`: B = 1.
- `PlasticWall` (alpha, eta, w): a diffuse base under a smooth-on-average dielectric coat
  with GGX microfacet roughness alpha (the "rough plastic" model of physically based
  rendering: Weidlich & Wilkie 2007; Mitsuba's `roughplastic`, Pharr, Jakob & Humphreys,
  "Physically Based Rendering", 4th ed., 9.x)::

      B = T(mu_l) T(mu_v) / T(1)^2 + w pi F(l.h) D(h) G1(l) G1(v) / (4 mu_l mu_v)

  with mu = cos of the angle to the wall normal, h = (l + v) / |l + v|, F the unpolarised
  Fresnel reflectance of index of refraction eta, D the GGX distribution, G1 Smith's
  masking, and T(mu) the coat's rough transmittance, 1 minus the energy the rough
  interface reflects (integrated over visible normals, tabulated on 64 nodes of mu and
  interpolated linearly, exactly as Mitsuba does). w is the specular weight relative to
  the diffuse level: for a base of albedo rho_d, `PlasticWall.from_albedo` sets
  w = eta^2 (1 - F_dr) / (rho_d T(1)^2), F_dr the coat's internal diffuse reflectance,
  which makes B proportional to Mitsuba's `roughplastic` BRDF (nonlinear = false).
- `OrenNayarWall` (sigma): rough matte surfaces, the qualitative Oren-Nayar model
  B = A + B_on max(0, cos(phi_l - phi_v)) sin(max(theta)) tan(min(theta)),
  A = 1 - 0.5 s^2 / (s^2 + 0.33), B_on = 0.45 s^2 / (s^2 + 0.09), s = sigma (radians).

The factor is evaluated once per (super-)pixel with l and v at the centre of its
footprint (`Footprints.centers_world`); `footprint_spread` bounds the error of that
approximation per pixel.
"""

from __future__ import annotations

import functools
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numpy as np

from lightcal.core.kernels import wall as wk
from lightcal.core.kernels.wall import TABLE_SIZE

__all__ = [
    "WALL_MODELS",
    "LambertianWall",
    "OrenNayarWall",
    "PlasticWall",
    "WallData",
    "WallReflectance",
    "internal_reflectance",
    "make_wall",
    "rough_transmittance",
    "wall_from_description",
]


class WallData(NamedTuple):
    """What the compiled evaluator needs.

    Attributes:
        kind: one of `kernels.wall.KIND_*`.
        params: (MAX_PARAMS,) the model's parameters (padded with 0).
        tables: (3, TABLE_SIZE) plastic transmittance T, dT/dalpha, dT/deta on
            mu_k = k / (TABLE_SIZE - 1) (zeros for other models).
    """

    kind: int
    params: np.ndarray
    tables: np.ndarray


_NO_TABLES = np.zeros((3, TABLE_SIZE))


class WallReflectance(ABC):
    """A wall's reflectance relative to a Lambertian wall (see the module docstring)."""

    #: The model's name in project files.
    name: ClassVar[str]
    #: Its parameters' names, in order (internal units: radians, plain numbers).
    parameter_names: ClassVar[tuple[str, ...]]
    #: Box bounds of each parameter, same order.
    parameter_bounds: ClassVar[tuple[tuple[float, float], ...]]
    #: The parameters estimated unless the user says otherwise.
    default_estimate: ClassVar[tuple[str, ...]] = ()

    @property
    def is_lambertian(self) -> bool:
        """B = 1 everywhere: the renderer skips the factor."""
        return False

    @abstractmethod
    def parameters(self) -> np.ndarray:
        """(P,) the parameter values, in `parameter_names` order."""

    @abstractmethod
    def with_parameters(self, values: np.ndarray) -> WallReflectance:
        """The same model with other parameter values (P,)."""

    @abstractmethod
    def data(self) -> WallData:
        """The arrays the compiled evaluator uses."""

    def factor(
        self, l_world: np.ndarray, v_world: np.ndarray, *, want_grad: bool = False
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """B for unit directions to the light and to the camera, (N, 3) each.

        Returns:
            B (N,) and, with want_grad, dB/d(parameters) (N, P).
        """
        l = np.asarray(l_world, dtype=np.float64).reshape(-1, 3)
        v = np.asarray(v_world, dtype=np.float64).reshape(-1, 3)
        d = self.data()
        b, _, _, dp = wk.brdf_many(
            np.ascontiguousarray(l[:, 2]),
            np.ascontiguousarray(np.sum(l * v, axis=1)),
            np.ascontiguousarray(v[:, 2]),
            d.kind,
            d.params,
            d.tables,
        )
        return b, (dp[:, : len(self.parameter_names)] if want_grad else None)

    def describe(self) -> dict:
        """Name and parameters for results (angles in degrees, named _deg)."""
        out: dict = {"model": self.name}
        for nm, v in zip(self.parameter_names, self.parameters(), strict=True):
            if nm == "sigma":
                out["sigma_deg"] = math.degrees(float(v))
            else:
                out[nm] = float(v)
        return out


@dataclass(frozen=True)
class LambertianWall(WallReflectance):
    """The ideal matte wall: B = 1."""

    name: ClassVar[str] = "lambertian"
    parameter_names: ClassVar[tuple[str, ...]] = ()
    parameter_bounds: ClassVar[tuple[tuple[float, float], ...]] = ()

    @property
    def is_lambertian(self) -> bool:
        return True

    def parameters(self) -> np.ndarray:
        return np.zeros(0)

    def with_parameters(self, values: np.ndarray) -> LambertianWall:
        if np.asarray(values).size:
            raise ValueError("lambertian wall: expected no parameters")
        return self

    def data(self) -> WallData:
        return WallData(wk.KIND_LAMBERTIAN, np.zeros(wk.MAX_PARAMS), _NO_TABLES)


def _check_range(name: str, value: float, lo: float, hi: float, model: str) -> float:
    v = float(value)
    if not (math.isfinite(v) and lo <= v <= hi):
        raise ValueError(f"{model} wall: {name}: expected a value in [{lo:g}, {hi:g}], got {v:g}")
    return v


@dataclass(frozen=True)
class PlasticWall(WallReflectance):
    """Rough plastic: a diffuse base under a GGX-rough dielectric coat.

    Args:
        roughness: GGX alpha of the coat (0.02 mirror-like ... 1 very rough).
        ior: the coat's index of refraction eta (paint binders: about 1.5).
        specular_weight: w, the specular lobe's weight relative to the diffuse level.
    """

    roughness: float = 0.3
    ior: float = 1.5
    specular_weight: float = 1.0

    name: ClassVar[str] = "plastic"
    parameter_names: ClassVar[tuple[str, ...]] = ("roughness", "ior", "specular_weight")
    parameter_bounds: ClassVar[tuple[tuple[float, float], ...]] = (
        (0.02, 1.0),
        (1.05, 3.0),
        (0.0, 100.0),
    )
    # The index of refraction changes the Fresnel curve only slightly: fixed by default.
    default_estimate: ClassVar[tuple[str, ...]] = ("roughness", "specular_weight")

    def __post_init__(self) -> None:
        for nm, (lo, hi) in zip(self.parameter_names, self.parameter_bounds, strict=True):
            object.__setattr__(self, nm, _check_range(nm, getattr(self, nm), lo, hi, "plastic"))

    @classmethod
    def from_albedo(cls, roughness: float, ior: float, albedo: float) -> PlasticWall:
        """The wall proportional to Mitsuba's roughplastic with this diffuse reflectance.

        w = eta^2 (1 - F_dr) / (rho_d T(1)^2); F_dr the coat's internal diffuse reflectance.
        """
        albedo = _check_range("albedo", albedo, 1e-3, 1.0, "plastic")
        t, _, _ = rough_transmittance(roughness, ior)
        f_dr = internal_reflectance(roughness, ior)
        w = ior * ior * (1.0 - f_dr) / (albedo * t[-1] ** 2)
        return cls(roughness, ior, w)

    def parameters(self) -> np.ndarray:
        return np.array([self.roughness, self.ior, self.specular_weight])

    def with_parameters(self, values: np.ndarray) -> PlasticWall:
        a, e, w = (float(v) for v in np.asarray(values, dtype=np.float64))
        return PlasticWall(a, e, w)

    def data(self) -> WallData:
        return self._data

    @functools.cached_property
    def _data(self) -> WallData:
        # Once per wall: a solve renders every image with the same wall at each x.
        return WallData(
            wk.KIND_PLASTIC,
            self.parameters(),
            np.stack(rough_transmittance(self.roughness, self.ior)),
        )


@dataclass(frozen=True)
class OrenNayarWall(WallReflectance):
    """Rough matte (Oren-Nayar, qualitative model).

    Args:
        sigma: standard deviation of the facet slope angle, radians (0: Lambertian).
    """

    sigma: float = math.radians(20.0)

    name: ClassVar[str] = "oren_nayar"
    parameter_names: ClassVar[tuple[str, ...]] = ("sigma",)
    parameter_bounds: ClassVar[tuple[tuple[float, float], ...]] = ((0.0, math.radians(60.0)),)
    default_estimate: ClassVar[tuple[str, ...]] = ("sigma",)

    def __post_init__(self) -> None:
        lo, hi = self.parameter_bounds[0]
        object.__setattr__(self, "sigma", _check_range("sigma", self.sigma, lo, hi, "oren_nayar"))

    def parameters(self) -> np.ndarray:
        return np.array([self.sigma])

    def with_parameters(self, values: np.ndarray) -> OrenNayarWall:
        return OrenNayarWall(float(np.asarray(values, dtype=np.float64).ravel()[0]))

    def data(self) -> WallData:
        p = np.zeros(wk.MAX_PARAMS)
        p[0] = self.sigma
        return WallData(wk.KIND_OREN_NAYAR, p, _NO_TABLES)


WALL_MODELS: dict[str, type[WallReflectance]] = {
    "lambertian": LambertianWall,
    "plastic": PlasticWall,
    "oren_nayar": OrenNayarWall,
}

LAMBERTIAN = LambertianWall()


def make_wall(model: str, parameters: dict[str, float] | None = None) -> WallReflectance:
    """A wall model by name with parameters by name (defaults for the others)."""
    if model not in WALL_MODELS:
        raise ValueError(f"wall model: expected one of {', '.join(WALL_MODELS)}, got {model!r}")
    cls = WALL_MODELS[model]
    params = dict(parameters or {})
    unknown = sorted(set(params) - set(cls.parameter_names))
    if unknown:
        expected = ", ".join(cls.parameter_names) or "none"
        raise ValueError(
            f"{model} wall: unknown parameter(s) {', '.join(unknown)}; expected {expected}"
        )
    return cls(**params)


def wall_from_description(description: dict) -> WallReflectance:
    """The wall a `WallReflectance.describe()` dictionary (e.g. a result's `wall`) names."""
    model = str(description.get("model", "lambertian"))
    if model not in WALL_MODELS:
        raise ValueError(f"wall model: expected one of {', '.join(WALL_MODELS)}, got {model!r}")
    cls = WALL_MODELS[model]
    params = {}
    for name in cls.parameter_names:
        if name == "sigma" and "sigma_deg" in description:
            params[name] = math.radians(float(description["sigma_deg"]))
        elif name in description:
            params[name] = float(description[name])
    return cls(**params)


# -- the coat's rough transmittance ------------------------------------------------------

_GL_NODES = 32  # Gauss-Legendre nodes per side for eta > 1, 128 below (as Mitsuba)


def _mu_nodes() -> np.ndarray:
    return np.maximum(1e-6, np.linspace(0.0, 1.0, TABLE_SIZE))


def _vndf_normals(mu: np.ndarray, alpha: float, u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """GGX visible normals (Heitz 2018) for incident directions (sqrt(1 - mu^2), 0, mu).

    Args:
        mu: (M,) cosines of the incident directions.
        u1, u2: (Q,) points of the unit square.

    Returns:
        (M, Q, 3) microfacet normals, distributed as the visible normals when (u1, u2)
        is uniform.
    """
    wi = np.stack([np.sqrt(1.0 - mu * mu), np.zeros_like(mu), mu], axis=-1)
    vh = wi * np.array([alpha, alpha, 1.0])
    vh /= np.linalg.norm(vh, axis=-1, keepdims=True)
    lensq = vh[:, 0] ** 2 + vh[:, 1] ** 2
    t1 = np.where(
        lensq[:, None] > 0,
        np.stack([-vh[:, 1], vh[:, 0], np.zeros_like(mu)], axis=-1)
        / np.sqrt(np.maximum(lensq, 1e-300))[:, None],
        np.array([1.0, 0.0, 0.0]),
    )
    t2 = np.cross(vh, t1)
    r = np.sqrt(u1)
    phi = 2.0 * math.pi * u2
    p1 = r * np.cos(phi)
    p2 = r * np.sin(phi)
    s = 0.5 * (1.0 + vh[:, 2])[:, None]
    p2 = (1.0 - s) * np.sqrt(1.0 - p1 * p1)[None, :] + s * p2[None, :]
    p1 = np.broadcast_to(p1[None, :], p2.shape)
    p3 = np.sqrt(np.maximum(0.0, 1.0 - p1 * p1 - p2 * p2))
    nh = (
        p1[..., None] * t1[:, None, :]
        + p2[..., None] * t2[:, None, :]
        + p3[..., None] * vh[:, None, :]
    )
    ne = nh * np.array([alpha, alpha, 1.0])
    ne[..., 2] = np.maximum(ne[..., 2], 1e-12)
    return ne / np.linalg.norm(ne, axis=-1, keepdims=True)


def _fresnel_np(cos_i: np.ndarray, eta: float) -> tuple[np.ndarray, np.ndarray]:
    """Unpolarised dielectric Fresnel F and the refracted cosine (both (...)).

    eta = n_inside / n_outside as seen from the incident side (eta < 1: from inside).
    Total internal reflection: F = 1, cos_t = 0.
    """
    sin_t2 = (1.0 - cos_i * cos_i) / (eta * eta)
    tir = sin_t2 >= 1.0
    cos_t = np.sqrt(np.clip(1.0 - sin_t2, 0.0, 1.0))
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    f = np.where(tir, 1.0, 0.5 * (rs * rs + rp * rp))
    return f, cos_t


def _g1_np(w: np.ndarray, m: np.ndarray, alpha: float) -> np.ndarray:
    """Smith G1 of GGX for directions w and normals m (..., 3), Mitsuba's conventions."""
    xy = alpha * alpha * (w[..., 0] ** 2 + w[..., 1] ** 2)
    t = xy / np.maximum(w[..., 2] ** 2, 1e-300)
    g = 2.0 / (1.0 + np.sqrt(1.0 + t))
    g = np.where(xy == 0.0, 1.0, g)
    return np.where(np.sum(w * m, axis=-1) * w[..., 2] <= 0.0, 0.0, g)


def _interface_energy(alpha: float, eta: float, *, transmitted: bool) -> np.ndarray:
    """(TABLE_SIZE,) energy the rough interface transmits (or reflects) per incident mu."""
    x, wts = np.polynomial.legendre.leggauss(_GL_NODES if eta > 1.0 else 4 * _GL_NODES)
    u = 0.5 * x + 0.5
    uu1, uu2 = np.meshgrid(u, u, indexing="ij")
    ww = np.outer(wts, wts).ravel() * 0.25
    mu = _mu_nodes()
    m = _vndf_normals(mu, alpha, uu1.ravel(), uu2.ravel())
    wi = np.stack([np.sqrt(1.0 - mu * mu), np.zeros_like(mu), mu], axis=-1)[:, None, :]
    c = np.sum(wi * m, axis=-1)
    f, cos_t = _fresnel_np(c, eta)
    if transmitted:
        # Refraction into the coat: w_t = -w_i / eta + (c / eta - cos_t) m.
        wt = -wi / eta + (c / eta - cos_t)[..., None] * m
        val = _g1_np(wt, m, alpha) * (1.0 - f)
        val = np.where(wt[..., 2] * wi[..., 2] >= 0.0, 0.0, val)
    else:
        wo = 2.0 * c[..., None] * m - wi
        val = _g1_np(wo, m, alpha) * f
        val = np.where(wo[..., 2] <= 0.0, 0.0, val)
    return val @ ww


@functools.lru_cache(maxsize=64)
def _transmittance_cached(alpha: float, eta: float) -> np.ndarray:
    t = _interface_energy(alpha, eta, transmitted=True)
    t.setflags(write=False)
    return t


def rough_transmittance(alpha: float, eta: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The coat's rough transmittance T(mu) on mu_k = k / 63, and its derivatives.

    T(mu) = integral over GGX visible normals m of (1 - F(w_i . m)) G1(w_t, m), w_t the
    refracted direction (Mitsuba's `eval_transmittance`: 32 x 32 Gauss-Legendre nodes).

    Returns:
        T, dT/dalpha, dT/deta, each (TABLE_SIZE,); derivatives by central differences.
    """
    a, e = float(alpha), float(eta)
    t = _transmittance_cached(a, e)
    ha = 1e-5 * max(a, 1e-3)
    he = 1e-5 * e
    t_a = (_transmittance_cached(a + ha, e) - _transmittance_cached(a - ha, e)) / (2 * ha)
    t_e = (_transmittance_cached(a, e + he) - _transmittance_cached(a, e - he)) / (2 * he)
    return t, t_a, t_e


@functools.lru_cache(maxsize=64)
def internal_reflectance(alpha: float, eta: float) -> float:
    """The coat's internal diffuse reflectance F_dr: 2 mean_k(R_in(mu_k) mu_k).

    R_in(mu) is the rough interface's reflectance seen from inside (relative index
    1 / eta); the mean runs over the table nodes, as Mitsuba computes it.
    """
    r = _interface_energy(float(alpha), 1.0 / float(eta), transmitted=False)
    return float(2.0 * np.mean(r * _mu_nodes()))


def footprint_spread(
    corners_world: np.ndarray,
    centers_world: np.ndarray,
    light_world: np.ndarray,
    camera_world: np.ndarray,
    wall: WallReflectance,
) -> np.ndarray:
    """(N,) the relative error of evaluating B once at each footprint's centre.

    The renderer uses B(centre); the exact factor is B's mean over the footprint. For
    each quad k of a footprint (a parallelogram to first order), the mean of a quadratic
    B is (mean of B at its 4 corners + 2 B(quad centre)) / 3; the footprint's mean is the
    mean over its quads. Returns |that mean - B(centre)| / B(centre): exact for B
    quadratic over each quad, the curvature term that the centre value leaves (its linear
    variation averages out).

    Args:
        corners_world: (N, K, 4, 3) footprint quads; centers_world: (N, 3) their centres.
        light_world, camera_world: (3,) positions, world frame, m.
        wall: the wall model.
    """
    n = corners_world.shape[0]
    if wall.is_lambertian or n == 0:
        return np.zeros(n)
    k = corners_world.shape[1]
    quad_centers = corners_world.mean(axis=2).reshape(-1, 3)
    pts = np.ascontiguousarray(
        np.concatenate([centers_world, quad_centers, corners_world.reshape(-1, 3)]),
        dtype=np.float64,
    )
    d = wall.data()
    b = np.empty(len(pts))
    wk.wall_factor(
        pts,
        np.ascontiguousarray(light_world, dtype=np.float64),
        np.ascontiguousarray(camera_world, dtype=np.float64),
        d.kind,
        d.params,
        d.tables,
        b,
    )
    center = b[:n]
    at_quads = b[n : n + n * k].reshape(n, k)
    at_corners = b[n + n * k :].reshape(n, k, 4).mean(axis=2)
    mean = ((at_corners + 2.0 * at_quads) / 3.0).mean(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.abs(mean - center) / center
