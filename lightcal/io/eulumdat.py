"""Read and write EULUMDAT (`.ldt`) photometric files.

EULUMDAT has a fixed line layout, one field per line:

| line | field |
|---|---|
| 1 | company identification |
| 2 | Ityp, type indicator |
| 3 | Isym, symmetry indicator (0..4, below) |
| 4 | Mc, number of C-planes in 0..360 |
| 5 | Dc, distance between C-planes (0: not equidistant) |
| 6 | Ng, number of intensities (gamma angles) per C-plane |
| 7 | Dg, distance between gamma angles (0: not equidistant) |
| 8-12 | measurement report, luminaire name, luminaire number, file name, date/user |
| 13-21 | luminaire and luminous-area dimensions (mm) |
| 22-23 | downward flux fraction, light output ratio (%) |
| 24 | conversion factor for the luminous intensities |
| 25 | tilt of the luminaire during the measurement (not applied) |
| 26 | n, number of standard sets of lamps |
| 26a-f | per lamp set, 6 lines: number of lamps (< 0: absolute photometry), lamp type, |
| | total lamp flux (lm), colour, colour rendering, wattage |
| +10 | direct ratios for room indices 0.6 .. 5 |
| +Mc | the C angles (degrees) |
| +Ng | the gamma angles (degrees) |
| rest | intensities in cd/klm, Ng per stored C-plane, plane after plane |

Which C-planes are stored, as indices into the list of C angles (the EULUMDAT
specification's Mc1..Mc2), and the table symmetry they become:

| Isym | stored planes | symmetry |
|---|---|---|
| 0 | all Mc: C0 .. C(360 - Dc) | `none` |
| 1 | one plane (the C angles are ignored) | `axial` |
| 2 | Mc/2 + 1: C0 .. C180 | `bilateral_0_180` |
| 3 | Mc/2 + 1: C270 .. C360 = C0 .. C90 (Mc1 = 3 Mc/4 + 1, wrapping) | `bilateral_90_270` |
| 4 | Mc/4 + 1: C0 .. C90 | `quadrant` |

For Isym 3 the planes C270 .. C0 .. C90 are mirrored (C -> 180 - C) onto 90 .. 270,
the horizontal angles the table stores. Some programs write Isym 3 files with the
planes C90 .. C270 instead; read with this module such a file is turned by 180 degrees
about the light axis, which the calibrated pose absorbs.

Intensities are converted from cd/klm to candela with the total lamp flux of the first
lamp set (the other sets are alternative lamps) times the conversion factor:
cd = cd/klm x flux / 1000 x factor. A file without a lamp flux (no lamp set, or a flux
of 0) keeps cd/klm x factor. The RID is relative, so this scale never changes it.
Numbers may use a decimal comma. How the table maps onto the light frame is described
in `lightcal.io.photometric_table`.

Every error is an `InputError` naming the file and the line (for a file that ends too
early, its last line).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from lightcal.errors import InputError
from lightcal.io.escaping import plain_line
from lightcal.io.photometric_table import (
    PhotometricTable,
    Symmetry,
    expand_full,
    format_number,
    parse_number,
    read_text_file,
    write_text_file_atomic,
)

__all__ = ["read_ldt", "write_ldt"]

_SYMMETRY_OF_ISYM: dict[int, Symmetry] = {
    0: "none",
    1: "axial",
    2: "bilateral_0_180",
    3: "bilateral_90_270",
    4: "quadrant",
}
_ISYM_OF_SYMMETRY = {symmetry: isym for isym, symmetry in _SYMMETRY_OF_ISYM.items()}
_LINES_PER_LAMP_SET = 6
_N_DIRECT_RATIOS = 10
_MAX_TEXT_CHARS = 78  # EULUMDAT text lines (company, luminaire name): at most 78
_AXIAL_MC = 24
"""C-planes declared for an axially symmetric table written by `write_ldt` (Dc = 15)."""


@dataclass
class _Lines:
    """The file's lines, read by 1-based line number."""

    path: Path
    lines: list[str]

    def text(self, number: int, what: str) -> str:
        if number > len(self.lines):
            raise InputError(
                self.path,
                f"unexpected end of file: expected line {number}, {what}",
                line=max(len(self.lines), 1),
            )
        return self.lines[number - 1].strip()

    def number(self, number: int, what: str) -> float:
        text = self.text(number, what)
        candidate = text.replace(",", ".") if "," in text and "." not in text else text
        return parse_number(self.path, text, what, number, value=candidate)

    def integer(self, number: int, what: str, minimum: int | None) -> int:
        value = self.number(number, what)
        if value != int(value) or (minimum is not None and value < minimum):
            expected = "an integer" if minimum is None else f"an integer >= {minimum}"
            raise InputError(self.path, f"{what} {value:g}: expected {expected}", line=number)
        return int(value)


def _stored_plane_indices(isym: int, mc: int) -> list[int]:
    """Indices into the C-angle list of the planes an Isym stores, in file order."""
    if isym == 0:
        return list(range(mc))
    if isym == 1:
        return [0]
    if isym == 2:
        return list(range(mc // 2 + 1))
    if isym == 3:
        return [(3 * mc // 4 + k) % mc for k in range(mc // 2 + 1)]
    return list(range(mc // 4 + 1))


def read_ldt(path: str | Path) -> PhotometricTable:
    """Read an EULUMDAT file (format in the module docstring).

    Args:
        path: The `.ldt` file.

    Returns:
        The table in candela (see the module docstring for the cd/klm conversion);
        `lamp_lumens` is the first lamp set's total flux (None for absolute photometry or
        when the file gives no flux); `luminaire` is line 9.

    Raises:
        InputError: Naming the file and line: a field that is not a number, Isym outside
            0..4, Mc that does not fit Isym, angles that do not increase or are out of
            range, stored C-planes that are not where Isym puts them, a conversion factor
            <= 0, a negative intensity, too few lines (at the last line) or lines left over.
    """
    path = Path(path)
    lines = read_text_file(path).splitlines()
    if not any(line.strip() for line in lines):
        raise InputError(path, "the file is empty: expected an EULUMDAT file")
    f = _Lines(path, lines)
    f.integer(2, "type indicator Ityp", 0)
    isym = f.integer(3, "symmetry indicator Isym", 0)
    if isym not in _SYMMETRY_OF_ISYM:
        raise InputError(path, f"symmetry indicator Isym {isym}: expected 0, 1, 2, 3 or 4", line=3)
    mc = f.integer(4, "number of C-planes Mc", 1)
    divisor = {0: 1, 1: 1, 2: 2, 3: 4, 4: 4}[isym]
    if mc % divisor != 0:
        raise InputError(
            path,
            f"number of C-planes Mc {mc}: expected a multiple of {divisor} for Isym {isym}",
            line=4,
        )
    if isym == 0 and mc < 2:
        raise InputError(
            path, f"number of C-planes Mc {mc}: expected at least 2 for Isym 0", line=4
        )
    f.number(5, "distance between C-planes Dc")
    ng = f.integer(6, "number of intensities per C-plane Ng", 2)
    f.number(7, "distance between intensities Dg")
    luminaire = f.text(9, "luminaire name")
    factor = f.number(24, "conversion factor for luminous intensities")
    if factor <= 0.0:
        raise InputError(
            path,
            f"conversion factor for luminous intensities {factor:g}: expected a value > 0",
            line=24,
        )
    n_sets = f.integer(26, "number of standard sets of lamps n", 0)
    flux = 0.0
    n_lamps = 0
    if n_sets > 0:
        n_lamps = f.integer(27, "number of lamps of lamp set 1", None)
        flux = f.number(29, "total luminous flux of lamp set 1 (lm)")
    c_line = 26 + _LINES_PER_LAMP_SET * n_sets + _N_DIRECT_RATIOS + 1
    # Counts the file cannot hold are refused before anything is allocated by them (a
    # file that is merely short gets the line-precise message below).
    stored = {0: mc, 1: 1, 2: mc // 2 + 1, 3: mc // 2 + 1, 4: mc // 4 + 1}[isym]
    needed = c_line - 1 + mc + ng + stored * ng
    if needed > max(len(lines), 1_000_000):
        raise InputError(
            path,
            f"the counts (Mc {mc} C-planes, Ng {ng} intensities each, {n_sets} lamp sets) "
            f"demand {needed} lines, the file has {len(lines)}",
        )
    c_angles = _read_angles(f, c_line, mc, "C", 0.0, 360.0, upper_open=True)
    g_line = c_line + mc
    gamma = _read_angles(f, g_line, ng, "gamma", 0.0, 180.0, upper_open=False)

    indices = _stored_plane_indices(isym, mc)
    placed = {
        0: [(0, 0.0)],
        2: [(0, 0.0), (mc // 2, 180.0)],
        3: [(3 * mc // 4, 270.0), (mc // 4, 90.0)],
        4: [(0, 0.0), (mc // 4, 90.0)],
    }
    for index, angle in placed.get(isym, []):
        if c_angles[index] != angle:
            raise InputError(
                path,
                f"C angle {index + 1} of {mc} is {c_angles[index]:g}: expected {angle:g}, "
                f"where Isym {isym} puts a stored C-plane",
                line=c_line + index,
            )
    stored_angles = np.array([0.0]) if isym == 1 else c_angles[indices]

    i_line = g_line + ng
    cd_per_klm = np.empty((len(indices), ng))
    for p, c in enumerate(stored_angles):
        for j in range(ng):
            number = i_line + p * ng + j
            what = f"intensity {j + 1} of {ng} in C-plane {c:g}"
            value = f.number(number, what)
            if value < 0.0:
                raise InputError(
                    path, f"{what} is negative ({value:g}): expected values >= 0", line=number
                )
            cd_per_klm[p, j] = value
    end = i_line + len(indices) * ng
    for number in range(end, len(lines) + 1):
        if lines[number - 1].strip():
            raise InputError(
                path,
                f"unexpected line after the intensities: Isym {isym} with Mc {mc} and Ng {ng} "
                f"stores {len(indices)} C-planes x {ng} intensities, ending at line {end - 1}",
                line=number,
            )

    if isym == 3:  # C270 .. C0 .. C90 mirrored (C -> 180 - C) onto 90 .. 270
        horizontal = np.mod(180.0 - stored_angles, 360.0)[::-1]
        cd_per_klm = cd_per_klm[::-1]
    else:
        horizontal = stored_angles
    multiplier = factor * (abs(flux) / 1000.0 if flux != 0.0 else 1.0)
    lamp_lumens = abs(flux) if flux != 0.0 and n_lamps >= 0 else None
    return PhotometricTable(
        vertical_deg=gamma,
        horizontal_deg=horizontal,
        candela=cd_per_klm * multiplier,
        source=str(path),
        symmetry=_SYMMETRY_OF_ISYM[isym],
        multiplier=multiplier,
        lamp_lumens=lamp_lumens,
        luminaire=luminaire,
    )


def _read_angles(
    f: _Lines, first_line: int, n: int, kind: str, low: float, high: float, *, upper_open: bool
) -> NDArray[np.float64]:
    angles = np.empty(n)
    interval = f"[{low:g}, {high:g})" if upper_open else f"[{low:g}, {high:g}]"
    for k in range(n):
        number = first_line + k
        what = f"{kind} angle {k + 1} of {n}"
        value = f.number(number, what)
        if value < low or value > high or (upper_open and value == high):
            raise InputError(
                f.path, f"{what} is {value:g}: expected angles in {interval} degrees", line=number
            )
        if k > 0 and value <= angles[k - 1]:
            raise InputError(
                f.path,
                f"{what} ({value:g}) is not greater than the previous one ({angles[k - 1]:g}): "
                "expected strictly increasing angles",
                line=number,
            )
        angles[k] = value
    return angles


def _spacing(angles: NDArray[np.float64], period: float | None) -> float:
    """The constant step of `angles` from 0 (covering `period` when given), else 0."""
    if angles.size < 2 or angles[0] != 0.0:
        return 0.0
    step = float(angles[1] - angles[0])
    if not np.allclose(np.diff(angles), step, rtol=0.0, atol=1e-9):
        return 0.0
    if period is not None and not np.isclose(step * angles.size, period, rtol=0.0, atol=1e-9):
        return 0.0
    return step


def flux_fractions(table: PhotometricTable) -> tuple[float, float]:
    """The luminous flux the table's intensities emit, lumens, and its downward fraction.

    The intensities (candela) integrated over the sphere: trapezoids of I sin(gamma) in
    gamma (the table is 0 beyond its last angle) and of the unfolded C-planes over the
    circle (each plane weighs half the gaps to its neighbours); downward is gamma <= 90
    (type C: gamma 0 points down). A table that emits nothing: (0, 0).
    """
    gamma = np.asarray(table.vertical_deg, dtype=np.float64)
    c_deg, planes = expand_full(table)
    if c_deg.size == 1:
        weights = np.array([2.0 * np.pi])
    else:
        gaps = np.radians(np.diff(np.append(c_deg, c_deg[0] + 360.0)))
        weights = 0.5 * (gaps + np.roll(gaps, 1))
    if gamma[0] < 90.0 < gamma[-1] and not np.any(gamma == 90.0):
        at = int(np.searchsorted(gamma, 90.0))
        planes = np.array([np.insert(row, at, np.interp(90.0, gamma, row)) for row in planes])
        gamma = np.insert(gamma, at, 90.0)
    g = np.radians(gamma)
    per_gamma = (weights[:, None] * planes).sum(axis=0) * np.sin(g)
    pieces = 0.5 * (per_gamma[1:] + per_gamma[:-1]) * np.diff(g)
    total = float(pieces.sum())
    down = float(pieces[gamma[1:] <= 90.0].sum())
    return total, (down / total if total > 0.0 else 0.0)


def write_ldt(
    path: str | Path,
    table: PhotometricTable,
    *,
    company: str = "lightcal",
    report: str = "",
    digits: int | None = None,
) -> None:
    """Write a table as an EULUMDAT file, atomically (`lightcal.io.atomic`).

    The C-planes are the table's unfolded planes (`expand_full`, without a duplicate
    360); an axial table declares Mc = 24 (Dc = 15) and stores one plane. A
    `bilateral_90_270` table whose unfolded planes do not fit the Isym 3 layout (the
    planes C270 and C90 at indices 3 Mc/4 and Mc/4) is written with Isym 0, all planes,
    which needs a C0 plane (i.e. a 180 plane in the table).
    One lamp set: 1 lamp of `table.lamp_lumens` lumens, or, when that is None, -1 lamp
    (absolute photometry) of 1000 lm, so that cd/klm equals candela. Dimensions, flux
    direct ratios are written as 0, the conversion factor and tilt as 1 and 0. The
    downward flux fraction (DFF) and the light output ratio (LORL) are the table's own
    (`flux_fractions`): a table of the luminaire's own intensities (absolute photometry)
    has LORL 100 %.
    Reading the file back with `read_ldt` returns the same table up to the rounding of
    the cd/klm conversion (and of `digits`).

    Args:
        path: Destination.
        table: The table.
        company: Line 1, the company identification.
        report: Line 8, the measurement report (lightcal says where the RID comes from).
        digits: Significant digits of the numbers, or None for the shortest text that
            reads back exactly.

    Raises:
        InputError: A `bilateral_90_270` table fits neither layout, or the destination
            folder does not exist.
    """
    path = Path(path)
    isym = _ISYM_OF_SYMMETRY[table.symmetry]
    if table.symmetry == "axial":
        c_angles = np.arange(_AXIAL_MC, dtype=np.float64) * (360.0 / _AXIAL_MC)
        planes = np.asarray(table.candela)
    else:
        c_angles, full = expand_full(table)
        mc = c_angles.size
        if isym == 3 and (
            mc % 4 != 0 or c_angles[3 * mc // 4] != 270.0 or c_angles[mc // 4] != 90.0
        ):
            if c_angles[0] != 0.0:
                raise InputError(
                    path,
                    "cannot write this bilateral 90-270 table as EULUMDAT: its unfolded "
                    f"C-planes ({mc}, from {c_angles[0]:g}) fit neither Isym 3 (C270 and C90 "
                    "at indices 3 Mc/4 and Mc/4) nor Isym 0 (a C0 plane first); expected a "
                    "180 plane, or as many planes in 90..180 as in 180..270",
                )
            isym = 0
        planes = full[_stored_plane_indices(isym, mc)]
    gamma = np.asarray(table.vertical_deg)
    flux = 1000.0 if table.lamp_lumens is None else table.lamp_lumens
    cd_per_klm = planes * (1000.0 / flux)
    luminaire_lm, downward = flux_fractions(table)
    output_ratio = 1.0 if table.lamp_lumens is None else luminaire_lm / table.lamp_lumens

    def num(value: float) -> str:
        return format_number(value, digits)

    out = [
        plain_line(company, max_chars=_MAX_TEXT_CHARS),
        "1" if isym == 1 else "3",
        str(isym),
        str(c_angles.size),
        num(_spacing(c_angles, 360.0)),
        str(gamma.size),
        num(_spacing(gamma, None)),
        plain_line(report, max_chars=_MAX_TEXT_CHARS),
        plain_line(table.luminaire, max_chars=_MAX_TEXT_CHARS),
        "",
        plain_line(path.name, max_chars=_MAX_TEXT_CHARS),
        "",
        *["0"] * 9,
        num(round(100.0 * downward, 6)),
        num(round(100.0 * output_ratio, 6)),
        "1",
        "0",
        "1",
        "1" if table.lamp_lumens is not None else "-1",
        "unknown",
        num(flux),
        "",
        "",
        "0",
        *["0"] * _N_DIRECT_RATIOS,
        *[num(c) for c in c_angles],
        *[num(g) for g in gamma],
        *[num(v) for v in cd_per_klm.ravel()],
    ]
    write_text_file_atomic(path, "\n".join(out) + "\n", newline="\r\n")
