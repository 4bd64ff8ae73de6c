"""The data lightcal ships: the sample project and the app's pictures, and where they are.

In the repository they are the top-level folders `sample_data/` and `static/`. The wheel
carries them as package data (pyproject.toml maps them to `lightcal/sample_data/` and
`lightcal_app/static/`), so an installed copy finds them inside the package.
`data_folder` looks there first and falls back to the repository's folder, so a source
checkout, an editable install and an installed wheel all work.

`write_sample_project` copies the sample project to a folder of the user's
(`lightcal sample PATH`, and `lightcal app` without a project when installed: the
copy in `user_sample_dir()` keeps the app's autosave out of site-packages); it never
overwrites a file.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path

from lightcal import __version__
from lightcal.errors import InputError
from lightcal.io.atomic import atomic_create_bytes

__all__ = [
    "SampleCopy",
    "data_folder",
    "packaged_folder",
    "sample_files",
    "sample_project_dir",
    "sample_project_is_packaged",
    "user_sample_dir",
    "write_sample_project",
]

REPO_DIR = Path(__file__).resolve().parents[1]
"""The repository's root when this module runs from a source checkout."""

_NOT_SAMPLE_FILES = (".session.json", ".session.json.bad", ".saved-session.json", ".pyc")
"""Endings of files that may sit in a used sample folder but are not part of the sample."""


def packaged_folder(package: str, name: str) -> Path | None:
    """The folder `name` installed inside `package`, or None where there is none.

    Args:
        package: An importable regular package, e.g. "lightcal".
        name: The folder inside it, e.g. "sample_data".
    """
    root = files(package)
    if isinstance(root, Path) and (root / name).is_dir():
        return root / name
    return None


def data_folder(package: str, name: str, checkout_name: str | None = None) -> Path:
    """The folder `name` of `package` when installed, else the repository's top-level
    folder `checkout_name` (default `name`); it may not exist (a broken checkout)."""
    found = packaged_folder(package, name)
    return found if found is not None else REPO_DIR / (checkout_name or name)


def sample_project_dir() -> Path:
    """The bundled sample project's folder (`project.json`, images, masks, truth, ...)."""
    return data_folder("lightcal", "sample_data")


def sample_project_is_packaged() -> bool:
    """True when the sample is the installed package's copy (site-packages, often
    read-only and not a place for the user's files), False in a source checkout."""
    return packaged_folder("lightcal", "sample_data") is not None


def user_sample_dir() -> Path:
    """`$XDG_DATA_HOME/lightcal/sample-VERSION` (default ~/.local/share/lightcal/...):
    the user's copy of the sample that an installed `lightcal app` opens by default."""
    base = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(base) / "lightcal" / f"sample-{__version__}"


def sample_files(folder: Path) -> list[Path]:
    """The sample project's files under `folder`, relative to it, sorted.

    Leaves out what using the sample adds: `__pycache__/`, hidden files and the app's
    session files.
    """
    found = []
    for path in folder.rglob("*"):
        rel = path.relative_to(folder)
        if not path.is_file() or any(p.startswith(".") or p == "__pycache__" for p in rel.parts):
            continue
        if path.name.endswith(_NOT_SAMPLE_FILES):
            continue
        found.append(rel)
    return sorted(found)


@dataclass(frozen=True)
class SampleCopy:
    """What `write_sample_project` did.

    Attributes:
        folder: where the sample is.
        written: the files written, relative to `folder`.
        kept: the sample's files that already existed there and were left as they were.
    """

    folder: Path
    written: tuple[Path, ...]
    kept: tuple[Path, ...]


def write_sample_project(
    folder: str | Path, *, force: bool = False, source: Path | None = None
) -> SampleCopy:
    """Copy the sample project into `folder`.

    A new folder is filled under a temporary name beside it and renamed at the end, so
    it appears complete or not at all. Into an existing folder (empty, or any with
    `force`), each file is created atomically and only where none exists: a file of
    that name is kept as it is (so `force` restores missing files without touching
    edited ones).

    Args:
        folder: The folder to write (created with its parents when missing).
        force: Also write into a non-empty folder.
        source: The sample to copy (default `sample_project_dir()`).

    Raises:
        InputError: `folder` is a file, or a non-empty folder without `force`, or the
            sample is missing.
        OSError: `folder` cannot be written.
    """
    dest = Path(folder)
    source = source if source is not None else sample_project_dir()
    if not (source / "project.json").is_file():
        raise InputError(source / "project.json", "the bundled sample project is missing")
    names = sample_files(source)
    if dest.exists() or dest.is_symlink():
        if not dest.is_dir():
            raise InputError(dest, "exists and is not a folder; choose a new folder")
        if not force and any(dest.iterdir()):
            raise InputError(
                dest,
                "the folder is not empty; choose a new or empty folder, or add --force to "
                "write the sample's missing files into it (existing files are never "
                "overwritten)",
            )
        return _add_missing_files(source, names, dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    temp = dest.parent / f".{dest.name}.{secrets.token_hex(6)}.partial"
    temp.mkdir()  # the usual 0o777 & ~umask, unlike tempfile.mkdtemp's 0o700
    try:
        for rel in names:
            (temp / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(source / rel, temp / rel)
        temp.rename(dest)
    except BaseException:
        with contextlib.suppress(OSError):
            shutil.rmtree(temp)
        raise
    return SampleCopy(dest, tuple(names), ())


def _add_missing_files(source: Path, names: list[Path], dest: Path) -> SampleCopy:
    written, kept = [], []
    for rel in names:
        target = dest / rel
        if os.path.lexists(target):
            kept.append(rel)
            continue
        target.parent.mkdir(parents=True, exist_ok=True)
        try:
            atomic_create_bytes(target, (source / rel).read_bytes())
        except FileExistsError:  # appeared meanwhile
            kept.append(rel)
        else:
            written.append(rel)
    return SampleCopy(dest, tuple(written), tuple(kept))
