"""In-memory description of what is rendered: views of the wall, lights, the rig.

Frames (docs/conventions.md): world W has the wall at z = 0 with cameras at z > 0;
camera C is OpenCV's; light L has +z along its axis. A view carries `T_camera_world`;
a light carries `T_camera_light`, the same for every view.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from lightcal.core.flat_port import FlatPort
from lightcal.core.rid import RID
from lightcal.core.rotations import as_finite_array, check_rotation_matrix


@dataclass(frozen=True, eq=False)
class View:
    """One image of the wall: its camera pose and exposure.

    Args:
        R_camera_world: (3, 3) rotation world -> camera.
        t_camera_world: (3,) translation, m: X_c = R X_w + t.
        exposure: relative exposure g_i (> 0): time x ISO / f-number^2, normalised.
    """

    R_camera_world: np.ndarray
    t_camera_world: np.ndarray
    exposure: float = 1.0
    center_world: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        R = check_rotation_matrix(self.R_camera_world, name="R_camera_world")
        t = as_finite_array(self.t_camera_world, (3,), name="t_camera_world")
        if not (math.isfinite(self.exposure) and self.exposure > 0.0):
            raise ValueError(f"exposure: expected a finite value > 0, got {self.exposure}")
        center = -R.T @ t
        if center[2] <= 0.0:
            raise ValueError(
                f"camera pose: the camera centre is at z = {center[2]:.4g} m, "
                "on or behind the wall; expected z > 0 "
                "(the wall is z = 0 and cameras look at it from z > 0)"
            )
        object.__setattr__(self, "R_camera_world", R)
        object.__setattr__(self, "t_camera_world", t)
        object.__setattr__(self, "center_world", center)

    @classmethod
    def looking_at(
        cls,
        center_world: np.ndarray,
        target_world: np.ndarray,
        *,
        up_world: tuple[float, float, float] = (0.0, -1.0, 0.0),
        exposure: float = 1.0,
    ) -> View:
        """A view whose optical axis runs from `center_world` (3,) to `target_world` (3,).

        The camera's y axis (image down) is aligned with -`up_world` as far as possible.
        """
        c = as_finite_array(center_world, (3,), name="center_world")
        z = as_finite_array(target_world, (3,), name="target_world") - c
        if np.linalg.norm(z) == 0.0:
            raise ValueError("target_world: expected a point different from center_world")
        z = z / np.linalg.norm(z)
        x = np.cross(-np.asarray(up_world, dtype=np.float64), z)
        if np.linalg.norm(x) < 1e-9:
            raise ValueError("up_world: expected a direction not parallel to the optical axis")
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        R = np.stack([x, y, z])  # rows: camera axes in world coordinates
        return cls(R, -R @ c, exposure)


@dataclass(frozen=True, eq=False)
class Light:
    """A light rigidly mounted on the camera.

    Args:
        rid: its relative radiant intensity distribution.
        t_camera_light: (3,) emitter position in the camera frame, m.
        R_camera_light: (3, 3) rotation light -> camera (light +z is its axis).
        scale: the global scale k of docs/model.md (I0 x albedo / pi x sensor gain), > 0.
        name: a label for results and the viewer.
        port: the flat window of its underwater housing (a `FlatPort` in the light
            frame: its normal `normal_camera` is the light frame's, by default the axis
            +z), or None: the light shines straight into the medium
            (docs/model.md, "The light's flat port").
    """

    rid: RID
    t_camera_light: np.ndarray
    R_camera_light: np.ndarray = field(default_factory=lambda: np.eye(3))
    scale: float = 1.0
    name: str = "light"
    port: FlatPort | None = None

    def __post_init__(self) -> None:
        object.__setattr__(
            self,
            "t_camera_light",
            as_finite_array(self.t_camera_light, (3,), name="t_camera_light"),
        )
        object.__setattr__(
            self,
            "R_camera_light",
            check_rotation_matrix(self.R_camera_light, name="R_camera_light"),
        )
        if not (math.isfinite(self.scale) and self.scale > 0.0):
            raise ValueError(f"light scale: expected a finite value > 0, got {self.scale}")

    @property
    def axis_camera(self) -> np.ndarray:
        """(3,) unit light axis in the camera frame."""
        return self.R_camera_light[:, 2].copy()

    def position_world(self, view: View) -> np.ndarray:
        """(3,) emitter position in the world frame for `view`, m."""
        return view.center_world + view.R_camera_world.T @ self.t_camera_light

    def rotation_world(self, view: View) -> np.ndarray:
        """(3, 3) R_world_light for `view`."""
        return view.R_camera_world.T @ self.R_camera_light

    def replace(self, **changes: object) -> Light:
        """A copy with some fields changed (validated again)."""
        fields = {
            "rid": self.rid,
            "t_camera_light": self.t_camera_light,
            "R_camera_light": self.R_camera_light,
            "scale": self.scale,
            "name": self.name,
            "port": self.port,
        }
        fields.update(changes)
        return Light(**fields)  # type: ignore[arg-type]


@dataclass(frozen=True)
class Rig:
    """The lights mounted on one camera (one or more, their contributions add up)."""

    lights: tuple[Light, ...]

    def __post_init__(self) -> None:
        if len(self.lights) == 0:
            raise ValueError("rig: expected at least one light")
        object.__setattr__(self, "lights", tuple(self.lights))

    @classmethod
    def single(cls, light: Light) -> Rig:
        return cls((light,))


def with_view(view: View, **changes: object) -> View:
    """A copy of a view with some fields replaced."""
    fields: dict[str, object] = {
        "R_camera_world": view.R_camera_world,
        "t_camera_world": view.t_camera_world,
        "exposure": view.exposure,
    }
    fields.update(changes)
    return View(**fields)  # type: ignore[arg-type]
