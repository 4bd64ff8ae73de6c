"""Read a light's photometric file, the reader chosen by the file's suffix.

| suffix | reader | gives |
|---|---|---|
| `.ies` | `lightcal.io.ies.read_ies` (IES LM-63) | a `PhotometricTable` |
| `.ldt` | `lightcal.io.eulumdat.read_ldt` (EULUMDAT) | a `PhotometricTable` |
| `.csv` | `lightcal.io.photometric_table.read_rid_csv` | a rotationally symmetric RID |

The table itself, its symmetries and its conversion to a RID are in
`lightcal.io.photometric_table`, which both file readers build on; this dispatcher sits
above the readers, so no module imports one that imports it back.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from lightcal.core.rid import SymmetricTableRID, Table2DRID
from lightcal.errors import InputError
from lightcal.io.eulumdat import read_ldt
from lightcal.io.ies import read_ies
from lightcal.io.photometric_table import PhotometricTable, read_rid_csv, table_to_rid

__all__ = ["read_photometric_table", "read_rid_file"]

_TABLE_READERS: dict[str, Callable[[Path], PhotometricTable]] = {
    ".ies": read_ies,
    ".ldt": read_ldt,
}


def read_photometric_table(path: str | Path) -> PhotometricTable:
    """Read an IES LM-63 (`.ies`) or EULUMDAT (`.ldt`) file, chosen by its suffix.

    Raises:
        InputError: Unknown suffix, or the reader's errors.
    """
    path = Path(path)
    reader = _TABLE_READERS.get(path.suffix.lower())
    if reader is None:
        raise InputError(path, f"unsupported file suffix {path.suffix!r}: expected .ies or .ldt")
    return reader(path)


def read_rid_file(path: str | Path) -> SymmetricTableRID | Table2DRID:
    """Read a light's RID from an `.ies`, `.ldt` or `.csv` file, chosen by its suffix.

    Raises:
        InputError: Unknown suffix, or the reader's or `table_to_rid`'s errors.
    """
    path = Path(path)
    if path.suffix.lower() == ".csv":
        return read_rid_csv(path)
    if path.suffix.lower() not in _TABLE_READERS:
        raise InputError(
            path, f"unsupported file suffix {path.suffix!r}: expected .ies, .ldt or .csv"
        )
    return table_to_rid(read_photometric_table(path))
