"""A new project from photos, without a browser: the staging area
(`lightcal_app.photo_project`), its build (`lightcal init`'s steps, the intrinsics from
chessboard photos) and the worker's handler (`lightcal_app.photo_service`).

The photos are synthetic (`tests.photo_fixtures`): a marker wall lit by a known light,
and one photo without markers that the build must reject with its reason.
"""

from __future__ import annotations

import io
import json
import math
import subprocess
import sys
import zipfile
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from lightcal_app import requests as rq
from lightcal_app.files_service import FilesService
from lightcal_app.photo_build import black_level_warning, read_levels
from lightcal_app.photo_project import (
    PhotoOptions,
    PhotoStaging,
    outcomes_markdown,
    staged_markdown,
)
from lightcal_app.photo_service import PhotoFields, PhotoService, check_fields
from lightcal_app.solve_service import SolveService
from lightcal_app.state import AppState

from lightcal.errors import InputError
from lightcal.io.project import load_project
from lightcal.pipeline import load_images
from lightcal.resources import sample_project_dir
from tests.app_fixtures import make_project
from tests.photo_fixtures import BLANK_NAME, BLANK_REASON, Photos, write_photos
from tests.raw_dng import write_dng
from tests.test_cli_init import IES  # the same small IES file


@pytest.fixture(scope="module")
def photos(tmp_path_factory: pytest.TempPathFactory) -> Photos:
    return write_photos(tmp_path_factory.mktemp("photos"))


def _stage(staging: PhotoStaging, photos: Photos, *, blank: bool = True) -> None:
    for path in photos.photos:
        if blank or path.name != BLANK_NAME:
            staging.receive("wall", path.name, path.read_bytes())
    staging.receive("camera", "camera.yaml", photos.camera.read_bytes())
    staging.receive("board", "board.yaml", photos.board.read_bytes())


def _zip(files: dict[str, bytes]) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as zf:
        for name, content in files.items():
            zf.writestr(name, content)
    return buffer.getvalue()


def test_the_photo_services_import_no_viser() -> None:
    code = (
        "import sys; import lightcal_app.photo_project, lightcal_app.photo_service; "
        "print('viser' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_photos_uploaded_one_at_a_time_build_a_project(photos: Photos, tmp_path: Path) -> None:
    staging = PhotoStaging(tmp_path / "state" / "photos")
    assert staging.staged().empty
    assert staging.staged().missing == (
        "photos of the wall with the printed marker board",
        "a camera file, or photos of a chessboard for the intrinsics",
        "the board file of the wall's markers (aruco_grid, markers or charuco)",
    )
    assert "**Received**: nothing yet." in staged_markdown(staging.staged())
    received = staging.receive("wall", "wall_0.png", photos.photos[0].read_bytes())
    assert received.placed == (("wall photo", "wall_0.png"),)
    assert received.text() == "Received 1 wall photo."
    _stage(staging, photos)
    staged = staging.staged()
    assert staged.wall_photos == tuple(p.name for p in photos.photos)
    assert staged.camera == "camera.yaml"
    assert staged.wall_boards == (("aruco_grid", "board.yaml"),)
    assert staged.ready
    text = staged_markdown(staged)
    assert "wall photos (6)" in text and "**Ready**" in text
    assert "light: no file, a cos^m profile of the half angle below" in text
    area = staging.folder
    assert area is not None and area.parent == tmp_path / "state" / "photos"

    seen: list[str] = []
    built = staging.build(seen.append, PhotoOptions(half_angle_deg=25.0))
    assert seen == [f"image {k} of 6" for k in range(1, 7)] + ["reading the 5 accepted images"]
    # One outcome per photo, in name order; the blank photo is rejected with the reason.
    assert [p.name for p in built.photos] == [p.name for p in photos.photos]
    assert [p.accepted for p in built.photos] == [True] * 5 + [False]
    blank = built.photos[-1]
    assert blank.reason == BLANK_REASON
    assert blank.text() == f"rejected: {BLANK_REASON}"
    for outcome in built.accepted:
        assert outcome.markers is not None and outcome.markers >= 8
        assert outcome.rms_px is not None and outcome.rms_px < 0.5
        assert outcome.text().startswith(f"accepted: {outcome.markers} markers, rms ")
    assert built.camera.text() == "the camera file camera.yaml"
    table = outcomes_markdown(built)
    assert table.startswith("**Built**: 5 of 6 photos accepted, 1 rejected; camera: ")
    assert "| wall\\_9\\_blank\\.png | **rejected**: found 0 markers, need at least 4 |" in table
    # The project: lightcal init's, in a build folder of the staging area, every path
    # relative and inside the area; the poses from the markers, the light's half angle.
    project = built.project
    assert project.path.parent.parent == area and project.path.name == "project.json"
    data = json.loads(project.path.read_text())
    assert data["camera"]["path"] == "../camera/camera.yaml"
    assert [im["path"] for im in data["images"]] == [f"../photos/wall_{k}.png" for k in range(5)]
    assert all(im["mask"].startswith("masks/") for im in data["images"])
    assert data["lights"][0]["rid"]["half_angle_deg"] == 25.0
    assert project.names == [f"wall_{k}" for k in range(5)]
    camera_path = project.folder / data["camera"]["path"]
    for p in [camera_path, *project.image_paths, *project.mask_paths]:
        assert p is not None and p.resolve().is_relative_to(area.resolve())
    for view, true in zip(project.views, photos.views, strict=True):
        assert np.linalg.norm(view.center_world - true.center_world) < 1e-3
    assert len(built.loaded.images) == 5
    assert built.loaded.images[0].values.shape == (240, 320)
    # A new build replaces the last one (nothing shown reads it).
    again = staging.build(options=PhotoOptions(initial_position_m=(0.05, 0.0, 0.0)))
    assert not project.path.exists() and again.project.path.exists()
    assert again.warnings == (
        "no light file nor half angle given: the light's profile is taken as cos^m, its "
        "exponent estimated from a start at a half angle of 30 degrees (give its IES/LDT file "
        "or half angle if known)",
    )
    assert load_project(again.project.path).spec.lights[0].initial.position_m == [0.05, 0, 0]
    with pytest.raises(InputError) as info:  # before any work, named as the page labels it
        staging.build(options=PhotoOptions(min_markers=1000))
    assert str(info.value) == "fewest markers: expected at most the board's 24 markers, got 1000"


def test_a_zip_is_sorted_by_what_each_file_is(photos: Photos, tmp_path: Path) -> None:
    staging = PhotoStaging(tmp_path / "photos")
    wall = photos.photos[0].read_bytes()
    content = _zip(
        {
            "set/a/wall_0.png": wall,
            "set/b/wall_0.png": photos.photos[1].read_bytes(),  # same name, other folder
            "set/Chessboard views/c1.png": wall,
            "set/camera.yaml": photos.camera.read_bytes(),
            "set/board.yaml": photos.board.read_bytes(),
            "set/led.ies": IES.encode(),
            "set/README.md": b"# notes",
            "set/broken.json": b"{not json",
            "__MACOSX/set/._wall_0.png": b"resource fork",
            "set/.DS_Store": b"finder",
        }
    )
    received = staging.receive("wall", "everything.zip", content)
    assert sorted(received.placed) == [
        ("board file (aruco_grid)", "board.yaml"),
        ("camera file", "camera.yaml"),
        ("chessboard photo", "c1.png"),
        ("light file", "led.ies"),
        ("wall photo", "set_b_wall_0.png"),
        ("wall photo", "wall_0.png"),
    ]
    ignored = dict(received.ignored)
    assert sorted(ignored) == ["set/README.md", "set/broken.json"]
    assert ignored["set/README.md"] == "not a photo, camera, board or light file"
    assert ignored["set/broken.json"].startswith("line 1: ")  # read as a camera file
    assert received.text().startswith(
        "Received 2 wall photos, 1 chessboard photo, 1 camera file, 1 board file (aruco_grid), "
        "1 light file. Left out: set/README.md (not a photo, camera, board or light file); "
    )
    staged = staging.staged()
    assert staged.wall_photos == ("set_b_wall_0.png", "wall_0.png")
    assert staged.chessboard_photos == ("c1.png",) and not staged.calibrates_camera
    assert staged.light == "led.ies" and staged.ready
    text = staged_markdown(staged)
    assert "chessboard photos (1) (not used: a camera file is given)" in text
    assert "light file: led\\.ies (the half angle is not used)" in text
    # The extraction folder is gone; nothing is left outside the role folders.
    assert staging.folder is not None
    assert sorted(p.name for p in staging.folder.iterdir()) == [
        "board-aruco_grid",
        "camera",
        "chessboard",
        "light",
        "photos",
    ]
    # A zip on the chessboard button: its images are chessboard photos.
    staging.receive("chessboard", "more.zip", _zip({"c2.png": wall, "c3.png": wall}))
    assert staging.staged().chessboard_photos == ("c1.png", "c2.png", "c3.png")


def test_uploads_are_refused_naming_the_file_and_what_was_expected(
    photos: Photos, tmp_path: Path
) -> None:
    staging = PhotoStaging(tmp_path / "photos", limit=200_000)

    def refused(kind: Any, name: str, content: bytes) -> str:
        with pytest.raises(InputError) as info:
            staging.receive(kind, name, content)
        text = str(info.value)
        assert str(tmp_path) not in text  # never the server's folders
        return text

    assert refused("wall", "notes.txt", b"text") == (
        "notes.txt: unsupported photo suffix '.txt': expected .png, .tif, .tiff, .npy, .exr, "
        ".jpg or camera raw such as .dng, .cr2, .nef, .arw"
    )
    assert refused("wall", "big.png", b"x" * 200_001) == (
        "big.png: the file is 200.0 kB; uploads are limited to 200.0 kB per file"
    )
    assert refused("wall", "empty.png", b"") == "empty.png: the file is empty"
    assert refused("camera", "camera.yaml", b"%YAML:1.0\n---\ncamera_matrix: [1, 2\n").startswith(
        "camera.yaml: "
    )
    assert refused("camera", "camera.ini", b"fx=1") == (
        "camera.ini: unsupported camera file suffix '.ini': expected an OpenCV .yaml, .yml, "
        ".xml or .json file, or a COLMAP cameras.txt"
    )
    assert refused("board", "board.yaml", b"\x00\xff\xfe binary junk") == (
        "board.yaml: the board file is not UTF-8 text (byte 1): save it as UTF-8"
    )
    assert refused("light", "led.csv", b"0,1") == (
        "led.csv: unsupported light file suffix '.csv': expected an IES (.ies) or EULUMDAT "
        "(.ldt) file"
    )
    assert refused("light", "bad.ies", b"IESNA:LM-63-2002\nTILT=NONE\n1 -1 1 4\n").startswith(
        "bad.ies: "
    )
    assert refused("wall", "escape.zip", _zip({"../evil.png": b"x"})) == (
        "escape.zip: unsafe path in the zip: '../evil.png'; expected relative paths"
    )
    assert refused("wall", "junk.zip", _zip({"notes.md": b"x"})) == (
        "junk.zip: nothing in the zip could be used (notes.md: not a photo, camera, board or "
        "light file)"
    )
    assert refused("wall", "fake.zip", b"PK not a zip") == "fake.zip: not a valid zip file"
    huge = np.zeros((1, 1), np.uint8)
    huge_png = photos.photos[0].read_bytes()[:16] + (30_000).to_bytes(4, "big") * 2
    assert refused("wall", "huge.png", huge_png + huge.tobytes()).startswith(
        "huge.png: the image is 30000 x 30000 pixels"
    )
    with pytest.raises(InputError, match=r"^kind: expected one of wall, chessboard"):
        staging.receive("project", "x.png", b"x")  # type: ignore[arg-type]
    # Names are made safe and confined: no folder, no hidden file, no odd character.
    staging.receive("wall", "../../up/.hidden wall#1.png", photos.photos[0].read_bytes())
    assert staging.staged().wall_photos == ("_hidden_wall_1.png",)
    assert not (tmp_path / "up").exists()
    # Nothing refused was kept; the build says what is missing.
    with pytest.raises(InputError) as info:
        staging.build()
    assert str(info.value) == (
        "new project: missing: a camera file, or photos of a chessboard for the intrinsics; "
        "the board file of the wall's markers (aruco_grid, markers or charuco)"
    )
    # No usable photo: the build says why each was rejected, and leaves no build behind.
    staging.receive("camera", "camera.yaml", photos.camera.read_bytes())
    staging.receive("board", "board.yaml", photos.board.read_bytes())
    staging.clear()
    staging.receive("wall", BLANK_NAME, photos.photos[-1].read_bytes())
    staging.receive("camera", "camera.yaml", photos.camera.read_bytes())
    staging.receive("board", "board.yaml", photos.board.read_bytes())
    with pytest.raises(InputError) as info:
        staging.build()
    assert str(info.value) == (
        f"wall photos: no usable images: all 1 were rejected ({BLANK_NAME}: {BLANK_REASON})"
    )
    assert staging.folder is not None and not list(staging.folder.glob("build-*"))


def test_a_board_file_is_kept_by_its_role(photos: Photos, tmp_path: Path) -> None:
    staging = PhotoStaging(tmp_path / "photos")
    sample = sample_project_dir()
    staging.receive("board", "chessboard.yaml", (sample / "chessboard.yaml").read_bytes())
    staged = staging.staged()
    assert staged.chessboard_board == ("chessboard", "chessboard.yaml")
    assert staged.wall_boards == ()
    staging.receive("chessboard", "c.png", photos.photos[0].read_bytes())
    assert staging.staged().missing == (
        "photos of the wall with the printed marker board",
        "at least 3 chessboard photos (have 1)",
        "the board file of the wall's markers (aruco_grid, markers or charuco)",
    )
    staging.receive("board", "wall board.yaml", photos.board.read_bytes())
    staging.receive("board", "other.yaml", photos.board.read_bytes())  # its markers: replaced
    staged = staging.staged()
    assert staged.boards == (("aruco_grid", "other.yaml"), ("chessboard", "chessboard.yaml"))
    text = staged_markdown(staged)
    assert "board file (aruco_grid) for the wall's markers: other\\.yaml" in text
    assert "board file (chessboard) for the chessboard photos: chessboard\\.yaml" in text


def test_clear_forgets_the_files_but_keeps_a_folder_in_use(photos: Photos, tmp_path: Path) -> None:
    in_use: list[Path] = []
    staging = PhotoStaging(tmp_path / "photos", keep=lambda: in_use)
    _stage(staging, photos, blank=False)
    first = staging.folder
    assert first is not None
    staging.clear()
    assert staging.folder is None and staging.staged().empty and not first.exists()
    _stage(staging, photos, blank=False)
    built = staging.build()
    in_use.append(built.project.folder)  # the app shows the project built here
    second = staging.folder
    assert second is not None
    staging.clear()
    assert staging.staged().empty and second.exists() and built.project.path.exists()
    # The next file starts a fresh staging area.
    staging.receive("camera", "camera.yaml", photos.camera.read_bytes())
    assert staging.folder not in (None, first, second)


class Messages:
    """A `notify` that keeps what the page would show."""

    def __init__(self) -> None:
        self.items: list[tuple[Any, str, str, bool]] = []

    def __call__(self, client: Any, title: str, body: str, *, error: bool = False) -> None:
        self.items.append((client, title, body, error))

    def titles(self) -> list[str]:
        return [t for _, t, _, _ in self.items]


def make_service(tmp_path: Path) -> tuple[PhotoService, AppState, Messages, list[str], list[Any]]:
    """(a photo service of an app, its state, messages, busy texts, projects switched to)"""
    first = make_project(tmp_path / "first", n_views=3, width=96, height=72)
    project = load_project(first.path)
    state = AppState(project, load_images(project))
    messages = Messages()
    solve = SolveService(state, notify=messages, follow_iterations=False)
    switched: list[Any] = []
    files = FilesService(
        state,
        solve,
        notify=messages,
        deliver=lambda c, n, b: None,
        on_switch=lambda p, loaded, t: switched.append(p),
        truth=None,
        session_path=None,
        state_dir=tmp_path / "state",
    )
    busy: list[str] = []
    service = PhotoService(files, notify=messages, show_work=busy.append)
    return service, state, messages, busy, switched


def test_the_build_request_switches_the_app_and_names_rejected_photos(
    photos: Photos, tmp_path: Path
) -> None:
    service, state, messages, busy, switched = make_service(tmp_path)
    changes: list[int] = []
    service.listeners.append(lambda: changes.append(1))

    # Not ready: refused at once, nothing queued.
    service.request_build(PhotoFields(), client="page")
    assert messages.items[-1][:2] == ("page", "Not ready to build")
    assert not state.requests
    service.upload("wall", "notes.txt", b"x", client="page")
    assert messages.items[-1][1:] == (
        "Upload rejected: notes.txt",
        "notes.txt: unsupported photo suffix '.txt': expected .png, .tif, .tiff, .npy, .exr, "
        ".jpg or camera raw such as .dng, .cr2, .nef, .arw",
        True,
    )
    for path in photos.photos:
        service.upload("wall", path.name, path.read_bytes(), client="page")
    service.upload("camera", "camera.yaml", photos.camera.read_bytes(), client="page")
    service.upload("board", "board.yaml", photos.board.read_bytes(), client="page")
    assert len(changes) == 9 and service.staged().ready
    n_messages = len(messages.items)
    service.request_build(PhotoFields(half_angle_deg=95.0), client="page")
    assert messages.items[-1][1:3] == (
        "Value refused",
        "half angle (deg): expected a value in (0, 90) degrees, got 95.0",
    )
    fields = PhotoFields(initial_position_mm=(50, 0, 0), initial_auto=False)
    service.request_build(replace(fields, half_angle_known=True), client="page")
    assert len(messages.items) == n_messages + 1
    (req,) = list(state.requests)
    state.requests.clear()
    assert isinstance(req, rq.BuildPhotoProject) and req.client == "page"
    assert req.half_angle_deg == 30.0 and req.initial_position_m == (0.05, 0.0, 0.0)
    assert rq.work_of(req) == "building the project from the photos"

    service.build(req)  # what the worker does with it
    assert busy == [
        *(f"building the project: image {k} of 6" for k in range(1, 7)),
        "building the project: reading the 5 accepted images",
        "building the project: drawing the new project",
    ]
    built = service.last_build
    assert built is not None
    with state.lock:
        assert state.project is built.project and state.loaded is built.loaded
        assert state.project.names == [f"wall_{k}" for k in range(5)]
        assert state.guess[0].t_camera_light.tolist() == [0.05, 0.0, 0.0]
    assert switched == [built.project]
    updated = [m for m in messages.items if m[1] == "Project updated"]
    assert updated and updated[-1][0] == "page"
    assert updated[-1][2].startswith(
        "Project built from the photos: 5 of 6 accepted; camera: the camera file camera.yaml."
    )
    client, title, body, error = messages.items[-1]
    assert (client, title, error) == ("page", "1 of 6 photos rejected", True)
    assert body == f"{BLANK_NAME}: {BLANK_REASON}"
    # The staging area keeps the files for another build; clearing it keeps the project
    # shown (it reads the photos there) and forgets the table.
    service.clear("page")
    assert service.last_build is None and service.staged().empty
    assert built.project.path.exists() and all(p.exists() for p in built.project.image_paths)

    # A build that fails says why in the page and changes nothing.
    service.upload("wall", BLANK_NAME, photos.photos[-1].read_bytes())
    service.upload("camera", "camera.yaml", photos.camera.read_bytes())
    service.upload("board", "board.yaml", photos.board.read_bytes())
    service.build(rq.BuildPhotoProject(30.0, client="page"))
    assert messages.items[-1] == (
        "page",
        "Project not built",
        f"wall photos: no usable images: all 1 were rejected ({BLANK_NAME}: {BLANK_REASON})",
        True,
    )
    assert state.project is built.project


@pytest.mark.parametrize(
    ("fields", "refusal"),
    [
        (PhotoFields(black_level=math.nan), "black level: expected a finite value >= 0, got nan"),
        (PhotoFields(black_level=-1), "black level: expected a finite value >= 0, got -1.0"),
        (PhotoFields(black_level=6, white_level=5), "white level: expected a value above black l"),
        (PhotoFields(black_level=70000), "black level: expected a value below the photos' white"),
        (PhotoFields(min_markers=2.5), "fewest markers: expected an integer >= 1, got 2.5"),
        (PhotoFields(min_markers=0), "fewest markers: expected an int >= 1, got 0"),
        (PhotoFields(mask_margin_px=150.0), "mask margin (px): expected a padding of 0 to 100"),
        (PhotoFields(max_rms_px=0.0), "largest marker RMS (px): expected a value > 0 pixels"),
        (PhotoFields(pose_floor_mm=-0.1), "pose floor (mm): expected a finite value >= 0"),
        (PhotoFields(pose_floor_deg=math.nan), "pose floor (deg): expected a finite value >= 0"),
        (PhotoFields(initial_axis=(0, 0, 0)), "initial axis: expected a non-zero direction"),
        (PhotoFields(initial_axis=(0, 0, -2)), "initial axis: expected an axis other than -z"),
        (PhotoFields(initial_position_mm=(9e9, 0, 0)), "initial light (mm): expected 3 finite"),
    ],
)
def test_every_field_is_checked_as_lightcal_init_checks_it(
    fields: PhotoFields, refusal: str, photos: Photos
) -> None:
    with pytest.raises(InputError) as info:
        check_fields(fields, read_levels(photos.photos[0]))  # 16-bit PNG: black 0, white 65535
    assert str(info.value).startswith(refusal)


def test_the_levels_come_from_the_photos_files(photos: Photos, tmp_path: Path) -> None:
    png = read_levels(photos.photos[0])
    assert png.fields() == (0.0, 65535.0) and not png.raw
    # The photos' own levels are passed as none (the reader applies them), others as typed.
    options = check_fields(PhotoFields(black_level=0, white_level=4095), png)
    assert (options.black_level, options.white_level) == (None, 4095.0)
    raw = read_levels(
        write_dng(tmp_path / "w.dng", np.full((32, 48), 900, np.uint16), black_level=256)
    )
    assert raw.raw and raw.fields() == (256.0, 4095.0) and "camera raw metadata" in raw.text()
    options = check_fields(PhotoFields(black_level=256, white_level=4095), raw)
    assert (options.black_level, options.white_level) == (None, None)  # LibRaw's, per channel
    # A black offset the files do not say is warned of (the sample: 512 under 14-bit data).
    assert black_level_warning(png) == [] and black_level_warning(raw) == []
    sample = read_levels(sample_project_dir() / "images" / "view_00.png")
    (warning,) = black_level_warning(sample)
    assert warning.startswith("black level 0, while the darkest value of view_00.png is 537")
