"""The names of the synthetic lights' angular profiles (`LightModel`).

Apart from `scenes` so that `lightcal synth --help` lists them without importing NumPy
and the renderer (the CLI builds its parser from cheap imports only).
"""

from __future__ import annotations

from typing import Literal, get_args

__all__ = ["LIGHT_MODELS", "LightModel"]

LightModel = Literal["isotropic", "cos_power", "gaussian", "table", "table2d", "ies"]
"""Angular profile of a synthetic light.

`table` and `ies` are the same rotationally symmetric measured-like profile
(`symmetric_profile_table`), written as a CSV or an axial IES file; `table2d` is a
lopsided elliptical beam without rotational symmetry (`elliptical_beam_table`).
"""

LIGHT_MODELS: tuple[str, ...] = get_args(LightModel)
