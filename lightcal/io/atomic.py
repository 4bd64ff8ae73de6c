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
`atomic_folder` is the same for a folder of files (a report): written aside, moved in
whole, one writer at a time.

The removal of a temporary file or folder, and the moving in of a finished folder, run
with Ctrl-C and SIGTERM held (`signals_held`): a second signal arriving during the
cleanup of the first waits for it to end instead of leaving half of it behind.
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import shutil
import signal
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from lightcal.errors import InputError

__all__ = [
    "LOCK_NAME",
    "atomic_create_bytes",
    "atomic_folder",
    "atomic_write_bytes",
    "atomic_write_text",
    "signals_held",
]

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
        with signals_held():
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
                with signals_held():
                    _remove(target)
                raise
    finally:
        with signals_held():
            _remove(temp)
    _fsync_folder(target.parent)


def _temporary_name(target: Path) -> Path:
    """A new hidden name beside `target` (48 random bits: no other file or folder has it)."""
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


_HELD_SIGNALS = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def signals_held() -> Iterator[None]:
    """Ctrl-C and SIGTERM wait for the block to end, then act as they would have.

    For the few steps that must not be cut in half: removing temporary files on the way
    out of an interruption, moving a finished folder into place. A signal that arrived
    meanwhile is raised again once the block has ended (and the previous handlers are
    back): Ctrl-C still ends the command, only a few milliseconds later. Python runs
    signal handlers in the main thread only; in any other thread the block runs as is.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[int] = []

    def hold(signum: int, frame: object) -> None:
        received.append(signum)

    previous = {}
    for signum in _HELD_SIGNALS:
        handler = signal.getsignal(signum)
        if handler not in (None, signal.SIG_IGN):  # None: a handler not set from Python
            previous[signum] = signal.signal(signum, hold)
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        for held in dict.fromkeys(received):
            signal.raise_signal(held)


LOCK_NAME = ".lightcal-writing.lock"
"""The lock file `atomic_folder` holds in an existing folder while it moves files in."""

LOCK_WAIT_S = 30.0
"""How long `atomic_folder` waits for another writer's lock before giving up."""


@contextlib.contextmanager
def atomic_folder(
    target: str | Path, *, earlier_files: Callable[[Path], Iterable[str]] = lambda _: ()
) -> Iterator[Path]:
    """Write the files of the folder `target` aside, then move them in, complete.

    The block writes into the folder it is given: a new hidden sibling of `target`
    (`.NAME.<random>.tmp`). When the block ends normally:

    - `target` does not exist: the folder is renamed to `target`, atomically; readers
      never see a partial folder.
    - `target` exists (an earlier report, another run's that appeared meanwhile, or a
      folder of the user's): under a lock file in it (`LOCK_NAME`, naming this process),
      each file is moved in (replacing a file of the same name), then the files that
      `earlier_files(target)` names (the earlier writer's own, read before anything
      moves) and that this writer did not write are removed. Nothing else in `target` is
      touched. Writers take the lock one at a time, so two runs writing the same folder
      leave the files of one of them, never a mix. A writer finding the lock held waits
      up to `LOCK_WAIT_S` seconds; a lock left by a process that no longer exists is
      taken over (its files, listed in it, count as earlier ones).

    When the block raises (Ctrl-C included), the hidden folder is removed and `target`
    is untouched. The caller must not leave threads writing into the folder after its
    block ends.

    Args:
        target: The folder to write. Its parent must exist.
        earlier_files: The plain file names in an existing `target` that an earlier
            writer of the same kind put there (e.g. listed by one of its files).

    Raises:
        InputError: Another process holds the lock for longer than `LOCK_WAIT_S`.
        OSError: The file system said no; no hidden folder is left behind (`target`
            keeps what it had, unless moving files into an existing one failed midway).
    """
    target = Path(target)
    staging = _temporary_name(target)
    try:
        staging.mkdir()  # (a name no other folder has: removing it below is safe)
        yield staging
        _move_folder(staging, target, earlier_files)
    finally:
        with signals_held():  # after a rename, nothing is left to remove
            shutil.rmtree(staging, ignore_errors=True)


def _move_folder(
    staging: Path, target: Path, earlier_files: Callable[[Path], Iterable[str]]
) -> None:
    """`atomic_folder`'s end: `staging` renamed to `target`, or its files moved in."""
    if not os.path.lexists(target):
        with signals_held():
            try:
                staging.rename(target)
            except OSError as exc:  # another writer's folder appeared meanwhile: join it
                if exc.errno not in (errno.EEXIST, errno.ENOTEMPTY):
                    raise
            else:
                _fsync_folder(target.parent)
                return
    names = sorted(p.name for p in staging.iterdir())
    deadline = time.monotonic() + LOCK_WAIT_S
    while True:
        with signals_held():  # the lock is never left behind by an interruption
            holder, stale = _take_lock(target, names)
            if holder is None:
                try:
                    _move_in(staging, target, names, set(earlier_files(target)) | stale)
                finally:
                    _remove(target / LOCK_NAME)
                return
        if time.monotonic() >= deadline:
            raise InputError(
                target / LOCK_NAME,
                f"another lightcal run ({holder}) is writing into {target}; wait for it to "
                "end, or remove this lock file if no such run is going on",
            )
        time.sleep(0.05)


def _take_lock(folder: Path, names: list[str]) -> tuple[str | None, set[str]]:
    """Create `folder`'s lock file naming this process and `names` (the files it moves
    in). Returns (None, files of a stale lock taken over) when taken, else (who holds
    it, empty set)."""
    lock = folder / LOCK_NAME
    content = "".join(f"{line}\n" for line in (f"pid {os.getpid()}", *names)).encode()
    stale: set[str] = set()
    for _ in range(2):  # a second try after taking over a stale lock
        try:
            atomic_create_bytes(lock, content)
        except FileExistsError:
            pid, listed = _read_lock(lock)
            if pid is None:
                return "a process that left no id in its lock file", set()
            if _alive(pid):
                return f"process {pid}", set()
            stale |= listed  # its writer is gone: the files it moved in are earlier ones
            _remove(lock)
            continue
        return None, stale
    return "another process", set()


def _read_lock(lock: Path) -> tuple[int | None, set[str]]:
    """The process id and file names a lock file holds (None: unreadable)."""
    try:
        lines = lock.read_text(encoding="utf-8", errors="replace")[:1_000_000].splitlines()
    except OSError:
        return None, set()
    if not lines or not lines[0].startswith("pid ") or not lines[0][4:].isdigit():
        return None, set()
    return int(lines[0][4:]), set(lines[1:])


def _alive(pid: int) -> bool:
    """Whether process `pid` exists (where that cannot be known: yes)."""
    if os.name != "posix" or pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # PermissionError: another user's process
        return True
    return True


def _move_in(staging: Path, target: Path, names: list[str], earlier: set[str]) -> None:
    """Move `names` from `staging` into `target`, then remove the `earlier` files not
    among them (plain names of regular files only: never a folder, link or hidden file)."""
    for name in names:
        try:
            (staging / name).replace(target / name)
        except OSError as exc:
            if exc.errno != errno.EXDEV:  # `target` is a link to another file system
                raise
            atomic_write_bytes(target / name, (staging / name).read_bytes())
    for name in sorted(earlier - set(names)):
        if not _plain_name(name):
            continue
        path = target / name
        if path.is_file() and not path.is_symlink():
            _remove(path)
    _fsync_folder(target)


def _plain_name(name: str) -> bool:
    """A file name of one part, not hidden (what a writer may remove as its own)."""
    return bool(name) and not name.startswith(".") and "/" not in name and "\\" not in name
