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


def _surface(**changes: Any) -> dict[str, Any]:
    """A ceiling for `surroundings` with some fields changed."""
    return {
        "corner_m": [-1.0, -0.5, 0.0],
        "edge_u_m": [2.0, 0.0, 0.0],
        "edge_v_m": [0.0, 0.0, 0.5],
        "albedo": 0.8,
        **changes,
    }


#: A light's flat port (`lights[i].port`) for the cases of what it does not model.
_LIGHT_PORT = {"distance_mm": 15, "thickness_mm": 8}

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
        "images[0].T_camera_world: t: [1e+308, 0.0, 0.0] m: expected a camera within 10000 m "
        "of the wall's origin (a translation this large is a unit or sign mistake)",
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
        "light port distance 0",
        _set("lights.0.port", {"distance_mm": 0, "thickness_mm": 8}),
        "lights[0].port.distance_mm: Input should be greater than 0",
    ),
    (
        "light port unknown key",
        _set("lights.0.port", {"distance_mm": 15, "thickness_mm": 8, "index": 1.5}),
        "lights[0].port.index: Extra inputs are not permitted",
    ),
    (
        "light port with a glossy wall",
        lambda p: (_set("lights.0.port", _LIGHT_PORT)(p), _set("wall", {"model": "plastic"})(p)),
        "lights[0].port: not modelled together with wall.model: plastic (a non-Lambertian "
        "wall's reflectance needs the water direction at the wall)",
    ),
    (
        "light port with surroundings",
        lambda p: (
            _set("lights.0.port", _LIGHT_PORT)(p),
            _set("surroundings", {"surfaces": [_surface()]})(p),
        ),
        "lights[0].port: not modelled together with surroundings (their bounce light is "
        "traced straight from the light)",
    ),
    (
        "light port with an estimated RID",
        lambda p: (
            _set("lights.0.port", _LIGHT_PORT)(p),
            _set("lights.0.estimate_rid", "cos_power")(p),
        ),
        "lights[0].port: not modelled together with lights[0].estimate_rid: cos_power (its "
        "columns take the straight direction, not the air's)",
    ),
    (
        "light port with initial auto",
        lambda p: (_set("lights.0.port", _LIGHT_PORT)(p), _set("lights.0.initial", "auto")(p)),
        "lights[0].port: not modelled together with lights[0].initial: auto (the beam is "
        "sighted along straight rays)",
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
        "light guess 20 m from the camera",
        _set("lights.0.initial.position_m", [20.0, 0.0, 0.0]),
        "lights[0].initial.position_m[0]: Input should be less than or equal to 10",
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
        "medium attenuation negative",
        _set("medium", {"attenuation_per_m": -0.1}),
        "medium.attenuation_per_m: Input should be greater than or equal to 0",
    ),
    (
        "medium attenuation NaN",
        _set("medium", {"attenuation_per_m": math.nan}),
        "medium.attenuation_per_m: Input should be a finite number",
    ),
    (
        "medium attenuation beyond the bound",
        _set("medium", {"attenuation_per_m": 20}),
        "medium.attenuation_per_m: Input should be less than or equal to 10",
    ),
    (
        "medium parameter unknown",
        _set("medium", {"estimate": ["scattering"]}),
        "medium.estimate[0]: Input should be 'attenuation_per_m', 'backscatter_per_m' or 'phase_g'",
    ),
    (
        "medium phase g estimated without backscatter",
        _set("medium", {"attenuation_per_m": 0.2, "estimate": ["phase_g"]}),
        "medium.estimate: phase_g shapes the backscatter; expected backscatter_per_m > 0 or "
        "estimated beside it",
    ),
    (
        "wall albedo map with a robust loss",
        lambda p: (_set("solver.loss", "huber")(p), _set("wall", {"albedo_map": {}})(p)),
        "wall.albedo_map: expected solver.loss linear, got 'huber' (the albedo map is solved "
        "by linear least squares)",
    ),
    (
        "wall albedo map spacing below 1 mm",
        _set("wall", {"albedo_map": {"spacing_mm": 0.5}}),
        "wall.albedo_map.spacing_mm: Input should be greater than or equal to 1",
    ),
    (
        "medium phase g beyond 0.99",
        _set("medium", {"backscatter_per_m": 0.5, "phase_g": 1.5}),
        "medium.phase_g: Input should be less than or equal to 0.99",
    ),
    (
        "medium backscatter with the cos4 sensor model",
        lambda p: (_set("sensor.model", "cos4")(p), _set("medium", {"backscatter_per_m": 0.5})(p)),
        "medium.backscatter_per_m: the backscatter is modelled for sensor.model radiance; "
        "got 'cos4'",
    ),
    (
        "medium parameter twice",
        _set("medium", {"estimate": ["attenuation_per_m", "attenuation_per_m"]}),
        "medium.estimate: expected each parameter once",
    ),
    (
        "medium key unknown",
        _set("medium", {"attenuation": 0.2}),
        "medium.attenuation: Extra inputs are not permitted",
    ),
    (
        "surroundings: a surface behind the wall",
        _set("surroundings", {"surfaces": [_surface(corner_m=[0, -0.5, -0.2])]}),
        "surroundings.surfaces[0]: reaches behind the wall (z = -0.2 m); expected z >= 0 "
        "everywhere (the wall is the plane z = 0, the cameras are at z > 0)",
    ),
    (
        "surroundings: a surface in the wall's plane",
        _set("surroundings", {"surfaces": [_surface(edge_v_m=[0, 1, 0])]}),
        "surroundings.surfaces[0]: lies in the wall's plane z = 0 (it would overlap the "
        "wall); expected a surface in front of it",
    ),
    (
        "surroundings: a surface of zero size",
        _set("surroundings", {"surfaces": [_surface(name="shelf", edge_u_m=[0, 0, 0])]}),
        "surroundings.surfaces[0] (shelf): expected edges of 1 mm to 100 m, got 0 and 0.5 m",
    ),
    (
        "surroundings: parallel edges",
        _set("surroundings", {"surfaces": [_surface(edge_v_m=[2, 0, 0])]}),
        "surroundings.surfaces[0]: expected two edges that are not parallel",
    ),
    (
        "surroundings: NaN",
        _set("surroundings", {"surfaces": [_surface(corner_m=[0, math.nan, 0])]}),
        "surroundings.surfaces[0].corner_m[1]: Input should be a finite number",
    ),
    (
        "surroundings: albedo 1",
        _set("surroundings", {"surfaces": [_surface(albedo=1.0)]}),
        "surroundings.surfaces[0].albedo: Input should be less than 1",
    ),
    (
        "surroundings: no surface",
        _set("surroundings", {"surfaces": []}),
        "surroundings.surfaces: List should have at least 1 item after validation, not 0",
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
    (
        "polygon of two points",
        _set("selection.regions", [{"kind": "polygon", "points": [[0, 0], [1, 1]]}]),
        "selection.regions[0]: a polygon needs at least 3 points",
    ),
    (
        "RID estimate unknown",
        _set("lights.0.estimate_rid", "magic"),
        "lights[0].estimate_rid: Input should be 'none', 'cos_power' or 'curve'",
    ),
    (
        "tolerance above 1",
        _set("solver.tolerance", 2),
        "solver.tolerance: Input should be less than or equal to 1",
    ),
    (
        "binning 0",
        _set("selection.binning", 0),
        "selection.binning: Input should be greater than or equal to 1",
    ),
    (
        "curve range 90",
        _set("lights.0.curve_max_angle_deg", 90),
        "lights[0].curve_max_angle_deg: Input should be less than or equal to 89",
    ),
    (
        "noise read variance NaN",
        _set("sensor.noise.read_variance", math.nan),
        "sensor.noise.read_variance: Input should be a finite number",
    ),
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
    assert "not converged: the" in capsys.readouterr().out  # the answer: stdout


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


# Every command: (case, argv template, expected stderr line). {d}: the dataset folder,
# {t}: a temporary folder, {r}: a result of calibrating the dataset.
COMMAND_CASES: list[tuple[str, str, str]] = [
    (
        "render: result missing",
        "render {d}/project.json --result {t}/nope.json --out {t}/rr",
        "lightcal render: error: {t}/nope.json: result file not found",
    ),
    (
        "render: result without lights",
        "render {d}/project.json --result {t}/bad.json --out {t}/rr",
        "lightcal render: error: {t}/bad.json: lights: Field required",
    ),
    (
        "render: NaN in the result",
        "render {d}/project.json --result {t}/nan.json --out {t}/rr",
        "lightcal render: error: {t}/nan.json: lights.0.position_m.0: Input should be a finite number",
    ),
    (
        "render: result not JSON",
        "render {d}/project.json --result {t}/bin.json --out {t}/rr",
        "lightcal render: error: {t}/bin.json:1: not valid JSON: Expecting value",
    ),
    (
        "render: --out a file",
        "render {d}/project.json --result {r} --out {d}/project.json",
        "lightcal render: error: {d}/project.json: --out: is a file; expected a folder to write into",
    ),
    (
        "render: --out the images",
        "render {d}/project.json --result {r} --out {d}/images",
        "lightcal render: error: {d}/images: --out: holds image view_00, an input of the project; choose another folder",
    ),
    (
        "export: result missing",
        "export {t}/nope.json --format opencv --out {t}/x.yaml",
        "lightcal export: error: {t}/nope.json: result file not found",
    ),
    (
        "export: result without lights",
        "export {t}/bad.json --format opencv --out {t}/x.yaml",
        "lightcal export: error: {t}/bad.json: lights: Field required",
    ),
    (
        "export: IES without a RID",
        "export {r} --format ies --out {t}/x.ies",
        "lightcal export: error: {r}: light 'light' has no estimated RID: expected a result of a calibration with estimate_rid (cos_power or curve)",
    ),
    (
        "export: folder missing",
        "export {r} --format opencv --out {t}/no/x.yaml",
        "lightcal export: error: {t}/no/x.yaml: --out: the folder {t}/no does not exist; create it first",
    ),
    (
        "export: onto an existing file",
        "export {r} --format opencv --out {d}/project.json",
        "lightcal export: error: {d}/project.json: the file exists: expected a new path, or --force",
    ),
    (
        "init: image folder missing",
        "init {t}/nope --camera {d}/camera.yaml --board {t}/b.yaml --out {t}/p.json",
        "lightcal init: error: {t}/nope: image folder not found",
    ),
    (
        "init: camera missing",
        "init {d}/images --camera {t}/nope.yaml --board {t}/b.yaml --out {t}/p.json",
        "lightcal init: error: {t}/nope.yaml: camera file not found",
    ),
    (
        "init: board missing",
        "init {d}/images --camera {d}/camera.yaml --board {t}/b.yaml --out {t}/p.json",
        "lightcal init: error: {t}/b.yaml: board file not found",
    ),
    (
        "camera calibrate: board missing",
        "camera calibrate {t}/nope --board {t}/b.yaml --out {t}/c.yaml",
        "lightcal camera: error: {t}/b.yaml: board file not found",
    ),
    (
        "camera import: file missing",
        "camera import {t}/nope.txt --out {t}/c.yaml",
        "lightcal camera: error: {t}/nope.txt: camera file not found",
    ),
    (
        "synth: no views",
        "synth {t}/s --views 0",
        "lightcal synth: error: --views: expected an integer >= 1, got 0",
    ),
    (
        "synth: negative width",
        "synth {t}/s --width -5",
        "lightcal synth: error: --width/--height: expected > 0, got -5 x 800",
    ),
    (
        "synth: into the dataset",
        "synth {d} --views 2",
        "lightcal synth: error: {d}: the folder is not empty: expected a new or empty folder (--force replaces the dataset in it)",
    ),
    (
        "sample: into the dataset",
        "sample {d}",
        "lightcal sample: error: {d}: the folder is not empty; choose a new or empty folder, or add --force to write the sample's missing files into it (existing files are never overwritten)",
    ),
    (
        "calibrate: --report a file",
        "calibrate {d}/project.json --out {t}/r.json --report {d}/project.json",
        "lightcal calibrate: error: {d}/project.json: --report: is a file; expected a folder to write into",
    ),
]


@pytest.fixture(scope="module")
def result_file(dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("result") / "result.json"
    assert main(["calibrate", str(dataset / "project.json"), "--out", str(out), "--quiet"]) in (
        0,
        3,
    )
    return out


@pytest.mark.parametrize(
    ("case", "argv", "expected"), COMMAND_CASES, ids=[c[0] for c in COMMAND_CASES]
)
def test_bad_command_lines(
    dataset: Path,
    result_file: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    case: str,
    argv: str,
    expected: str,
) -> None:
    (tmp_path / "bad.json").write_text('{"bad": 1}')
    broken = json.loads(result_file.read_text())
    broken["lights"][0]["position_m"][0] = math.nan
    (tmp_path / "nan.json").write_text(json.dumps(broken))
    (tmp_path / "bin.json").write_bytes(b"\x01\x02")
    fill = {"d": dataset, "t": tmp_path, "r": result_file}
    before = _hashes(dataset)
    capsys.readouterr()
    assert main(argv.format(**fill).split()) == 2
    assert capsys.readouterr().err == expected.format(**fill) + "\n"
    assert _hashes(dataset) == before


def _ies() -> str:
    return (Path(__file__).parent / "data" / "photometry" / "bilateral_0_180_2019.ies").read_text()


def _ldt(line: int, value: str) -> str:
    lines = (Path(__file__).parent / "data" / "photometry" / "isym4_quadrant.ldt").read_text()
    rows = lines.splitlines()
    rows[line - 1] = value
    return "\n".join(rows)


def _ldt_first(n: int) -> str:
    lines = (Path(__file__).parent / "data" / "photometry" / "isym4_quadrant.ldt").read_text()
    return "\n".join(lines.splitlines()[:n])


# Every text reader: (case, reader, suffix, content, expected message after "<file>").
READER_CASES: list[tuple[str, str, str, Callable[[], str], str]] = [
    (
        "ies: no TILT line",
        "ies",
        ".ies",
        lambda: "\n".join(l for l in _ies().splitlines() if not l.startswith("TILT")),
        ":15: no TILT= line: expected TILT=NONE after the header and keyword lines",
    ),
    (
        "ies: tilt table",
        "ies",
        ".ies",
        lambda: _ies().replace("TILT=NONE", "TILT=INCLUDE"),
        ":7: TILT=INCLUDE: tilt tables are not supported; expected TILT=NONE",
    ),
    (
        "ies: header only",
        "ies",
        ".ies",
        lambda: "\n".join(_ies().splitlines()[:3]),
        ":3: no TILT= line: expected TILT=NONE after the header and keyword lines",
    ),
    ("ies: empty", "ies", ".ies", lambda: "", ": the file is empty: expected an IES LM-63 file"),
    (
        "ies: a word for a number",
        "ies",
        ".ies",
        lambda: _ies().replace(" 0 ", " zero ", 1),
        ":8: luminous opening width: expected a number, got 'zero'",
    ),
    (
        "ies: nan",
        "ies",
        ".ies",
        lambda: _ies().replace(" 0 ", " nan ", 1),
        ":8: luminous opening width: expected a finite number, got 'nan'",
    ),
    ("ldt: empty", "ldt", ".ldt", lambda: "", ": the file is empty: expected an EULUMDAT file"),
    (
        "ldt: Isym 7",
        "ldt",
        ".ldt",
        lambda: _ldt(3, "7"),
        ":3: symmetry indicator Isym 7: expected 0, 1, 2, 3 or 4",
    ),
    (
        "ldt: no C-planes",
        "ldt",
        ".ldt",
        lambda: _ldt(4, "0"),
        ":4: number of C-planes Mc 0: expected an integer >= 1",
    ),
    (
        "ldt: one intensity",
        "ldt",
        ".ldt",
        lambda: _ldt(6, "1"),
        ":6: number of intensities per C-plane Ng 1: expected an integer >= 2",
    ),
    (
        "ldt: truncated",
        "ldt",
        ".ldt",
        lambda: _ldt_first(30),
        ":30: unexpected end of file: expected line 43, C angle 1 of 8",
    ),
    (
        "ldt: conversion factor 0",
        "ldt",
        ".ldt",
        lambda: _ldt(24, "0"),
        ":24: conversion factor for luminous intensities 0: expected a value > 0",
    ),
    ("camera: empty", "camera", ".yml", lambda: "", ": empty file: expected a mapping of keys"),
    (
        "camera: no matrix",
        "camera",
        ".yml",
        lambda: "%YAML:1.0\n---\nimage_width: 10\n",
        ": camera_matrix: missing key: expected one of camera_matrix, K, cameraMatrix",
    ),
    (
        "camera: COLMAP width 10^11",
        "camera",
        ".txt",
        lambda: "# Camera list\n1 PINHOLE 100000000000 600 500 500 400 300\n",
        ":2: WIDTH: expected a positive integer up to 65535, got '100000000000'",
    ),
    (
        "camera: JSON cut",
        "camera",
        ".json",
        lambda: "{",
        ":1: not valid JSON: Expecting property name enclosed in double quotes",
    ),
    (
        "camera: JSON without a matrix",
        "camera",
        ".json",
        lambda: '{"width": 10}',
        ": camera_matrix: missing key: expected one of camera_matrix, K, cameraMatrix",
    ),
    (
        "csv: empty",
        "csv",
        ".csv",
        lambda: "",
        ": expected at least 2 data rows (angle in degrees, relative intensity), got 0",
    ),
    (
        "csv: one row",
        "csv",
        ".csv",
        lambda: "theta_deg,value\n0,1\n",
        ":2: expected at least 2 data rows (angle in degrees, relative intensity), got 1",
    ),
    (
        "csv: a word",
        "csv",
        ".csv",
        lambda: "theta_deg,value\n0,1\n10,x\n",
        ":3: cell 'x': expected a number",
    ),
    (
        "csv: angles decreasing",
        "csv",
        ".csv",
        lambda: "theta_deg,value\n0,1\n20,0.5\n10,0.7\n",
        ":4: angle 10 is not greater than the previous angle 20: expected strictly increasing angles",
    ),
    (
        "csv: negative",
        "csv",
        ".csv",
        lambda: "theta_deg,value\n0,1\n10,-0.5\n",
        ":3: relative intensity -0.5 is negative: expected values >= 0",
    ),
    (
        "csv: beyond 180 degrees",
        "csv",
        ".csv",
        lambda: "theta_deg,value\n0,1\n200,0.5\n",
        ":3: angle 200 degrees: expected angles <= 180",
    ),
]


@pytest.mark.parametrize(
    ("case", "reader", "suffix", "content", "expected"),
    READER_CASES,
    ids=[c[0] for c in READER_CASES],
)
def test_bad_text_files(
    tmp_path: Path, case: str, reader: str, suffix: str, content: Callable[[], str], expected: str
) -> None:
    from lightcal.errors import InputError
    from lightcal.io.camera_file import read_camera
    from lightcal.io.eulumdat import read_ldt
    from lightcal.io.ies import read_ies
    from lightcal.io.photometric_table import read_rid_csv

    read = {"ies": read_ies, "ldt": read_ldt, "camera": read_camera, "csv": read_rid_csv}[reader]
    path = tmp_path / f"case{suffix}"
    path.write_text(content())
    before = path.read_bytes()
    with pytest.raises(InputError) as info:
        read(path)
    assert str(info.value) == f"{path}{expected}"
    assert path.read_bytes() == before


def _write_u8_png(path: Path) -> None:
    import cv2
    import numpy as np

    cv2.imwrite(str(path), np.full((10, 12), 100, np.uint8))


def _write_npy(path: Path, array: Any) -> None:
    import numpy as np

    np.save(path, array)


def _write_nan_tiff(path: Path) -> None:
    import numpy as np
    import tifffile

    tifffile.imwrite(path, np.full((10, 12), np.nan, np.float32))


# More files: (case, name, writer, reader, expected message after "<file>: ").
FILE_READER_CASES: list[tuple[str, str, Callable[[Path], Any], str, str]] = [
    (
        "8-bit PNG without a response curve",
        "u8.png",
        _write_u8_png,
        "image",
        "8-bit image values are gamma-encoded by the camera, not proportional to light; supply a camera response curve fitted from an exposure bracket (lightcal.io.response.fit_response_debevec, Debevec & Malik 1997) as response=..., or pass assume_linear=True if the camera really wrote linear values",
    ),
    (
        "3-D array",
        "f3.npy",
        lambda p: _write_npy(p, __import__("numpy").zeros((2, 3, 4))),
        "image",
        "expected an (H, W) array, got shape (2, 3, 4)",
    ),
    (
        "NaN float TIFF",
        "nan.tif",
        _write_nan_tiff,
        "image",
        "120 pixel values are NaN or infinite; expected finite linear values",
    ),
    (
        "BMP",
        "x.bmp",
        lambda p: p.write_bytes(b"BM"),
        "image",
        "unsupported image extension '.bmp'; expected .png, .jpg, .tif, .tiff, .npy, .exr or a camera raw extension such as .dng, .cr2, .nef, .arw",
    ),
    (
        "a folder named .png",
        "dir.png",
        lambda p: p.mkdir(),
        "image",
        "not a file; expected an image file",
    ),
    (
        "complex array",
        "c.npy",
        lambda p: _write_npy(p, __import__("numpy").zeros((4, 4), complex)),
        "image",
        "unsupported pixel type complex128; expected unsigned integers or floats",
    ),
    (
        "board of an unknown type",
        "b.yaml",
        lambda p: p.write_text("type: hexagon\n"),
        "board",
        "type: expected aruco_grid, charuco, chessboard or markers, got 'hexagon'",
    ),
    (
        "vignetting map of another size",
        "v.npy",
        lambda p: _write_npy(p, __import__("numpy").zeros((3, 3))),
        "vignetting",
        "expected a map of the camera's size 10 x 8 (W x H), got 3 x 3",
    ),
    (
        "vignetting JSON without a format",
        "v.json",
        lambda p: p.write_text('{"model": "radial"}'),
        "vignetting",
        "field format: Field required",
    ),
]


@pytest.mark.parametrize(
    ("case", "name", "write", "reader", "expected"),
    FILE_READER_CASES,
    ids=[c[0] for c in FILE_READER_CASES],
)
def test_bad_files(
    tmp_path: Path, case: str, name: str, write: Callable[[Path], Any], reader: str, expected: str
) -> None:
    from lightcal.errors import InputError
    from lightcal.io.board_file import read_board
    from lightcal.io.images import read_image
    from lightcal.io.vignetting_file import load_vignetting

    read: dict[str, Callable[[Path], Any]] = {
        "image": read_image,
        "board": read_board,
        "vignetting": lambda p: load_vignetting(p, width=10, height=8),
    }
    path = tmp_path / name
    write(path)
    with pytest.raises(InputError) as info:
        read[reader](path)
    assert str(info.value) == f"{path}: {expected}"


def _text_readers() -> list[tuple[str, str, Callable[[Path], Any], str]]:
    """(case, file name, reader, what the messages call the file) of every text reader."""
    from lightcal.io.camera_file import read_camera
    from lightcal.io.colmap import read_images_txt
    from lightcal.io.result_file import read_result
    from lightcal.io.vignetting_file import load_radial_vignetting

    return [
        ("camera", "camera.yaml", read_camera, "camera file"),
        ("COLMAP images.txt", "images.txt", read_images_txt, "COLMAP text model file"),
        ("radial fall-off", "falloff.json", load_radial_vignetting, "radial fall-off JSON file"),
        ("result", "result.json", read_result, "result file"),
    ]


@pytest.mark.parametrize("index", range(4), ids=[c[0] for c in _text_readers()])
def test_every_text_reader_checks_its_file_the_same_way(tmp_path: Path, index: int) -> None:
    """A folder, a FIFO, UTF-16 without a byte-order mark and bytes that are not UTF-8
    get the words of `lightcal.io.text_files`, naming the reader's kind of file."""
    from lightcal.errors import InputError

    _, name, read, what = _text_readers()[index]
    path = tmp_path / name
    path.mkdir()
    with pytest.raises(InputError) as info:
        read(path)
    assert str(info.value) == f"{path}: is a folder; expected a {what}"
    path.rmdir()
    os.mkfifo(path)
    with pytest.raises(InputError) as info:
        read(path)
    assert (
        str(info.value) == f"{path}: is not a regular file (a pipe or a device); expected a {what}"
    )
    path.unlink()
    path.write_bytes("K: 1\n".encode("utf-16-le"))
    with pytest.raises(InputError) as info:
        read(path)
    assert str(info.value) == (
        f"{path}: the {what} looks like UTF-16 without a byte-order mark: save it as UTF-8"
    )
    path.write_bytes(b"K: \x80\x81\n")
    with pytest.raises(InputError) as info:
        read(path)
    assert str(info.value) == f"{path}: the {what} is not UTF-8 text (byte 3): save it as UTF-8"
