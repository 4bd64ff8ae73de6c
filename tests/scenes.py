"""Canonical cameras, views, RIDs and rigs for the renderer tests (importable by any test).

Frames and units follow docs/model.md: the wall is z = 0 of the world frame, cameras sit at
z > 0 (OpenCV camera frame), a light's +z is its axis, metres and radians. Images are
small (64 x 48 by default) so that the NumPy reference renders them in milliseconds.
"""

from __future__ import annotations

import math

import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.rid import (
    RID,
    CosPowerRID,
    GaussianRID,
    IsotropicRID,
    SymmetricTableRID,
    Table2DRID,
)
from lightcal.core.scene import Light, Rig, View

WIDTH = 64
HEIGHT = 48

#: Mild OpenCV distortion (k1, k2, p1, p2, k3): every corner of a 64 x 48 image undistorts.
MILD_DISTORTION = (-0.12, 0.03, 0.0007, -0.0011, -0.004)

RID_NAMES = ("isotropic", "cos_power", "gaussian", "table_1d", "table_2d")


def pinhole_camera(
    *,
    width: int = WIDTH,
    height: int = HEIGHT,
    focal_px: float = 60.0,
    dist: tuple[float, ...] = (),
) -> Camera:
    """A camera with near-square pixels (fy = 1.01 fx) and its principal point off centre."""
    return Camera.from_params(
        fx=focal_px,
        fy=focal_px * 1.01,
        cx=(width - 1) / 2 + 1.3,
        cy=(height - 1) / 2 - 0.7,
        width=width,
        height=height,
        dist=dist,
    )


def distorted_camera(*, width: int = WIDTH, height: int = HEIGHT) -> Camera:
    """`pinhole_camera` with `MILD_DISTORTION`."""
    return pinhole_camera(width=width, height=height, dist=MILD_DISTORTION)


def wide_camera(*, width: int = WIDTH, height: int = HEIGHT) -> Camera:
    """A distortion-free camera with a ~116 x 100 degree field of view."""
    return Camera.from_params(
        fx=20.0, fy=20.0, cx=(width - 1) / 2, cy=(height - 1) / 2, width=width, height=height
    )


def telephoto_camera(*, width: int = WIDTH, height: int = HEIGHT) -> Camera:
    """A long focal length (20,000 px): footprints of ~1e-4 m at a few metres.

    The principal point sits at integer coordinates (31, 23): the optical axis is the
    centre of pixel (31, 23).
    """
    return Camera.from_params(fx=20000.0, fy=20000.0, cx=31.0, cy=23.0, width=width, height=height)


def rotation_about(axis: np.ndarray | tuple[float, float, float], angle_rad: float) -> np.ndarray:
    """(3, 3) rotation by `angle_rad` about `axis` (Rodrigues; right-handed)."""
    k = np.asarray(axis, dtype=np.float64)
    k = k / np.linalg.norm(k)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle_rad) * K + (1.0 - math.cos(angle_rad)) * (K @ K)


def rotation_with_z(z_axis: np.ndarray | tuple[float, float, float]) -> np.ndarray:
    """(3, 3) a rotation whose third column is the unit vector along `z_axis`."""
    z = np.asarray(z_axis, dtype=np.float64)
    z = z / np.linalg.norm(z)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=1)


def oblique_view(*, exposure: float = 1.0) -> View:
    """A camera 1.5 m from the wall looking at it obliquely (about 20 degrees)."""
    return View.looking_at(
        np.array([0.3, -0.4, 1.5]), np.array([-0.1, 0.15, 0.0]), exposure=exposure
    )


def straight_down_view(*, height_m: float = 1.0, exposure: float = 1.0) -> View:
    """A camera at (0, 0, height_m) with its optical axis along -z (image x = world x)."""
    R = np.diag([1.0, -1.0, -1.0])
    center = np.array([0.0, 0.0, height_m])
    return View(R, -R @ center, exposure)


def horizon_view() -> View:
    """A camera 0.5 m above the wall looking almost along it: its upper rows miss the wall."""
    return View.looking_at(
        np.array([0.0, -2.0, 0.5]), np.array([0.0, 3.0, 0.0]), up_world=(0.0, 0.0, 1.0)
    )


def symmetric_table_rid() -> SymmetricTableRID:
    """A measured-looking symmetric profile on 0..80 degrees (axis value 4: normalised)."""
    theta = np.radians([0.0, 10.0, 20.0, 30.0, 45.0, 60.0, 80.0])
    values = 4.0 * np.array([1.0, 0.97, 0.88, 0.72, 0.45, 0.2, 0.03])
    return SymmetricTableRID(theta, values)


def table_2d_values(theta_rad: np.ndarray, phi_rad: np.ndarray) -> np.ndarray:
    """(n_p, n_t) an azimuth-dependent profile: cos(theta)^(2.5 + 1.5 cos phi + 0.8 sin 2 phi)."""
    tt, pp = np.meshgrid(theta_rad, phi_rad)
    exponent = 2.5 + 1.5 * np.cos(pp) + 0.8 * np.sin(2 * pp)
    return np.cos(tt) ** exponent


def table_2d_rid() -> Table2DRID:
    """A non-symmetric 2-D table: 8 uneven azimuth rows (first at 0.2 rad), 0..85 degrees."""
    theta = np.radians([0.0, 8.0, 17.0, 30.0, 45.0, 60.0, 72.0, 85.0])
    phi = np.array([0.2, 0.9, 1.6, 2.5, 3.3, 4.1, 5.0, 5.8])
    return Table2DRID(theta, phi, table_2d_values(theta, phi))


def rid_model(name: str) -> RID:
    """One RID of each model, by name (see `RID_NAMES`)."""
    if name == "isotropic":
        return IsotropicRID()
    if name == "cos_power":
        return CosPowerRID(3.7)
    if name == "gaussian":
        return GaussianRID(0.45)
    if name == "table_1d":
        return symmetric_table_rid()
    if name == "table_2d":
        return table_2d_rid()
    raise KeyError(name)


def two_light_rig(rid: RID) -> Rig:
    """Two lights of the same RID beside the camera, tilted differently, scales 1.7 and 0.6."""
    first = Light(
        rid,
        np.array([0.12, -0.05, 0.02]),
        rotation_with_z((-0.15, 0.1, 1.0)) @ rotation_about((0, 0, 1), 0.4),
        scale=1.7,
        name="left",
    )
    second = Light(
        rid,
        np.array([-0.2, 0.08, -0.03]),
        rotation_with_z((0.25, -0.05, 1.0)) @ rotation_about((0, 0, 1), -1.1),
        scale=0.6,
        name="right",
    )
    return Rig((first, second))


def mixed_rig() -> Rig:
    """Six lights, one of each RID model plus a second, differently sized 2-D table."""
    theta = np.radians([0.0, 20.0, 50.0, 88.0])
    phi = np.linspace(0.0, 2 * math.pi, 11, endpoint=False) + 0.1
    coarse_2d = Table2DRID(theta, phi, table_2d_values(theta, phi) + 0.05)
    rids = [rid_model(name) for name in RID_NAMES] + [coarse_2d]
    lights = []
    for k, rid in enumerate(rids):
        angle = 2 * math.pi * k / len(rids)
        t = np.array([0.15 * math.cos(angle), 0.1 * math.sin(angle), 0.01 * k])
        axis = np.array([0.1 * math.sin(angle), -0.08 * math.cos(angle), 1.0])
        R = rotation_with_z(axis) @ rotation_about((0, 0, 1), 0.9 * k)
        lights.append(Light(rid, t, R, scale=0.5 + 0.3 * k, name=f"light {k}"))
    return Rig(tuple(lights))


def light_fixed_in_world(
    rid: RID, view: View, L_world: np.ndarray, R_world_light: np.ndarray, *, scale: float = 1.0
) -> Light:
    """The light mounted on `view`'s camera that sits at `L_world` with `R_world_light`."""
    R = view.R_camera_world
    return Light(rid, R @ (L_world - view.center_world), R @ R_world_light, scale=scale)


def all_pixels(width: int, height: int) -> np.ndarray:
    """(H * W, 2) every (u, v) of a width x height image, row-major."""
    vv, uu = np.meshgrid(np.arange(height), np.arange(width), indexing="ij")
    return np.stack([uu.ravel(), vv.ravel()], axis=1)
