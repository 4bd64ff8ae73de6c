"""Files uploaded through the page: size cap, safe unpacking, validation by the readers.

Limits (also shown in the page): at most `MAX_UPLOAD_BYTES` (50 MB) per file; a zip may
unpack to at most `MAX_UNPACKED_BYTES` (500 MB) in at most `MAX_ZIP_MEMBERS` files,
none with an absolute path or `..`. viser holds a whole upload in memory and has no
cap of its own, so `install_size_guard` drops a transfer whose announced size is over
the limit before its data arrives.

Every upload is written into a fresh folder and read back with the project, image and
photometry readers; anything they reject raises `InputError`, which the app shows in
the page. Nothing uploaded touches the original project's folder: a changed project
(another image, another RID file) is a new project file in the upload folder with
absolute paths.
"""

from __future__ import annotations

import io
import uuid
import zipfile
from collections.abc import Callable
from pathlib import Path, PurePosixPath
from typing import Any, Literal

from lightcal.errors import InputError
from lightcal.io.project import Project, ProjectFile, load_project, project_from_spec, save_project
from lightcal.pipeline import LoadedImages, load_images

MAX_UPLOAD_BYTES = 50 * 1024 * 1024
MAX_UNPACKED_BYTES = 500 * 1024 * 1024
MAX_ZIP_MEMBERS = 2000
PROJECT_SUFFIXES = (".json", ".yaml", ".yml")
RID_SUFFIXES = (".ies", ".ldt")


def format_size(n_bytes: int) -> str:
    """A byte count for people: '812 bytes', '3.4 kB', '51.2 MB'."""
    if n_bytes < 1000:
        return f"{n_bytes} bytes"
    if n_bytes < 1_000_000:
        return f"{n_bytes / 1e3:.1f} kB"
    return f"{n_bytes / 1e6:.1f} MB"


def check_size(name: str, size: int, *, limit: int = MAX_UPLOAD_BYTES) -> None:
    """InputError when an upload is over the limit (or empty)."""
    if size > limit:
        raise InputError(
            name,
            f"the file is {format_size(size)}; "
            f"uploads are limited to {format_size(limit)} per file",
        )
    if size == 0:
        raise InputError(name, "the file is empty")


def install_size_guard(
    server: Any, on_reject: Callable[[int, str, int], None], *, limit: int = MAX_UPLOAD_BYTES
) -> None:
    """Drop uploads announced over `limit` before their data is buffered.

    Runs after viser's own handler of the transfer start (handlers run in registration
    order) and forgets the transfer, so its parts are ignored.

    Args:
        server: the viser server.
        on_reject: called with (client id, file name, size in bytes) for a dropped upload.
        limit: the cap in bytes.
    """
    from viser import _messages

    gui = server.gui

    def guard(client_id: int, message: Any) -> None:
        if message.size_bytes > limit:
            gui._current_file_upload_states.pop(message.transfer_uuid, None)
            on_reject(client_id, message.filename, int(message.size_bytes))

    server._websock_server.register_handler(_messages.FileTransferStartUpload, guard)


def new_upload_folder(root: Path) -> Path:
    """A fresh folder for one upload."""
    folder = root / uuid.uuid4().hex[:12]
    folder.mkdir(parents=True)
    return folder


def _safe_member(name: str, archive: str) -> PurePosixPath:
    p = PurePosixPath(name)
    if p.is_absolute() or ".." in p.parts or name.startswith(("/", "\\")) or ":" in p.parts[0]:
        raise InputError(archive, f"unsafe path in the zip: {name!r}; expected relative paths")
    return p


def unpack_zip(name: str, content: bytes, folder: Path) -> None:
    """Extract a zip into `folder` after checking its paths and sizes."""
    try:
        zf = zipfile.ZipFile(io.BytesIO(content))
    except zipfile.BadZipFile as exc:
        raise InputError(name, "not a valid zip file") from exc
    with zf:
        members = [m for m in zf.infolist() if not m.is_dir()]
        if len(members) > MAX_ZIP_MEMBERS:
            raise InputError(name, f"the zip holds {len(members)} files; at most {MAX_ZIP_MEMBERS}")
        total = sum(m.file_size for m in members)
        if total > MAX_UNPACKED_BYTES:
            raise InputError(
                name,
                f"the zip unpacks to {format_size(total)}; "
                f"at most {format_size(MAX_UNPACKED_BYTES)}",
            )
        for m in members:
            rel = _safe_member(m.filename, name)
            target = folder.joinpath(*rel.parts)
            target.parent.mkdir(parents=True, exist_ok=True)
            with zf.open(m) as src:
                data = src.read(m.file_size + 1)
            if len(data) != m.file_size:
                raise InputError(name, f"{m.filename}: size differs from the zip's directory")
            target.write_bytes(data)


def find_project_file(folder: Path, source: str) -> Path:
    """The project file in an unpacked upload: project.json/.yaml/.yml, shallowest first."""
    candidates = sorted(
        (p for p in folder.rglob("*") if p.is_file() and p.stem == "project"),
        key=lambda p: (len(p.relative_to(folder).parts), str(p)),
    )
    candidates = [p for p in candidates if p.suffix.lower() in PROJECT_SUFFIXES]
    if not candidates:
        raise InputError(source, "no project file in the upload; expected project.json (or .yaml)")
    return candidates[0]


def receive_project(
    name: str, content: bytes, root: Path, *, limit: int = MAX_UPLOAD_BYTES
) -> tuple[Project, LoadedImages]:
    """Unpack and validate an uploaded project (a .zip with project.json, images, camera
    file; or a lone project file whose paths are absolute or relative to nothing else).

    Returns:
        the project and its images, read from a fresh folder under `root`.
    """
    check_size(name, len(content), limit=limit)
    folder = new_upload_folder(root)
    suffix = Path(name).suffix.lower()
    if suffix == ".zip":
        unpack_zip(name, content, folder)
        path = find_project_file(folder, name)
    elif suffix in PROJECT_SUFFIXES:
        path = folder / f"project{suffix}"
        path.write_bytes(content)
    else:
        raise InputError(name, "expected a project .zip, .json or .yaml file")
    try:
        project = load_project(path)
        loaded = load_images(project)
    except InputError as exc:
        raise InputError(name, _relative_message(exc, folder)) from exc
    return project, loaded


def _relative_message(exc: InputError, folder: Path) -> str:
    return str(exc).replace(str(folder.resolve()) + "/", "").replace(str(folder) + "/", "")


def absolute_spec(spec: ProjectFile, folder: Path) -> ProjectFile:
    """A copy of `spec` whose relative file paths are made absolute against `folder`."""

    def fix(p: str | None) -> str | None:
        if p is None:
            return None
        q = Path(p)
        return str(q if q.is_absolute() else (folder / q).resolve())

    camera = spec.camera.model_copy(update={"path": fix(spec.camera.path)})
    sensor = spec.sensor.model_copy(
        update={"vignetting": fix(spec.sensor.vignetting), "response": fix(spec.sensor.response)}
    )
    images = [
        im.model_copy(update={"path": fix(im.path), "mask": fix(im.mask)}) for im in spec.images
    ]
    lights = [
        ls.model_copy(update={"rid": ls.rid.model_copy(update={"path": fix(ls.rid.path)})})
        for ls in spec.lights
    ]
    return spec.model_copy(
        update={"camera": camera, "sensor": sensor, "images": images, "lights": lights}
    )


def _rebuild(project: Project, spec: ProjectFile, folder: Path) -> tuple[Project, LoadedImages]:
    path = folder / "project.json"
    save_project(spec, path)
    new = project_from_spec(spec, path)
    return new, load_images(new)


def receive_rid(
    name: str,
    content: bytes,
    project: Project,
    light_index: int,
    root: Path,
    *,
    limit: int = MAX_UPLOAD_BYTES,
) -> tuple[Project, LoadedImages]:
    """An uploaded IES/LDT file as the RID of light `light_index`.

    Returns:
        the project with that light's RID replaced, and its images.
    """
    check_size(name, len(content), limit=limit)
    suffix = Path(name).suffix.lower()
    if suffix not in RID_SUFFIXES:
        raise InputError(name, "expected an IES (.ies) or EULUMDAT (.ldt) file")
    if not 0 <= light_index < len(project.spec.lights):
        raise InputError("light", f"expected a light index below {len(project.spec.lights)}")
    folder = new_upload_folder(root)
    path = folder / Path(name).name
    path.write_bytes(content)
    kind: Literal["ies", "ldt"] = "ies" if suffix == ".ies" else "ldt"
    spec = absolute_spec(project.spec, project.folder)
    lights = list(spec.lights)
    light = lights[light_index]
    lights[light_index] = light.model_copy(
        update={"rid": light.rid.model_copy(update={"type": kind, "path": str(path)})}
    )
    spec = spec.model_copy(update={"lights": lights})
    try:
        return _rebuild(project, spec, folder)
    except InputError as exc:
        raise InputError(name, _relative_message(exc, folder)) from exc


def receive_image(
    name: str, content: bytes, project: Project, root: Path, *, limit: int = MAX_UPLOAD_BYTES
) -> tuple[Project, LoadedImages, int]:
    """An uploaded image replacing the project image with the same file name (or stem).

    Returns:
        the project with that image replaced, its images, and the replaced image's index.
    """
    check_size(name, len(content), limit=limit)
    stem = Path(name).stem
    index = next(
        (i for i, p in enumerate(project.image_paths) if p.name == Path(name).name),
        next((i for i, p in enumerate(project.image_paths) if p.stem == stem), None),
    )
    if index is None:
        known = ", ".join(p.name for p in project.image_paths)
        raise InputError(
            name, f"no project image has this file name; expected one of {known} (same pose)"
        )
    folder = new_upload_folder(root)
    path = folder / Path(name).name
    path.write_bytes(content)
    spec = absolute_spec(project.spec, project.folder)
    images = list(spec.images)
    images[index] = images[index].model_copy(
        update={"path": str(path), "name": project.names[index]}
    )
    spec = spec.model_copy(update={"images": images})
    try:
        new, loaded = _rebuild(project, spec, folder)
    except InputError as exc:
        raise InputError(name, _relative_message(exc, folder)) from exc
    return new, loaded, index
