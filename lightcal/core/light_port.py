"""The light's flat port: the refracted path from the emitter to a point in the water.

Underwater a light (an LED behind its reflector) sits in a housing and shines through
a flat window: a plate of thickness t and index n_g whose inner face lies at distance d
from the emitter along the port's normal n, water of index n_w outside (docs/model.md,
"The light's flat port"). The port is a `lightcal.core.flat_port.FlatPort` whose frame
is its owner's: here the light's (`FlatPort.normal_camera` is then the normal in the
light frame, by default the light's axis +z).

A ray leaving the emitter in the air at angle theta_a from n is refracted twice and
reaches, in the plane of n and the point, the radial distance

    rho = d tan(theta_a) + t tan(theta_g) + (h - d - t) tan(theta_w),
    sin(theta_a) = (n_g / n_a) sin(theta_g) = (n_w / n_a) sin(theta_w),

at the axial distance h (n_a the air's index, 1). For a point Y (light frame) with
h = n . Y and rho = |Y - h n| this is solved for s = sin(theta_a) (`air_sines`): the
left side minus rho, g(s), is increasing and convex in s on [0, 1) with g(0) = -rho <= 0,
so Newton's method started right of the root (where one term alone reaches rho)
decreases monotonically to it, quadratically, to round-off (compiled, point by point:
`lightcal.core.kernels.port_flux.air_sine`). A point with h <= d + t is not in front of
the port: no ray reaches it (`ok` False).

The air direction u_a = s rho_hat + cos(theta_a) n is where the emitter's RID (given in
air) is evaluated. Its derivative in Y (`PortPaths.pull_back`) comes from implicit
differentiation of g(s; rho, h) = 0:

    dg/ds = d / c_a^3 + t n_g^2 / (n_g^2 - s^2)^(3/2) + H n_w^2 / (n_w^2 - s^2)^(3/2),
    ds = (d rho - tan(theta_w) dh) / (dg/ds),   H = h - d - t,

(indices relative to the air's), and u_a = k (Y - h n) + c_a n with k = s / rho
(1 / (dg/ds) on the axis), so that

    du_a/dY = k P + rho_hat (a - k rho_hat)^T - (s / c_a) n a^T,
    a = (rho_hat - tan(theta_w) n) / (dg/ds),   P = I - n n^T.

The path's length in the water, from the exit point E on the port's outer face, is
H / cos(theta_w) (`PortPaths.water_m`, with its derivative in Y).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lightcal.core.flat_port import FlatPort
from lightcal.core.kernels.port_flux import air_sines_into


def _indices(port: FlatPort) -> tuple[float, float]:
    """The glass's and the water's indices relative to the air's."""
    return port.glass_index / port.air_index, port.water_index / port.air_index


def air_sines(rho_m: np.ndarray, h_m: np.ndarray, port: FlatPort) -> tuple[np.ndarray, np.ndarray]:
    """sin(theta_a) of the refracted paths from the emitter to points at radial distance
    rho_m (M,) and axial distance h_m (M,) from it (port frame, m).

    Returns:
        s: (M,) the sine of the air ray's angle to the port's normal (NaN where not ok).
        ok: (M,) the point is finite and in front of the port's outer face (h > d + t).
    """
    rho = np.ascontiguousarray(rho_m, dtype=np.float64).reshape(-1)
    h = np.ascontiguousarray(h_m, dtype=np.float64).reshape(-1)
    n_g, n_w = _indices(port)
    s = np.empty(rho.shape)
    ok = np.empty(rho.shape, dtype=np.bool_)
    air_sines_into(rho, h, port.distance_m, port.thickness_m, n_g, n_w, s, ok)
    shape = np.shape(rho_m)
    return s.reshape(shape), ok.reshape(shape)


def _path_equation(
    s: np.ndarray, rho: np.ndarray, big_h: np.ndarray, d: float, t: float, n_g: float, n_w: float
) -> tuple[np.ndarray, np.ndarray]:
    """g(s) = d tan(theta_a) + t tan(theta_g) + H tan(theta_w) - rho and dg/ds, (M,) each."""
    c_a2 = 1.0 - s * s
    c_g2 = n_g * n_g - s * s
    c_w2 = n_w * n_w - s * s
    g = d * s / np.sqrt(c_a2) + t * s / np.sqrt(c_g2) + big_h * s / np.sqrt(c_w2) - rho
    g_s = d / c_a2**1.5 + t * n_g * n_g / c_g2**1.5 + big_h * n_w * n_w / c_w2**1.5
    return g, g_s


@dataclass(frozen=True, eq=False)
class PortPaths:
    """The refracted paths from the emitter to M points, port frame = light frame.

    Attributes:
        directions_light: (M, 3) u_a, the unit air direction leaving the emitter (NaN
            where not ok).
        cos_air: (M,) cos(theta_a) = u_a . n.
        ok: (M,) the point is in front of the port (h > d + t).
        water_m: (M,) the path's length in the water, from the exit point on the outer
            face, m.
        exits_light: (M, 3) the exit points E on the outer face, light frame, m.
    """

    directions_light: np.ndarray
    cos_air: np.ndarray
    ok: np.ndarray
    water_m: np.ndarray
    exits_light: np.ndarray
    _normal: np.ndarray
    _k: np.ndarray
    _rho_hat: np.ndarray
    _a: np.ndarray
    _sin_air: np.ndarray
    _water_grad: np.ndarray

    def pull_back(self, g_u: np.ndarray) -> np.ndarray:
        """(du_a/dY)^T g_u: a gradient (M, 3) with respect to u_a turned into one with
        respect to the point Y (M, 3) (0 where not ok)."""
        n = self._normal
        gu_n = g_u @ n
        gu_r = np.einsum("ij,ij->i", g_u, self._rho_hat)
        s_over_c = self._sin_air / self.cos_air
        out = self._k[:, None] * (g_u - gu_n[:, None] * n)
        out += (self._a - self._k[:, None] * self._rho_hat) * gu_r[:, None]
        out -= (s_over_c * gu_n)[:, None] * self._a
        out[~self.ok] = 0.0
        return out

    @property
    def water_grad(self) -> np.ndarray:
        """(M, 3) d water_m / dY (0 where not ok)."""
        return self._water_grad


def port_paths(points_light: np.ndarray, port: FlatPort) -> PortPaths:
    """The refracted paths from the emitter to points (M, 3) of the light frame, m."""
    Y = np.asarray(points_light, dtype=np.float64).reshape(-1, 3)
    n = np.asarray(port.normal_camera, dtype=np.float64)
    d, t = port.distance_m, port.thickness_m
    n_g, n_w = _indices(port)
    h = Y @ n
    radial = Y - h[:, None] * n
    rho = np.linalg.norm(radial, axis=1)
    s, ok = air_sines(rho, h, port)
    s0 = np.where(ok, s, 0.0)
    big_h = np.where(ok, h - d - t, 1.0)
    c_a = np.sqrt(1.0 - s0 * s0)
    c_w = np.sqrt(1.0 - (s0 / n_w) ** 2)
    tan_w = s0 / (n_w * c_w)
    _, g_s = _path_equation(s0, np.zeros_like(s0), big_h, d, t, n_g, n_w)
    with np.errstate(invalid="ignore", divide="ignore"):
        on_axis = rho == 0.0
        k = np.where(on_axis, 1.0 / g_s, s0 / np.where(on_axis, 1.0, rho))
        rho_hat = np.where(on_axis[:, None], 0.0, radial / np.where(on_axis, 1.0, rho)[:, None])
    u = k[:, None] * radial + c_a[:, None] * n
    a = (rho_hat - tan_w[:, None] * n) / g_s[:, None]
    water = big_h / c_w
    # d(H / c_w) = dH / c_w + H (s / n_w^2) / c_w^3 ds, dH = n . dY, ds = a . dY.
    water_grad = n[None, :] / c_w[:, None] + (big_h * s0 / (n_w * n_w * c_w**3))[:, None] * a
    tan_a = s0 / c_a
    tan_g = s0 / np.sqrt(n_g * n_g - s0 * s0)
    exits = (d * tan_a + t * tan_g)[:, None] * rho_hat + (d + t) * n
    for arr in (u, exits, water_grad):
        arr[~ok] = np.nan
    water = np.where(ok, water, np.nan)
    water_grad[~ok] = 0.0
    return PortPaths(
        u, np.where(ok, c_a, np.nan), ok, water, exits, n, k, rho_hat, a, s0, water_grad
    )
