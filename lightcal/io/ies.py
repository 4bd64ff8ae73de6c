"""Read and write IES LM-63 photometric files (type C photometry, no tilt tables).

Accepted vintages, told apart by the first line:

| first line | vintage |
|---|---|
| `IESNA:LM-63-1995` | LM-63-1995 |
| `IESNA:LM-63-2002` | LM-63-2002 |
| `IES:LM-63-2019` | LM-63-2019 |
| `IESNA91` | LM-63-1991 |
| anything else | LM-63-1986 (no header line: free label lines up to `TILT=`) |

After the header come keyword lines `[KEYWORD] value` (`[MORE]` continues the previous
one; `[LUMINAIRE]` becomes `PhotometricTable.luminaire`; other lines are ignored), then
the line `TILT=NONE`. `TILT=INCLUDE` and `TILT=<file>` (lamp tilt tables) are not
supported. Then come numbers separated by blanks or commas, wrapped across lines in any
way:

1. number of lamps, lumens per lamp (-1: absolute photometry), candela multiplier,
   number of vertical angles n_v, number of horizontal angles n_h, photometric type
   (only 1 = type C is supported), units type, luminous opening width, length, height;
2. ballast factor, a second factor (the ballast-lamp photometric factor up to
   LM-63-1995, "future use" in LM-63-2002, the file generation type in LM-63-2019),
   input watts;
3. n_v vertical angles, n_h horizontal angles, then n_h rows of n_v candela values.

The candela values are multiplied by the candela multiplier and the ballast factor,
and, for LM-63-1995 and older files, by the ballast-lamp photometric factor. The
horizontal angles set the symmetry: {0} axial, 0..90 quadrant, 0..180 bilateral about
the 0-180 plane, 90..270 bilateral about the 90-270 plane, 0..360 none. How the table
maps onto the light frame is described in `lightcal.io.photometric_table`.

Every error is an `InputError` naming the file and the line of the offending number
(for a file that ends too early, its last non-blank line).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from lightcal.errors import InputError
from lightcal.io.escaping import plain_line
from lightcal.io.photometric_table import (
    PhotometricTable,
    Symmetry,
    format_number,
    parse_number,
    read_text_file,
    write_text_file_atomic,
)

__all__ = ["IesVintage", "read_ies", "write_ies"]

IesVintage = Literal["LM-63-1986", "LM-63-1991", "LM-63-1995", "LM-63-2002", "LM-63-2019"]

_HEADERS: dict[str, IesVintage] = {
    "IESNA:LM-63-1995": "LM-63-1995",
    "IESNA:LM-63-2002": "LM-63-2002",
    "IES:LM-63-2019": "LM-63-2019",
    "IESNA91": "LM-63-1991",
}
_OLD_VINTAGES = ("LM-63-1986", "LM-63-1991", "LM-63-1995")
_SECOND_FACTOR_NAME: dict[str, str] = {
    "LM-63-1986": "ballast-lamp photometric factor",
    "LM-63-1991": "ballast-lamp photometric factor",
    "LM-63-1995": "ballast-lamp photometric factor",
    "LM-63-2002": "future use value",
    "LM-63-2019": "file generation type",
}
_KEYWORD_LINE = re.compile(r"\[\s*([^\]]*?)\s*\]\s?(.*)")
_SEPARATORS = re.compile(r"[\s,]+")
_PHOTOMETRIC_TYPE_NAMES = {2: "type B", 3: "type A"}
_NUMBERS_PER_LINE = 10
_MAX_LINE_CHARS = 256  # LM-63-2002: no line longer


@dataclass
class _Numbers:
    """The numbers after `TILT=`, read one at a time with their line numbers."""

    path: Path
    tokens: list[tuple[str, int]]
    end_line: int
    position: int = 0
    demand: str = ""

    def next(self, what: str) -> tuple[float, int]:
        """The next number and its line; `what` names it in error messages."""
        if self.position >= len(self.tokens):
            raise InputError(
                self.path,
                f"unexpected end of file: expected {what}{self.demand}",
                line=self.end_line,
            )
        text, line = self.tokens[self.position]
        self.position += 1
        return parse_number(self.path, text, what, line), line

    def count(self, what: str, minimum: int) -> int:
        value, line = self.next(what)
        if value != int(value) or value < minimum:
            raise InputError(
                self.path, f"{what} {value:g}: expected an integer >= {minimum}", line=line
            )
        return int(value)

    def positive(self, what: str) -> float:
        value, line = self.next(what)
        if value <= 0.0:
            raise InputError(self.path, f"{what} {value:g}: expected a value > 0", line=line)
        return value


_MAX_TABLE_NUMBERS = 1_000_000
"""Counts beyond the data and beyond this many numbers are refused before allocating."""


def read_ies(path: str | Path) -> PhotometricTable:
    """Read an IES LM-63 file (format in the module docstring).

    Args:
        path: The `.ies` file.

    Returns:
        The table, candela multiplied by the file's multipliers, `lamp_lumens` = number of
        lamps x lumens per lamp (None for absolute photometry, lumens per lamp -1).

    Raises:
        InputError: Naming the file and line: an unknown `IES...` header, no `TILT=` line,
            a tilt table, a number that is not a number, a count that is not an integer,
            photometric type B or A, angles that do not increase or are out of range, a
            horizontal-angle set that is no known symmetry, a negative candela value, too
            few numbers for the counts (at the last line) or numbers left over.
    """
    path = Path(path)
    lines = read_text_file(path).splitlines()
    if not any(line.strip() for line in lines):
        raise InputError(path, "the file is empty: expected an IES LM-63 file")
    first = lines[0].strip().replace(" ", "").upper()
    vintage: IesVintage
    if first in _HEADERS:
        vintage = _HEADERS[first]
        start = 1
    elif first.startswith(("IESNA", "IES:")):
        raise InputError(
            path,
            f"unknown header {lines[0].strip()!r}: expected IESNA:LM-63-1995, "
            "IESNA:LM-63-2002, IES:LM-63-2019, IESNA91, or no header (LM-63-1986)",
            line=1,
        )
    else:
        vintage, start = "LM-63-1986", 0

    keywords: dict[str, str] = {}
    last_key: str | None = None
    tilt_index: int | None = None
    for index in range(start, len(lines)):
        stripped = lines[index].strip()
        if stripped.replace(" ", "").upper().startswith("TILT="):
            tilt_index = index
            break
        match = _KEYWORD_LINE.fullmatch(stripped) if vintage != "LM-63-1986" else None
        if match is None:
            continue
        key, value = match.group(1).upper(), match.group(2).strip()
        if key == "MORE" and last_key is not None:
            keywords[last_key] = f"{keywords[last_key]} {value}".strip()
        else:
            keywords[key] = value
            last_key = key
    if tilt_index is None:
        raise InputError(
            path,
            "no TILT= line: expected TILT=NONE after the header and keyword lines",
            line=len(lines),
        )
    tilt = lines[tilt_index].strip().split("=", 1)[1].strip()
    if tilt.upper() != "NONE":
        raise InputError(
            path,
            f"TILT={tilt}: tilt tables are not supported; expected TILT=NONE",
            line=tilt_index + 1,
        )

    tokens = [
        (token, number)
        for number, line in enumerate(lines[tilt_index + 1 :], start=tilt_index + 2)
        for token in _SEPARATORS.split(line.strip())
        if token
    ]
    end_line = max(i + 1 for i, line in enumerate(lines) if line.strip())
    numbers = _Numbers(path, tokens, end_line)
    n_lamps, _ = numbers.next("number of lamps")
    lumens_per_lamp, _ = numbers.next("lumens per lamp")
    candela_multiplier = numbers.positive("candela multiplier")
    n_v = numbers.count("number of vertical angles", 2)
    n_h = numbers.count("number of horizontal angles", 1)
    _check_photometric_type(numbers)
    for what in (
        "units type",
        "luminous opening width",
        "luminous opening length",
        "luminous opening height",
    ):
        numbers.next(what)
    multiplier = candela_multiplier * numbers.positive("ballast factor")
    second_factor = _SECOND_FACTOR_NAME[vintage]
    if vintage in _OLD_VINTAGES:
        multiplier *= numbers.positive(second_factor)
    else:
        numbers.next(second_factor)
    numbers.next("input watts")

    total = 13 + n_v + n_h + n_h * n_v
    numbers.demand = (
        f" (the counts, {n_h} horizontal x {n_v} vertical angles, demand {total} numbers "
        f"after TILT=NONE, found {len(tokens)})"
    )
    # Counts the data cannot hold are refused before anything is allocated by them (a
    # file that is merely short gets the line-precise message below).
    remaining = len(tokens) - numbers.position
    if n_v + n_h + n_h * n_v > max(remaining, _MAX_TABLE_NUMBERS):
        raise InputError(
            path,
            f"the counts ({n_h} horizontal x {n_v} vertical angles) demand "
            f"{n_v + n_h + n_h * n_v} numbers after the header, found {remaining}",
        )
    vertical, _ = _read_angles(numbers, "vertical", n_v, 180.0)
    horizontal, horizontal_lines = _read_angles(numbers, "horizontal", n_h, 360.0)
    symmetry = _symmetry(path, horizontal, horizontal_lines)
    candela = np.empty((n_h, n_v))
    for i in range(n_h):
        for j in range(n_v):
            what = f"candela value {j + 1} of {n_v} at horizontal angle {horizontal[i]:g}"
            value, line = numbers.next(what)
            if value < 0.0:
                raise InputError(
                    path, f"{what} is negative ({value:g}): expected values >= 0", line=line
                )
            candela[i, j] = value
    if numbers.position < len(tokens):
        text, line = tokens[numbers.position]
        raise InputError(
            path,
            f"unexpected {text!r} after the candela table: the counts, {n_h} horizontal x "
            f"{n_v} vertical angles, demand {total} numbers after TILT=NONE, "
            f"found {len(tokens)}",
            line=line,
        )
    lamp_lumens = n_lamps * lumens_per_lamp if n_lamps > 0 and lumens_per_lamp > 0 else None
    return PhotometricTable(
        vertical_deg=vertical,
        horizontal_deg=horizontal,
        candela=candela * multiplier,
        source=str(path),
        symmetry=symmetry,
        multiplier=multiplier,
        lamp_lumens=lamp_lumens,
        luminaire=keywords.get("LUMINAIRE", ""),
    )


def _check_photometric_type(numbers: _Numbers) -> None:
    value, line = numbers.next("photometric type")
    if value == 1.0:
        return
    if value in _PHOTOMETRIC_TYPE_NAMES:
        name = _PHOTOMETRIC_TYPE_NAMES[int(value)]
        message = f"photometric type {value:g} ({name}) is not supported: expected 1 (type C)"
    else:
        message = f"photometric type {value:g}: expected 1 (type C)"
    raise InputError(numbers.path, message, line=line)


def _read_angles(
    numbers: _Numbers, kind: str, n: int, high: float
) -> tuple[NDArray[np.float64], list[int]]:
    angles = np.empty(n)
    lines: list[int] = []
    for k in range(n):
        what = f"{kind} angle {k + 1} of {n}"
        value, line = numbers.next(what)
        if not 0.0 <= value <= high:
            raise InputError(
                numbers.path,
                f"{what} is {value:g}: expected angles in [0, {high:g}] degrees",
                line=line,
            )
        if k > 0 and value <= angles[k - 1]:
            raise InputError(
                numbers.path,
                f"{what} ({value:g}) is not greater than the previous one ({angles[k - 1]:g}): "
                "expected strictly increasing angles",
                line=line,
            )
        angles[k] = value
        lines.append(line)
    return angles, lines


def _symmetry(path: Path, horizontal: NDArray[np.float64], lines: list[int]) -> Symmetry:
    first, last = float(horizontal[0]), float(horizontal[-1])
    if horizontal.size == 1 and first == 0.0:
        return "axial"
    if horizontal.size > 1:
        known: dict[tuple[float, float], Symmetry] = {
            (0.0, 90.0): "quadrant",
            (0.0, 180.0): "bilateral_0_180",
            (90.0, 270.0): "bilateral_90_270",
            (0.0, 360.0): "none",
        }
        if (first, last) in known:
            return known[first, last]
    got = f"{first:g}" if horizontal.size == 1 else f"{first:g}..{last:g}"
    line = lines[0] if horizontal.size == 1 or first not in (0.0, 90.0) else lines[-1]
    raise InputError(
        path,
        f"horizontal angles {got}: expected 0 (axial symmetry), 0..90 (quadrant), "
        "0..180 (bilateral about the 0-180 plane), 90..270 (bilateral about the 90-270 "
        "plane) or 0..360 (no symmetry)",
        line=line,
    )


def write_ies(
    path: str | Path,
    table: PhotometricTable,
    *,
    keywords: Mapping[str, str] | None = None,
    digits: int | None = None,
) -> None:
    """Write a table as an IES LM-63-2002 file, atomically (`lightcal.io.atomic`).

    The file has one lamp of `table.lamp_lumens` lumens (-1: absolute photometry when
    None), candela multiplier 1, photometric type 1 (type C), units 2 (metres), a
    0 x 0 x 0 luminous opening, ballast factor 1, future use 1, input watts 0. A table of
    symmetry `none` that ends below 360 gets a 360 plane repeating the 0 plane, as
    LM-63 requires. Reading the file back with `read_ies` returns the same table to the
    printed precision (exactly when `digits` is None).

    Args:
        path: Destination.
        table: The table.
        keywords: Keyword lines `[KEY] value`, in addition to (or replacing) the defaults:
            `TEST`, `TESTLAB`, `ISSUEDATE`, `MANUFAC` ("unknown", required by LM-63-2002)
            and `LUMINAIRE` (`table.luminaire`, when not empty). Keys are upper-case
            letters, digits and underscores; a value with line breaks continues on
            `[MORE]` lines.
        digits: Significant digits of the numbers, or None for the shortest text that
            reads back exactly.

    Raises:
        InputError: A keyword is malformed, or the destination folder does not exist.
    """
    path = Path(path)
    entries: dict[str, str] = {
        key: "unknown" for key in ("TEST", "TESTLAB", "ISSUEDATE", "MANUFAC")
    }
    if table.luminaire:
        entries["LUMINAIRE"] = table.luminaire
    for key, value in (keywords or {}).items():
        if not re.fullmatch(r"[A-Z0-9_]+", key):
            raise InputError(
                "keywords",
                f"keyword {key!r}: expected upper-case letters, digits and underscores",
            )
        entries[key] = str(value)

    horizontal = np.asarray(table.horizontal_deg)
    candela = np.asarray(table.candela)
    if table.symmetry == "none" and horizontal[-1] < 360.0:
        horizontal = np.append(horizontal, 360.0)
        candela = np.vstack([candela, candela[:1]])
    vertical = np.asarray(table.vertical_deg)

    def numbers_text(values: NDArray[np.float64]) -> list[str]:
        texts = [format_number(v, digits) for v in values]
        return [
            " ".join(texts[i : i + _NUMBERS_PER_LINE])
            for i in range(0, len(texts), _NUMBERS_PER_LINE)
        ]

    out = ["IESNA:LM-63-2002"]
    for key, value in entries.items():
        # Each line printable and within LM-63's 256 characters: no value adds a line
        # of its own (a `TILT=`) or a control character.
        parts = [
            plain_line(part, max_chars=_MAX_LINE_CHARS - len("[MORE] ") - len(key))
            for part in str(value).splitlines()
        ] or [""]
        out.append(f"[{key}] {parts[0]}".rstrip())
        out += [f"[MORE] {part}".rstrip() for part in parts[1:]]
    lumens = "-1" if table.lamp_lumens is None else format_number(table.lamp_lumens, digits)
    out += [
        "TILT=NONE",
        f"1 {lumens} 1 {vertical.size} {horizontal.size} 1 2 0 0 0",
        "1 1 0",
        *numbers_text(vertical),
        *numbers_text(horizontal),
    ]
    for row in candela:
        out += numbers_text(row)
    write_text_file_atomic(path, "\n".join(out) + "\n", newline="\r\n")
