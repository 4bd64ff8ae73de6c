"""A table of bad inputs: each gets one line naming the input and what was expected,
exit code 2, and leaves every input file as it was."""

from __future__ import annotations

import copy
import hashlib
import json
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from lightcal.cli.main import main


@pytest.fixture(scope="module")
def dataset(tiny_dataset: Path) -> Path:
    return tiny_dataset


def _set(path: str, value: Any) -> Callable[[dict[str, Any]], None]:
    """A project edit: set the field at a dotted path (list indices as numbers)."""

    def edit(project: dict[str, Any]) -> None:
        *parents, last = path.split(".")
        node: Any = project
        for key in parents:
            node = node[int(key)] if key.isdigit() else node[key]
        node[int(last) if last.isdigit() else last] = value

    return edit


# (case, project edit, the message after "<project>: ")
PROJECT_CASES: list[tuple[str, Callable[[dict[str, Any]], None], str]] = [
    (
        "negative seed",
        _set("selection.seed", -1),
        "selection.seed: Input should be greater than or equal to 0",
    ),
    (
        "seed beyond numpy",
        _set("selection.seed", 10**24),
        "selection.seed: Input should be less than or equal to 4294967295",
    ),
    (
        "tolerance below 1e-15",
        _set("solver.tolerance", 1e-300),
        "solver.tolerance: Input should be greater than or equal to 0.000000000000001",
    ),
    (
        "binning larger than the image",
        lambda p: p["selection"].update(strategy="all", binning=5000),
        "selection.binning: 5000 is larger than the image (96x72); expected at most 72",
    ),
    (
        "exposure 0",
        _set("images.0.exposure", 0),
        "images[0].exposure: expected a finite value > 0, got 0.0",
    ),
    (
        "fewer pixels than parameters",
        lambda p: p["selection"].update(strategy="random", n_per_image=1),
        "selection: 4 usable pixels for 6 parameters; expected more pixels than parameters "
        "(more images or pixels per image, a lower binning, or fewer parameters to estimate)",
    ),
    (
        "camera on the wall's far side",
        _set("images.0.T_camera_world.t", [1e308, 0.0, 0.0]),
        "images[0].T_camera_world: camera pose: the camera centre is at z = ",
    ),
    (
        "missing image",
        _set("images.1.path", "images/nope.png"),
        "images[1].path: image file not found: ",
    ),
    # Every field of the project file (generated once from `lightcal synth` data, kept as
    # the contract: each message names the field and what was expected).
    (
        "rotation matrix 2 x 2",
        _set("images.0.T_camera_world.R", [[1, 0], [0, 1]]),
        "images[0].T_camera_world.R[0]: List should have at least 3 items after validation, not 2",
    ),
    (
        "rotation scaled",
        _set("images.0.T_camera_world.R", [[2, 0, 0], [0, 1, 0], [0, 0, 1]]),
        "images[0].T_camera_world: R_camera_world: expected a rotation matrix (max |R^T R - I| <= 1e-06), got max |R^T R - I| = 3",
    ),
    (
        "camera looking away",
        _set("images.0.T_camera_world.R", [[1, 0, 0], [0, 1, 0], [0, 0, 1]]),
        "images[0].T_camera_world: camera pose: the camera centre is at z = -1.147 m, on or behind the wall; expected z > 0 (the wall is z = 0 and cameras look at it from z > 0)",
    ),
    (
        "translation of 2",
        _set("images.0.T_camera_world.t", [0, 0]),
        "images[0].T_camera_world.t: List should have at least 3 items after validation, not 2",
    ),
    (
        "translation NaN",
        _set("images.0.T_camera_world.t", [0, 0, math.nan]),
        "images[0].T_camera_world.t[2]: Input should be a finite number",
    ),
    (
        "covariance 1 x 1",
        _set("images.0.T_camera_world.covariance", [[1]]),
        "images[0].T_camera_world.covariance[0]: List should have at least 6 items after validation, not 1",
    ),
    (
        "covariance not symmetric",
        _set(
            "images.0.T_camera_world.covariance",
            [
                [-1, 0, 0, 0, 0, 0],
                [-1, 0, 0, 0, 0, 0],
                [-1, 0, 0, 0, 0, 0],
                [-1, 0, 0, 0, 0, 0],
                [-1, 0, 0, 0, 0, 0],
                [-1, 0, 0, 0, 0, 0],
            ],
        ),
        "images[0].T_camera_world: covariance: expected a symmetric matrix",
    ),
    (
        "exposure negative",
        _set("images.0.exposure", -1),
        "images[0].exposure: expected a finite value > 0, got -1.0",
    ),
    (
        "exposure time 0",
        _set("images.0.exposure.exposure_time_s", 0),
        "images[0].exposure.exposure_time_s: Input should be greater than 0",
    ),
    (
        "image path empty",
        _set("images.0.path", ""),
        "images[0].path: image file not found: {folder}",
    ),
    (
        "image named twice",
        _set("images.1.name", "view_00"),
        "images: two images are named 'view_00'; names must be unique",
    ),
    (
        "no images",
        _set("images", []),
        "images: List should have at least 1 item after validation, not 0",
    ),
    (
        "no lights",
        _set("lights", []),
        "lights: List should have at least 1 item after validation, not 0",
    ),
    (
        "light behind the wall",
        _set("lights.0.initial.position_m", [0, 0, 5]),
        "lights[0].initial.position_m: the light is on or behind the wall in image 'view_00' (world z = -3.65 m); expected it in front (z > 0)",
    ),
    (
        "light position of 2",
        _set("lights.0.initial.position_m", [0, 0]),
        "lights[0].initial.position_m: List should have at least 3 items after validation, not 2",
    ),
    (
        "light scale negative",
        _set("lights.0.initial.scale", -1),
        "lights[0].initial.scale: Input should be greater than 0",
    ),
    (
        "RID type unknown",
        _set("lights.0.rid.type", "nonsense"),
        "lights[0].rid.type: Input should be 'isotropic', 'cos_power', 'gaussian', 'half_angle', 'table', 'ies' or 'ldt'",
    ),
    (
        "cos^m exponent negative",
        _set("lights.0.rid", {"type": "cos_power", "m": -1}),
        "lights[0].rid.m: Input should be greater than or equal to 0",
    ),
    (
        "IES without a path",
        _set("lights.0.rid", {"type": "ies"}),
        "lights[0].rid: RID type 'ies' needs path",
    ),
    (
        "IES file missing",
        _set("lights.0.rid", {"type": "ies", "path": "nope.ies"}),
        "lights[0].rid.path: RID file not found: {folder}/nope.ies",
    ),
    (
        "pose kind unknown",
        _set("lights.0.pose", "sideways"),
        "lights[0].pose: Input should be 'auto', 'isotropic', 'symmetric' or 'general'",
    ),
    (
        "one curve knot",
        _set("lights.0.curve_knots", 1),
        "lights[0].curve_knots: Input should be greater than or equal to 2",
    ),
    (
        "strategy unknown",
        _set("selection.strategy", "best"),
        "selection.strategy: Input should be 'random', 'grid' or 'all'",
    ),
    (
        "no pixels per image",
        _set("selection.n_per_image", 0),
        "selection.n_per_image: Input should be greater than or equal to 1",
    ),
    (
        "grid step 0",
        _set("selection.grid_step", 0),
        "selection.grid_step: Input should be greater than or equal to 1",
    ),
    (
        "region of one point",
        _set("selection.regions", [{"kind": "rect", "points": [[0, 0]]}]),
        "selection.regions[0].points: List should have at least 2 items after validation, not 1",
    ),
    (
        "min_signal NaN",
        _set("selection.min_signal", math.nan),
        "selection.min_signal: Input should be a finite number",
    ),
    (
        "map without a file",
        _set("sensor.model", "map"),
        "sensor: the 'map' sensor model needs a vignetting file",
    ),
    (
        "black level negative",
        _set("sensor.black_level", -5),
        "sensor.black_level: Input should be greater than or equal to 0",
    ),
    (
        "white below black",
        _set("sensor.white_level", 10),
        "sensor: white_level 10 must be above black_level 512",
    ),
    (
        "noise gain negative",
        _set("sensor.noise.gain", -1),
        "sensor.noise.gain: Input should be greater than or equal to 0",
    ),
    (
        "channel unknown",
        _set("sensor.channel", "purple"),
        "sensor.channel: Input should be 'auto', 'green_binned', 'luminance', 'R', 'G', 'G1', 'G2' or 'B'",
    ),
    (
        "loss unknown",
        _set("solver.loss", "huberish"),
        "solver.loss: Input should be 'linear', 'huber', 'soft_l1' or 'cauchy'",
    ),
    (
        "no iterations",
        _set("solver.max_iterations", 0),
        "solver.max_iterations: Input should be greater than or equal to 1",
    ),
    ("f_scale 0", _set("solver.f_scale", 0), "solver.f_scale: Input should be greater than 0"),
    (
        "multistart negative",
        _set("solver.multistart", -1),
        "solver.multistart: Input should be greater than or equal to 0",
    ),
    (
        "position bound 0",
        _set("solver.position_bound_m", 0),
        "solver.position_bound_m: Input should be greater than 0",
    ),
    (
        "RID subsamples 100",
        _set("solver.rid_subsamples", 100),
        "solver.rid_subsamples: Input should be less than or equal to 16",
    ),
    (
        "wall model unknown",
        _set("wall.model", "velvet"),
        "wall.model: Input should be 'lambertian', 'plastic', 'oren_nayar' or 'auto'",
    ),
    (
        "wall roughness negative",
        _set("wall", {"model": "plastic", "parameters": {"roughness": -1}}),
        "wall.parameters: plastic wall: roughness: expected a value in [0.02, 1], got -1",
    ),
    (
        "Lambertian wall estimating",
        _set("wall", {"model": "lambertian", "estimate": ["roughness"]}),
        "wall: the lambertian wall takes no parameters and estimates none",
    ),
    (
        "camera file missing",
        _set("camera.path", "nope.yaml"),
        "camera.path: camera file not found: {folder}/nope.yaml",
    ),
    (
        "camera half given",
        _set("camera", {"fx": 100}),
        "camera: give either path or all of fx, fy, cx, cy, width, height",
    ),
    ("version 2", _set("version", 2), "version: this lightcal reads project version 1, got 2"),
    ("unknown field", _set("extra_field", 1), "extra_field: Extra inputs are not permitted"),
]


def _hashes(folder: Path) -> dict[str, str]:
    return {
        p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


@pytest.mark.parametrize(
    ("case", "edit", "expected"), PROJECT_CASES, ids=[c[0] for c in PROJECT_CASES]
)
def test_bad_projects(
    dataset: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    case: str,
    edit: Callable[[dict[str, Any]], None],
    expected: str,
) -> None:
    project = copy.deepcopy(json.loads((dataset / "project.json").read_text()))
    edit(project)
    path = dataset / f"case-{abs(hash(case))}.json"
    path.write_text(json.dumps(project))
    before = _hashes(dataset)
    out = tmp_path / "r.json"
    try:
        assert main(["calibrate", str(path), "--out", str(out), "--quiet"]) == 2
    finally:
        after = _hashes(dataset)
        path.unlink()
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    expected = expected.format(folder=dataset)
    assert err.startswith(f"lightcal calibrate: error: {path}: {expected}"), err
    assert after == before
    assert not out.exists()


def _project_file(tmp_path: Path, content: bytes) -> Path:
    path = tmp_path / "project.json"
    path.write_bytes(content)
    return path


FILE_CASES: list[tuple[str, Callable[[Path], Path], str]] = [
    (
        "a folder",
        lambda d: (d / "folder.json").mkdir() or d / "folder.json",
        "is a folder; expected a project file",
    ),
    (
        "a FIFO",
        lambda d: os.mkfifo(d / "fifo.json") or d / "fifo.json",
        "is not a regular file (a pipe or a device); expected a project file",
    ),
    (
        "UTF-16 without a byte-order mark",
        lambda d: _project_file(d, '{"version": 1}'.encode("utf-16-le")),
        "the project file looks like UTF-16 without a byte-order mark: save it as UTF-8",
    ),
    (
        "Latin-1 bytes",
        lambda d: _project_file(d, b'{"name": "caf\xe9"}'),
        "the project file is not UTF-8 text (byte 13): save it as UTF-8",
    ),
    (
        "nested 20,000 deep",
        lambda d: _project_file(d, b"[" * 20000 + b"]" * 20000),
        "the project file is nested too deeply to be read",
    ),
    (
        "nested 100 deep",
        lambda d: _project_file(d, b"[" * 100 + b"]" * 100),
        "the project file is nested more than 64 levels deep",
    ),
]


@pytest.mark.parametrize(("case", "make", "expected"), FILE_CASES, ids=[c[0] for c in FILE_CASES])
def test_bad_project_files(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    case: str,
    make: Callable[[Path], Path],
    expected: str,
) -> None:
    path = make(tmp_path)
    assert main(["calibrate", str(path), "--out", str(tmp_path / "r.json"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err == f"lightcal calibrate: error: {path}: {expected}\n"


def test_utf16_with_a_byte_order_mark_is_read(dataset: Path) -> None:
    text = (dataset / "project.json").read_text()
    project = json.loads(text)
    path = dataset / "utf16.json"
    path.write_bytes(json.dumps(project).encode("utf-16"))  # with a BOM
    from lightcal.io.project import load_project

    try:
        assert load_project(path).names == load_project(dataset / "project.json").names
    finally:
        path.unlink()


def test_a_solution_on_the_search_box_is_not_converged(
    dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    project = json.loads((dataset / "project.json").read_text())
    project["solver"]["position_bound_m"] = 0.01
    path = dataset / "bound.json"
    path.write_text(json.dumps(project))
    out = tmp_path / "r.json"
    try:
        assert main(["calibrate", str(path), "--out", str(out), "--quiet"]) == 1
    finally:
        path.unlink()
    result = json.loads(out.read_text())
    assert result["converged"] is False
    assert any(
        w.startswith("light light: its position ends on the edge of the solver's search box")
        for w in result["warnings"]
    )
    assert "did not converge" in capsys.readouterr().err


def _png_header(width: int, height: int) -> bytes:
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        crc = struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
        return struct.pack(">I", len(data)) + kind + data + crc

    ihdr = struct.pack(">IIBBBBB", width, height, 16, 0, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", ihdr)
        + chunk(b"IDAT", zlib.compress(b"\x00" * 10))
        + chunk(b"IEND", b"")
    )


IMAGE_CASES: list[tuple[str, str, bytes, str]] = [
    (
        "PNG header claiming 100000 x 100000",
        "huge.png",
        _png_header(100_000, 100_000),
        "the image is 100000 x 100000 pixels; at most 65535 a side and 400 megapixels",
    ),
    (
        "text named .npy",
        "text.npy",
        b"hello, not an array",
        "not a NumPy .npy file (no .npy header); expected an (H, W) array",
    ),
    ("corrupt PNG", "bad.png", b"\x89PNG\r\n\x1a\nnot really", "not a readable PNG image"),
]


@pytest.mark.parametrize(
    ("case", "name", "content", "expected"), IMAGE_CASES, ids=[c[0] for c in IMAGE_CASES]
)
def test_bad_images(tmp_path: Path, case: str, name: str, content: bytes, expected: str) -> None:
    from lightcal.errors import InputError
    from lightcal.io.images import read_image

    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(InputError) as info:
        read_image(path, assume_linear=True)
    assert str(info.value) == f"{path}: {expected}"


def test_photometric_counts_beyond_the_data_are_refused_before_allocating(tmp_path: Path) -> None:
    from lightcal.errors import InputError
    from lightcal.io.eulumdat import read_ldt
    from lightcal.io.ies import read_ies

    ies = tmp_path / "big.ies"
    header = "IESNA:LM-63-2002\nTILT=NONE\n1 1000 1 1000000000000 1 1 1 0 0 0\n"
    ies.write_text(header + "1 1 100\n0 1 2\n0\n1 1 1\n")
    with pytest.raises(InputError) as info:
        read_ies(ies)
    assert str(info.value) == (
        f"{ies}: the counts (1 horizontal x 1000000000000 vertical angles) demand "
        "2000000000001 numbers after the header, found 7"
    )
    lines = ["x"] * 42
    for number, value in {2: "1", 3: "0", 4: "1000000000000", 5: "0", 6: "3", 7: "0"}.items():
        lines[number - 1] = value  # Ityp 1, Isym 0, Mc 10^12, Dc, Ng 3, Dg
    lines[23], lines[25] = "1", "0"  # conversion factor, no lamp sets
    ldt = tmp_path / "big.ldt"
    ldt.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"the counts \(Mc 1000000000000 C-planes"):
        read_ldt(ldt)
