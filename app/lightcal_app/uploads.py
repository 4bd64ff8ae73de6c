"""Files uploaded through the page: size caps, safe unpacking, validation by the readers.

Limits (also shown in the page): at most `MAX_UPLOAD_BYTES` (50 MB) per file, and the
checks of `lightcal_app.upload_checks` (zip size and member count, paths confined to
the upload, image sizes from their headers, a bound on the upload folder). viser holds
a whole upload in memory and has no cap of its own: `lightcal_app.transfer_guard`
bounds the bytes in flight.

Every upload is written into a fresh folder and read back with the project, image and
photometry readers; anything they reject raises `InputError`, which the app shows in
the page, and the folder is removed. Nothing uploaded touches the original project's
folder: a changed project (another image, another RID file) is a new project file in
the upload folder with absolute paths.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from lightcal.errors import InputError
from lightcal.io.document import read_document
from lightcal.io.project import (
    Project,
    ProjectFile,
    RIDSpec,
    parse_project,
    project_from_spec,
    save_project,
)
from lightcal.pipeline import LoadedImages, load_images
from lightcal_app.upload_checks import (
    MAX_UPLOAD_FOLDER_BYTES,
    PROJECT_SUFFIXES,
    check_confined,
    check_image_headers,
    format_size,
    make_room,
    unpack_zip,
    upload_folder,
)

MAX_UPLOAD_BYTES = 50 * 1024 * 1024
RID_SUFFIXES = (".ies", ".ldt")


@dataclass(frozen=True)
class Place:
    """Where uploads go.

    Attributes:
        root: the upload folder (one sub-folder per upload).
        limit: the per-file cap in bytes.
        keep: folders under `root` that must stay (those the project shown reads).
    """

    root: Path
    limit: int = MAX_UPLOAD_BYTES
    keep: tuple[Path, ...] = ()


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


def receive_project(name: str, content: bytes, place: Place) -> tuple[Project, LoadedImages]:
    """Unpack and validate an uploaded project (a .zip with project.json, images, camera
    file; or a lone project file naming no other file).

    Returns:
        the project and its images, read from a fresh folder under `place.root`.
    """
    check_size(name, len(content), limit=place.limit)
    suffix = Path(name).suffix.lower()
    if suffix not in (".zip", *PROJECT_SUFFIXES):
        raise InputError(name, "expected a project .zip, .json or .yaml file")
    make_room(place.root, len(content), keep=place.keep, limit=MAX_UPLOAD_FOLDER_BYTES)
    with upload_folder(place.root) as folder:
        if suffix == ".zip":
            path = unpack_zip(name, content, folder)
        else:
            path = folder / f"project{suffix}"
            path.write_bytes(content)
        try:
            doc = read_document(path, what="project file", as_json=path.suffix.lower() == ".json")
            spec = parse_project(doc, path)
            check_confined(spec, path.parent, name)
            project = project_from_spec(spec, path.resolve())
            check_image_headers(project.image_paths, name)
            loaded = load_images(project)
        except InputError as exc:
            raise InputError(name, relative_message(exc, folder, name)) from exc
    return project, loaded


def relative_message(exc: InputError, folder: Path, name: str) -> str:
    """The reader's message with the upload folder left out (and the upload's own name
    once: the caller puts it in front)."""
    text = str(exc).replace(str(folder.resolve()) + "/", "").replace(str(folder) + "/", "")
    return text.removeprefix(f"{name}: ")


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
        im.model_copy(update={"path": fix(im.path), "mask": fix(im.mask), "dark": fix(im.dark)})
        for im in spec.images
    ]
    lights = [
        ls.model_copy(update={"rid": ls.rid.model_copy(update={"path": fix(ls.rid.path)})})
        for ls in spec.lights
    ]
    return spec.model_copy(
        update={"camera": camera, "sensor": sensor, "images": images, "lights": lights}
    )


def _file_name(name: str, suffix: str) -> str:
    """The uploaded file's own name, without any folder (never empty)."""
    base = Path(name.replace("\\", "/")).name
    return base if base not in ("", ".", "..") else f"upload{suffix}"


_UNSAFE_CHARACTERS = re.compile(r"[^A-Za-z0-9._+-]")
MAX_NAME_CHARACTERS = 120


def safe_file_name(name: str, suffix: str = "") -> str:
    """The uploaded file's own name made safe to store: no folder, only letters, digits and
    `._+-` (anything else becomes `_`), no leading dot (hidden files are skipped by the
    readers of a folder), at most `MAX_NAME_CHARACTERS` with its suffix kept."""
    base = _UNSAFE_CHARACTERS.sub("_", _file_name(name, suffix))
    if base.startswith("."):
        base = "_" + base[1:]
    if len(base) > MAX_NAME_CHARACTERS:
        ext = Path(base).suffix[:20]
        base = base[: MAX_NAME_CHARACTERS - len(ext)] + ext
    return base


def _with_upload(
    name: str,
    content: bytes,
    project: Project,
    place: Place,
    change: Callable[[ProjectFile, Path], ProjectFile],
) -> tuple[Project, LoadedImages]:
    """Write the upload into a fresh folder, change the project's spec with it (paths
    made absolute) and read the new project back; the folder goes when it fails."""
    check_size(name, len(content), limit=place.limit)
    make_room(place.root, len(content), keep=place.keep, limit=MAX_UPLOAD_FOLDER_BYTES)
    with upload_folder(place.root) as folder:
        path = folder / _file_name(name, Path(name).suffix.lower())
        path.write_bytes(content)
        try:
            check_image_headers([path], name)
            spec = change(absolute_spec(project.spec, project.folder), path)
            new_path = folder / "project.json"
            save_project(spec, new_path)
            new = project_from_spec(spec, new_path)
            return new, load_images(new)
        except InputError as exc:
            raise InputError(name, relative_message(exc, folder, name)) from exc


def receive_rid(
    name: str, content: bytes, project: Project, light_index: int, place: Place
) -> tuple[Project, LoadedImages]:
    """An uploaded IES/LDT file as the RID of light `light_index`.

    Returns:
        the project with that light's RID replaced, and its images.
    """
    suffix = Path(name).suffix.lower()
    if suffix not in RID_SUFFIXES:
        raise InputError(name, "expected an IES (.ies) or EULUMDAT (.ldt) file")
    if not 0 <= light_index < len(project.spec.lights):
        raise InputError("light", f"expected a light index below {len(project.spec.lights)}")
    kind: Literal["ies", "ldt"] = "ies" if suffix == ".ies" else "ldt"

    def change(spec: ProjectFile, path: Path) -> ProjectFile:
        lights = list(spec.lights)
        # A fresh RID: the old type's fields (half_angle_deg, m, ...) would be keys the
        # new type ignores, which a saved project's reload refuses.
        rid = RIDSpec(type=kind, path=str(path))
        lights[light_index] = lights[light_index].model_copy(update={"rid": rid})
        return spec.model_copy(update={"lights": lights})

    return _with_upload(name, content, project, place, change)


def receive_image(
    name: str, content: bytes, project: Project, place: Place
) -> tuple[Project, LoadedImages, int]:
    """An uploaded image replacing the project image with the same file name (or stem).

    Returns:
        the project with that image replaced, its images, and the replaced image's index.
    """
    base = _file_name(name, "")
    stem = Path(base).stem
    index = next(
        (i for i, p in enumerate(project.image_paths) if p.name == base),
        next((i for i, p in enumerate(project.image_paths) if p.stem == stem), None),
    )
    if index is None:
        known = ", ".join(p.name for p in project.image_paths)
        raise InputError(
            name, f"no project image has this file name; expected one of {known} (same pose)"
        )

    def change(spec: ProjectFile, path: Path) -> ProjectFile:
        images = list(spec.images)
        images[index] = images[index].model_copy(
            update={"path": str(path), "name": project.names[index]}
        )
        return spec.model_copy(update={"images": images})

    new, loaded = _with_upload(name, content, project, place, change)
    return new, loaded, index
