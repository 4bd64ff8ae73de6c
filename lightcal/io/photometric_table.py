"""Photometric tables (IES LM-63, EULUMDAT) in memory, and their conversion to RIDs.

A `PhotometricTable` holds a luminaire's intensity table in type C photometry as read
from an IES LM-63 file (`lightcal.io.ies`) or an EULUMDAT file (`lightcal.io.eulumdat`):
intensities in candela on a grid of vertical angles gamma (degrees, 0..180) and
horizontal angles C (degrees, 0..360), stored only over the part the file's symmetry
needs. `expand_full` unfolds the symmetry; `table_to_rid` turns the table into the
relative radiant intensity distribution (RID) the calibration uses. The module also
reads and writes the simplest measured profile, a two-column CSV (`read_rid_csv`,
`write_rid_csv`). `lightcal.io.photometric_file` picks the reader by the file's suffix.

How a type C table maps onto the light frame
--------------------------------------------
- The vertical angle gamma = 0 is the light's axis, +z of the light frame: theta = gamma.
  For a downlight this is nadir, the direction the luminaire points at.
- The horizontal angle C = 0 is the azimuth phi = 0 (+x of the light frame). LM-63 and
  EULUMDAT measure C counterclockwise seen from above a downlight, that is looking along
  its axis (+z); in our right-handed light frame that runs from +x towards -y, so
  phi = -C (mod 360 degrees): C = 90 is phi = 270 (-y). The light frame's rotation about
  its axis is part of the calibrated pose, so which physical direction C = 0 is does not
  matter; the handedness does, for tables without mirror symmetry.
- A downlight's vertical angles run 0..90 or 0..180; in directions beyond the last
  vertical angle the RID is 0. A table must start at gamma = 0: an uplight's table
  (vertical angles 90..180 only) raises `InputError`.
- The RID is relative: it is normalised so f = 1 on the axis (the mean over the C-planes
  of the intensities at gamma = 0), so absolute candela, lamp lumens and multipliers do
  not change it. Between the table's angles the RID interpolates with cubic Hermite
  splines (see `lightcal.core.rid`), so it equals the table exactly at its angles.

Symmetries (the horizontal angles a table stores, and what they stand for):

| symmetry | stored C | unfolds by |
|---|---|---|
| `axial` | 0 only | the same plane at every azimuth |
| `quadrant` | 0..90 | mirrors about the C0-C180 and the C90-C270 planes |
| `bilateral_0_180` | 0..180 | mirror about the C0-C180 plane: I(C) = I(360 - C) |
| `bilateral_90_270` | 90..270 | mirror about the C90-C270 plane: I(C) = I(180 - C) |
| `none` | 0..360 (or 0..<360) | nothing; a final 360 plane repeats the 0 plane and is dropped |

CSV profiles (`read_rid_csv`): two columns, the angle from the axis in degrees and the
relative intensity, separated by a comma (or by blanks when a line has no comma); `#`
starts a comment; blank lines are skipped; the first line may be a header whose cells
are not numbers. Angles start at 0, increase strictly and stay <= 180.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, get_args

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lightcal.core.rid import SymmetricTableRID, Table2DRID
from lightcal.errors import InputError
from lightcal.io.atomic import atomic_write_text
from lightcal.io.text_files import read_text

__all__ = [
    "PhotometricTable",
    "Symmetry",
    "expand_full",
    "format_number",
    "parse_number",
    "read_rid_csv",
    "read_text_file",
    "table_to_rid",
    "write_rid_csv",
    "write_text_file_atomic",
]

Symmetry = Literal["axial", "quadrant", "bilateral_0_180", "bilateral_90_270", "none"]
"""Lateral symmetry of a type C table; see the module docstring."""

SYMMETRIES: tuple[str, ...] = get_args(Symmetry)

_ANGLE_TOL_DEG = 1e-9
"""Horizontal angles closer than this (degrees) are the same plane when unfolding."""

# Stored horizontal range (first, last) of each symmetry; `none` ends in (0, 360].
_STORED_RANGE_DEG: dict[str, tuple[float, float]] = {
    "axial": (0.0, 0.0),
    "quadrant": (0.0, 90.0),
    "bilateral_0_180": (0.0, 180.0),
    "bilateral_90_270": (90.0, 270.0),
    "none": (0.0, 360.0),
}


@dataclass(frozen=True, eq=False)
class PhotometricTable:
    """A type C intensity table of a luminaire, over the horizontal angles its symmetry needs.

    The arrays are validated, converted to float64 and made read-only on construction.

    Args:
        vertical_deg: (n_v,) vertical angles gamma, degrees, strictly increasing in [0, 180],
            n_v >= 2. gamma = 0 is the light's axis.
        horizontal_deg: (n_h,) horizontal angles C, degrees, strictly increasing, covering
            the range of `symmetry` (see the module docstring): `[0]` for `axial`, 0..90,
            0..180, 90..270, or 0..360 / 0..<360 for `none` (at least 2 distinct planes).
        candela: (n_h, n_v) intensities in candela (>= 0), row i at horizontal angle
            `horizontal_deg[i]`, already multiplied by the file's multipliers.
        source: Where the table came from (a file path), used in error messages.
        symmetry: The lateral symmetry the stored angles stand for.
        multiplier: The factor that was applied to the file's numbers to give `candela`
            (IES: candela multiplier x ballast factor, x the ballast-lamp photometric
            factor up to LM-63-1995; EULUMDAT: lamp flux / 1000 x conversion factor).
            Informational.
        lamp_lumens: Total rated lamp flux in lumens (relative photometry), or None
            (absolute photometry, or unknown).
        luminaire: Luminaire name or description, "" when unknown.

    Raises:
        InputError: An array has the wrong shape, angles are not increasing or outside
            their range, the horizontal angles do not fit `symmetry`, or a value is
            negative or not finite. The error names `source`.
    """

    vertical_deg: NDArray[np.float64]
    horizontal_deg: NDArray[np.float64]
    candela: NDArray[np.float64]
    source: str
    symmetry: Symmetry
    multiplier: float = 1.0
    lamp_lumens: float | None = None
    luminaire: str = ""

    def __post_init__(self) -> None:
        src = self.source
        vertical = _as_angles(src, "vertical angles", self.vertical_deg, 0.0, 180.0)
        if vertical.size < 2:
            raise InputError(src, f"expected at least 2 vertical angles, got {vertical.size}")
        horizontal = _as_angles(src, "horizontal angles", self.horizontal_deg, 0.0, 360.0)
        if self.symmetry not in SYMMETRIES:
            raise InputError(
                src, f"symmetry {self.symmetry!r}: expected one of {', '.join(SYMMETRIES)}"
            )
        _check_horizontal_range(src, horizontal, self.symmetry)
        candela = np.array(self.candela, dtype=np.float64)
        if candela.shape != (horizontal.size, vertical.size):
            raise InputError(
                src,
                f"candela: expected shape ({horizontal.size}, {vertical.size}) "
                f"(horizontal x vertical angles), got {candela.shape}",
            )
        if not np.all(np.isfinite(candela)):
            raise InputError(src, "candela: expected finite values, got NaN or inf")
        if np.any(candela < 0.0):
            raise InputError(src, "candela: expected values >= 0, got a negative value")
        if not (math.isfinite(self.multiplier) and self.multiplier > 0.0):
            raise InputError(src, f"multiplier: expected a finite value > 0, got {self.multiplier}")
        if self.lamp_lumens is not None and not (
            math.isfinite(self.lamp_lumens) and self.lamp_lumens > 0.0
        ):
            raise InputError(
                src, f"lamp lumens: expected a finite value > 0 or None, got {self.lamp_lumens}"
            )
        for name, array in (
            ("vertical_deg", vertical),
            ("horizontal_deg", horizontal),
            ("candela", candela),
        ):
            array.flags.writeable = False
            object.__setattr__(self, name, array)
        object.__setattr__(self, "source", str(src))
        object.__setattr__(self, "multiplier", float(self.multiplier))
        if self.lamp_lumens is not None:
            object.__setattr__(self, "lamp_lumens", float(self.lamp_lumens))


def _as_angles(
    source: str, name: str, values: ArrayLike, low: float, high: float
) -> NDArray[np.float64]:
    angles = np.array(values, dtype=np.float64)
    if angles.ndim != 1 or angles.size == 0:
        raise InputError(
            source, f"{name}: expected a non-empty 1-D array, got shape {angles.shape}"
        )
    if not np.all(np.isfinite(angles)):
        raise InputError(source, f"{name}: expected finite values, got NaN or inf")
    if np.any(np.diff(angles) <= 0.0):
        raise InputError(source, f"{name}: expected strictly increasing values")
    if angles[0] < low or angles[-1] > high:
        raise InputError(
            source,
            f"{name}: expected values in [{low:g}, {high:g}] degrees, "
            f"got {angles[0]:g}..{angles[-1]:g}",
        )
    return angles


def _check_horizontal_range(source: str, horizontal: NDArray[np.float64], symmetry: str) -> None:
    first, last = _STORED_RANGE_DEG[symmetry]
    got = f"{horizontal[0]:g}..{horizontal[-1]:g}"
    if symmetry == "axial":
        if horizontal.size != 1 or horizontal[0] != 0.0:
            raise InputError(
                source, f"horizontal angles {got}: expected the single angle 0 for symmetry 'axial'"
            )
        return
    if symmetry == "none":
        planes = horizontal[horizontal < 360.0 - _ANGLE_TOL_DEG]
        if horizontal[0] != 0.0 or planes.size < 2:
            raise InputError(
                source,
                f"horizontal angles {got}: expected at least 2 planes from 0 up to at most 360 "
                "for symmetry 'none'",
            )
        return
    if horizontal[0] != first or horizontal[-1] != last:
        raise InputError(
            source,
            f"horizontal angles {got}: expected {first:g}..{last:g} for symmetry {symmetry!r}",
        )


def _mirror_images_deg(h: NDArray[np.float64], symmetry: str) -> NDArray[np.float64]:
    """All azimuths (degrees, not yet wrapped) that the stored angles `h` stand for."""
    if symmetry == "quadrant":
        return np.concatenate([h, 180.0 - h, 180.0 + h, 360.0 - h])
    if symmetry == "bilateral_0_180":
        return np.concatenate([h, 360.0 - h])
    if symmetry == "bilateral_90_270":
        return np.concatenate([h, 180.0 - h])
    return h.copy()


def _fold_deg(phi: NDArray[np.float64], symmetry: str) -> NDArray[np.float64]:
    """Map azimuths in [0, 360) onto the stored range of `symmetry`."""
    if symmetry == "quadrant":
        c = np.where(phi <= 180.0, phi, 360.0 - phi)
        return np.where(c <= 90.0, c, 180.0 - c)
    if symmetry == "bilateral_0_180":
        return np.where(phi <= 180.0, phi, 360.0 - phi)
    if symmetry == "bilateral_90_270":
        return np.where((phi >= 90.0) & (phi <= 270.0), phi, np.mod(180.0 - phi, 360.0))
    return phi


def expand_full(table: PhotometricTable) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Unfold a table's symmetry into its planes over the whole circle.

    Args:
        table: The table.

    Returns:
        phi_deg: (n,) strictly increasing horizontal angles in [0, 360), degrees (no
            duplicate 360). For an `axial` table this is `[0]`: its one plane holds at
            every azimuth.
        candela: (n, n_v) the intensities of each plane, candela.
    """
    h = table.horizontal_deg
    if table.symmetry == "axial":
        return np.zeros(1), np.array(table.candela, dtype=np.float64)
    images = np.sort(np.mod(_mirror_images_deg(h, table.symmetry), 360.0))
    keep = np.ones(images.size, dtype=bool)
    keep[1:] = np.diff(images) > _ANGLE_TOL_DEG
    keep &= images < 360.0 - _ANGLE_TOL_DEG
    phi = images[keep]
    stored = _fold_deg(phi, table.symmetry)
    rows = np.abs(stored[:, None] - h[None, :]).argmin(axis=1)
    assert np.all(np.abs(h[rows] - stored) <= 1e-6), "unfolded azimuth without a stored plane"
    return phi, np.array(table.candela[rows], dtype=np.float64)


def table_to_rid(table: PhotometricTable) -> SymmetricTableRID | Table2DRID:
    """The light's RID from a type C table (mapping in the module docstring).

    Args:
        table: The table; its vertical angles must start at gamma = 0.

    Returns:
        A `SymmetricTableRID` for an `axial` table, else a `Table2DRID` over the unfolded
        planes (`expand_full`). Both are normalised so f = 1 on the axis and are 0 beyond
        the last vertical angle.

    Raises:
        InputError: The vertical angles do not start at 0 (e.g. an uplight's 90..180
            table), or the intensity on the axis (gamma = 0) is 0.
    """
    gamma0 = float(table.vertical_deg[0])
    if gamma0 != 0.0:
        raise InputError(
            table.source,
            f"vertical angles start at {gamma0:g} degrees: expected the table to start at "
            "gamma 0 (the light axis); uplight tables (vertical angles 90..180) are not supported",
        )
    theta_rad = np.deg2rad(table.vertical_deg)
    if table.symmetry == "axial":
        values = np.array(table.candela[0], dtype=np.float64)
        axis_cd = float(values[0])
    else:
        phi_deg, values = expand_full(table)
        axis_cd = float(values[:, 0].mean())
    if axis_cd <= 0.0:
        raise InputError(
            table.source,
            "the intensity on the light axis (gamma 0) is 0: expected a positive value, "
            "the RID is normalised to 1 there",
        )
    if table.symmetry == "axial":
        return SymmetricTableRID(theta_rad, values)
    # phi = -C: C runs counterclockwise seen looking along the light's axis.
    phi_light_deg = np.mod(-phi_deg, 360.0)
    order = np.argsort(phi_light_deg)
    return Table2DRID(theta_rad, np.deg2rad(phi_light_deg[order]), values[order])


# --------------------------------------------------------------------------- files


def read_text_file(path: Path) -> str:
    """The text of a photometric file: UTF-8 (BOM tolerated), UTF-16 with a BOM, else
    Latin-1 (`lightcal.io.text_files`).

    Raises:
        InputError: The file does not exist, is not a regular file, is too large, or is
            UTF-16 without a byte-order mark.
    """
    return read_text(path, "photometric file", latin1=True)


def parse_number(path: Path, text: str, what: str, line: int, *, value: str | None = None) -> float:
    """The finite number a photometric file gives for `what` at `line`.

    Args:
        text: the token as the file writes it (quoted in messages).
        value: the token to parse, if it differs from `text` (a decimal comma replaced).

    Raises:
        InputError: Not a number, or not finite; naming the file, the line and `what`.
    """
    try:
        number = float(text if value is None else value)
    except ValueError:
        raise InputError(path, f"{what}: expected a number, got {text!r}", line=line) from None
    if not np.isfinite(number):
        raise InputError(path, f"{what}: expected a finite number, got {text!r}", line=line)
    return number


def write_text_file_atomic(path: Path, text: str, *, newline: str = "\n") -> None:
    """Write `text` (UTF-8) to `path` atomically with `lightcal.io.atomic.atomic_write_text`.

    Args:
        path: Destination.
        text: Content, lines separated by "\\n".
        newline: Line ending written in the file ("\\n" or "\\r\\n").

    Raises:
        InputError: The destination folder does not exist.
    """
    folder = path.parent
    if not folder.is_dir():
        raise InputError(path, f"cannot write: folder {str(folder)!r} does not exist")
    atomic_write_text(path, text.replace("\n", newline))


def format_number(value: float, digits: int | None) -> str:
    """A number as written in photometric files.

    Args:
        value: The number.
        digits: Significant digits, or None for the shortest text that reads back exactly.
    """
    if digits is None:
        text = repr(float(value))
        return text[:-2] if text.endswith(".0") else text
    return f"{float(value):.{digits}g}"


def _parse_csv_cell(path: Path, line: int, cell: str) -> float | None:
    try:
        value = float(cell)
    except ValueError:
        return None
    if not math.isfinite(value):
        raise InputError(path, f"cell {cell!r}: expected a finite number", line=line)
    return value


def read_rid_csv(path: str | Path) -> SymmetricTableRID:
    """Read a rotationally symmetric RID from a two-column CSV (format in the module docstring).

    Args:
        path: The CSV file: angle from the axis in degrees, relative intensity.

    Returns:
        The profile, normalised so f(0) = 1.

    Raises:
        InputError: Naming the file and line: a cell that is not a number, a row without
            exactly 2 columns, an angle not greater than the previous one, an angle above
            180, a negative intensity, a first angle other than 0, a zero intensity on the
            axis, or fewer than 2 data rows (reported at the file's last line).
    """
    path = Path(path)
    lines = read_text_file(path).splitlines()
    angles: list[float] = []
    values: list[float] = []
    seen_content = False
    for number, raw in enumerate(lines, start=1):
        content = raw.split("#", 1)[0].strip()
        if not content:
            continue
        cells = [c.strip() for c in content.split(",")] if "," in content else content.split()
        if len(cells) != 2:
            raise InputError(
                path,
                f"expected 2 columns (angle in degrees, relative intensity), got {len(cells)}",
                line=number,
            )
        parsed = [_parse_csv_cell(path, number, c) for c in cells]
        first_content = not seen_content
        seen_content = True
        if first_content and all(p is None for p in parsed):
            continue  # header line
        numbers = [p for p in parsed if p is not None]
        if len(numbers) != 2:
            bad = cells[parsed.index(None)]
            raise InputError(path, f"cell {bad!r}: expected a number", line=number)
        angle, value = numbers
        if not angles and angle != 0.0:
            raise InputError(
                path,
                f"first angle is {angle:g} degrees: expected 0 (the light axis)",
                line=number,
            )
        if angles and angle <= angles[-1]:
            raise InputError(
                path,
                f"angle {angle:g} is not greater than the previous angle {angles[-1]:g}: "
                "expected strictly increasing angles",
                line=number,
            )
        if angle > 180.0:
            raise InputError(path, f"angle {angle:g} degrees: expected angles <= 180", line=number)
        if value < 0.0:
            raise InputError(
                path, f"relative intensity {value:g} is negative: expected values >= 0", line=number
            )
        if not angles and value == 0.0:
            raise InputError(
                path,
                "relative intensity on the axis (angle 0) is 0: expected a positive value",
                line=number,
            )
        angles.append(angle)
        values.append(value)
    if len(angles) < 2:
        raise InputError(
            path,
            "expected at least 2 data rows (angle in degrees, relative intensity), "
            f"got {len(angles)}",
            line=len(lines) if lines else None,
        )
    return SymmetricTableRID(np.deg2rad(np.array(angles)), np.array(values))


def write_rid_csv(
    path: str | Path,
    theta_deg: ArrayLike,
    values: ArrayLike,
    *,
    digits: int | None = None,
) -> None:
    """Write a rotationally symmetric profile as a CSV that `read_rid_csv` reads back.

    The file has the header `theta_deg,relative_intensity` and one row per angle; it is
    written atomically.

    Args:
        path: Destination.
        theta_deg: (n,) angles from the axis, degrees (0 first, strictly increasing, <= 180).
        values: (n,) relative intensities >= 0, values[0] > 0.
        digits: Significant digits, or None for the shortest text that reads back exactly.

    Raises:
        InputError: The arrays do not have the same 1-D shape, or the destination folder
            does not exist.
    """
    path = Path(path)
    theta = np.asarray(theta_deg, dtype=np.float64)
    vals = np.asarray(values, dtype=np.float64)
    if theta.ndim != 1 or vals.shape != theta.shape:
        raise InputError(
            path,
            f"expected angles and values of the same 1-D shape, got {theta.shape} and {vals.shape}",
        )
    rows = ["theta_deg,relative_intensity"]
    rows += [
        f"{format_number(t, digits)},{format_number(v, digits)}"
        for t, v in zip(theta, vals, strict=True)
    ]
    write_text_file_atomic(path, "\n".join(rows) + "\n")
