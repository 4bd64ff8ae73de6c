"""Checks on uploaded files before the project readers touch them.

- Zips: at most `MAX_ZIP_MEMBERS` files and `MAX_UNPACKED_BYTES` unpacked (each
  member's bytes are counted as they are written, not taken from the zip's directory),
  relative paths only, and a project file among them, all checked before extraction.
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
import struct
import uuid
import zipfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path, PurePosixPath, PureWindowsPath

from lightcal.errors import InputError
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
    try:
        zf = zipfile.ZipFile(io.BytesIO(content))
    except zipfile.BadZipFile as exc:
        raise InputError(name, "not a valid zip file") from exc
    with zf:
        members = [m for m in zf.infolist() if not m.is_dir()]
        if len(members) > max_members:
            raise InputError(name, f"the zip holds {len(members)} files; at most {max_members}")
        paths = [_safe_member(m.filename, name) for m in members]
        project = project_member(paths, name)
        declared = sum(m.file_size for m in members)
        if declared > max_bytes:
            raise InputError(name, _too_big(declared, max_bytes))
        written = 0
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
    return folder.joinpath(*project.parts)


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


def header_size(path: Path) -> tuple[int, int] | None:
    """(width, height) from an image file's header without decoding it; None when the
    format has no header read here (camera raw files)."""
    suffix = path.suffix.lower()
    if suffix == ".npy":
        return _npy_size(path)
    if suffix == ".exr":
        return _exr_size(path)
    if suffix == ".png":
        return _png_size(path)
    if suffix in (".jpg", ".jpeg", ".tif", ".tiff"):
        from PIL import Image

        Image.MAX_IMAGE_PIXELS = None  # the size is checked below, nothing is decoded
        try:
            with Image.open(path) as im:
                return int(im.size[0]), int(im.size[1])
        except Exception:
            return None  # the image reader says what is wrong
    return None


def _png_size(path: Path) -> tuple[int, int] | None:
    """Width and height of a PNG's IHDR chunk (its first, at byte 8)."""
    try:
        with path.open("rb") as f:
            head = f.read(24)
    except OSError:
        return None
    if len(head) < 24 or head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR":
        return None
    w, h = struct.unpack(">II", head[16:24])
    return int(w), int(h)


def _npy_size(path: Path) -> tuple[int, int] | None:
    import numpy as np

    try:
        with path.open("rb") as f:
            version = np.lib.format.read_magic(f)
            read = {
                (1, 0): np.lib.format.read_array_header_1_0,
                (2, 0): np.lib.format.read_array_header_2_0,
            }.get(version)
            if read is None:
                return None
            shape, _, _ = read(f)
    except Exception:
        return None
    if len(shape) < 2:
        return None
    return int(shape[1]), int(shape[0])


def _exr_size(path: Path) -> tuple[int, int] | None:
    """The dataWindow of an OpenEXR header (attributes: name, type, size, value)."""
    try:
        with path.open("rb") as f:
            head = f.read(1 << 16)
    except OSError:
        return None
    if head[:4] != b"\x76\x2f\x31\x01":
        return None
    pos = 8
    while pos < len(head) and head[pos] != 0:
        name_end = head.find(b"\0", pos)
        type_end = head.find(b"\0", name_end + 1)
        if name_end < 0 or type_end < 0 or type_end + 5 > len(head):
            return None
        (size,) = struct.unpack_from("<i", head, type_end + 1)
        value = type_end + 5
        if head[pos:name_end] == b"dataWindow" and size == 16 and value + 16 <= len(head):
            x0, y0, x1, y1 = struct.unpack_from("<4i", head, value)
            return x1 - x0 + 1, y1 - y0 + 1
        pos = value + max(size, 0)
    return None


def check_image_headers(paths: Iterable[Path], source: str) -> None:
    """InputError when an image's header declares more pixels than the app decodes."""
    for path in paths:
        with contextlib.suppress(OSError):
            size = header_size(path)
            if size is None:
                continue
            w, h = size
            if w > MAX_IMAGE_SIDE or h > MAX_IMAGE_SIDE or w * h > MAX_IMAGE_PIXELS:
                raise InputError(
                    source,
                    f"{path.name}: the image is {w} x {h} pixels; at most {MAX_IMAGE_SIDE} "
                    f"a side and {MAX_IMAGE_PIXELS // 1_000_000} megapixels",
                )
