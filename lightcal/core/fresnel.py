"""The Fresnel transmittance of a flat window (a port) between air and water.

A ray crossing a plate of glass of index n_g from air (n_a) into water (n_w) loses the
part of its flux reflected at each face. For unpolarised light the reflectance of one
interface n_1 -> n_2 at angles of incidence theta_i and refraction theta_t is the mean
of the s and p reflectances (Born and Wolf, section 1.5):

    r_s = (n_1 cos_i - n_2 cos_t) / (n_1 cos_i + n_2 cos_t),
    r_p = (n_2 cos_i - n_1 cos_t) / (n_2 cos_i + n_1 cos_t),   R = r^2, T = 1 - R.

Between two parallel faces the light reflected back and forth adds up incoherently
(the plate is thick against the coherence length): per polarisation

    T_plate = T_1 T_2 / (1 - R_1 R_2),

and the unpolarised transmittance is the mean of the s and p plates'. The rays the inner
reflections send on are displaced sideways by about 2 t tan(theta_g), which is ignored
(their share is R_1 R_2, about 2e-4 for acrylic in water).

The angle in the air fixes the others (n sin(theta) is the same in every layer of a flat
port), so the transmittance is a function of cos(theta_air) alone, analytic where no
ray is totally reflected; its derivative is taken by a complex step (exact to round-off,
Squire and Trapp 1998).
"""

from __future__ import annotations

import numpy as np

#: The complex step of `port_transmittance`'s derivative.
_STEP = 1e-30


def port_transmittance(
    cos_air: np.ndarray, air_index: float, glass_index: float, water_index: float
) -> tuple[np.ndarray, np.ndarray]:
    """The unpolarised Fresnel transmittance of a flat port and its derivative.

    Args:
        cos_air: (N,) cosine of each ray's angle to the port's normal in the air, in
            (0, 1].
        air_index, glass_index, water_index: n_a, n_g, n_w (n_g, n_w >= n_a: no total
            internal reflection).

    Returns:
        T: (N,) the fraction of the flux that crosses the plate, in (0, 1].
        dT_dcos: (N,) its derivative with respect to cos_air.
    """
    c = np.asarray(cos_air, dtype=np.float64)
    t = _plate(c + 1j * _STEP, air_index, glass_index, water_index)
    return t.real, t.imag / _STEP


def _plate(cos_air: np.ndarray, n_a: float, n_g: float, n_w: float) -> np.ndarray:
    """The plate's transmittance for complex cos_air (complex step), (N,)."""
    sin2_air = 1.0 - cos_air * cos_air
    cos_g = np.sqrt(1.0 - (n_a / n_g) ** 2 * sin2_air)
    cos_w = np.sqrt(1.0 - (n_a / n_w) ** 2 * sin2_air)
    total = np.zeros_like(cos_air)
    for s_polarised in (True, False):
        r1 = _reflectance(n_a, n_g, cos_air, cos_g, s_polarised)
        r2 = _reflectance(n_g, n_w, cos_g, cos_w, s_polarised)
        total = total + (1.0 - r1) * (1.0 - r2) / (1.0 - r1 * r2)
    return 0.5 * total


def _reflectance(
    n1: float, n2: float, cos_i: np.ndarray, cos_t: np.ndarray, s_polarised: bool
) -> np.ndarray:
    """R = r^2 of one interface n1 -> n2 for s or p polarisation (complex step safe)."""
    if s_polarised:
        r = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t)
    else:
        r = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t)
    return r * r
