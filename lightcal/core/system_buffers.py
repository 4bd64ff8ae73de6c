"""Work arrays the calibration model reuses across images and evaluations."""

from __future__ import annotations

import numpy as np

__all__ = ["SystemBuffers"]


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
