"""Write a file so that readers see either the old content or the new, never half of it.

The data goes to a temporary file in the same folder (same file system, so the final
`os.replace` is atomic), is flushed and fsync'ed, and only then replaces the target.
If anything fails on the way (including an exception raised by the iterable that
produces the data, and a KeyboardInterrupt: Ctrl-C, or SIGTERM in the CLI), the temporary
file is removed and the old file is left untouched. The temporary file's name is chosen
before it is created and removed by that name on any exit, so an interruption between
creating it and the cleanup code leaves nothing behind either.
`atomic_create_bytes` is the same for a file that must not exist yet: the temporary
file is hard-linked to the target, which fails instead of replacing a file.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Iterable
from pathlib import Path

__all__ = ["atomic_create_bytes", "atomic_write_bytes", "atomic_write_text"]

_NEW_FILE_MODE = 0o666
"""Mode of a newly created file before the umask applies (as `open(path, "w")` does)."""


def atomic_write_bytes(
    path: str | Path, data: bytes | bytearray | memoryview | Iterable[bytes]
) -> None:
    """Replace the content of `path` by `data` atomically.

    Args:
        path: The file to write. Its folder must exist. An existing file keeps its
            permission bits; a new one gets the usual `0o666 & ~umask`.
        data: The bytes to write, or an iterable of byte chunks (written in order; if
            the iterable raises, nothing is replaced).

    Raises:
        OSError: The folder does not exist or cannot be written; the old file, if any,
            is unchanged and no temporary file is left behind.
    """
    target = Path(path)
    temp = _temporary_name(target)
    try:
        _write_new(temp, data)
        with contextlib.suppress(FileNotFoundError):
            temp.chmod(target.stat().st_mode & 0o7777)
        temp.replace(target)
    except BaseException:
        _remove(temp)
        raise
    _fsync_folder(target.parent)


def atomic_create_bytes(path: str | Path, data: bytes | bytearray | memoryview) -> None:
    """Create `path` holding `data`, atomically, never replacing an existing file.

    Args:
        path: The file to create. Its folder must exist.
        data: The bytes to write.

    Raises:
        FileExistsError: `path` exists (it is left untouched).
        OSError: The folder does not exist or cannot be written; no temporary file is
            left behind.
    """
    target = Path(path)
    temp = _temporary_name(target)
    try:
        _write_new(temp, data)
        try:
            os.link(temp, target)
        except FileExistsError:
            raise
        except OSError:  # no hard links on this file system: exclusive create instead
            fd = os.open(target, os.O_WRONLY | os.O_CREAT | os.O_EXCL, _NEW_FILE_MODE)
            try:
                with os.fdopen(fd, "wb") as stream:
                    stream.write(data)
            except BaseException:  # the file is ours: no half of it stays
                _remove(target)
                raise
    finally:
        _remove(temp)
    _fsync_folder(target.parent)


def _temporary_name(target: Path) -> Path:
    """A new hidden name beside `target` (48 random bits: no other file has it)."""
    return target.parent / f".{target.name}.{secrets.token_hex(6)}.tmp"


def _write_new(temp: Path, data: bytes | bytearray | memoryview | Iterable[bytes]) -> None:
    """Create `temp` holding `data`, flushed to disk (the caller removes it on failure)."""
    fd = os.open(temp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, _NEW_FILE_MODE)
    with os.fdopen(fd, "wb") as stream:
        if isinstance(data, bytes | bytearray | memoryview):
            stream.write(data)
        else:
            for chunk in data:
                stream.write(chunk)
        stream.flush()
        os.fsync(stream.fileno())


def _remove(temp: Path) -> None:
    """Remove a temporary file if it is there (after a rename it is not)."""
    with contextlib.suppress(OSError):
        temp.unlink()


def atomic_write_text(path: str | Path, text: str, *, encoding: str = "utf-8") -> None:
    """Replace the content of `path` by `text` atomically (see `atomic_write_bytes`).

    Args:
        path: The file to write.
        text: The new content; written as is (no newline translation).
        encoding: Text encoding.
    """
    atomic_write_bytes(path, text.encode(encoding))


def _fsync_folder(folder: Path) -> None:
    """Make the rename itself durable (POSIX); a no-op where folders cannot be opened."""
    if os.name != "posix":
        return
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
