"""Where the commands write: checked before any work, never onto an input, never outside.

- `project_inputs`: every file a project reads (the project, images, masks, camera, RID,
  vignetting and response files), by role.
- `check_output_file` / `check_output_folder`: an output path is refused when it is an
  input of the project or the command (the result, board or camera file it reads: never
  replaced, even with `--force`), or a folder holding one (for folders written into), a folder
  where a file is expected (or the reverse), in a folder that does not exist or is not
  writable, has a name longer than the file system allows, or replaces existing results
  without `force`. Checked before the work starts, so a long solve never ends in an
  unwritable path.
- `safe_name` / `inside`: names that come from the data (image names) become one plain
  file-name component, and every path built from one is proven to stay in its folder.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from lightcal.errors import InputError
from lightcal.io.project import Project

_UNSAFE = re.compile(r"[^A-Za-z0-9._+-]+")
NAME_MAX = 255
"""Longest file name (bytes) on the usual file systems."""


def project_inputs(project: Project) -> dict[Path, str]:
    """Every file `project` reads, resolved, with its role ("image view_03", ...)."""
    spec = project.spec
    folder = project.folder
    found: dict[Path, str] = {}

    def add(path: str | Path | None, role: str) -> None:
        if path is not None:
            p = Path(path)
            found.setdefault((p if p.is_absolute() else folder / p).resolve(), role)

    add(project.path, "the project file")

    for name, path in zip(project.names, project.image_paths, strict=True):
        add(path, f"image {name}")
    for name, mask in zip(project.names, project.mask_paths, strict=True):
        add(mask, f"mask of image {name}")
    add(getattr(spec.camera, "path", None), "the camera file")
    add(project.vignetting_path, "the vignetting file")
    add(spec.sensor.response, "the response curve")
    for light in spec.lights:
        add(getattr(light.rid, "path", None), f"the RID file of light {light.name}")
    return found


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.resolve() == b.resolve() or (a.exists() and b.exists() and a.samefile(b))
    except OSError:
        return False


def _check_name(path: Path, option: str) -> None:
    """Names the file system refuses (it would raise, not answer, when asked about them)."""
    if any(len(part.encode("utf-8")) > NAME_MAX for part in path.parts):
        raise InputError(path, f"{option}: the file name is longer than {NAME_MAX} bytes")
    if "\x00" in str(path):
        raise InputError(path, f"{option}: the path contains a NUL character")


def _check_parent(path: Path, option: str) -> None:
    parent = path.parent
    if not parent.is_dir():
        raise InputError(path, f"{option}: the folder {parent} does not exist; create it first")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(path, f"{option}: the folder {parent} is not writable")


def check_output_file(
    path: Path,
    *,
    option: str,
    inputs: dict[Path, str] | None = None,
    force: bool = True,
    inputs_of: str = "the project",
) -> Path:
    """Validate a file the command will write (see the module docstring); returns it.

    inputs: every file the command reads, resolved, with its role; never replaced, even
        with `force`.
    force: False refuses an existing file (results the user may want to keep).
    inputs_of: whose inputs they are, for the message ("the project", "the export").
    """
    path = Path(path)
    _check_name(path, option)
    if path.is_dir():
        raise InputError(path, f"{option}: is a folder; expected the path of a file to write")
    if path.exists() and not path.is_file():
        raise InputError(path, f"{option}: is not a regular file; expected a file to write")
    for p, role in (inputs or {}).items():
        if _same_file(path, p):
            raise InputError(path, f"{option}: is {role}, an input of {inputs_of}; write elsewhere")
    _check_parent(path, option)
    if path.exists() and not force:
        raise InputError(path, f"{option}: exists; use --force to replace it")
    return path


def check_output_folder(
    path: Path, *, option: str, inputs: dict[Path, str] | None = None, force: bool = False
) -> Path:
    """Validate a folder the command will write files into; returns it.

    A folder holding an input of the project is refused (its files could be replaced), and
    so is a non-empty folder without `force`.
    """
    path = Path(path)
    _check_name(path, option)
    if path.exists() and not path.is_dir():
        raise InputError(path, f"{option}: is a file; expected a folder to write into")
    resolved = path.resolve()
    for p, role in (inputs or {}).items():
        if p.parent == resolved:
            raise InputError(
                path, f"{option}: holds {role}, an input of the project; choose another folder"
            )
    if path.is_dir():
        if not os.access(path, os.W_OK | os.X_OK):
            raise InputError(path, f"{option}: the folder is not writable")
        if not force and any(path.iterdir()):
            raise InputError(
                path, f"{option}: the folder is not empty; use --force to write into it"
            )
    else:
        _check_parent(path, option)
    return path


def safe_name(name: str) -> str:
    """`name` (from the data: an image name, a light name) as one plain file-name part.

    Separators, `..`, spaces and other characters outside [A-Za-z0-9._+-] become `_`;
    leading dots are dropped (no hidden or parent names); never empty.
    """
    plain = _UNSAFE.sub("_", str(name)).lstrip(".")
    plain = plain.replace("..", "_")
    return plain[: NAME_MAX - 40] or "unnamed"


def safe_names(names: list[str]) -> list[str]:
    """`safe_name` of each, made unique (a suffix _2, _3, ... where two would meet)."""
    seen: set[str] = set()
    out = []
    for name in names:
        base = safe_name(name)
        plain, k = base, 1
        while plain in seen:
            k += 1
            plain = f"{base}_{k}"
        seen.add(plain)
        out.append(plain)
    return out


def inside(folder: Path, filename: str) -> Path:
    """folder / filename, proven to stay inside folder (InputError otherwise)."""
    target = Path(folder) / filename
    if target.resolve().parent != Path(folder).resolve():
        raise InputError(target, f"refusing to write outside {folder}")
    return target
