"""Checks on uploaded files before the project readers touch them.

- Zips: at most `MAX_ZIP_MEMBERS` files and `MAX_UNPACKED_BYTES` unpacked (each
  member's bytes are counted as they are written, not taken from the zip's directory),
  relative paths only, and (`unpack_zip`) a project file among them, all checked before
  extraction; `extract_zip` makes the same checks on a zip of any files (the photos of a
  new project, `lightcal_app.photo_project`).
- Confinement: every file a project names (camera, images, masks, RID files, sensor
  maps) must be a relative path that stays inside the upload's folder; absolute and
  escaping paths are refused before any of those files is read.
- Images: the width and height in the file's header (PNG, JPEG, TIFF, NPY, EXR) at
  most `MAX_IMAGE_SIDE` and `MAX_IMAGE_PIXELS`, read before anything is decoded.
- Folders: each upload is written into a folder of its own, removed when rejected;
  the upload folder holds at most `MAX_UPLOAD_FOLDER_BYTES`, the oldest uploads
  removed first (never the project shown).
"""

from __future__ import annotations

import contextlib
import io
import shutil
import uuid
import zipfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path, PurePosixPath, PureWindowsPath

from lightcal.errors import InputError
from lightcal.io.image_header import check_image_size
from lightcal.io.project import ProjectFile

MAX_UNPACKED_BYTES = 500 * 1024 * 1024
MAX_ZIP_MEMBERS = 2000
MAX_UPLOAD_FOLDER_BYTES = 2 * 1024**3
MAX_IMAGE_SIDE = 20_000
MAX_IMAGE_PIXELS = 100_000_000
PROJECT_SUFFIXES = (".json", ".yaml", ".yml")


def format_size(n_bytes: int) -> str:
    """A byte count for people: '812 bytes', '3.4 kB', '51.2 MB'."""
    if n_bytes < 1000:
        return f"{n_bytes} bytes"
    if n_bytes < 1_000_000:
        return f"{n_bytes / 1e3:.1f} kB"
    return f"{n_bytes / 1e6:.1f} MB"


# ---------------------------------------------------------------------------- folders


def _size_of(folder: Path) -> int:
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file() and not p.is_symlink())


def make_room(root: Path, incoming: int, *, keep: Iterable[Path] = (), limit: int) -> None:
    """Remove the oldest upload folders under `root` until `incoming` more bytes fit in
    `limit` (folders in `keep`, or holding them, stay)."""
    if not root.is_dir():
        return
    kept = [k.resolve() for k in keep]
    folders = sorted(
        (p for p in root.iterdir() if p.is_dir() and not p.is_symlink()),
        key=lambda p: p.stat().st_mtime,
    )
    sizes = {p: _size_of(p) for p in folders}
    total = sum(sizes.values())
    for p in folders:
        if total + incoming <= limit:
            return
        if any(k == p.resolve() or k.is_relative_to(p.resolve()) for k in kept):
            continue
        shutil.rmtree(p, ignore_errors=True)
        total -= sizes[p]


@contextmanager
def upload_folder(root: Path) -> Iterator[Path]:
    """A fresh folder under `root` for one upload, removed with everything in it when
    the block raises (a rejected upload leaves nothing behind)."""
    folder = root / uuid.uuid4().hex[:12]
    folder.mkdir(parents=True)
    try:
        yield folder
    except BaseException:
        shutil.rmtree(folder, ignore_errors=True)
        raise


# ---------------------------------------------------------------------------- zips


def _safe_member(name: str, archive: str) -> PurePosixPath:
    p = PurePosixPath(name)
    if (
        p.is_absolute()
        or ".." in p.parts
        or name.startswith(("/", "\\"))
        or "\\" in name
        or PureWindowsPath(name).drive
        or (p.parts and ":" in p.parts[0])
    ):
        raise InputError(archive, f"unsafe path in the zip: {name!r}; expected relative paths")
    return p


def project_member(names: list[PurePosixPath], archive: str) -> PurePosixPath:
    """The project file among a zip's members: project.json/.yaml/.yml, shallowest first."""
    candidates = sorted(
        (p for p in names if p.stem == "project" and p.suffix.lower() in PROJECT_SUFFIXES),
        key=lambda p: (len(p.parts), str(p)),
    )
    if not candidates:
        raise InputError(archive, "no project file in the upload; expected project.json (or .yaml)")
    return candidates[0]


def unpack_zip(
    name: str,
    content: bytes,
    folder: Path,
    *,
    max_bytes: int = MAX_UNPACKED_BYTES,
    max_members: int = MAX_ZIP_MEMBERS,
) -> Path:
    """Extract a zip into `folder` after checking its paths, its member count and that it
    holds a project file; stops as soon as the bytes written pass `max_bytes`.

    Returns:
        the project file's path in `folder`.
    """
    with _open_zip(name, content) as zf:
        members, paths = _checked_members(zf, name, max_members)
        project = project_member(paths, name)
        _extract(zf, members, paths, name, folder, max_bytes)
    return folder.joinpath(*project.parts)


def extract_zip(
    name: str,
    content: bytes,
    folder: Path,
    *,
    max_bytes: int = MAX_UNPACKED_BYTES,
    max_members: int = MAX_ZIP_MEMBERS,
) -> list[Path]:
    """Extract any zip into `folder` with the checks of `unpack_zip` (paths, member count,
    bytes written), without asking for a project file.

    Returns:
        the extracted files, in the zip's order.
    """
    with _open_zip(name, content) as zf:
        members, paths = _checked_members(zf, name, max_members)
        return _extract(zf, members, paths, name, folder, max_bytes)


def _open_zip(name: str, content: bytes) -> zipfile.ZipFile:
    try:
        return zipfile.ZipFile(io.BytesIO(content))
    except zipfile.BadZipFile as exc:
        raise InputError(name, "not a valid zip file") from exc


def _checked_members(
    zf: zipfile.ZipFile, name: str, max_members: int
) -> tuple[list[zipfile.ZipInfo], list[PurePosixPath]]:
    """The zip's files (folders left out) and their checked relative paths."""
    members = [m for m in zf.infolist() if not m.is_dir()]
    if len(members) > max_members:
        raise InputError(name, f"the zip holds {len(members)} files; at most {max_members}")
    return members, [_safe_member(m.filename, name) for m in members]


def _extract(
    zf: zipfile.ZipFile,
    members: list[zipfile.ZipInfo],
    paths: list[PurePosixPath],
    name: str,
    folder: Path,
    max_bytes: int,
) -> list[Path]:
    """Write the members under `folder`, counting the bytes as they are written."""
    declared = sum(m.file_size for m in members)
    if declared > max_bytes:
        raise InputError(name, _too_big(declared, max_bytes))
    written = 0
    out: list[Path] = []
    for m, rel in zip(members, paths, strict=True):
        target = folder.joinpath(*rel.parts)
        target.parent.mkdir(parents=True, exist_ok=True)
        try:
            with zf.open(m) as src, target.open("wb") as dst:
                while chunk := src.read(1 << 20):
                    written += len(chunk)
                    if written > max_bytes:
                        raise InputError(name, _too_big(written, max_bytes))
                    dst.write(chunk)
        except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, EOFError) as exc:
            raise InputError(name, f"{m.filename}: cannot be unpacked") from exc
        out.append(target)
    return out


def _too_big(n: int, limit: int) -> str:
    return f"the zip unpacks to more than {format_size(limit)} (at least {format_size(n)})"


# ---------------------------------------------------------------------------- confinement


def project_paths(spec: ProjectFile) -> list[tuple[str, str]]:
    """(field, path) of every file a project names."""
    out = [("camera.path", spec.camera.path)]
    out += [
        ("sensor.vignetting", spec.sensor.vignetting),
        ("sensor.response", spec.sensor.response),
    ]
    for i, im in enumerate(spec.images):
        out += [(f"images[{i}].path", im.path), (f"images[{i}].mask", im.mask)]
        out += [(f"images[{i}].dark", im.dark)]
    out += [(f"lights[{j}].rid.path", ls.rid.path) for j, ls in enumerate(spec.lights)]
    return [(f, p) for f, p in out if p is not None]


def check_confined(spec: ProjectFile, folder: Path, source: str) -> None:
    """InputError naming the field when a file the project names is not inside `folder`."""
    root = folder.resolve()
    for field, path in project_paths(spec):
        p = PurePosixPath(path.replace("\\", "/"))
        inside = not (p.is_absolute() or PureWindowsPath(path).drive or ".." in p.parts)
        if inside:
            inside = (root / p).resolve().is_relative_to(root)
        if not inside:
            raise InputError(
                source,
                f"{field}: expected a path inside the uploaded project (relative, without "
                "'..'); absolute and escaping paths are refused",
            )


# ---------------------------------------------------------------------------- images


def check_image_headers(paths: Iterable[Path], source: str) -> None:
    """InputError when an image's header declares more pixels than the app decodes."""
    for path in paths:
        with contextlib.suppress(OSError):
            check_image_size(
                path, max_side=MAX_IMAGE_SIDE, max_pixels=MAX_IMAGE_PIXELS, source=source
            )
