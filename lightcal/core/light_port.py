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
left side minus rho, g(s), is increasing and convex in s on [0, 1) with g(0) = -rho <= 0.
The compiled solve (`lightcal.core.kernels.port_paths.solve_paths`, point by point)
works in the water's slope u = tan(theta_w) (s = n_w u / sqrt(1 + u^2)), where the
dominant term H u is linear: from the paraxial start u_0 = rho / (H + n_w (d + t / n_g)),
Halley's steps safeguarded by the bracket [0, rho / H] reach round-off in 2-3
evaluations up to 60 degrees in the air (at most 12 up to 80). Past 80 degrees, where
the outputs amplify the last bits of s, it solves g(s) = 0 by Newton's method started
right of the root (where one term alone reaches rho), which decreases monotonically to
it, quadratically, to round-off. A point with h <= d + t is not in front of
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
from lightcal.core.kernels.port_paths import PATH_SIZE, air_sines_into
from lightcal.core.kernels.port_water import paths_into


def _indices(port: FlatPort) -> tuple[float, float]:
    """The glass's and the water's indices relative to the air's."""
    return port.glass_index / port.air_index, port.water_index / port.air_index


def port_geometry(port: FlatPort) -> np.ndarray:
    """(7,) the port's numbers as the kernels take them: d, t, n_g / n_a, n_w / n_a, n_a,
    n_g, n_w."""
    n_g, n_w = _indices(port)
    return np.array(
        [
            port.distance_m, port.thickness_m, n_g, n_w, port.air_index, port.glass_index,
            port.water_index,
        ]
    )  # fmt: skip


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
    """The refracted paths from the emitter to points (M, 3) of the light frame, m
    (compiled, point by point: `lightcal.core.kernels.port_water.paths_into`)."""
    Y = np.ascontiguousarray(points_light, dtype=np.float64).reshape(-1, 3)
    n = np.ascontiguousarray(port.normal_camera, dtype=np.float64)
    n_g, n_w = _indices(port)
    m = Y.shape[0]
    path = np.empty((m, PATH_SIZE))
    ok = np.empty(m, dtype=np.bool_)
    water = np.empty(m)
    water_grad = np.empty((m, 3))
    exits = np.empty((m, 3))
    paths_into(
        Y, n, port.distance_m, port.thickness_m, n_g, n_w, path, ok, water, water_grad, exits
    )
    return PortPaths(
        path[:, 0:3], path[:, 12], ok, water, exits, n, path[:, 9], path[:, 3:6],
        path[:, 6:9], path[:, 11], water_grad,
    )  # fmt: skip
