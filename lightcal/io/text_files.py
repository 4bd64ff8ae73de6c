"""Reading the text files users hand over: one place for the checks every reader needs.

- The path must be a regular file: a folder, a FIFO or a device is named as such (not
  "not found"), so a typo and a wrong kind of path read differently.
- At most `MAX_TEXT_BYTES`: a text input larger than that is not a project, camera or
  light file, and reading it whole would only exhaust memory.
- Encodings: UTF-8 with or without a byte-order mark; UTF-16 with a byte-order mark (what
  some Windows editors and photometric tools save) is decoded; UTF-16 without one gets
  "save it as UTF-8". Photometric files may fall back to Latin-1 (old IES files).
"""

from __future__ import annotations

import stat
from pathlib import Path

from lightcal.errors import InputError

MAX_TEXT_BYTES = 64 * 1024 * 1024
"""The largest text input read (64 MB)."""


def check_regular_file(path: Path, what: str) -> None:
    """InputError unless `path` is an existing regular file (named `what` in messages)."""
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise InputError(path, f"{what} not found") from None
    except OSError as exc:
        raise InputError(path, f"cannot read the {what} ({exc.strerror or exc})") from None
    if stat.S_ISDIR(mode):
        raise InputError(path, f"is a folder; expected a {what}")
    if not stat.S_ISREG(mode):
        raise InputError(path, f"is not a regular file (a pipe or a device); expected a {what}")


def decode_text(data: bytes, path: Path, what: str, *, latin1: bool = False) -> str:
    """The text of a file's bytes (see the module docstring for the encodings)."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        try:
            return data.decode("utf-16")
        except UnicodeDecodeError:
            raise InputError(path, f"the {what} is not valid UTF-16 text") from None
    if data.count(b"\x00") > len(data) // 8:
        raise InputError(
            path, f"the {what} looks like UTF-16 without a byte-order mark: save it as UTF-8"
        )
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        if latin1:
            return data.decode("latin-1")
        raise InputError(
            path, f"the {what} is not UTF-8 text (byte {exc.start}): save it as UTF-8"
        ) from None


def read_text(path: Path, what: str, *, latin1: bool = False) -> str:
    """A text input, checked (module docstring). `what` names it in messages."""
    path = Path(path)
    check_regular_file(path, what)
    try:
        with path.open("rb") as f:
            data = f.read(MAX_TEXT_BYTES + 1)
    except OSError as exc:
        raise InputError(path, f"cannot read the {what} ({exc.strerror or exc})") from None
    if len(data) > MAX_TEXT_BYTES:
        raise InputError(
            path, f"the {what} is larger than {MAX_TEXT_BYTES // 2**20} MB; expected a text file"
        )
    return decode_text(data, path, what, latin1=latin1)
