"""Work arrays and per-evaluation state of `CalibrationModel`'s image systems."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lightcal.core.medium import Medium
from lightcal.core.scene import Rig
from lightcal.core.wall import WallReflectance


class SystemBuffers:
    """Work arrays reused across images and evaluations: fresh multi-MB arrays cost a
    page fault per 4 kB on first touch (~10 ms per 375,000-pixel image system)."""

    def __init__(self) -> None:
        self._system = np.empty(0)
        self._grad = np.empty(0)

    def system(self, rows: int, cols: int, zeroed: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """A (rows, cols) Fortran-order array, its columns `zeroed` set to 0 (the others
        hold what the last caller left), and a (rows, 6) C-order one."""
        if self._system.size < rows * cols:
            self._system = np.empty(rows * cols)
        if self._grad.size < rows * 6:
            self._grad = np.empty(rows * 6)
        A = self._system[: rows * cols].reshape((rows, cols), order="F")
        A[:, zeroed] = 0.0
        return A, self._grad[: rows * 6].reshape(rows, 6)


@dataclass(frozen=True)
class StateAtX:
    """What every image's system needs at x: the lights, gains, offset, pose maps, wall,
    medium; `rigs` and `media` per colour channel when channels are solved jointly (the
    first channel's are `rig` and `medium`)."""

    rig: Rig
    gains: np.ndarray
    offset: float
    pose_maps: list[np.ndarray]
    wall: WallReflectance
    medium: Medium
    rigs: tuple[Rig, ...] = ()
    media: tuple[Medium, ...] = ()
    surface_albedos: np.ndarray | None = None  # the surroundings' (None: the declared)

    def rig_of(self, channel: int) -> Rig:
        """The lights, their scales those of `channel`."""
        return self.rigs[channel] if self.rigs else self.rig

    def medium_of(self, channel: int) -> Medium:
        """`channel`'s medium."""
        return self.media[channel] if self.media else self.medium
