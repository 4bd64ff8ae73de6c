"""Read and write camera intrinsics files.

Formats read by `read_camera`, chosen by the file's suffix:

- `.yaml`, `.yml`, `.xml`: files written by OpenCV's `cv2.FileStorage` (a `%YAML`
  header and `!!opencv-matrix` nodes, or OpenCV XML), read with `cv2.FileStorage`;
  a `.yaml`/`.yml` file without a `%YAML` header nor OpenCV tags is read as plain
  YAML (e.g. ROS `camera_info` files).
- `.json`: plain JSON (also what `cv2.FileStorage` writes as JSON).
- `.txt`: a COLMAP `cameras.txt` (see `read_camera`).

In YAML and JSON files the keys may be spelt (the first one is what we write):

| value | accepted keys |
|---|---|
| 3x3 intrinsics | `camera_matrix`, `K`, `cameraMatrix` |
| distortion | `distortion_coefficients`, `dist_coeffs`, `D`, `distCoeffs` |
| width | `image_width`, `width` (or `image_size: [w, h]`) |
| height | `image_height`, `height` (or `image_size: [w, h]`) |
| intrinsics covariance (optional) | `intrinsics_covariance` |

A matrix is an OpenCV matrix (`rows`, `cols`, `data`), a nested list, or a flat
row-major list (9 values for K). Distortion has 0, 4, 5 or 8 coefficients
(12 or 14 are accepted when the thin-prism and tilt terms are all zero).

`intrinsics_covariance` (optional, written by `lightcal camera calibrate`) is the
(p, p) covariance of (fx, fy, cx, cy, k1, k2, p1, p2[, k3[, k4, k5, k6]]), p = 4 + the
number of distortion coefficients (`Camera.intrinsics_covariance`); files without it
give a camera whose intrinsics' uncertainty is unknown.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from lightcal.core.camera import Camera
from lightcal.errors import InputError
from lightcal.io.atomic import atomic_create_bytes, atomic_write_text
from lightcal.io.camera_mapping import (
    KEY_COVARIANCE,
    build_camera,
    camera_from_mapping,
)
from lightcal.io.document import check_bounds
from lightcal.io.image_header import MAX_IMAGE_SIDE
from lightcal.io.text_files import check_regular_file, read_text

OPENCV_SUFFIXES = (".yaml", ".yml", ".xml")
"""Suffixes written with `cv2.FileStorage` by `write_camera`."""

COLMAP_MODELS: dict[str, tuple[str, ...]] = {
    "SIMPLE_PINHOLE": ("f", "cx", "cy"),
    "PINHOLE": ("fx", "fy", "cx", "cy"),
    "SIMPLE_RADIAL": ("f", "cx", "cy", "k"),
    "RADIAL": ("f", "cx", "cy", "k1", "k2"),
    "OPENCV": ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2"),
    "FULL_OPENCV": (
        "fx",
        "fy",
        "cx",
        "cy",
        "k1",
        "k2",
        "p1",
        "p2",
        "k3",
        "k4",
        "k5",
        "k6",
    ),
}
"""COLMAP camera models that `read_camera` converts, with their parameter names."""

_SUPPORTED = ".yaml, .yml, .xml, .json or a COLMAP cameras .txt"


def read_camera(path: str | Path, *, camera_id: int | None = None) -> Camera:
    """Read a camera from an OpenCV YAML/XML, JSON, YAML or COLMAP cameras.txt file.

    COLMAP `cameras.txt` lines read `CAMERA_ID MODEL WIDTH HEIGHT PARAMS...` for the
    models SIMPLE_PINHOLE (f, cx, cy), PINHOLE (fx, fy, cx, cy), SIMPLE_RADIAL
    (f, cx, cy, k), RADIAL (f, cx, cy, k1, k2), OPENCV (fx, fy, cx, cy, k1, k2, p1, p2)
    and FULL_OPENCV (fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6); their
    distortion is OpenCV's. COLMAP puts the centre of the upper-left pixel at
    (0.5, 0.5), lightcal (like OpenCV) at (0, 0), so the principal point is
    converted as cx = cx_colmap - 0.5, cy = cy_colmap - 0.5. The radial-only
    models become 4 OpenCV coefficients (k1, k2, 0, 0); the pinhole ones none.

    Args:
        path: The camera file.
        camera_id: For a COLMAP cameras.txt: which camera to read. May be omitted
            when the file holds exactly one camera. Not allowed for other formats.

    Returns:
        The camera.

    Raises:
        InputError: The file is missing, unreadable or corrupt, a key is missing, a
            matrix has the wrong shape or non-finite values, or the intrinsics are
            invalid. The message names the key and what was expected.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    check_regular_file(path, "camera file")
    if suffix not in (*OPENCV_SUFFIXES, ".json", ".txt"):
        raise InputError(path, f"unsupported file suffix {path.suffix!r}: expected {_SUPPORTED}")
    text = read_text(path, "camera file")

    if suffix == ".txt":
        return _read_colmap(path, text, camera_id)
    if not text.strip():
        raise InputError(path, "empty file: expected a mapping of keys")
    if camera_id is not None:
        raise InputError(
            "camera_id",
            f"applies only to COLMAP cameras.txt files, got camera_id={camera_id} "
            f"for a {suffix} file",
        )
    if suffix == ".json":
        try:
            content = json.loads(text)
        except json.JSONDecodeError as error:
            raise InputError(path, f"not valid JSON: {error.msg}", line=error.lineno) from error
    elif suffix == ".xml" or _looks_like_opencv_yaml(text):
        content = _load_filestorage(path)
    else:
        content = _load_plain_yaml(path, text)
    if content is None:  # YAML with only comments
        raise InputError(path, "empty file: expected a mapping of keys")
    if not isinstance(content, dict):
        raise InputError(
            path, f"expected a mapping of keys at the top level, got {type(content).__name__}"
        )
    return camera_from_mapping(path, content)


def write_camera(camera: Camera, path: str | Path, *, replace: bool = True) -> None:
    """Write a camera file atomically, readable back exactly by `read_camera`.

    `.yaml`, `.yml` and `.xml` are written with `cv2.FileStorage` (so OpenCV
    programs read them) and `.json` as plain JSON, each with the keys
    `image_width`, `image_height`, `camera_matrix` (3x3) and
    `distortion_coefficients` (n x 1, n = `camera.n_dist`), plus
    `intrinsics_covariance` ((4 + n) x (4 + n)) when the camera has one. The text goes to a
    temporary file next to the destination, which then replaces it
    (`lightcal.io.atomic`): readers see the old file or the new one, never half.

    Args:
        camera: The camera to write.
        path: Destination; its suffix chooses the format.
        replace: False: never replace an existing file (created atomically, or not at all).

    Raises:
        InputError: Unsupported suffix, the destination folder does not exist or
            the file cannot be written.
        FileExistsError: `replace` is False and `path` exists (it is left untouched).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (*OPENCV_SUFFIXES, ".json"):
        raise InputError(
            path, f"unsupported file suffix {path.suffix!r}: expected .yaml, .yml, .xml or .json"
        )
    folder = path.parent
    if not folder.is_dir():
        raise InputError(path, f"cannot write: folder {str(folder)!r} does not exist")
    text = _json_text(camera) if suffix == ".json" else _filestorage_text(camera, suffix)
    try:
        if replace:
            atomic_write_text(path, text)
        else:
            atomic_create_bytes(path, text.encode("utf-8"))
    except FileExistsError:
        raise
    except OSError as error:
        raise InputError(path, f"cannot write: {error.strerror or error}") from error


def _json_text(camera: Camera) -> str:
    content: dict[str, Any] = {
        "image_width": camera.width,
        "image_height": camera.height,
        "camera_matrix": [[float(v) for v in row] for row in camera.K],
        "distortion_coefficients": [float(v) for v in camera.dist_opencv],
    }
    if camera.intrinsics_covariance is not None:
        content[KEY_COVARIANCE] = [[float(v) for v in row] for row in camera.intrinsics_covariance]
    return json.dumps(content, indent=2) + "\n"


def _filestorage_text(camera: Camera, suffix: str) -> str:
    """What cv2.FileStorage writes for the camera, in the format of `suffix`."""
    storage = cv2.FileStorage(suffix, cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    storage.write("image_width", camera.width)
    storage.write("image_height", camera.height)
    storage.write("camera_matrix", np.ascontiguousarray(camera.K))
    storage.write("distortion_coefficients", camera.dist_opencv.reshape(-1, 1))
    if camera.intrinsics_covariance is not None:
        storage.write(KEY_COVARIANCE, np.ascontiguousarray(camera.intrinsics_covariance))
    text: str = storage.releaseAndGetString()
    return text


# --------------------------------------------------------------------------- loading


def _looks_like_opencv_yaml(text: str) -> bool:
    """A `%YAML` header (OpenCV writes one) or an OpenCV tag."""
    return text.lstrip().startswith("%YAML") or "!!opencv-" in text


def _load_plain_yaml(path: Path, text: str) -> Any:
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        problem = getattr(error, "problem", None) or str(error)
        line = None if mark is None else mark.line + 1
        raise InputError(path, f"not valid YAML: {problem}", line=line) from error
    # Bounded like every other document lightcal reads (an alias bomb, a deep nesting).
    check_bounds(data, path=path, what="camera file")
    return data


_CV_ERROR = re.compile(r"error: \(-?\d+:(?P<kind>[^)]*)\) (?P<detail>.*)", re.DOTALL)
_CV_LINE = re.compile(r"\((?P<line>\d+)\): (?P<detail>.*?)'?\s*$", re.DOTALL)


def _cv_error_detail(error: Exception) -> tuple[int | None, str]:
    """(line, short message) from a cv2.error's text."""
    text = str(error).strip()
    match = _CV_ERROR.search(text)
    if match is None:
        return None, text
    detail = match["detail"].strip()
    line_match = _CV_LINE.search(detail)
    if line_match is not None:
        return int(line_match["line"]), line_match["detail"].strip()
    return None, f"{match['kind'].strip()}: {detail}"


def _load_filestorage(path: Path) -> dict[str, Any]:
    """Read a cv2.FileStorage file into plain Python values (matrices as dicts)."""
    storage = cv2.FileStorage()
    try:
        opened = storage.open(str(path), cv2.FILE_STORAGE_READ)
    except cv2.error as error:
        line, detail = _cv_error_detail(error)
        raise InputError(path, f"not a valid OpenCV YAML/XML file: {detail}", line=line) from error
    try:
        root = storage.root()
        if not opened or not root.isMap():
            raise InputError(path, "not a valid OpenCV YAML/XML file: expected a mapping of keys")
        return {key: _node_value(root.getNode(key)) for key in root.keys()}  # noqa: SIM118 (FileNode is not iterable)
    finally:
        storage.release()


def _node_value(node: Any) -> Any:
    """Convert a cv2.FileNode to int/float/str/list/dict (None for an empty node)."""
    if node.isInt():
        return int(node.real())
    if node.isReal():
        return float(node.real())
    if node.isString():
        return node.string()
    if node.isSeq():
        return [_node_value(node.at(i)) for i in range(node.size())]
    if node.isMap():
        return {key: _node_value(node.getNode(key)) for key in node.keys()}  # noqa: SIM118 (FileNode is not iterable)
    return None


# --------------------------------------------------------------------------- COLMAP


def _read_colmap(path: Path, text: str, camera_id: int | None) -> Camera:
    """Parse COLMAP cameras.txt; see `read_camera` for the conventions."""
    entries: dict[int, tuple[int, list[str]]] = {}
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        fields = line.split()
        if len(fields) < 4:
            raise InputError(
                path,
                "expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS..., "
                f"got {len(fields)} field{'s' if len(fields) != 1 else ''}",
                line=number,
            )
        try:
            cid = int(fields[0])
        except ValueError:
            raise InputError(
                path, f"CAMERA_ID: expected an integer, got {fields[0]!r}", line=number
            ) from None
        if cid in entries:
            raise InputError(
                path,
                f"CAMERA_ID: camera {cid} appears twice (first on line {entries[cid][0]})",
                line=number,
            )
        entries[cid] = (number, fields)
    if not entries:
        raise InputError(path, "no camera found: expected lines CAMERA_ID MODEL WIDTH HEIGHT ...")
    ids = ", ".join(str(i) for i in entries)
    if camera_id is None:
        if len(entries) > 1:
            raise InputError(
                path, f"found {len(entries)} cameras (ids {ids}): pass camera_id to choose one"
            )
        camera_id = next(iter(entries))
    if camera_id not in entries:
        raise InputError(path, f"camera_id {camera_id} not found: the file has ids {ids}")
    number, fields = entries[camera_id]
    return _colmap_camera(path, number, fields)


def _colmap_camera(path: Path, number: int, fields: list[str]) -> Camera:
    model = fields[1]
    names = COLMAP_MODELS.get(model)
    if names is None:
        raise InputError(
            path,
            f"camera model {model!r} is not supported: expected one of {', '.join(COLMAP_MODELS)}",
            line=number,
        )
    sizes: list[int] = []
    for name, text in zip(("WIDTH", "HEIGHT"), fields[2:4], strict=True):
        try:
            size = int(text)
        except ValueError:
            size = 0
        if not 0 < size <= MAX_IMAGE_SIDE:
            raise InputError(
                path,
                f"{name}: expected a positive integer up to {MAX_IMAGE_SIDE}, got {text!r}",
                line=number,
            )
        sizes.append(size)
    width, height = sizes
    texts = fields[4:]
    if len(texts) != len(names):
        raise InputError(
            path,
            f"{model}: expected {len(names)} parameters ({', '.join(names)}), got {len(texts)}",
            line=number,
        )
    params: dict[str, float] = {}
    for name, text in zip(names, texts, strict=True):
        try:
            value = float(text)
        except ValueError:
            raise InputError(
                path, f"{model} {name}: expected a number, got {text!r}", line=number
            ) from None
        if not math.isfinite(value):
            raise InputError(
                path, f"{model} {name}: expected a finite number, got {text!r}", line=number
            )
        params[name] = value
    fx = params.get("fx", params.get("f"))
    fy = params.get("fy", params.get("f"))
    assert fx is not None and fy is not None  # every model has f or fx, fy
    dist: tuple[float, ...] = ()
    if model == "SIMPLE_RADIAL":
        dist = (params["k"], 0.0, 0.0, 0.0)
    elif model == "RADIAL":
        dist = (params["k1"], params["k2"], 0.0, 0.0)
    elif model in ("OPENCV", "FULL_OPENCV"):
        dist = tuple(params[name] for name in names[4:])
    cx = params["cx"] - 0.5
    cy = params["cy"] - 0.5
    return build_camera(
        path,
        lambda: Camera.from_params(
            fx=fx, fy=fy, cx=cx, cy=cy, width=width, height=height, dist=dist
        ),
        line=number,
        name=model,
    )
