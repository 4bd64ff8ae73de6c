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

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from lightcal.core.kernels import medium as mk

__all__ = [
    "AIR",
    "MAX_ATTENUATION_PER_M",
    "Medium",
    "apply_medium",
    "footprint_spread",
    "medium_from_description",
]

#: The largest attenuation coefficient, 1/m: beyond, exp(-c d) leaves no beam over a metre
#: or two (the turbid coastal waters of Jerlov's type 9 reach about 2 /m).
MAX_ATTENUATION_PER_M = 10.0


@dataclass(frozen=True)
class Medium:
    """The medium's optical properties.

    Args:
        attenuation_per_m: c >= 0, the attenuation (extinction) coefficient, 1/m.
    """

    attenuation_per_m: float = 0.0

    #: Its parameters' names, in order, and their box bounds (the solver's).
    parameter_names: ClassVar[tuple[str, ...]] = ("attenuation_per_m",)
    parameter_bounds: ClassVar[tuple[tuple[float, float], ...]] = ((0.0, MAX_ATTENUATION_PER_M),)

    def __post_init__(self) -> None:
        c = float(self.attenuation_per_m)
        if not (math.isfinite(c) and 0.0 <= c <= MAX_ATTENUATION_PER_M):
            raise ValueError(
                f"medium: attenuation_per_m: expected a value in [0, {MAX_ATTENUATION_PER_M:g}]"
                f" per metre, got {c:g}"
            )
        object.__setattr__(self, "attenuation_per_m", c)

    @property
    def is_clear(self) -> bool:
        """No attenuation (air): the renderer skips the factor."""
        return self.attenuation_per_m == 0.0

    def parameters(self) -> np.ndarray:
        """(1,) the parameter values, in `parameter_names` order."""
        return np.array([self.attenuation_per_m])

    def with_parameters(self, values: np.ndarray) -> Medium:
        """The medium with other parameter values (1,)."""
        (c,) = (float(v) for v in np.asarray(values, dtype=np.float64).reshape(-1))
        return Medium(c)

    def transmittance(
        self, points_world: np.ndarray, light_world: np.ndarray, camera_world: np.ndarray
    ) -> np.ndarray:
        """(N,) T at wall points (N, 3) for a light and a camera at (3,) each, m."""
        p = np.asarray(points_world, dtype=np.float64).reshape(-1, 3)
        path = np.linalg.norm(p - light_world, axis=1) + np.linalg.norm(p - camera_world, axis=1)
        return np.exp(-self.attenuation_per_m * path)

    def describe(self) -> dict:
        """Its parameters for results."""
        return {"attenuation_per_m": self.attenuation_per_m}


AIR = Medium()


def medium_from_description(description: dict) -> Medium:
    """The medium of a result's `medium` (`Medium.describe` and more); air when absent."""
    c = description.get("attenuation_per_m", 0.0)
    if isinstance(c, bool) or not isinstance(c, int | float):
        raise ValueError(f"medium: attenuation_per_m: expected a number, got {c!r}")
    return Medium(float(c))


def apply_medium(
    centers_world: np.ndarray,
    light_world: np.ndarray,
    camera_world: np.ndarray,
    medium: Medium,
    flux: np.ndarray,
    grad: np.ndarray | None,
    *,
    extra_grads: np.ndarray | None = None,
    d_attenuation_out: np.ndarray | None = None,
) -> None:
    """Multiply one light's flux (N,) by T at the footprint centres, in place, with the
    chain rule on its world-frame gradients (N, 6) (`render.light_flux`).

    Args:
        centers_world: (N, 3) footprint centres; light_world, camera_world: (3,), m.
        medium: the medium (not clear).
        flux: (N,) the light's flux.
        grad: (N, 6) d flux / d (L_world, delta_world) or None.
        extra_grads: (N, P) other derivatives of the flux (the wall's parameters),
            multiplied by T in place.
        d_attenuation_out: (N,) receives d(flux T)/dc (with grad).
    """
    n = flux.shape[0]
    t = np.empty(n)
    mk.apply_attenuation(
        np.ascontiguousarray(centers_world, dtype=np.float64),
        np.ascontiguousarray(light_world, dtype=np.float64),
        np.ascontiguousarray(camera_world, dtype=np.float64),
        medium.attenuation_per_m,
        flux,
        grad if grad is not None else _NO_GRAD,
        want_grad=grad is not None,
        out_transmittance=t,
        out_d_attenuation=d_attenuation_out if d_attenuation_out is not None else _NO_DC,
    )
    if extra_grads is not None and extra_grads.size:
        extra_grads *= t[:, None]


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
