"""The garbage collector's settings for the `lightcal` process.

Python's cyclic collector walks every tracked object in a full collection. After the
imports (numba, SciPy, viser) that is ~170,000 objects: 77-88 ms per full collection
in the app with the sample project (measured), a pause as long as a solver step.
Arrays are freed by their reference counts whatever the collector does.

- A short command (`lightcal calibrate`, ...): full collections 10x rarer while it
  runs (the imports alone triggered two, 0.1 s), and everything frozen for the
  interpreter's exit, whose final collections took 0.25-0.45 s.
- The app, a process that runs for hours: what exists once it has started (modules,
  compiled kernels, the first project) frozen out of the collector's walks (a full
  collection then takes ~0.1 ms), and Python's own thresholds back, so the cyclic
  garbage of hours of use is collected as usual.
"""

from __future__ import annotations

import gc

PYTHON_THRESHOLDS = gc.get_threshold()  # the interpreter's, read before a command sets any
COMMAND_THRESHOLDS = (700, 10, 100)


def for_a_command() -> None:
    """Full collections made rarer (before a command runs)."""
    gc.set_threshold(*COMMAND_THRESHOLDS)


def for_the_exit() -> None:
    """Every object left frozen: the interpreter's final collections skip them."""
    gc.freeze()


def for_a_server() -> None:
    """The start-up's objects frozen, Python's thresholds back (a long-running process)."""
    gc.freeze()
    gc.set_threshold(*PYTHON_THRESHOLDS)
