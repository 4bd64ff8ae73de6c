"""The light's flat port compiled (lightcal.core.kernels.port_flux) gives the numbers of
the NumPy code it replaced (tests/light_port_numpy.py) to round-off: the path solve
(`air_sines`), the paths (`port_paths`) and the flux of pixels with gradients
(`quads_flux`), on the calling thread and on all threads."""

from __future__ import annotations

import numpy as np
import pytest

from lightcal.core import light_port, light_port_flux
from lightcal.core.camera import Camera
from lightcal.core.flat_port import FlatPort
from lightcal.core.footprint import pixel_footprints
from lightcal.core.kernels import port_flux, port_water
from lightcal.core.rid import CosPowerRID, GaussianRID, Table2DRID
from lightcal.core.scene import Light, View
from tests import light_port_numpy as reference

PORTS = {
    "axial": FlatPort(0.02, 0.01, 1.49, 1.333),
    "tilted": FlatPort(0.03, 0.008, 1.52, 1.34, normal_camera=np.array([0.06, -0.04, 1.0])),
    "thin-close": FlatPort(0.002, 0.0, 1.49, 1.333),
    # the outer face beyond some footprints: those pixels are not lit
    "far": FlatPort(1.0, 0.2, 1.49, 1.333),
}
RTOL = 1e-12


def _table_rid() -> Table2DRID:
    theta = np.radians(np.linspace(0.0, 90.0, 19))
    phi = np.radians(np.arange(0.0, 360.0, 30.0))
    values = np.cos(theta)[None, :] ** (2.0 + 0.8 * np.cos(phi)[:, None] ** 2)
    return Table2DRID(theta, phi, values)


RIDS = {"cos3": CosPowerRID(3.0), "gauss": GaussianRID(0.6), "table2d": _table_rid()}


def _quads() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    camera = Camera.from_params(
        fx=36.0, fy=36.0, cx=19.5, cy=14.5, width=40, height=30, dist=(-0.08, 0.02, 0.0, 0.0)
    )
    view = View.looking_at(np.array([0.25, -0.15, 1.3]), np.array([0.05, 0.1, 0.0]))
    v, u = np.mgrid[0 : camera.height, 0 : camera.width]
    fp = pixel_footprints(camera, view, np.stack([u.ravel(), v.ravel()], axis=1))
    rows = np.flatnonzero(fp.valid & np.isfinite(fp.corners_world).reshape(len(fp), -1).all(1))
    axis = np.array([0.1, -0.05, 1.0])
    z = axis / np.linalg.norm(axis)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    R = np.stack([x, np.cross(z, x), z], axis=1)
    light = Light(CosPowerRID(3.0), np.array([0.12, -0.05, 0.03]), R)
    L, R_world = light.position_world(view), light.rotation_world(view)
    return fp.corners_world[rows], fp.weights[rows], L, R_world


def _close(got: np.ndarray, want: np.ndarray, scale: np.ndarray) -> None:
    assert np.all(np.abs(got - want) <= RTOL * scale), np.max(np.abs(got - want) / scale)


@pytest.mark.parametrize("port", PORTS.values(), ids=PORTS.keys())
def test_the_path_solve_and_the_paths_match_numpy(port: FlatPort) -> None:
    rng = np.random.default_rng(1)
    Y = rng.normal(size=(5000, 3)) * [0.4, 0.4, 0.3] + [0.0, 0.0, 0.2]
    Y[:3] = [[0.0, 0.0, 0.5], [np.nan, 0.0, 1.0], [0.0, 0.0, -1.0]]
    n = port.normal_camera / np.linalg.norm(port.normal_camera)
    h = Y @ n
    rho = np.linalg.norm(Y - h[:, None] * n, axis=1)
    s, ok = light_port.air_sines(rho, h, port)
    s_ref, ok_ref = reference.air_sines(rho, h, port)
    assert np.array_equal(ok, ok_ref) and 0 < ok.sum() < len(ok)
    assert np.array_equal(np.isnan(s), ~ok)
    _close(s[ok], s_ref[ok], np.abs(s_ref[ok]))
    got, want = light_port.port_paths(Y, port), reference.port_paths(Y, port)
    g_u = rng.normal(size=Y.shape)
    for a, b in (
        (got.directions_light, want.directions_light),
        (got.exits_light, want.exits_light),
        (got.water_grad, want.water_grad),
        (got.pull_back(g_u), want.pull_back(g_u)),
    ):
        _close(a[ok], b[ok], np.abs(b[ok]).max(axis=1, keepdims=True))


@pytest.mark.parametrize("threads", [False, True], ids=["serial", "parallel"])
@pytest.mark.parametrize("n_sub", [1, 2, 3])
@pytest.mark.parametrize("rid", RIDS.values(), ids=RIDS.keys())
@pytest.mark.parametrize("port", PORTS.values(), ids=PORTS.keys())
def test_the_flux_and_its_gradients_match_numpy(
    port: FlatPort, rid, n_sub: int, threads: bool, monkeypatch
) -> None:
    corners, weights, L, R = _quads()
    monkeypatch.setattr(port_flux, "PORT_SERIAL_POINTS", 0 if threads else 10**12)
    data = rid.data()
    flux, lit, grad = light_port_flux.quads_flux(corners, weights, L, R, data, port, n_sub, True)
    f_ref, lit_ref, g_ref = reference.quads_flux(corners, weights, L, R, data, port, n_sub, True)
    assert g_ref is not None and grad is not None
    assert np.array_equal(lit, lit_ref) and lit.sum() > 100
    assert lit.all() != (port is PORTS["far"])
    _close(flux, f_ref, np.abs(f_ref))
    _close(grad, g_ref, np.abs(g_ref).max(axis=1, keepdims=True))
    plain, lit_plain, none = light_port_flux.quads_flux(
        corners, weights, L, R, data, port, n_sub, False
    )
    assert none is None and np.array_equal(plain, flux) and np.array_equal(lit_plain, lit)


@pytest.mark.parametrize("threads", [False, True], ids=["serial", "parallel"])
@pytest.mark.parametrize("per_pixel_camera", [False, True], ids=["camera", "per-pixel"])
@pytest.mark.parametrize("port", PORTS.values(), ids=PORTS.keys())
def test_the_attenuation_through_the_port_matches_numpy(
    port: FlatPort, per_pixel_camera: bool, threads: bool, monkeypatch
) -> None:
    corners, weights, L, R = _quads()
    monkeypatch.setattr(port_water, "ATTENUATE_SERIAL_ROWS", 0 if threads else 10**12)
    flux, lit, grad = reference.quads_flux(
        corners, weights, L, R, CosPowerRID(3.0).data(), port, 2, True
    )
    assert grad is not None
    centers = corners.mean(axis=(1, 2))[lit]
    camera = np.array([0.3, -0.1, 1.3])
    if per_pixel_camera:
        camera = camera + 0.01 * np.random.default_rng(2).normal(size=centers.shape)
    got_f, got_g, plain = flux.copy(), grad.copy(), flux.copy()
    got_dc = light_port_flux.attenuate_through_port(
        centers, camera, L, R, port, 0.3, got_f, lit, got_g
    )
    dc = reference.attenuate_through_port(centers, camera, L, R, port, 0.3, flux, lit, grad)
    _close(got_f, flux, np.abs(flux))
    _close(got_g, grad, np.abs(grad).max(axis=1, keepdims=True))
    _close(got_dc, dc, np.abs(dc))
    light_port_flux.attenuate_through_port(centers, camera, L, R, port, 0.3, plain, lit, None)
    assert np.array_equal(plain, got_f)
