"""Whole frames of a rig with a light behind its flat port (`lightcal.core.light_port_frame`,
what `port_render.render_view_image` renders for the report and the page): the straight
twin's fused image times the port's ratio and plus its veil, exact on the nodes and cubic
between them, against every pixel's footprint shaded through the port
(`render.render_image`, `port_render.render_image_per_pixel_through_port`)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lightcal.core.camera import Camera
from lightcal.core.flat_port import FlatPort
from lightcal.core.footprint import pixel_footprints
from lightcal.core.kernels.node_image import add_on_nodes, cubic_lines, cubic_weights
from lightcal.core.medium import Medium
from lightcal.core.port_footprints import port_footprints
from lightcal.core.port_nodes import node_grid
from lightcal.core.port_render import render_view_image
from lightcal.core.render import render_image, shade
from lightcal.core.rid import CosPowerRID, GaussianRID, Table2DRID
from lightcal.core.scene import Light, Rig, View
from tests.test_port_fused import _camera as fused_camera
from tests.test_port_fused import _rotation

CAMERA_PORT = FlatPort(0.02, 0.01, 1.49, 1.333)
LIGHT_PORT = FlatPort(0.015, 0.008, 1.49, 1.333)
VIEW = View.looking_at(np.array([0.2, -0.1, 1.4]), np.array([0.05, 0.05, 0.0]), exposure=1.3)
# Oblique and wide: the upper rows' rays run above the horizon and miss the wall.
OBLIQUE = View.looking_at(np.array([0.1, -1.2, 0.5]), np.array([0.0, 0.2, 0.0]))


def _camera(width: int = 320, height: int = 240, f: float = 290.0) -> Camera:
    return fused_camera(width, height, f)


def _lopsided() -> Table2DRID:
    """A 2-D table: cos^(3 + cos(phi)) on 7 x 8 nodes."""
    theta = np.linspace(0.0, math.radians(80.0), 9)
    phi = np.linspace(0.0, 2.0 * math.pi, 8, endpoint=False)
    values = np.cos(theta)[None, :] ** (3.0 + np.cos(phi))[:, None]
    return Table2DRID(theta, phi, values)


def _rig(rid: str = "cos") -> Rig:
    """A light behind its port (cos^3, or the 2-D table) and a Gaussian one without."""
    ported = Light(
        CosPowerRID(3.0) if rid == "cos" else _lopsided(),
        np.array([0.12, -0.05, 0.03]),
        _rotation((0.1, -0.05, 1.0)),
        2.0,
        port=LIGHT_PORT,
    )
    plain = Light(
        GaussianRID.from_half_angle(math.radians(35.0)),
        np.array([-0.1, 0.04, 0.0]),
        _rotation((-0.15, 0.1, 1.0)),
        0.7,
    )
    return Rig((ported, plain))


def _exact(
    camera: Camera, view: View, rig: Rig, port: FlatPort | None, **options: object
) -> np.ma.MaskedArray:
    """Every pixel's footprint shaded, the veil exact at every pixel too (what
    `render.render_image` does but for its veil, which it interpolates between nodes)."""
    b = int(options.pop("binning", 1))  # type: ignore[call-overload]
    common = {k: options.pop(k) for k in ("sensor", "vignetting") if k in options}
    hb, wb = camera.height // b, camera.width // b
    v, u = np.mgrid[0:hb, 0:wb]
    pixels = np.stack([u.ravel(), v.ravel()], axis=1)
    if port is None:
        fp = pixel_footprints(camera, view, pixels, binning=b, max_quads_per_side=None, **common)
    else:
        fp = port_footprints(
            camera, view, pixels, port, binning=b, max_quads_per_side=None, **common
        )
    return shade(fp, view, rig, **options).values.reshape(hb, wb)  # type: ignore[arg-type]


def _node_mask(shape: tuple[int, int]) -> np.ndarray:
    rows, cols = node_grid(shape)
    nodes = np.zeros(shape, dtype=np.bool_)
    nodes[np.ix_(rows, cols)] = True
    return nodes


MEDIA = {"water": Medium(0.3), "veil": Medium(0.3, 0.6, 0.8)}


@pytest.mark.parametrize("port", [None, CAMERA_PORT], ids=["air camera", "camera port"])
@pytest.mark.parametrize("medium", list(MEDIA))
@pytest.mark.parametrize("binning", [1, 2])
def test_the_frame_is_the_exact_image(port: FlatPort | None, medium: str, binning: int) -> None:
    """In water both lights; in water that scatters the ported light alone (the other's
    veil is the fused kernels', bilinear between their own nodes, as in air)."""
    camera = _camera()
    sensor = "radiance" if medium == "veil" else "cos4"  # the veil: radiance only
    options = {"binning": binning, "offset": 0.02, "medium": MEDIA[medium], "sensor": sensor}
    rig = _rig() if medium == "water" else Rig.single(_rig().lights[0])
    fast = render_view_image(camera, VIEW, rig, port=port, **options)  # type: ignore[arg-type]
    exact = _exact(camera, VIEW, rig, port, **options)
    assert fast.shape == (240 // binning, 320 // binning)
    mask = np.ma.getmaskarray(exact)
    np.testing.assert_array_equal(np.ma.getmaskarray(fast), mask)
    nodes = _node_mask(fast.shape) & ~mask
    # On the nodes: the exact shading itself (round-off of the sums).
    np.testing.assert_allclose(fast.data[nodes], exact.data[nodes], rtol=1e-12, atol=0.0)
    # Between them the cubics (measured here: 6.5e-7 at most, 9e-9 median; with the veil
    # 4.6e-6 and 1e-7; the in-air image's veil, bilinear between its nodes, 1e-4).
    np.testing.assert_allclose(
        fast.data[~mask], exact.data[~mask], rtol=2e-5 if medium == "veil" else 2e-6, atol=0.0
    )


def test_a_tabulated_light_behind_its_port() -> None:
    camera = _camera()
    fast = render_view_image(camera, VIEW, _rig("table"), medium=Medium(0.2))
    exact = render_image(camera, VIEW, _rig("table"), medium=Medium(0.2))
    ok = ~np.ma.getmaskarray(exact)
    np.testing.assert_array_equal(np.ma.getmaskarray(fast), ~ok)
    np.testing.assert_allclose(fast.data[ok], exact.data[ok], rtol=1e-6, atol=0.0)


def test_pixels_beside_a_node_that_cannot_say_are_exact() -> None:
    """An oblique wide view whose upper rows miss the wall: the pixels whose stencil
    holds an invalid node are shaded exactly (to round-off)."""
    camera = _camera(384, 288, f=128.0)
    rig = Rig.single(_rig().lights[0])
    fast = render_view_image(camera, OBLIQUE, rig, medium=Medium(0.2, 0.4, 0.5))
    exact = _exact(camera, OBLIQUE, rig, None, medium=Medium(0.2, 0.4, 0.5))
    mask = np.ma.getmaskarray(exact)
    np.testing.assert_array_equal(np.ma.getmaskarray(fast), mask)
    assert mask.any() and not mask.all()
    rows, cols = node_grid(fast.shape)
    (rk, _), (ck, _) = cubic_weights(rows, fast.shape[0]), cubic_weights(cols, fast.shape[1])
    node_bad = mask[np.ix_(rows, cols)]
    beside = np.zeros(fast.shape, dtype=np.bool_)
    for a in range(4):
        for b in range(4):
            beside |= node_bad[rk + a][:, ck + b]
    redone = beside & ~mask
    assert redone.sum() > 100
    np.testing.assert_allclose(fast.data[redone], exact.data[redone], rtol=1e-12, atol=0.0)
    np.testing.assert_allclose(fast.data[~mask], exact.data[~mask], rtol=3e-6, atol=0.0)


def test_a_ported_light_behind_the_wall_lights_nothing() -> None:
    light = Light(CosPowerRID(2.0), np.array([0.0, 0.3, 3.0]), np.eye(3), 0.3, port=LIGHT_PORT)
    assert light.position_world(VIEW)[2] < 0.0
    fast = render_view_image(_camera(), VIEW, Rig.single(light), offset=0.5)
    assert fast.count() > 0
    np.testing.assert_array_equal(fast.compressed(), 0.5)


def test_the_cubic_weights_are_exact_for_cubics() -> None:
    """Lagrange's four-node weights reproduce any cubic, inside and at the borders (the
    last interval shorter), and are 1 at a node."""
    rows, _ = node_grid((203, 300))
    assert rows[-1] == 202 and np.all(np.diff(rows)[:-1] == 4)
    first, weights = cubic_weights(rows, 203)
    x = np.arange(203.0)
    f = 0.3 * x**3 - 2.0 * x**2 + 5.0 * x - 7.0
    stencil = rows[first[:, None] + np.arange(4)]
    fs = 0.3 * stencil**3 - 2.0 * stencil**2 + 5.0 * stencil - 7.0
    np.testing.assert_allclose((weights * fs).sum(axis=1), f, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, rtol=0.0, atol=1e-12)
    at = weights[rows]
    np.testing.assert_allclose(np.sort(at, axis=1)[:, -1], 1.0, rtol=0.0, atol=1e-15)


def test_node_grid_of_small_images_is_every_pixel() -> None:
    assert [len(a) for a in node_grid((3, 500))] == [3, 500]
    rows, cols = node_grid((96, 200))
    np.testing.assert_array_equal(rows, np.append(np.arange(0, 96, 2), 95))  # s = 96 // 48
    np.testing.assert_array_equal(cols, np.append(np.arange(0, 200, 2), 199))


def test_a_node_that_cannot_say_flags_its_stencils_pixels() -> None:
    rows = cols = np.array([0, 3, 6, 9, 12, 15, 18, 19])
    ratio = np.ones((8, 8))
    ratio[3, 5] = np.nan
    frame = np.full((20, 20), 2.0)
    total = np.zeros((20, 20))
    redo = np.zeros((20, 20), dtype=np.bool_)
    rk, rw = cubic_weights(rows, 20)
    ck, cw = cubic_weights(cols, 20)
    lines = cubic_lines(np.stack([ratio, np.zeros((8, 8))], axis=2), rk, rw)
    add_on_nodes(frame, lines, ck, cw, 0.0, True, total, redo)
    uses = ((rk[:, None] <= 3) & (rk[:, None] + 3 >= 3)) & ((ck[None, :] <= 5) & (ck + 3 >= 5))
    np.testing.assert_array_equal(redo, uses)
    np.testing.assert_allclose(total[~redo], 2.0, rtol=1e-14)
    assert (total[redo] == 0.0).all()
    # Not accumulating, in place on the frame: base + frame x r, base where it cannot say.
    again = np.zeros((20, 20), dtype=np.bool_)
    add_on_nodes(frame, lines, ck, cw, 0.5, False, frame, again)
    np.testing.assert_array_equal(again, uses)
    np.testing.assert_allclose(frame[~again], 2.5, rtol=1e-14)
    assert (frame[again] == 0.5).all()


@pytest.mark.parametrize("with_plain", [False, True], ids=["ported only", "and a plain light"])
def test_two_ported_lights_add_up_beside_nodes_that_cannot_say(with_plain: bool) -> None:
    """Two lights behind their ports (the first's twin frame scaled in place, the
    second's added), with and without a light without a port, on the oblique view: the
    redone pixels hold every light's exact value and the offset once."""
    camera = _camera(384, 288, f=128.0)
    ported, plain = _rig().lights
    lights = (ported, plain.replace(port=LIGHT_PORT)) + ((plain,) if with_plain else ())
    rig = Rig(lights)
    options = {"medium": Medium(0.2), "offset": 0.05}
    fast = render_view_image(camera, OBLIQUE, rig, **options)  # type: ignore[arg-type]
    exact = _exact(camera, OBLIQUE, rig, None, **options)
    mask = np.ma.getmaskarray(exact)
    np.testing.assert_array_equal(np.ma.getmaskarray(fast), mask)
    assert mask.any() and not mask.all()
    np.testing.assert_allclose(fast.data[~mask], exact.data[~mask], rtol=3e-6, atol=0.0)
