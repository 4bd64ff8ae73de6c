"""The calibrated light pose in other programs' camera and light conventions.

lightcal's camera frame is OpenCV's (docs/conventions.md): x right, y down, z forward
along the optical axis. Its light frame has +z along the light's axis. The pose is
`T_camera_light` (4, 4), mapping light-frame coordinates to camera-frame coordinates.

Blender
-------
- A Blender camera object looks down its local **-Z** with **+Y up** and +X right.
  The OpenCV camera frame maps to it by a 180 degree turn about x:
  `R_blendercam_opencv = diag(1, -1, -1)` (x stays, y down -> y up, z forward -> -z).
- A Blender spot (or area) light shines along its local **-Z**. Its local frame is the
  lightcal light frame turned 180 degrees about x: `R_light_blenderspot = diag(1, -1, -1)`
  (the azimuth reference +x is kept).
- The light object's matrix in the camera object's frame (what `matrix_local` of a light
  parented to the camera, with an identity parent inverse, must be) is therefore
  `M = F T_camera_light G` with `F = G = diag(1, -1, -1, 1)`; `F` and `G` are their own
  inverses, so `T_camera_light = F M G`.
- Spot cone: Blender's `spot_size` is the full cone angle and `spot_blend` the softness
  of its edge (a smoothstep over the outer `spot_blend` fraction of `1 - cos(size / 2)` in
  cosine). lightcal picks `spot_blend = 1` and the size that puts the smoothstep's 50 %
  point on the RID's half angle h: cos(size / 2) = 2 cos(h) - 1. An approximation: a
  spot cannot follow a measured profile.

Mitsuba 3
---------
- A Mitsuba perspective sensor looks down its local **+Z** with **+Y up**; its film's x
  runs towards its local **-X** (Mitsuba's `to_sample` scales x by -1/2), so +X is
  left in the image. The OpenCV camera frame maps to it by a 180 degree turn about z:
  `R_mitsubacam_opencv = diag(-1, -1, 1)`.
- A Mitsuba `spot` emitter shines along its local +Z, as lightcal's light frame; its
  `to_world` in the Mitsuba camera frame is `F_m T_camera_light` with
  `F_m = diag(-1, -1, 1, 1)`. Placing the camera in a scene with sensor `to_world` S, the
  light's `to_world` is `S F_m T_camera_light`.
- Spot cone: intensity 1 within `beam_width`, falling linearly in angle to 0 at
  `cutoff_angle`. Without a RID texture lightcal puts the ramp's middle on the RID's half
  angle h: cutoff = min(2 h, 90 degrees), beam_width = 2 h - cutoff. With a texture
  (`lightcal.io.export_mitsuba.spot_texture`) beam_width = cutoff and the texture is the RID.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lightcal.core.rotations import as_finite_array, check_rotation_matrix

__all__ = [
    "F_BLENDER",
    "F_MITSUBA",
    "blender_from_opencv",
    "blender_spot_cone",
    "mitsuba_from_opencv",
    "mitsuba_spot_cone",
    "opencv_from_blender",
    "opencv_from_mitsuba",
    "transform_camera_light",
]

F_BLENDER: NDArray[np.float64] = np.diag([1.0, -1.0, -1.0, 1.0])
"""(4, 4) Blender camera <- OpenCV camera; also lightcal light <- Blender spot light."""

F_MITSUBA: NDArray[np.float64] = np.diag([-1.0, -1.0, 1.0, 1.0])
"""(4, 4) Mitsuba camera <- OpenCV camera."""

for _matrix in (F_BLENDER, F_MITSUBA):
    _matrix.flags.writeable = False


def transform_camera_light(R_camera_light: ArrayLike, t_camera_light: ArrayLike) -> NDArray:
    """The (4, 4) homogeneous `T_camera_light` from R (3, 3) and t (3,) (metres)."""
    R = check_rotation_matrix(R_camera_light, name="R_camera_light")
    t = as_finite_array(t_camera_light, (3,), name="t_camera_light")
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def blender_from_opencv(T_camera_light: ArrayLike) -> NDArray[np.float64]:
    """(4, 4) light object's matrix in the Blender camera's frame, spot along its -Z."""
    T = as_finite_array(T_camera_light, (4, 4), name="T_camera_light")
    return F_BLENDER @ T @ F_BLENDER


def opencv_from_blender(M_blendercam_spot: ArrayLike) -> NDArray[np.float64]:
    """The inverse of `blender_from_opencv`: (4, 4) `T_camera_light`."""
    M = as_finite_array(M_blendercam_spot, (4, 4), name="M_blendercam_spot")
    return F_BLENDER @ M @ F_BLENDER


def mitsuba_from_opencv(T_camera_light: ArrayLike) -> NDArray[np.float64]:
    """(4, 4) the spot emitter's `to_world` in the Mitsuba camera's frame."""
    T = as_finite_array(T_camera_light, (4, 4), name="T_camera_light")
    return F_MITSUBA @ T


def opencv_from_mitsuba(to_world_mitsubacam: ArrayLike) -> NDArray[np.float64]:
    """The inverse of `mitsuba_from_opencv`: (4, 4) `T_camera_light`."""
    M = as_finite_array(to_world_mitsubacam, (4, 4), name="to_world_mitsubacam")
    return F_MITSUBA @ M


def blender_spot_cone(half_angle_rad: float) -> tuple[float, float]:
    """Blender's `(spot_size, spot_blend)` (radians, 0..1) for a RID's half angle."""
    cos_edge = max(2.0 * math.cos(half_angle_rad) - 1.0, -1.0)
    return 2.0 * math.acos(cos_edge), 1.0


def mitsuba_spot_cone(half_angle_rad: float) -> tuple[float, float]:
    """Mitsuba's `(cutoff_angle, beam_width)` in degrees for a RID's half angle."""
    half_deg = math.degrees(half_angle_rad)
    cutoff_deg = min(2.0 * half_deg, 90.0)
    return cutoff_deg, max(2.0 * half_deg - cutoff_deg, 0.0)
