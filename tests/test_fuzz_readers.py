"""Property-based fuzzing of the file readers: whatever the bytes, the project's input
error or a result, never another exception (a traceback for the user).

Each reader gets random bytes and random edits of a valid file (cut, duplicated or
replaced spans; numbers swapped for extreme or malformed ones), the way a truncated
download, a wrong file or a hand edit gone wrong look.
"""

from __future__ import annotations

import contextlib
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from lightcal.errors import LightcalError  # noqa: E402
from lightcal.io.camera_file import read_camera  # noqa: E402
from lightcal.io.colmap import read_camera_ids, read_images_txt  # noqa: E402
from lightcal.io.eulumdat import read_ldt  # noqa: E402
from lightcal.io.ies import read_ies  # noqa: E402
from lightcal.io.photometric_table import read_rid_csv  # noqa: E402
from lightcal.io.project import load_project  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
DATA = REPO / "tests" / "data"

# Tokens that break parsers: extremes, non-numbers, separators, other encodings.
NASTY = [
    "nan",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "1e-320",
    "0",
    "-1",
    "99999999999999999999999",
    "",
    " ",
    ",",
    ";",
    "\n",
    "{",
    "[",
    "]",
    "}",
    '"',
    "\x00",
    "\ufeff",
    "é",
    "TILT=",
    "null",
    "true",
    "-0",
]

FUZZ = settings(
    max_examples=120,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    derandomize=True,  # the same cases on every run: a failure reproduces
)


@st.composite
def edited(draw: st.DrawFn, text: str) -> bytes:
    """`text` with a few random edits (see the module docstring)."""
    s = text
    for _ in range(draw(st.integers(1, 4))):
        i = draw(st.integers(0, len(s)))
        j = draw(st.integers(i, min(len(s), i + 40)))
        kind = draw(st.sampled_from(["cut", "nasty", "dup", "text"]))
        if kind == "cut":
            s = s[:i] + s[j:]
        elif kind == "nasty":
            s = s[:i] + draw(st.sampled_from(NASTY)) + s[j:]
        elif kind == "dup":
            s = s[:i] + s[i:j] * draw(st.integers(2, 5)) + s[j:]
        else:
            s = s[:i] + draw(st.text(max_size=20)) + s[j:]
    encoding = draw(st.sampled_from(["utf-8", "utf-8", "utf-8", "utf-16", "latin-1"]))
    return s.encode(encoding, errors="replace")


def _survives(reader: Callable[[Path], Any], name: str, content: bytes) -> None:
    """reader(file with `content`) returns, or raises the project's input error."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / name
        path.write_bytes(content)
        with contextlib.suppress(LightcalError):
            reader(path)


CASES: list[tuple[str, Callable[[Path], Any], Path]] = [
    ("project.json", load_project, REPO / "sample_data" / "project.json"),
    ("light.ies", read_ies, DATA / "photometry" / "bilateral_0_180_2019.ies"),
    ("light.ldt", read_ldt, DATA / "photometry" / "isym4_quadrant.ldt"),
    ("camera.yml", read_camera, DATA / "camera" / "opencv4_calibration.yml"),
    ("camera.yaml", read_camera, DATA / "camera" / "ros_camera_info.yaml"),
    ("cameras.txt", read_camera, DATA / "camera" / "colmap_cameras.txt"),
    ("cameras.txt", read_camera_ids, DATA / "camera" / "colmap_cameras.txt"),
    ("images.txt", read_images_txt, DATA / "colmap" / "wall" / "images.txt"),
]


@pytest.mark.parametrize(("name", "reader", "valid"), CASES, ids=[c[0] for c in CASES])
def test_edited_files_give_input_errors_only(
    name: str, reader: Callable[[Path], Any], valid: Path
) -> None:
    text = valid.read_text(encoding="utf-8")
    # The project's relative paths must still resolve: it is read from its own folder.
    if name == "project.json":

        def reader_here(path: Path, _reader: Callable[[Path], Any] = reader) -> Any:
            target = valid.parent / f".fuzz-{path.name}"
            target.write_bytes(path.read_bytes())
            try:
                return _reader(target)
            finally:
                target.unlink()

        reader = reader_here

    @FUZZ
    @given(content=edited(text))
    def run(content: bytes) -> None:
        _survives(reader, name, content)

    run()


@pytest.mark.parametrize(
    ("name", "reader"),
    [
        ("project.json", load_project),
        ("project.yaml", load_project),
        ("light.ies", read_ies),
        ("light.ldt", read_ldt),
        ("rid.csv", read_rid_csv),
        ("camera.json", read_camera),
        ("camera.yaml", read_camera),
    ],
)
def test_random_bytes_give_input_errors_only(name: str, reader: Callable[[Path], Any]) -> None:
    @FUZZ
    @given(content=st.binary(max_size=400))
    def run(content: bytes) -> None:
        _survives(reader, name, content)

    run()


def test_a_valid_csv_survives_edits() -> None:
    text = "theta_deg,value\n0,1\n10,0.9\n20,0.7\n30,0.4\n40,0.1\n50,0\n"

    @FUZZ
    @given(content=edited(text))
    def run(content: bytes) -> None:
        _survives(read_rid_csv, "rid.csv", content)

    run()
