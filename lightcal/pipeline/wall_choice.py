"""The wall in the solve: mirror exclusion and the `auto` model choice.

- `selection.exclude_mirror_deg: X`: after the first convergence, the pixels whose half
  vector lies within X deg of the wall normal (where gloss concentrates) are dropped and the
  solve continues from the estimate; the angles are those of the estimate.
- `wall: {model: auto}`: fit Lambertian and test the fit (`lightcal.core.misfit`); where it
  has a finding, fit `plastic` if the test's `gloss` cause is significant and `oren_nayar`
  if its `rough_matte` cause is (`auto_candidates`), each from the Lambertian estimate,
  and keep the model with the lowest Bayesian information criterion BIC = chi^2 + k ln m
  (noise known) or m ln(RSS / m) + k ln m (noise unknown), k the parameter count and m the
  pixel count, among those whose wall parameters the data determine (`undetermined_wall`:
  a 1-sigma no larger than the value); Lambertian is always determined.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from lightcal.core.misfit import pixel_angles
from lightcal.core.model_rebuild import rebuilt
from lightcal.core.problem import WallUnknown
from lightcal.core.solver import CalibrationModel, SolveOutcome
from lightcal.core.wall import WALL_MODELS
from lightcal.errors import InputError
from lightcal.pipeline.results import CalibrationResult

#: The models `auto` tries after Lambertian, in order, and the fit test's cause that
#: calls for each.
AUTO_CANDIDATES = ("plastic", "oren_nayar")
AUTO_CAUSES = {"plastic": "gloss", "oren_nayar": "rough_matte"}


def auto_candidates(fit: dict) -> list[str]:
    """The wall models `auto` should try after a Lambertian fit whose test (`fit`, the
    result's dict) has a finding: those whose cause is significant with a relative effect
    of at least the fit test's floor."""
    floor = fit.get("floors", {}).get("relative_effect", 0.0)
    causes = {
        c["cause"]: c
        for c in fit.get("causes", [])
        if c.get("significant") and (c.get("relative_effect") or 0.0) >= floor
    }
    return [name for name in AUTO_CANDIDATES if AUTO_CAUSES[name] in causes]


def undetermined_wall(wall: dict) -> bool:
    """A wall model whose estimated parameter has a 1-sigma above its value (or none)."""
    sigma = wall.get("sigma", {})
    for name in wall.get("estimated", []):
        value, s = wall.get(name), sigma.get(name)
        if not isinstance(value, float) or s is None or not math.isfinite(s):
            return True
        if s > abs(value):
            return True
    return False


def restarted(model: CalibrationModel, x: np.ndarray, **changes: object) -> CalibrationModel:
    """A model like `model` (images, lights, options, wall, medium replaced by `changes`) whose
    lights start at their estimate in x."""
    lights = [
        replace(u, initial=model.layout.light_of(b, x))
        for u, b in zip(model.unknowns, model.layout.blocks, strict=True)
    ]
    return rebuilt(model, **({"unknowns": lights} | changes))


def start_from(model: CalibrationModel, old: CalibrationModel, x: np.ndarray) -> np.ndarray:
    """`model`'s start vector with every parameter `old` also has (by name) taken from x."""
    index = {name: k for k, name in enumerate(old.layout.names)}
    x0 = model.layout.x0.copy()
    for k, name in enumerate(model.layout.names):
        if name in index:
            x0[k] = x[index[name]]
    return x0


def mirror_angles(model: CalibrationModel, x: np.ndarray) -> list[np.ndarray]:
    """Per image (N_i,) the angle between the wall normal and the half vector, degrees,
    for the light nearest each pixel's mirror direction."""
    rig = model.layout.rig(x)
    out = []
    for im in model.images:
        angles = np.full(len(im.observed), np.inf)
        for light in rig.lights:
            a, _ = pixel_angles(
                im.footprints.centers_world, light.position_world(im.view), im.view.center_world
            )
            angles = np.minimum(angles, a)
        out.append(angles)
    return out


def without_mirror(
    model: CalibrationModel, x: np.ndarray, limit_deg: float, source: str | Path
) -> tuple[CalibrationModel, int]:
    """The model without the pixels within `limit_deg` of the mirror direction at x, and
    how many pixels it dropped."""
    images = []
    dropped = 0
    for im, a in zip(model.images, mirror_angles(model, x), strict=True):
        keep = a >= limit_deg
        dropped += int(np.count_nonzero(~keep))
        if keep.any():
            images.append(im.subset(keep))
    if not images or sum(len(im.observed) for im in images) <= model.layout.n:
        raise InputError(
            source,
            f"selection.exclude_mirror_deg: {limit_deg:g} deg leaves fewer pixels than the "
            f"{model.layout.n} parameters; use a smaller angle",
        )
    return restarted(model, x, images=images), dropped


def bic(result: CalibrationResult, model: CalibrationModel) -> float:
    """The Bayesian information criterion of a solved model (lower is better)."""
    fit = result.fit
    m, k = model.m, model.layout.n
    chi2 = float(fit["chi2"])
    if fit.get("noise_source", "none") == "none":
        return m * math.log(max(chi2, 1e-300) / m) + k * math.log(m)
    return chi2 + k * math.log(m)


@dataclass(frozen=True)
class Candidate:
    """One wall model tried by `auto`."""

    name: str
    model: CalibrationModel
    outcome: SolveOutcome
    result: CalibrationResult
    bic: float


def wall_candidate(model: CalibrationModel, x: np.ndarray, name: str) -> CalibrationModel:
    """A model with the `name` wall (default parameters and estimates), lights from x."""
    cls = WALL_MODELS[name]
    wall = WallUnknown(cls(), cls.default_estimate)
    return restarted(model, x, wall=wall)


def candidate_named(model: CalibrationModel, names: list[str]) -> CalibrationModel | None:
    """The `auto` candidate of `model` whose parameters are `names` (a solve that chose
    that wall, restored from its parameter names), or None."""
    for name in AUTO_CANDIDATES:
        candidate = wall_candidate(model, model.layout.x0, name)
        if list(candidate.layout.names) == names:
            return candidate
    return None


def choice_note(chosen: Candidate, candidates: list[Candidate]) -> str:
    """The sentence the result carries about what `auto` chose."""
    others = ", ".join(
        f"{c.name} {c.bic:.1f}"
        + (" (parameters undetermined)" if undetermined_wall(c.result.wall) else "")
        for c in candidates
        if c is not chosen
    )
    return f"wall: auto chose {chosen.name} (BIC {chosen.bic:.1f}; {others})"
