"""What a new project from photos is made of, and what the page says of it.

The records of `lightcal_app.photo_project` (the staging area) and
`lightcal_app.photo_build` (the build): what a staging area holds and still needs
(`Staged`), what an upload brought (`Received`), the build's choices (`PhotoOptions`) and
its outcome (`PhotoBuild`, with a `PhotoOutcome` per photo and where the intrinsics came
from, `CameraSource`); and the page's text of them (`staged_markdown`,
`outcomes_markdown`); and the levels the photos' files give (`FileLevels`, read by
`lightcal_app.photo_build.read_levels`). No files are touched here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, get_args

from lightcal.capture.init_checks import POSE_FLOOR_DEG, POSE_FLOOR_M
from lightcal.capture.intrinsics import MIN_VIEWS
from lightcal.capture.project_init import ImageOutcome
from lightcal.errors import InputError
from lightcal.io.project import Project
from lightcal.pipeline import LoadedImages
from lightcal_app.text import md

PhotoKind = Literal["wall", "chessboard", "camera", "board", "light", "response"]
PHOTO_KINDS: tuple[PhotoKind, ...] = get_args(PhotoKind)

DEFAULT_HALF_ANGLE_DEG = 30.0
"""The light's half angle without a light file nor a half angle (as `lightcal init`)."""

MAX_MASK_MARGIN_PX = 100.0
"""The largest mask margin, as `lightcal init --mask-margin-px` (`lightcal.cli.init`)."""

# The page's label of each field (a refusal names the field by it).
LABELS = {
    "half_angle_deg": "half angle (deg)",
    "initial_position_mm": "initial light (mm)",
    "initial_axis": "initial axis",
    "initial_auto": "guess the light from the beam",
    "half_angle_known": "the half angle is known",
    "black_level": "black level",
    "white_level": "white level",
    "min_markers": "fewest markers",
    "mask_margin_px": "mask margin (px)",
    "max_rms_px": "largest marker RMS (px)",
    "pose_floor_mm": "pose floor (mm)",
    "pose_floor_deg": "pose floor (deg)",
    "assume_linear": "8-bit photos are linear",
}

WALL_BOARD_TYPES = ("aruco_grid", "markers")
"""Board types only ever on the wall; a project takes any number of them (their markers
all make each photo's pose, as `lightcal init --board A --board B`)."""


@dataclass(frozen=True)
class FileLevels:
    """The black and white levels the wall photos' files give: what `read_image` uses
    when none is given, and what the page's level fields are prefilled with.

    Attributes:
        photo: the photo they were read from (the first wall photo).
        kind: where they come from, e.g. "camera raw metadata", "16-bit PNG".
        black: the black level (source units): the raw file's, else 0.
        white: the white (clipping) level (source units), None for float data.
        raw: read from a camera raw file's metadata (its black levels are per colour
            channel: the build passes none, so that the reader subtracts each).
        bits: bits per sample of integer data.
        darkest, brightest: the photo's extreme values (source units).
    """

    photo: str
    kind: str
    black: float
    white: float | None
    raw: bool = False
    bits: int | None = None
    darkest: float | None = None
    brightest: float | None = None

    def fields(self) -> tuple[float, float]:
        """The page's level fields prefilled: (black, white), white 0 for none."""
        return self.black, 0.0 if self.white is None else self.white

    def text(self) -> str:
        """What the page says of them, with what the user may have to change."""
        white = "none (float data)" if self.white is None else f"{self.white:g}"
        text = f"levels of {self.photo} ({self.kind}): black {self.black:g}, white {white}"
        if self.darkest is not None and self.brightest is not None:
            text += f"; its values run from {self.darkest:g} to {self.brightest:g}"
        if self.bits == 8:
            return text + (
                ". 8-bit photos (JPEG) are gamma-encoded: upload the camera's response curve "
                "(made by lightcal response from an exposure bracket), or tick "
                f"'{LABELS['assume_linear']}' if the camera wrote linear values."
            )
        if self.raw:
            return text + "."
        if self.bits is not None and self.brightest is not None and self.bits > 8:
            fits = max(1, math.ceil(math.log2(self.brightest + 1.0)))
            if fits < self.bits:
                text += (
                    f". A {fits}-bit sensor stored in {self.bits} bits has white level "
                    f"{2**fits - 1}"
                )
        return text + (
            ". The file does not say the sensor's black level: enter it in the black level "
            "field (e.g. 512 for many 14-bit sensors); without it the black offset is taken "
            "for light."
        )


@dataclass(frozen=True)
class Staged:
    """What a staging area holds (file names as stored).

    Attributes:
        wall_photos: the photos of the wall, sorted.
        chessboard_photos: the photos of the chessboard, sorted.
        camera: the camera file, if any.
        boards: (board type, file) of each board file: "aruco_grid" and "markers" any
            number, "charuco" and "chessboard" one each.
        light: the light's IES/LDT file, if any.
        response: the camera's response curve file (`lightcal response`), if any.
        levels: the levels the first wall photo's file gives (None without wall photos,
            or when it does not read).
    """

    wall_photos: tuple[str, ...] = ()
    chessboard_photos: tuple[str, ...] = ()
    camera: str | None = None
    boards: tuple[tuple[str, str], ...] = ()
    light: str | None = None
    levels: FileLevels | None = None
    response: str | None = None

    def board(self, kind: str) -> str | None:
        return dict(self.boards).get(kind)

    @property
    def wall_boards(self) -> tuple[tuple[str, str], ...]:
        """(type, file) of the boards on the wall: every ArUco grid and marker list, else
        a ChArUco board."""
        walls = tuple((kind, name) for kind, name in self.boards if kind in WALL_BOARD_TYPES)
        charuco = self.board("charuco")
        return walls or ((("charuco", charuco),) if charuco is not None else ())

    @property
    def chessboard_board(self) -> tuple[str, str] | None:
        """(type, file) of the board in the chessboard photos: a chessboard, else ChArUco."""
        for kind in ("chessboard", "charuco"):
            name = self.board(kind)
            if name is not None:
                return kind, name
        return None

    @property
    def calibrates_camera(self) -> bool:
        """The intrinsics come from the chessboard photos (no camera file given)."""
        return self.camera is None and bool(self.chessboard_photos)

    @property
    def missing(self) -> tuple[str, ...]:
        """What a build still needs, in words."""
        out = []
        if not self.wall_photos:
            out.append("photos of the wall with the printed marker board")
        if self.camera is None and not self.chessboard_photos:
            out.append("a camera file, or photos of a chessboard for the intrinsics")
        if self.calibrates_camera:
            if len(self.chessboard_photos) < MIN_VIEWS:
                out.append(
                    f"at least {MIN_VIEWS} chessboard photos (have {len(self.chessboard_photos)})"
                )
            if self.chessboard_board is None:
                out.append("the board file of the chessboard photos (chessboard or charuco)")
        if not self.wall_boards:
            out.append("the board file of the wall's markers (aruco_grid, markers or charuco)")
        return tuple(out)

    @property
    def ready(self) -> bool:
        return not self.missing

    @property
    def empty(self) -> bool:
        return not (
            self.wall_photos
            or self.chessboard_photos
            or self.camera
            or self.boards
            or self.light
            or self.response
        )


@dataclass(frozen=True)
class Received:
    """What one upload brought.

    Attributes:
        placed: (what it is, name) of each file kept, e.g. ("wall photo", "wall_0.png").
        ignored: (name in the zip, why) of each file of a zip left out.
    """

    placed: tuple[tuple[str, str], ...]
    ignored: tuple[tuple[str, str], ...] = ()

    def text(self) -> str:
        """In a sentence or two: what was received, what was left out."""
        counts: dict[str, int] = {}
        for what, _ in self.placed:
            counts[what] = counts.get(what, 0) + 1
        parts = [f"{n} {what}{'s' if n > 1 else ''}" for what, n in counts.items()]
        text = ("Received " + ", ".join(parts) + ".") if parts else "Nothing was received."
        if self.ignored:
            shown = "; ".join(f"{name} ({why})" for name, why in self.ignored[:8])
            more = f"; and {len(self.ignored) - 8} more" if len(self.ignored) > 8 else ""
            text += f" Left out: {shown}{more}."
        return text


@dataclass(frozen=True)
class PhotoOptions:
    """The choices of a build besides the files (`lightcal init`'s options).

    Attributes:
        half_angle_deg: the light's half-intensity angle, used without a light file
            (None: `DEFAULT_HALF_ANGLE_DEG`, as `lightcal init`).
        initial_position_m: the initial guess of the light, camera frame, m; None with
            `initial_axis_camera` None: `initial: auto`, the guess from the beam in the
            photos (`lightcal init` without --initial-position and --initial-axis).
        initial_axis_camera: the initial guess of its axis, camera frame.
        black_level, white_level: the images' levels (None: `read_image`'s defaults, the
            files' own: a raw file's per-channel levels, 0 and 2^bits - 1 for integers).
        min_markers: photos with fewer markers are rejected.
        mask_margin_px: the padding of the marker masks, pixels.
        max_rms_px: photos whose marker reprojection RMS exceeds this are rejected.
        pose_floor_m, pose_floor_deg: the systematic error of the marker poses added to
            each pose's covariance (`lightcal init --pose-floor-mm/--pose-floor-deg`).
        assume_linear: 8-bit photos are taken as linear (`lightcal init --assume-linear`);
            a staged response curve linearises them instead (`--response`).
    """

    half_angle_deg: float | None = None
    initial_position_m: tuple[float, float, float] | None = None
    initial_axis_camera: tuple[float, float, float] | None = None
    black_level: float | None = None
    white_level: float | None = None
    min_markers: int = 4
    mask_margin_px: float = 3.0
    max_rms_px: float = 1.0
    pose_floor_m: float = POSE_FLOOR_M
    pose_floor_deg: float = POSE_FLOOR_DEG
    assume_linear: bool = False


@dataclass(frozen=True)
class PhotoOutcome:
    """What the build made of one wall photo.

    Attributes:
        name: the photo's file name.
        accepted: in the project.
        markers: markers found (accepted photos).
        rms_px: the markers' reprojection RMS, px (accepted photos).
        reason: why it was rejected (rejected photos).
    """

    name: str
    accepted: bool
    markers: int | None = None
    rms_px: float | None = None
    reason: str | None = None

    @classmethod
    def of(cls, outcome: ImageOutcome) -> PhotoOutcome:
        pose = outcome.pose
        if pose is None:
            return cls(outcome.path.name, False, reason=outcome.reason or "rejected")
        return cls(outcome.path.name, True, pose.n_markers, float(pose.reprojection_rms_px))

    def text(self) -> str:
        """One line: 'accepted: 18 markers, rms 0.052 px' or 'rejected: <reason>'."""
        if self.accepted:
            return f"accepted: {self.markers} markers, rms {self.rms_px:.3f} px"
        return f"rejected: {self.reason}"


@dataclass(frozen=True)
class CameraSource:
    """Where the build's intrinsics came from.

    Attributes:
        file: the camera file uploaded, or None when calibrated from chessboard photos.
        rms_px: the calibration's reprojection RMS, px (calibrated only).
        used: the chessboard photos used (calibrated only).
        rejected: (photo, why) of the chessboard photos left out (calibrated only).
        warnings: what the calibration warned of (e.g. the board nearly square-on in every
            view: `IntrinsicsResult.warnings`).
    """

    file: str | None
    rms_px: float | None = None
    used: tuple[str, ...] = ()
    rejected: tuple[tuple[str, str], ...] = ()
    warnings: tuple[str, ...] = ()

    def text(self) -> str:
        if self.file is not None:
            return f"the camera file {self.file}"
        n = len(self.used) + len(self.rejected)
        text = (
            f"calibrated from {len(self.used)} of {n} chessboard photos, reprojection RMS "
            f"{self.rms_px:.3f} px"
        )
        if self.rejected:
            text += " (left out: " + "; ".join(f"{p}: {why}" for p, why in self.rejected) + ")"
        return text


@dataclass(frozen=True, eq=False)
class PhotoBuild:
    """A project built from the staged photos.

    Attributes:
        project: the project (its file in a `build-<id>/` folder of the staging area).
        loaded: its images.
        photos: one outcome per wall photo, in name order.
        camera: where the intrinsics came from.
        warnings: what `lightcal init` warned of (EXIF exposures, the light's profile).
        boards: the board files used (in the project's zip, which the project does not
            reference).
    """

    project: Project
    loaded: LoadedImages
    photos: tuple[PhotoOutcome, ...]
    camera: CameraSource
    warnings: tuple[str, ...] = ()
    boards: tuple[Path, ...] = ()

    @property
    def accepted(self) -> list[PhotoOutcome]:
        return [p for p in self.photos if p.accepted]

    @property
    def rejected(self) -> list[PhotoOutcome]:
        return [p for p in self.photos if not p.accepted]


# ---------------------------------------------------------------------- page text


def staged_markdown(staged: Staged) -> str:
    """What the page says of the staging area: what was received, what is missing."""

    def names(items: tuple[str, ...]) -> str:
        shown = ", ".join(md(n) for n in items[:6])
        return shown + (f", ... ({len(items)} in all)" if len(items) > 6 else "")

    lines = ["**Received**  "]
    if staged.empty:
        lines = ["**Received**: nothing yet.  "]
    if staged.wall_photos:
        lines.append(f"wall photos ({len(staged.wall_photos)}): {names(staged.wall_photos)}  ")
    if staged.levels is not None:
        lines.append(md(staged.levels.text()) + "  ")
    if staged.camera is not None:
        lines.append(f"camera file: {md(staged.camera)}  ")
    if staged.chessboard_photos:
        note = "" if staged.calibrates_camera else " (not used: a camera file is given)"
        lines.append(
            f"chessboard photos ({len(staged.chessboard_photos)}){note}: "
            f"{names(staged.chessboard_photos)}  "
        )
    for kind, name in staged.boards:
        uses = []
        if (kind, name) in staged.wall_boards:
            uses.append("the wall's markers")
        if staged.calibrates_camera and staged.chessboard_board == (kind, name):
            uses.append("the chessboard photos")
        use = f" for {' and '.join(uses)}" if uses else " (not used)"
        lines.append(f"board file ({kind}){use}: {md(name)}  ")
    if staged.response is not None:
        lines.append(f"response curve: {md(staged.response)} (linearises 8-bit photos)  ")
    if staged.light is not None:
        lines.append(f"light file: {md(staged.light)} (the half angle is not used)  ")
    else:
        lines.append("light: no file, a cos^m profile of the half angle below  ")
    if staged.missing:
        lines.append("")
        lines.append("**Missing**: " + "; ".join(staged.missing) + ".")
    else:
        lines.append("")
        lines.append("**Ready**: press **Build project**.")
    return "\n".join(lines)


def outcomes_markdown(build: PhotoBuild) -> str:
    """The table of the wall photos after a build: accepted (markers, RMS) or rejected."""
    n_ok, n = len(build.accepted), len(build.photos)
    lines = [
        f"**Built**: {n_ok} of {n} photos accepted, {n - n_ok} rejected; camera: "
        f"{md(build.camera.text())}.",
        "",
        "| photo | outcome |",
        "|---|---|",
    ]
    for photo in build.photos:
        mark = "" if photo.accepted else "**rejected**: "
        text = photo.text() if photo.accepted else (photo.reason or "rejected")
        lines.append(f"| {md(photo.name)} | {mark}{md(text)} |")
    for warning in build.camera.warnings:
        lines.append("")
        lines.append(f"Note (chessboard photos): {md(warning)}")
    for warning in build.warnings:
        lines.append("")
        lines.append(f"Note: {md(warning)}")
    return "\n".join(lines)


def check_half_angle(value: float) -> float:
    """A half angle from the page: a finite number of degrees in (0, 90)."""
    if not (isinstance(value, int | float) and math.isfinite(value) and 0.0 < value < 90.0):
        raise InputError("half angle (deg)", f"expected a value in (0, 90) degrees, got {value!r}")
    return float(value)
