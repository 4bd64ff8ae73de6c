"""A new project from photos uploaded through the page (`lightcal init` in the app), no viser.

`PhotoStaging` is a staging area: a fresh folder of its own under the app's state folder
(`<state_dir>/photos/<id>/`) that receives the files one at a time (viser uploads one
file per button press) or as a zip. The kinds of file, each checked as it arrives:

- `wall`: photos of the wall with the printed marker board, in any format
  `lightcal.io.images.read_image` takes (camera raw such as .dng, 16-bit PNG or TIFF,
  float TIFF, EXR or NPY); their suffix and the size in their header are checked.
- `chessboard`: photos of a chessboard or ChArUco board, for the intrinsics when no
  camera file is given; checked as the wall photos.
- `camera`: the camera file, OpenCV YAML/JSON/XML or a COLMAP cameras.txt; read.
- `board`: a board file (`lightcal.io.board_file`), read and kept by its type: the
  wall's `aruco_grid` or `markers` (any number: their markers all make each photo's
  pose; one that shares a marker with a staged wall board replaces it) or `charuco`,
  the chessboard photos' `chessboard` (a `charuco` serves either role when the other
  board is missing).
- `light`: the light's IES (.ies) or EULUMDAT (.ldt) file, read; without one the build
  uses a half angle.
- `response`: the camera's response curve (`lightcal response`), read; it linearises
  8-bit photos (JPEG), as `lightcal init --response`.

A zip (whatever the button) is unpacked with the checks of `upload_checks.extract_zip`,
and each file in it goes where it belongs: images in a folder whose name says chess,
charuco, calib or intrinsic are chessboard photos, other images are of the kind uploaded
(wall photos unless it was `chessboard`); .ies/.ldt files are the light; YAML and JSON
files a board file if they read as one, else a response curve if they read as one, else a
camera file; XML and TXT a camera file.
Files that are none of these (or do not read) are left out, each named with the reason.

Limits: every file the app's per-file cap (`uploads.check_size`), every image's size from
its header (`upload_checks.check_image_headers`), one staging area at most
`MAX_ZIP_MEMBERS` files and `MAX_UPLOAD_FOLDER_BYTES`, and the staging areas together
bounded by `upload_checks.make_room` (the oldest removed first, never the one in use nor
a folder the project shown reads). Names are made safe (`uploads.safe_file_name`); a
photo or wall board file of the same name, or a camera, light, response or other board
file of the same role, replaces the one there.

`build(progress, options)` runs `lightcal_app.photo_build.build_project` (the intrinsics
from the chessboard photos when no camera file was given, then `lightcal init`'s steps,
`progress` told each image) into a fresh `build-<id>/` folder of the area, and returns the
project, its images and what became of every photo (`PhotoBuild`). The records and the
page's text of them are in `lightcal_app.photo_records`, re-exported here. Errors are
`InputError`s naming the file as uploaded and what was expected.
"""

from __future__ import annotations

import shutil
import threading
import uuid
from collections.abc import Callable, Iterable
from pathlib import Path, PurePosixPath

from lightcal.errors import InputError
from lightcal.io.board_file import read_board
from lightcal.io.camera_file import read_camera
from lightcal.io.images import SUPPORTED_EXTENSIONS
from lightcal.io.photometric_file import read_rid_file
from lightcal.io.response import ResponseCurve
from lightcal_app.photo_build import (
    BOARD_DIRS,
    BUILD_PREFIX,
    CAMERA_DIR,
    CHESSBOARD_DIR,
    LIGHT_DIR,
    RESPONSE_DIR,
    WALL_DIR,
    Progress,
    build_project,
    read_levels,
)
from lightcal_app.photo_files import (
    BOARD_SUFFIXES,
    CAMERA_SUFFIXES,
    IMAGE_SUFFIXES_TEXT,
    add_wall_board,
    board_type,
    files_in,
    folder_size,
    read_checked,
)
from lightcal_app.photo_records import (
    DEFAULT_HALF_ANGLE_DEG,
    LABELS,
    MAX_MASK_MARGIN_PX,
    PHOTO_KINDS,
    WALL_BOARD_TYPES,
    CameraSource,
    FileLevels,
    PhotoBuild,
    PhotoKind,
    PhotoOptions,
    PhotoOutcome,
    Received,
    Staged,
    check_half_angle,
    outcomes_markdown,
    staged_markdown,
)
from lightcal_app.upload_checks import (
    MAX_UNPACKED_BYTES,
    MAX_UPLOAD_FOLDER_BYTES,
    MAX_ZIP_MEMBERS,
    check_image_headers,
    extract_zip,
    format_size,
    make_room,
    upload_folder,
)
from lightcal_app.uploads import (
    MAX_UPLOAD_BYTES,
    RID_SUFFIXES,
    check_size,
    safe_file_name,
)

__all__ = [
    "DEFAULT_HALF_ANGLE_DEG",
    "LABELS",
    "MAX_MASK_MARGIN_PX",
    "PHOTO_KINDS",
    "CameraSource",
    "FileLevels",
    "PhotoBuild",
    "PhotoKind",
    "PhotoOptions",
    "PhotoOutcome",
    "PhotoStaging",
    "Received",
    "Staged",
    "check_half_angle",
    "outcomes_markdown",
    "staged_markdown",
]

CHESSBOARD_FOLDER_WORDS = ("chess", "charuco", "calib", "intrinsic")
"""A zip's images in a folder whose name holds one of these are chessboard photos."""


class PhotoStaging:
    """The files of a new project, as they arrive, and its build (thread-safe).

    Args:
        root: the folder of the staging areas (one sub-folder each).
        limit: the per-file cap, bytes.
        keep: the folders the project shown reads (never removed).
    """

    def __init__(
        self,
        root: Path,
        *,
        limit: int = MAX_UPLOAD_BYTES,
        keep: Callable[[], Iterable[Path]] = tuple,
    ) -> None:
        self.root = root
        self.limit = limit
        self._keep = keep
        self._lock = threading.Lock()
        self._folder: Path | None = None
        self._building = False
        # The first wall photo's levels, by (path, size, mtime): read once per photo.
        self._levels: tuple[tuple[str, int, int], FileLevels | None] | None = None

    @property
    def folder(self) -> Path | None:
        """The staging area's folder (None until the first file arrives)."""
        return self._folder

    # ------------------------------------------------------------------ receiving

    def _check_idle(self) -> None:
        if self._building:
            raise InputError(
                "new project",
                "the photos are being built into a project; try again when it is done",
            )

    def _area(self) -> Path:
        if self._folder is None or not self._folder.is_dir():
            self._folder = self.root / uuid.uuid4().hex[:12]
            self._folder.mkdir(parents=True)
        return self._folder

    def _kept(self, area: Path) -> list[Path]:
        return [area, *self._keep()]

    def receive(self, kind: PhotoKind, name: str, content: bytes) -> Received:
        """Store one uploaded file (or the files of a zip) as `kind`.

        Raises:
            InputError: naming the upload: over the size cap, a suffix or content that is
                not of the kind, a staging area full, a build running.
        """
        if kind not in PHOTO_KINDS:
            raise InputError("kind", f"expected one of {', '.join(PHOTO_KINDS)}, got {kind!r}")
        check_size(name, len(content), limit=self.limit)
        with self._lock:
            self._check_idle()
            area = self._area()
            make_room(self.root, len(content), keep=self._kept(area), limit=MAX_UPLOAD_FOLDER_BYTES)
            room = MAX_UPLOAD_FOLDER_BYTES - folder_size(area)
            if len(content) > room:
                raise InputError(
                    name,
                    "the files of one new project are limited to "
                    f"{format_size(MAX_UPLOAD_FOLDER_BYTES)} in all",
                )
            with upload_folder(area) as incoming:
                try:
                    if Path(name).suffix.lower() == ".zip":
                        received = self._receive_zip(kind, name, content, incoming, room)
                    else:
                        path = incoming / safe_file_name(name)
                        path.write_bytes(content)
                        received = Received((self._place(kind, path, name, area),))
                finally:
                    shutil.rmtree(incoming, ignore_errors=True)
            return received

    def _receive_zip(
        self, kind: PhotoKind, name: str, content: bytes, incoming: Path, room: int
    ) -> Received:
        files = extract_zip(name, content, incoming, max_bytes=min(MAX_UNPACKED_BYTES, room))
        placed: list[tuple[str, str]] = []
        ignored: list[tuple[str, str]] = []
        image_kind: PhotoKind = "chessboard" if kind == "chessboard" else "wall"
        for path in files:
            rel = PurePosixPath(path.relative_to(incoming).as_posix())
            if any(part.startswith(".") or part == "__MACOSX" for part in rel.parts):
                continue  # hidden files and the resource forks of macOS zips
            shown = f"{name}: {rel}"
            suffix = rel.suffix.lower()
            folders = " ".join(rel.parts[:-1]).lower()
            member: PhotoKind | None
            if suffix in SUPPORTED_EXTENSIONS:
                chess = any(word in folders for word in CHESSBOARD_FOLDER_WORDS)
                member = "chessboard" if chess else image_kind
            elif suffix in RID_SUFFIXES:
                member = "light"
            elif suffix in BOARD_SUFFIXES:
                member = "board" if self._reads(read_board, path) else "camera"
                if member == "camera" and self._reads(ResponseCurve.load, path):
                    member = "response"
            elif suffix in CAMERA_SUFFIXES:
                member = "camera"
            else:
                ignored.append((str(rel), "not a photo, camera, board or light file"))
                continue
            try:
                placed.append(self._place(member, path, shown, incoming.parent, zip_rel=rel))
            except InputError as exc:
                ignored.append((str(rel), exc.detail))
        if not placed:
            reasons = "; ".join(f"{n}: {why}" for n, why in ignored[:5]) or "it is empty"
            raise InputError(name, f"nothing in the zip could be used ({reasons})")
        return Received(tuple(placed), tuple(ignored))

    @staticmethod
    def _reads(reader: Callable[[Path], object], path: Path) -> bool:
        try:
            reader(path)
        except InputError:
            return False
        return True

    def _count(self, area: Path) -> int:
        return sum(1 for p in area.rglob("*") if p.is_file())

    def _place(
        self,
        kind: PhotoKind,
        path: Path,
        shown: str,
        area: Path,
        *,
        zip_rel: PurePosixPath | None = None,
    ) -> tuple[str, str]:
        """Check the file `path` as `kind` and move it into its folder of the area.

        Returns:
            (what it is, its stored name).
        """
        suffix = path.suffix.lower()
        if kind in ("wall", "chessboard"):
            what = "wall photo" if kind == "wall" else "chessboard photo"
            if suffix not in SUPPORTED_EXTENSIONS:
                raise InputError(
                    shown,
                    f"unsupported photo suffix {path.suffix!r}: expected {IMAGE_SUFFIXES_TEXT}",
                )
            try:
                check_image_headers([path], shown)
            except InputError as exc:
                raise InputError(shown, exc.detail.removeprefix(f"{path.name}: ")) from exc
            folder = area / (WALL_DIR if kind == "wall" else CHESSBOARD_DIR)
            stored = safe_file_name(path.name)
            if zip_rel is not None and (folder / stored).exists() and len(zip_rel.parts) > 1:
                # Two photos of one name in a zip's folders: the second keeps its folder.
                stored = safe_file_name("_".join(zip_rel.parts))
            if self._count(area) >= MAX_ZIP_MEMBERS and not (folder / stored).exists():
                raise InputError(shown, f"a new project takes at most {MAX_ZIP_MEMBERS} files")
            folder.mkdir(exist_ok=True)
            path.replace(folder / stored)
            return what, stored
        if kind == "camera":
            read_checked(
                path,
                shown,
                CAMERA_SUFFIXES,
                "camera file",
                "an OpenCV .yaml, .yml, .xml or .json file, or a COLMAP cameras.txt",
                read_camera,
            )
            return "camera file", self._replace(area / CAMERA_DIR, path)
        if kind == "board":
            board = read_checked(
                path,
                shown,
                BOARD_SUFFIXES,
                "board file",
                "a .yaml, .yml or .json board description (aruco_grid, markers, charuco or "
                "chessboard)",
                read_board,
            )
            typ = board_type(board)
            folder = area / BOARD_DIRS[typ]
            if typ in WALL_BOARD_TYPES:  # one of several
                walls = [area / BOARD_DIRS[t] for t in WALL_BOARD_TYPES]
                return f"board file ({typ})", add_wall_board(walls, folder, path, board)
            return f"board file ({typ})", self._replace(folder, path)
        if kind == "response":
            read_checked(
                path,
                shown,
                (".json", ".npy"),
                "response curve",
                "a .json curve written by lightcal response (or a (256, C) .npy array)",
                ResponseCurve.load,
            )
            return "response curve", self._replace(area / RESPONSE_DIR, path)
        read_checked(
            path,
            shown,
            RID_SUFFIXES,
            "light file",
            "an IES (.ies) or EULUMDAT (.ldt) file",
            read_rid_file,
        )
        return "light file", self._replace(area / LIGHT_DIR, path)

    @staticmethod
    def _replace(folder: Path, path: Path) -> str:
        """`path` becomes the one file of `folder` (the role's previous file goes)."""
        if folder.is_dir():
            shutil.rmtree(folder)
        folder.mkdir()
        stored = safe_file_name(path.name)
        path.replace(folder / stored)
        return stored

    # ------------------------------------------------------------------ listing

    def staged(self) -> Staged:
        """What the staging area holds now."""
        with self._lock:
            return self._staged()

    def _staged(self) -> Staged:
        area = self._folder
        if area is None or not area.is_dir():
            return Staged()

        def one(folder: str) -> str | None:
            files = files_in(area / folder)
            return files[0].name if files else None

        boards = tuple(
            (kind, path.name) for kind in BOARD_DIRS for path in files_in(area / BOARD_DIRS[kind])
        )
        wall = files_in(area / WALL_DIR)
        return Staged(
            wall_photos=tuple(p.name for p in wall),
            chessboard_photos=tuple(p.name for p in files_in(area / CHESSBOARD_DIR)),
            camera=one(CAMERA_DIR),
            boards=boards,
            light=one(LIGHT_DIR),
            response=one(RESPONSE_DIR),
            levels=self._levels_of(wall[0]) if wall else None,
        )

    def _levels_of(self, photo: Path) -> FileLevels | None:
        """The levels the photo's file gives (None when it does not read: the build
        says why)."""
        stat = photo.stat()
        key = (str(photo), stat.st_size, stat.st_mtime_ns)
        if self._levels is None or self._levels[0] != key:
            try:
                levels: FileLevels | None = read_levels(photo)
            except InputError:
                levels = None
            self._levels = (key, levels)
        return self._levels[1]

    def clear(self) -> None:
        """Forget every file received: the next one starts a fresh staging area. Its folder
        is removed unless the project shown reads from it (then the upload bound removes
        it later, once no project uses it)."""
        with self._lock:
            self._check_idle()
            area, self._folder = self._folder, None
            if area is None or not area.is_dir():
                return
            in_use = any(
                k.resolve() == area.resolve() or k.resolve().is_relative_to(area.resolve())
                for k in self._keep()
            )
            if not in_use:
                shutil.rmtree(area, ignore_errors=True)

    # ------------------------------------------------------------------ building

    def build(
        self, progress: Progress = lambda text: None, options: PhotoOptions | None = None
    ) -> PhotoBuild:
        """Build a project from the staged files, as `lightcal camera calibrate` (when
        chessboard photos stand for the camera file) and `lightcal init` do.

        Args:
            progress: told each step ("calibrating the camera ...", "image 3 of 12", ...).
            options: the build's choices besides the files.

        Raises:
            InputError: something is missing, the chessboard photos give no intrinsics,
                no wall photo is usable, or the initial guess is behind the wall.
        """
        options = options if options is not None else PhotoOptions()
        with self._lock:
            self._check_idle()
            staged = self._staged()
            if staged.missing:
                raise InputError("new project", "missing: " + "; ".join(staged.missing))
            area = self._folder
            assert area is not None
            self._building = True
        try:
            self._remove_old_builds(area)
            out_dir = area / f"{BUILD_PREFIX}{uuid.uuid4().hex[:8]}"
            out_dir.mkdir()
            try:
                return build_project(area, out_dir, staged, progress, options)
            except BaseException:
                shutil.rmtree(out_dir, ignore_errors=True)
                raise
        finally:
            with self._lock:
                self._building = False

    def _remove_old_builds(self, area: Path) -> None:
        kept = [k.resolve() for k in self._keep()]
        for old in area.glob(f"{BUILD_PREFIX}*"):
            here = old.resolve()
            if not any(k == here or k.is_relative_to(here) for k in kept):
                shutil.rmtree(old, ignore_errors=True)
