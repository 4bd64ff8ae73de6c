"""Reading the text files users hand over: one place for the checks every reader needs.

- The path must be a regular file: a folder, a FIFO or a device is named as such (not
  "not found"), so a typo and a wrong kind of path read differently.
- At most `MAX_TEXT_BYTES`: a text input larger than that is not a project, camera or
  light file, and reading it whole would only exhaust memory.
- A file that starts like a known binary format (an image, an archive, a PDF) is named
  as that kind ("a PNG image; expected a project file (a text file)"), not as
  undecodable text.
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


#: Leading bytes of the files users most often give by mistake where text is expected.
BINARY_KINDS: tuple[tuple[bytes, str], ...] = (
    (b"\x89PNG\r\n\x1a\n", "a PNG image"),
    (b"\xff\xd8\xff", "a JPEG image"),
    (b"II*\x00", "a TIFF image (or a camera raw file)"),
    (b"MM\x00*", "a TIFF image (or a camera raw file)"),
    (b"II\x2b\x00", "a BigTIFF image"),
    (b"PK\x03\x04", "a zip archive"),
    (b"%PDF", "a PDF document"),
    (b"\x1f\x8b", "a gzip archive"),
    (b"BM", "a BMP image"),
    (b"FUJIFILMCCD-RAW", "a Fujifilm raw file"),
    (b"\x00\x00\x00\x0cjP  ", "a JPEG 2000 image"),
)


def binary_kind(data: bytes) -> str | None:
    """What kind of (non-text) file `data` starts like, in words; None: none known."""
    if data[4:12] in (b"ftypheic", b"ftypheix", b"ftypmif1", b"ftypcrx "):
        return "a HEIF image (or a Canon CR3 raw file)"
    for magic, kind in BINARY_KINDS:
        if data.startswith(magic) and (magic != b"BM" or b"\x00" in data[:64]):
            return kind
    return None


def decode_text(data: bytes, path: Path, what: str, *, latin1: bool = False) -> str:
    """The text of a file's bytes (see the module docstring for the encodings)."""
    kind = binary_kind(data)
    if kind is not None:
        raise InputError(path, f"{kind}; expected a {what} (a text file)")
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
