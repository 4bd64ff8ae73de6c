"""A homogeneous absorbing medium between the rig and the wall (clear water, haze).

The light travels from the emitter L to a wall point P and from there to the camera
centre C through the medium; Beer-Lambert's law attenuates it along both segments,

    T(P) = exp(-c (|P - L| + |P - C|)),

c the attenuation coefficient, 1/m (world frame, metres). The renderer multiplies each
light's flux into a (super-)pixel by T at the footprint's centre, as it does the wall's
B (docs/model.md, "Medium"); `footprint_spread` gives the error of that per pixel.
c = 0 is air: the renderer then skips the factor (bit for bit the numbers without a
medium). One coefficient for the image's one channel. Not modelled: scattering (no
backscatter, no forward-scattered blur) and refraction at the camera's or light's flat
ports (the rays are straight lines from the centres of projection).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from lightcal.core.kernels import backscatter as bk
from lightcal.core.kernels import medium as mk
from lightcal.core.rid_eval import RIDData
from lightcal.core.scene import Light, View

__all__ = [
    "AIR",
    "MAX_ATTENUATION_PER_M",
    "Medium",
    "MediumUnknown",
    "apply_medium",
    "backscatter",
    "footprint_spread",
    "medium_from_description",
]

#: The largest attenuation coefficient, 1/m: beyond, exp(-c d) leaves no beam over a metre
#: or two (the turbid coastal waters of Jerlov's type 9 reach about 2 /m).
MAX_ATTENUATION_PER_M = 10.0

#: The largest relative backscatter coefficient beta = sigma_s pi / albedo, 1/m.
MAX_BACKSCATTER_PER_M = 1000.0

#: The largest |g| of the Henyey-Greenstein phase function.
MAX_PHASE_G = 0.99

#: Gauss-Legendre nodes of the scattering integral along each pixel's ray (equiangular).
SCATTER_NODES = 24


@dataclass(frozen=True)
class Medium:
    """The medium's optical properties.

    Args:
        attenuation_per_m: c >= 0, the attenuation (extinction) coefficient, 1/m.
        backscatter_per_m: beta >= 0, the single-scattering coefficient relative to the
            wall's diffuse reflectance, 1/m (sigma_s pi / albedo for a Lambertian wall):
            each light adds beta S to a pixel (`lightcal.core.kernels.backscatter`).
        phase_g: g in [-0.99, 0.99], the Henyey-Greenstein phase function's asymmetry.
    """

    attenuation_per_m: float = 0.0
    backscatter_per_m: float = 0.0
    phase_g: float = 0.9

    #: The estimable parameters' names, in order, and their box bounds (the solver's).
    parameter_names: ClassVar[tuple[str, ...]] = (
        "attenuation_per_m",
        "backscatter_per_m",
        "phase_g",
    )
    parameter_bounds: ClassVar[tuple[tuple[float, float], ...]] = (
        (0.0, MAX_ATTENUATION_PER_M),
        (0.0, MAX_BACKSCATTER_PER_M),
        (-MAX_PHASE_G, MAX_PHASE_G),
    )

    def __post_init__(self) -> None:
        for name, (lo, hi) in zip(self.parameter_names, self.parameter_bounds, strict=True):
            v = float(getattr(self, name))
            if not (math.isfinite(v) and lo <= v <= hi):
                unit = "" if name == "phase_g" else " per metre"
                raise ValueError(
                    f"medium: {name}: expected a value in [{lo:g}, {hi:g}]{unit}, got {v:g}"
                )
            object.__setattr__(self, name, v)

    @property
    def is_clear(self) -> bool:
        """Neither attenuation nor scattering (air): the renderer skips the medium."""
        return self.attenuation_per_m == 0.0 and self.backscatter_per_m == 0.0

    @property
    def scatters(self) -> bool:
        """It adds backscatter (beta > 0)."""
        return self.backscatter_per_m > 0.0

    def parameters(self) -> np.ndarray:
        """(3,) the estimable parameters' values, in `parameter_names` order."""
        return np.array([self.attenuation_per_m, self.backscatter_per_m, self.phase_g])

    def with_parameters(self, values: np.ndarray) -> Medium:
        """The medium with other values (3,) of its estimable parameters."""
        c, beta, g = (float(v) for v in np.asarray(values, dtype=np.float64).reshape(-1))
        return Medium(c, beta, g)

    def transmittance(
        self, points_world: np.ndarray, light_world: np.ndarray, camera_world: np.ndarray
    ) -> np.ndarray:
        """(N,) T at wall points (N, 3) for a light and a camera at (3,) each, m."""
        p = np.asarray(points_world, dtype=np.float64).reshape(-1, 3)
        path = np.linalg.norm(p - light_world, axis=1) + np.linalg.norm(p - camera_world, axis=1)
        return np.exp(-self.attenuation_per_m * path)

    def describe(self) -> dict:
        """Its parameters for results."""
        return {
            "attenuation_per_m": self.attenuation_per_m,
            "backscatter_per_m": self.backscatter_per_m,
            "phase_g": self.phase_g,
        }


AIR = Medium()


def medium_from_description(description: dict) -> Medium:
    """The medium of a result's `medium` (`Medium.describe` and more); air when absent."""
    values = []
    for name, default in (("attenuation_per_m", 0.0), ("backscatter_per_m", 0.0), ("phase_g", 0.9)):
        v = description.get(name, default)
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise ValueError(f"medium: {name}: expected a number, got {v!r}")
        values.append(float(v))
    return Medium(*values)


#: The whole-image backscatter is exact on a grid of at least this many nodes along the
#: image's shorter side, interpolated between them.
SCATTER_GRID_NODES = 96


def scatter_grid(shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """The rows (m,) and columns (n,) of an (H, W) image where the whole-image renderer
    computes the backscatter exactly: every s-th, s = max(1, min(H, W) // 96), and the
    last (every pixel of images up to 191 pixels a side)."""
    h, w = int(shape[0]), int(shape[1])
    step = max(1, min(h, w) // SCATTER_GRID_NODES)
    rows = np.unique(np.append(np.arange(0, h, step), h - 1)).astype(np.int64)
    cols = np.unique(np.append(np.arange(0, w, step), w - 1)).astype(np.int64)
    return rows, cols


@functools.cache
def scatter_nodes() -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights (SCATTER_NODES,) on [0, 1]."""
    x, w = np.polynomial.legendre.leggauss(SCATTER_NODES)
    return 0.5 * (x + 1.0), 0.5 * w


def apply_medium(
    centers_world: np.ndarray,
    light_world: np.ndarray,
    R_world_light: np.ndarray,
    rid: RIDData,
    camera_world: np.ndarray,
    medium: Medium,
    flux: np.ndarray,
    grad: np.ndarray | None,
    *,
    exposure: float,
    extra_grads: np.ndarray | None = None,
    d_medium_out: np.ndarray | None = None,
    veil_factor: np.ndarray | None = None,
) -> None:
    """One light's flux (N,) through the medium, in place: times T at the footprint
    centres, plus exposure beta S (the backscatter along each pixel's ray, a radiance:
    the `radiance` sensor model), with the chain rule on its world-frame gradients (N, 6)
    (`render.light_flux`).

    Args:
        centers_world: (N, 3) footprint centres; light_world, camera_world: (3,), m.
            camera_world (N, 3): behind the camera's flat port, where each pixel's ray
            leaves the port (`Footprints.camera_side`).
        R_world_light: (3, 3) and rid: the light's orientation and RID (the backscatter's).
        medium: the medium.
        flux: (N,) the light's flux (exposure included).
        grad: (N, 6) d flux / d (L_world, delta_world) or None.
        exposure: the view's exposure (the backscatter's factor).
        extra_grads: (N, P) other derivatives of the wall term (the wall's parameters),
            multiplied by T in place.
        d_medium_out: with grad, (N, 1) receiving d/dc, (N, 2) d/dc and d/dbeta, or
            (N, 3) d/dc, d/dbeta and d/dg (the backscatter is then computed even at
            beta = 0).
        veil_factor: (N,) what each pixel's veil is multiplied by on its way into the
            camera (behind a flat port its Fresnel transmittance,
            `Footprints.port_transmittance`), or None (1).
    """
    n = flux.shape[0]
    want = grad is not None and d_medium_out is not None
    if medium.attenuation_per_m > 0.0 or want:
        # camera_world (N, 3) behind a flat port: each ray from its exit point.
        t = np.empty(n)
        dc = np.empty(n) if want else _NO_DC
        mk.apply_attenuation(
            np.ascontiguousarray(centers_world, dtype=np.float64),
            np.ascontiguousarray(light_world, dtype=np.float64),
            camera_world,
            medium.attenuation_per_m,
            flux,
            grad if grad is not None else _NO_GRAD,
            want_grad=grad is not None,
            out_transmittance=t,
            out_d_attenuation=dc,
        )
        if extra_grads is not None and extra_grads.size:
            extra_grads *= t[:, None]
        if want:
            assert d_medium_out is not None
            d_medium_out[:, 0] = dc
    if not (medium.scatters or (want and d_medium_out is not None and d_medium_out.shape[1] > 1)):
        return
    s = np.empty(n)
    ds = np.empty((n, 8)) if grad is not None else None
    nodes, weights = scatter_nodes()
    bk.scatter_points(
        centers_world,
        camera_world,
        light_world,
        R_world_light,
        rid,
        medium.attenuation_per_m,
        medium.phase_g,
        nodes,
        weights,
        s,
        ds,
    )
    if veil_factor is not None:  # through the camera's flat port
        s *= veil_factor
        if ds is not None:
            ds *= veil_factor[:, None]
    k = exposure * medium.backscatter_per_m
    flux += k * s
    if grad is not None and ds is not None:
        grad += k * ds[:, :6]
        if d_medium_out is not None:
            d_medium_out[:, 0] += k * ds[:, 6]
            if d_medium_out.shape[1] > 1:
                d_medium_out[:, 1] = exposure * s
            if d_medium_out.shape[1] > 2:
                d_medium_out[:, 2] = k * ds[:, 7]


def backscatter(
    points_world: np.ndarray,
    camera_world: np.ndarray,
    light: Light,
    view: View,
    medium: Medium,
) -> np.ndarray:
    """(N,) S, the single-scattering integral of `light`'s beam along the rays from the
    camera to wall points (N, 3) (`lightcal.core.kernels.backscatter`); a pixel's
    backscatter is scale x exposure x beta x S. 0 where a point is not finite."""
    nodes, weights = scatter_nodes()
    out = np.empty(len(points_world))
    bk.scatter_points(
        points_world,
        camera_world,
        light.position_world(view),
        light.rotation_world(view),
        light.rid.data(),
        medium.attenuation_per_m,
        medium.phase_g,
        nodes,
        weights,
        out,
        None,
    )
    return out


#: Placeholders for the kernel's unused outputs.
_NO_GRAD = np.zeros((1, 6))
_NO_DC = np.zeros(0)


def footprint_spread(
    corners_world: np.ndarray,
    centers_world: np.ndarray,
    light_world: np.ndarray,
    camera_world: np.ndarray,
    medium: Medium,
) -> np.ndarray:
    """(N,) the relative error of evaluating T once at each footprint's centre.

    As `lightcal.core.wall.footprint_spread` does for B: the mean of a T quadratic over
    each quad k (a parallelogram to first order) is (mean of T at its 4 corners + 2
    T(quad centre)) / 3; the footprint's mean is the mean over its quads. Returns
    |that mean - T(centre)| / T(centre).

    Args:
        corners_world: (N, K, 4, 3) footprint quads; centers_world: (N, 3) their centres.
        light_world, camera_world: (3,) positions, world frame, m.
        medium: the medium.
    """
    n = corners_world.shape[0]
    if medium.is_clear or n == 0:
        return np.zeros(n)
    k = corners_world.shape[1]
    center = medium.transmittance(centers_world, light_world, camera_world)
    at_quads = medium.transmittance(corners_world.mean(axis=2), light_world, camera_world)
    at_corners = medium.transmittance(corners_world, light_world, camera_world)
    mean = ((at_corners.reshape(n, k, 4).mean(axis=2) + 2.0 * at_quads.reshape(n, k)) / 3.0).mean(
        axis=1
    )
    return np.abs(mean - center) / center


@dataclass(frozen=True, eq=False)
class MediumUnknown:
    """The medium between the rig and the wall, and which of its parameters to estimate.

    Args:
        initial: the medium with its initial (or fixed) parameter values.
        estimate: names of the parameters to estimate (of `Medium.parameter_names`).
    """

    initial: Medium = AIR
    estimate: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "estimate", tuple(self.estimate))
        names = Medium.parameter_names
        for nm in self.estimate:
            if nm not in names:
                raise ValueError(
                    f"medium: estimate: no parameter {nm!r}; expected {', '.join(names)}"
                )
        if len(set(self.estimate)) != len(self.estimate):
            raise ValueError("medium: estimate: expected each parameter once")

    @property
    def indices(self) -> list[int]:
        """Positions of the estimated parameters in the medium's parameter vector."""
        return [Medium.parameter_names.index(nm) for nm in self.estimate]

    def position(self, name: str) -> int | None:
        """Where parameter `name` is among the estimated ones (None: not estimated)."""
        return self.estimate.index(name) if name in self.estimate else None
