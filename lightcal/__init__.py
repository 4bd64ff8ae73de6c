"""lightcal: calibrate where a light sits and points relative to its camera.

The Python API (`lightcal.api`, docs/api.md): `load_project`, `calibrate`,
`read_result`, `render`, `export`, `plan`, `ensure_compiled` and their result types
`Project`, `Calibration`, `ResultFile`, `Plan`. They are attributes of this package,
loaded on first use (PEP 562): `import lightcal` itself imports nothing else, so the
command line's `--help` stays fast.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

API = (
    "COMPILE_MESSAGE",
    "Calibration",
    "Plan",
    "Project",
    "ResultFile",
    "calibrate",
    "ensure_compiled",
    "export",
    "load_project",
    "plan",
    "read_result",
    "render",
)

__all__ = ["__version__", *API]

if TYPE_CHECKING:
    from lightcal.api import (  # noqa: F401
        COMPILE_MESSAGE,
        Calibration,
        Plan,
        Project,
        ResultFile,
        calibrate,
        ensure_compiled,
        export,
        load_project,
        plan,
        read_result,
        render,
    )


def __getattr__(name: str) -> Any:
    """The API's names, from `lightcal.api` when first asked for.

    (By module name: `lightcal.api` sits above every layer it uses, which import this
    package for its version; the package imports nothing of them when it is imported.)
    """
    if name in API:
        value = getattr(importlib.import_module(f"{__name__}.api"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *API])
