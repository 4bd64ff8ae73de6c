"""The whole image through the camera's flat port by the fused kernel
(`lightcal.core.kernels.port_image`, `port_render.render_image_through_port`) against
every pixel's footprint shaded (`port_render.render_image_per_pixel_through_port`, the
reference): binning, sensor models, vignetting, air and water (attenuation, backscatter),
wall models, several lights (one behind the wall), corners that miss the wall."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lightcal.core.camera import Camera
from lightcal.core.flat_port import FlatPort
from lightcal.core.medium import AIR, Medium, scatter_grid
from lightcal.core.port_render import (
    render_image_per_pixel_through_port,
    render_image_through_port,
    render_view_image,
)
from lightcal.core.render import render_image
from lightcal.core.rid import CosPowerRID, GaussianRID, IsotropicRID
from lightcal.core.scene import Light, Rig, View
from lightcal.core.wall import LAMBERTIAN, OrenNayarWall, PlasticWall, WallReflectance

PORT = FlatPort(0.02, 0.01, 1.49, 1.333)
TILTED = FlatPort(0.015, 0.0, 1.49, 1.333, normal_camera=np.array([0.06, -0.04, 1.0]))


def _camera(width: int = 40, height: int = 30, f: float = 36.0) -> Camera:
    return Camera.from_params(
        fx=f, fy=f, cx=(width - 1) / 2, cy=(height - 1) / 2, width=width, height=height,
        dist=(-0.08, 0.02, 0.0, 0.0),
    )  # fmt: skip


def _rotation(axis: tuple[float, float, float]) -> np.ndarray:
    z = np.asarray(axis) / np.linalg.norm(axis)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z], axis=1)


def _rig(n: int = 3) -> Rig:
    """Lights of three RID kinds (cos^m, Gaussian, isotropic); the third sits 3 m ahead of
    the camera, beyond the wall in both views (it lights nothing)."""
    lights = [
        Light(CosPowerRID(3.0), np.array([0.12, -0.05, 0.03]), _rotation((0.1, -0.05, 1.0)), 2.0),
        Light(
            GaussianRID.from_half_angle(math.radians(35.0)),
            np.array([-0.1, 0.04, 0.0]),
            _rotation((-0.15, 0.1, 1.0)),
            0.7,
        ),
        Light(IsotropicRID(), np.array([0.0, 0.3, 3.0]), np.eye(3), 0.3),
    ]
    return Rig(tuple(lights[:n]))


VIEW = View.looking_at(np.array([0.25, -0.15, 1.5]), np.array([0.05, 0.1, 0.0]), exposure=1.3)
# Oblique and wide: the upper rows' rays run above the horizon and miss the wall.
OBLIQUE = View.looking_at(np.array([0.1, -1.2, 0.5]), np.array([0.0, 0.2, 0.0]))


def _vignetting(camera: Camera) -> np.ndarray:
    v, u = np.mgrid[0 : camera.height, 0 : camera.width]
    r2 = ((u - camera.width / 2) ** 2 + (v - camera.height / 2) ** 2) / camera.width**2
    return 1.0 - 0.6 * r2 + 0.01 * np.sin(u * 1.3 + v * 0.7)


def _compare(fused: np.ma.MaskedArray, oracle: np.ma.MaskedArray, rtol: float = 1e-12) -> None:
    np.testing.assert_array_equal(np.ma.getmaskarray(fused), np.ma.getmaskarray(oracle))
    assert np.isnan(fused.data[fused.mask]).all()
    ok = ~np.ma.getmaskarray(oracle)
    assert ok.any()
    np.testing.assert_allclose(fused.data[ok], oracle.data[ok], rtol=rtol, atol=0.0)


def _both(camera: Camera, view: View, rig: Rig, port: FlatPort, **options: object) -> tuple:
    fused = render_image_through_port(camera, view, rig, port, **options)  # type: ignore[arg-type]
    oracle = render_image_per_pixel_through_port(camera, view, rig, port, **options)  # type: ignore[arg-type]
    return fused, oracle


MEDIA = {
    "air": AIR,
    "attenuation": Medium(0.3),
    "backscatter": Medium(0.3, 0.6, 0.7),
}


@pytest.mark.parametrize("binning", [1, 2, 3])
@pytest.mark.parametrize("sensor", ["radiance", "cos4", "map"])
@pytest.mark.parametrize("medium", list(MEDIA))
def test_the_fused_image_is_every_pixels_footprint(binning: int, sensor: str, medium: str) -> None:
    camera = _camera()
    vignetting = _vignetting(camera) if sensor == "map" else None
    fused, oracle = _both(
        camera, VIEW, _rig(2), PORT, sensor=sensor, vignetting=vignetting, binning=binning,
        offset=0.02, medium=MEDIA[medium],
    )  # fmt: skip
    assert fused.shape == (30 // binning, 40 // binning)
    _compare(fused, oracle)


@pytest.mark.parametrize(
    "wall", [PlasticWall(0.25, 1.5, 2.0), OrenNayarWall(math.radians(25.0))], ids=str
)
@pytest.mark.parametrize("binning", [1, 2])
@pytest.mark.parametrize("medium", ["air", "backscatter"])
def test_a_non_lambertian_wall_sees_from_the_exit_points(
    wall: WallReflectance, binning: int, medium: str
) -> None:
    camera = _camera()
    fused, oracle = _both(
        camera, VIEW, _rig(2), PORT, sensor="cos4", binning=binning, wall=wall,
        medium=MEDIA[medium],
    )  # fmt: skip
    _compare(fused, oracle)
    lambertian = render_image_through_port(camera, VIEW, _rig(2), PORT, binning=binning)
    assert np.nanmax(np.abs(fused / lambertian - 1.0)) > 1e-3  # the wall is not ignored


@pytest.mark.parametrize("binning", [1, 2])
@pytest.mark.parametrize("port", [PORT, TILTED], ids=["port", "tilted, no glass"])
def test_corners_that_miss_the_wall_mask_their_pixels(binning: int, port: FlatPort) -> None:
    """A wide camera looking obliquely: its lower rows see above the horizon. The light
    behind the wall (in this view) lights nothing, its veil included, as by `shade`."""
    camera = _camera(48, 36, f=16.0)
    for medium in (AIR, Medium(0.2, 0.4, 0.5)):
        fused, oracle = _both(
            camera, OBLIQUE, _rig(3), port, binning=binning, wall=PlasticWall(), medium=medium,
            rid_subsamples=2,
        )  # fmt: skip
        mask = np.ma.getmaskarray(fused)
        assert mask.any() and not mask.all()
        assert mask[-1].all() and not mask[0].any()
        _compare(fused, oracle)


def test_rid_subsamples_and_a_lone_light_behind_the_wall() -> None:
    camera = _camera()
    fused, oracle = _both(camera, VIEW, _rig(2), PORT, rid_subsamples=3, medium=Medium(0.2))
    _compare(fused, oracle)
    behind = Rig((_rig(3).lights[2],))
    assert behind.lights[0].position_world(VIEW)[2] < 0.0
    for medium in (AIR, Medium(0.2, 0.4, 0.5)):
        fused, oracle = _both(camera, VIEW, behind, PORT, offset=0.5, medium=medium)
        _compare(fused, oracle)
        # It lights nothing, the water in front of the wall included (no veil), as in air.
        np.testing.assert_array_equal(fused.compressed(), 0.5)
        np.testing.assert_array_equal(oracle.compressed(), 0.5)
        air = render_image(camera, VIEW, behind, offset=0.5, medium=medium)
        np.testing.assert_array_equal(air.compressed(), 0.5)


def test_a_light_behind_its_own_port_takes_the_per_pixel_path() -> None:
    """A rig with `lights[i].port` is shaded footprint by footprint (the fused kernel has
    no light port); 'paper' is refused as before."""
    camera = _camera()
    lights = _rig(2).lights
    rig = Rig((lights[0].replace(port=FlatPort(0.015, 0.008, 1.49, 1.333)), lights[1]))
    fused, oracle = _both(camera, VIEW, rig, PORT, medium=Medium(0.2))
    np.testing.assert_array_equal(fused.filled(-1.0), oracle.filled(-1.0))
    # The frames' path (`light_port_frame`): on an image this small every pixel is a node.
    via_view = render_view_image(camera, VIEW, rig, port=PORT, medium=Medium(0.2))
    _compare(via_view, oracle)
    with pytest.raises(ValueError, match="paper"):
        render_image_through_port(camera, VIEW, _rig(1), PORT, sensor="paper")
    with pytest.raises(ValueError, match="binning"):
        render_image_through_port(camera, VIEW, _rig(1), PORT, binning=0)
    with pytest.raises(ValueError, match="sensor"):
        render_image_through_port(camera, VIEW, _rig(1), PORT, sensor="nope")  # type: ignore[arg-type]


def test_the_fused_image_with_lambertian_defaults_matches() -> None:
    """The defaults (radiance, air, Lambertian) at a larger size, where the pixels' solid
    angles are small (the odd series of `kernels.solid_angle`)."""
    camera = _camera(160, 120, f=150.0)
    fused, oracle = _both(camera, VIEW, _rig(2), PORT)
    _compare(fused, oracle)
    assert LAMBERTIAN.is_lambertian


# A camera large enough that `scatter_grid` skips pixels: every 4th row and column at
# binning 1 (384 rows), every 2nd binned by 2.
LARGE = {"width": 480, "height": 384, "f": 430.0}


def _nodes(shape: tuple[int, int]) -> np.ndarray:
    rows, cols = scatter_grid(shape)
    at = np.zeros(shape, dtype=np.bool_)
    at[np.ix_(rows, cols)] = True
    return at


@pytest.mark.parametrize("binning", [1, 2])
def test_the_veil_is_exact_on_the_nodes_and_interpolated_between(binning: int) -> None:
    """With backscatter the fused image computes the veil exactly on `scatter_grid`'s
    nodes and interpolates it between them, as the image in air does: the per-pixel
    path's numbers to 1e-12 at the nodes, within 1e-4 elsewhere (the bound of air's
    interpolation, `tests/test_medium.py`), where the veil is much of the signal."""
    camera = _camera(**LARGE)  # type: ignore[arg-type]
    medium = Medium(0.3, 0.6, 0.7)
    fused, oracle = _both(camera, VIEW, _rig(2), PORT, binning=binning, medium=medium)
    rows, _ = scatter_grid(fused.shape)
    assert rows[1] - rows[0] == 4 // binning and rows[-1] == fused.shape[0] - 1
    clear = render_image_per_pixel_through_port(
        camera, VIEW, _rig(2), PORT, binning=binning, medium=Medium(0.3)
    )
    assert np.ma.median((oracle - clear) / oracle) > 0.05  # the veil matters
    at = _nodes(fused.shape)
    np.testing.assert_array_equal(np.ma.getmaskarray(fused), np.ma.getmaskarray(oracle))
    ok = ~np.ma.getmaskarray(oracle)
    np.testing.assert_allclose(fused.data[ok & at], oracle.data[ok & at], rtol=1e-12, atol=0.0)
    between = ok & ~at
    assert between.sum() > 0.5 * ok.sum()
    np.testing.assert_allclose(fused.data[between], oracle.data[between], rtol=1e-4, atol=0.0)
    assert np.abs(fused.data[between] / oracle.data[between] - 1.0).max() > 1e-12  # interpolated


def test_the_veil_beside_invalid_nodes_is_exact() -> None:
    """An oblique wide view whose upper rows miss the wall: pixels next to an invalid
    node take their own exact veil, to 1e-12 as the nodes."""
    camera = _camera(384, 288, f=128.0)
    fused, oracle = _both(camera, OBLIQUE, _rig(3), PORT, medium=Medium(0.2, 0.4, 0.5))
    mask = np.ma.getmaskarray(fused)
    np.testing.assert_array_equal(mask, np.ma.getmaskarray(oracle))
    assert mask.any() and not mask.all()
    rows, cols = scatter_grid(fused.shape)
    node_ok = ~mask[np.ix_(rows, cols)]
    # The pixels whose bracketing nodes include an invalid one: exact.
    i, j = (
        np.clip(np.searchsorted(nodes, np.arange(size), side="right") - 1, 0, len(nodes) - 2)
        for nodes, size in ((rows, fused.shape[0]), (cols, fused.shape[1]))
    )
    corners_ok = (
        node_ok[i][:, j] & node_ok[i + 1][:, j] & node_ok[i][:, j + 1] & node_ok[i + 1][:, j + 1]
    )
    exact = (~mask & ~corners_ok) | (~mask & _nodes(fused.shape))
    assert (~mask & ~corners_ok).any()
    np.testing.assert_allclose(fused.data[exact], oracle.data[exact], rtol=1e-12, atol=0.0)
    # Near the horizon the grazing rays' veil bends faster than the grid resolves (as
    # it would in air): there, not within air's 1e-4 (2.4e-2 measured).
    ok = ~mask
    np.testing.assert_allclose(fused.data[ok], oracle.data[ok], rtol=3e-2, atol=0.0)


@pytest.mark.parametrize("medium", ["air", "attenuation"])
def test_without_backscatter_a_large_image_is_every_pixels_footprint(medium: str) -> None:
    """No veil, no interpolation: 1e-12 at a size where the veil's grid skips pixels."""
    camera = _camera(**LARGE)  # type: ignore[arg-type]
    fused, oracle = _both(camera, VIEW, _rig(2), PORT, sensor="cos4", medium=MEDIA[medium])
    _compare(fused, oracle)
