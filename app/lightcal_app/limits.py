"""The ranges every value from a page (or a session file) must be in, in one place.

The widgets carry them as their min/max, the session file's schema checks them, and
`lightcal_app.panels.validation` refuses any value outside them before it reaches the
state. Integers are kept within 0..2^53, which every browser, JSON and msgpack hold.
"""

from __future__ import annotations

import math

import numpy as np

from lightcal.errors import InputError

MAX_INT = 2**53
"""Largest integer any value may take."""

POSITION_LIMIT_M = 10.0
"""A light's position: at most this far from the camera on each axis, m."""

AXIS_ROLL_LIMIT_DEG = 180.0
"""The paper's roll of the light axis (about the camera x axis), deg."""

AXIS_PITCH_LIMIT_DEG = 90.0
"""The paper's pitch of the light axis (about the camera y axis), deg."""

SPIN_LIMIT_DEG = 180.0
"""A general light's spin about its own axis, deg."""

MAX_PIXELS_PER_IMAGE = 1_000_000
MAX_GRID_STEP = 100_000
MAX_BINNING = 64
MAX_SEED = 2**32 - 1
"""Selection settings (NumPy seeds take 0..2^32 - 1 as one number)."""

MAX_NAME_LENGTH = 200
"""Text a page may send (dropdown choices are names)."""


STRATEGIES = ("random", "grid", "all")


def _shown(value: object) -> str:
    """A value as the page sent it, short: numbers plainly, (a, b, c) for sequences."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        return repr(value)[:60]
    if array.ndim == 0:
        return repr(value)[:60]
    items = array.ravel()
    return "(" + ", ".join(f"{v:g}" for v in items[:9]) + (", ..." if items.size > 9 else "") + ")"


def _refuse(field: str, expected: str, value: object) -> InputError:
    return InputError(field, f"expected {expected}, got {_shown(value)}")


def check_int(field: str, value: object, low: int, high: int) -> int:
    """An integer in [low, high] (a float with an integral value is accepted)."""
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):
        raise _refuse(field, f"an integer from {low} to {high}", value) from None
    if not (math.isfinite(number) and number == int(number) and low <= number <= high):
        raise _refuse(field, f"an integer from {low} to {high}", value)
    return int(number)


def check_position_m(value: object) -> np.ndarray:
    """A light position: 3 finite numbers within +-POSITION_LIMIT_M, m."""
    try:
        p = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise _refuse("light position", "3 numbers", value) from None
    limit_mm = POSITION_LIMIT_M * 1e3
    if p.shape != (3,) or not np.all(np.isfinite(p)) or np.any(np.abs(p) > POSITION_LIMIT_M):
        raise _refuse("light position", f"3 finite numbers within +-{limit_mm:g} mm", value)
    return p


def check_rotation(value: object) -> np.ndarray:
    """A light orientation: a finite (3, 3) rotation matrix."""
    try:
        R = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise _refuse("light orientation", "a 3 x 3 rotation", value) from None
    if R.shape != (3, 3) or not np.all(np.isfinite(R)) or not np.allclose(R @ R.T, np.eye(3)):
        raise _refuse("light orientation", "a 3 x 3 rotation (finite angles)", "...")
    return R


def check_selection(
    strategy: object, n: object, step: object, binning: object, seed: object
) -> tuple[str, int, int, int, int]:
    """The pixel selection settings a page sent, checked: (strategy, n, step, binning, seed)."""
    if strategy not in STRATEGIES:
        raise _refuse("strategy", "one of " + ", ".join(STRATEGIES), strategy)
    return (
        str(strategy),
        check_int("pixels per image", n, 1, MAX_PIXELS_PER_IMAGE),
        check_int("grid step", step, 1, MAX_GRID_STEP),
        check_int("binning", binning, 1, MAX_BINNING),
        check_int("seed", seed, 0, MAX_SEED),
    )


PLAN_MAX_VIEWS = 6
"""The most views the Plan tab suggests at once."""

PLAN_WALL_SIZE_M = (0.2, 100.0)
"""The wall size (width and height) the Plan tab's candidates stay within, m."""


def check_plan(n: object, wall_size_m: object) -> tuple[int, float]:
    """The Plan tab's (views to suggest, wall size in m), checked.

    Raises:
        InputError: naming the value, when it is not a whole number of views in
            1..PLAN_MAX_VIEWS or a wall size in PLAN_WALL_SIZE_M.
    """
    if isinstance(n, bool) or not isinstance(n, (int, float)) or int(n) != n:
        raise InputError("views to suggest", f"expected a whole number, got {n!r}")
    if not 1 <= int(n) <= PLAN_MAX_VIEWS:
        raise InputError("views to suggest", f"expected 1 to {PLAN_MAX_VIEWS}, got {int(n)}")
    lo, hi = PLAN_WALL_SIZE_M
    size = float(wall_size_m)  # type: ignore[arg-type]
    if not (math.isfinite(size) and lo <= size <= hi):
        raise InputError("wall size (m)", f"expected {lo:g} to {hi:g} m, got {wall_size_m!r}")
    return int(n), size
