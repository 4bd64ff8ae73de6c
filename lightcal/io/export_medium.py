"""The medium of a calibration result (water, haze) as the exporters write it.

The result's `medium` (docs/model.md, "Medium") holds the attenuation (extinction)
coefficient c, the backscatter coefficient beta = sigma_s pi / rho relative to the wall's
diffuse reflectance rho, and the Henyey-Greenstein asymmetry g. Renderers want the
scattering coefficient itself,

    sigma_s = beta rho / pi,

which needs rho: the albedo of the wall the calibration saw, and so the albedo to give
the wall in the renderer's scene (with the emitters' intensity the light's `scale`, a
wall of albedo rho renders rho / pi times lightcal's value and the water's veil
sigma_s / beta times it: the same factor only with this sigma_s). `lightcal export`
takes rho from `--wall-albedo`, else from the project's `surroundings.wall_albedo`; a
medium that scatters and no rho is refused for the renderers' formats (`mitsuba`,
`blender`), which need sigma_s; `opencv` and `ros` write beta as it is. A purely
absorbing medium (beta = 0) needs no rho: sigma_s = 0.

A result in air (c = 0, beta = 0, nothing estimated) has no `ExportMedium`: the exports
are then what they were before media existed, byte for byte.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from lightcal.core.medium import medium_from_description
from lightcal.errors import InputError
from lightcal.io.result_file import ResultFile

__all__ = ["ExportMedium", "check_wall_albedo", "export_medium"]

NAMES = ("attenuation_per_m", "backscatter_per_m", "phase_g")
"""The medium's parameters, in the result's names and order."""


@dataclass(frozen=True)
class ExportMedium:
    """A result's medium.

    Attributes:
        attenuation_per_m: c, the extinction coefficient, 1/m.
        backscatter_per_m: beta = sigma_s pi / rho, 1/m.
        phase_g: g, the Henyey-Greenstein asymmetry.
        estimated: the names (`NAMES`) the calibration estimated.
        sigma: 1-sigma of each estimated parameter (NaN where the result has none).
        source: the result's path, for messages.
    """

    attenuation_per_m: float
    backscatter_per_m: float
    phase_g: float
    estimated: tuple[str, ...]
    sigma: dict[str, float]
    source: str

    def value(self, name: str) -> float:
        return float(getattr(self, name))

    def sigma_of(self, name: str) -> float:
        """The parameter's 1-sigma; NaN when it was given (not estimated)."""
        return self.sigma.get(name, math.nan) if name in self.estimated else math.nan

    @property
    def scatters(self) -> bool:
        return self.backscatter_per_m > 0.0

    def scattering_per_m(self, wall_albedo: float | None) -> float:
        """sigma_s = beta rho / pi, 1/m (module docstring); 0 without scattering.

        Raises:
            InputError: the medium scatters and `wall_albedo` is None; sigma_s exceeds c
                (a single-scattering albedo above 1, no physical medium).
        """
        if not self.scatters:
            return 0.0
        if wall_albedo is None:
            raise InputError(
                self.source,
                f"medium: backscatter_per_m {self.backscatter_per_m:.6g} /m is relative to "
                "the wall's albedo rho (beta = sigma_s pi / rho): the scattering coefficient "
                "needs rho: expected --wall-albedo RHO (or --project with "
                "surroundings.wall_albedo)",
            )
        sigma_s = self.backscatter_per_m * float(wall_albedo) / math.pi
        if sigma_s > self.attenuation_per_m:
            raise InputError(
                self.source,
                f"medium: the scattering coefficient beta rho / pi = {sigma_s:.6g} /m "
                f"(rho {wall_albedo:.6g}) exceeds the attenuation {self.attenuation_per_m:.6g}"
                " /m: expected at most c (a scattering albedo up to 1)",
            )
        return sigma_s

    def albedo(self, wall_albedo: float | None) -> float:
        """The single-scattering albedo sigma_s / c (0 in an absorbing medium)."""
        sigma_s = self.scattering_per_m(wall_albedo)
        return 0.0 if sigma_s == 0.0 else sigma_s / self.attenuation_per_m

    def text(self) -> str:
        """One line: each parameter, its 1-sigma when estimated, else "given"."""
        parts = []
        for name in NAMES:
            how = f"± {self.sigma_of(name):.3g}" if name in self.estimated else "(given)"
            parts.append(f"{name} {self.value(name):.6g} {how}")
        return ", ".join(parts)


def check_wall_albedo(wall_albedo: float | None) -> None:
    """Raises InputError (naming `--wall-albedo`) unless None or in (0, 1]."""
    if wall_albedo is not None and not 0.0 < wall_albedo <= 1.0:
        raise InputError(
            "--wall-albedo", f"expected the wall's albedo in (0, 1], got {wall_albedo!r}"
        )


def export_medium(result: ResultFile, source: str | Path) -> ExportMedium | None:
    """The result's medium, or None in air (c = 0, beta = 0, nothing estimated).

    Raises:
        InputError: naming `source`: the medium's numbers are malformed.
    """
    description = result.medium
    try:
        medium = medium_from_description(description)
    except ValueError as exc:
        raise InputError(source, str(exc)) from None
    c, beta, g = medium.attenuation_per_m, medium.backscatter_per_m, medium.phase_g
    if not (0.0 <= c < math.inf and 0.0 <= beta < math.inf and abs(g) < 1.0):
        raise InputError(
            source,
            f"medium: expected attenuation_per_m and backscatter_per_m >= 0 and |phase_g| < 1, "
            f"got {c!r}, {beta!r}, {g!r}",
        )
    listed, sigmas = description.get("estimated", []), description.get("sigma", {})
    if not isinstance(listed, list) or not isinstance(sigmas, dict | None):
        raise InputError(
            source, "medium: expected estimated a list of names and sigma a mapping of them"
        )
    estimated = tuple(str(n) for n in listed if isinstance(n, str) and n in NAMES)
    if c == 0.0 and beta == 0.0 and not estimated:
        return None
    sigma: dict[str, float] = {}
    for name, value in (sigmas or {}).items():
        if name in NAMES:
            try:
                sigma[name] = math.nan if value is None else float(value)
            except (TypeError, ValueError):
                raise InputError(
                    source, f"medium: sigma: {name}: expected a number, got {value!r}"
                ) from None
    return ExportMedium(
        medium.attenuation_per_m,
        medium.backscatter_per_m,
        medium.phase_g,
        estimated,
        sigma,
        str(source),
    )
