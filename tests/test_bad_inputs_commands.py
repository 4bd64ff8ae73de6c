"""Every command and every option of `lightcal`, given a bad value as a careless or hostile
user would type it (issue 28): a missing file, a folder for a file, a file of the wrong
kind, binary garbage, NaN, infinity, zero, negative and huge numbers, empty strings,
unknown names, wrong suffixes, outputs onto inputs.

Each case gets exactly the one line `lightcal <command>: error: <where>: <message>` and
exit code 2 (argparse's usage errors: exit 2, the last line asserted), never an
"internal error", and leaves every input file as it was. A tiny `lightcal synth` dataset
(conftest.tiny_dataset) calibrated once per module gives the result file; nothing here
renders, solves or serves (the `app` cases stop before the server starts).
"""

from __future__ import annotations

import shlex
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from lightcal.capture.boards import ArucoGridBoard, Chessboard
from lightcal.cli.main import main
from lightcal.io.board_file import write_board
from tests.test_bad_inputs import _hashes


@pytest.fixture(scope="module")
def dataset(tiny_dataset: Path) -> Path:
    return tiny_dataset


@pytest.fixture(scope="module")
def result_file(dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("result") / "result.json"
    argv = ["calibrate", str(dataset / "project.json"), "--out", str(out), "--quiet"]
    assert main(argv) in (0, 3)
    return out


@pytest.fixture(scope="module")
def kit(dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Files of the wrong kind: a PNG, binary garbage, an empty file, a folder named like
    a file, boards, a COLMAP cameras.txt, and a copy of the dataset without truth.json."""
    folder = tmp_path_factory.mktemp("kit")
    cv2.imwrite(str(folder / "pic.png"), np.full((10, 12), 100, np.uint8))
    (folder / "bin.json").write_bytes(b"\x00\x01\xff\xfe garbage")
    (folder / "empty.json").write_bytes(b"")
    (folder / "dir.json").mkdir()
    (folder / "empty_dir").mkdir()
    board = ArucoGridBoard("DICT_4X4_50", 7, 5, 0.07, 0.06, origin_world_m=(-0.42, 0.29))
    write_board(board, folder / "aruco.yaml")
    write_board(Chessboard(9, 6, 0.03), folder / "chess.yaml")
    (folder / "nomatrix.yml").write_text("%YAML:1.0\n---\nimage_width: 10\n")
    (folder / "cameras.txt").write_text("# Camera list\n1 PINHOLE 100 80 50 50 40 30\n")
    shutil.copytree(dataset, folder / "notruth", ignore=shutil.ignore_patterns("truth.json"))
    return folder


def _error(command: str, message: str) -> tuple[str, bool]:
    return f"lightcal {command}: error: {message}", False


def _usage(command: str, message: str) -> tuple[str, bool]:
    """argparse's last line (after the usage lines), exit code 2."""
    prefix = f"lightcal {command}" if command else "lightcal"
    return f"{prefix}: error: {message}", True


# (case, argv template, (expected last stderr line, is a usage error)). {d}: the dataset,
# {r}: its result, {k}: the kit of wrong files, {t}: an empty temporary folder, {n}: a
# new path in it.
CASES: list[tuple[str, str, tuple[str, bool]]] = [
    # ------------------------------------------------------------------ lightcal itself
    ("lightcal: no command", "", _usage("", "the following arguments are required: COMMAND")),
    (
        "lightcal: unknown command",
        "nosuch",
        _usage(
            "",
            "argument COMMAND: invalid choice: 'nosuch' (choose from 'sample', 'synth', "
            "'calibrate', 'plan', 'render', 'export', 'schema', 'init', 'board', 'camera', "
            "'response', 'app', 'warmup')",
        ),
    ),
    # ---------------------------------------------------------------------- response
    (
        "response: no --out",
        "response {d}/images/view_00.png {d}/images/view_01.png",
        _usage("response", "the following arguments are required: --out"),
    ),
    (
        "response: one photo",
        "response {d}/images/view_00.png --out {n}.json --times 1",
        _error("response", "IMAGE: expected at least 2 photos of an exposure bracket, got 1"),
    ),
    (
        "response: --times NaN",
        "response {d}/images/view_00.png {d}/images/view_01.png --out {n}.json --times 1 nan",
        _error("response", "--times: expected exposure times in seconds, finite and > 0"),
    ),
    (
        "response: --out a .txt",
        "response {d}/images/view_00.png {d}/images/view_01.png --out {n}.txt --times 1 2",
        _error("response", "{n}.txt: --out: expected a .json or .npy file, got new.txt"),
    ),
    (
        "response: --plot a .jpg",
        "response {d}/images/view_00.png {d}/images/view_01.png --out {n}.json --times 1 2 "
        "--plot {n}.jpg",
        _error("response", "{n}.jpg: --plot: expected a .png file, got new.jpg"),
    ),
    (
        "response: --out an existing file",
        "response {d}/images/view_00.png {d}/images/view_01.png --out {k}/pic.png --times 1 2",
        _error("response", "{k}/pic.png: --out: exists; use --force to replace it"),
    ),
    (
        "response: --out a photo, --force",
        "response {d}/images/view_00.png {d}/images/view_01.png --out {d}/images/view_00.png "
        "--times 1 2 --force",
        _error(
            "response",
            "{d}/images/view_00.png: --out: is a photo of the bracket, an input of the fit; "
            "write elsewhere",
        ),
    ),
    (
        "response: a 16-bit photo",
        "response {d}/images/view_00.png {d}/images/view_01.png --out {n}.json --times 1 2",
        _error(
            "response",
            "{d}/images/view_00.png: 16-bit values: expected an 8-bit photo (a 16-bit or float "
            "image is linear already and needs no response curve)",
        ),
    ),
    # ------------------------------------------------------------------------ sample
    ("sample: no PATH", "sample", _usage("sample", "the following arguments are required: PATH")),
    (
        "sample: PATH empty",
        "sample ''",
        _error("sample", "PATH: expected the path of a folder to write, got ''"),
    ),
    (
        "sample: PATH a file",
        "sample {k}/pic.png",
        _error("sample", "{k}/pic.png: exists and is not a folder; choose a new folder"),
    ),
    (
        "sample: PATH inside a file",
        "sample {k}/pic.png/sample",
        _error(
            "sample", "{k}/pic.png/sample: {k}/pic.png is a file, not a folder; choose a new folder"
        ),
    ),
    (
        "sample: PATH the dataset's images",
        "sample {d}/images",
        _error(
            "sample",
            "{d}/images: the folder is not empty; choose a new or empty folder, or add --force "
            "to write the sample's missing files into it (existing files are never overwritten)",
        ),
    ),
    (
        "sample: --force with a value",
        "sample {n} --force=yes",
        _usage("sample", "argument --force: ignored explicit argument 'yes'"),
    ),
    # ------------------------------------------------------------------------- synth
    (
        "synth: no OUT_DIR",
        "synth",
        _usage("synth", "the following arguments are required: OUT_DIR"),
    ),
    (
        "synth: OUT_DIR empty",
        "synth ''",
        _error("synth", "OUT_DIR: expected the path of a dataset folder, got ''"),
    ),
    (
        "synth: OUT_DIR a file",
        "synth {d}/project.json",
        _error(
            "synth", "{d}/project.json: exists and is not a folder: expected a new or empty folder"
        ),
    ),
    (
        "synth: OUT_DIR inside a file",
        "synth {k}/pic.png/data",
        _error(
            "synth",
            "{k}/pic.png/data: {k}/pic.png is a file, not a folder: expected a new or empty folder",
        ),
    ),
    (
        "synth: OUT_DIR the images of a dataset",
        "synth {d}/images",
        _error(
            "synth",
            "{d}/images: the folder is not empty: expected a new or empty folder (--force "
            "replaces the dataset in it)",
        ),
    ),
    (
        "synth: --views x",
        "synth {n} --views x",
        _usage("synth", "argument --views: invalid int value: 'x'"),
    ),
    (
        "synth: --views -1",
        "synth {n} --views -1",
        _error("synth", "--views: expected an integer >= 1, got -1"),
    ),
    (
        "synth: --views 10^11",
        "synth {n} --views 100000000000",
        _error("synth", "--views: expected at most 10000 images, got 100000000000"),
    ),
    (
        "synth: --distance one number",
        "synth {n} --distance 1",
        _usage("synth", "argument --distance: expected 2 arguments"),
    ),
    (
        "synth: --distance nan",
        "synth {n} --distance nan 1",
        _error("synth", "--distance: expected two finite numbers (min, max), got (nan, 1.0)"),
    ),
    (
        "synth: --distance 0",
        "synth {n} --distance 0 1",
        _error("synth", "--distance: expected 0.001 <= min <= max <= 1000, got (0, 1)"),
    ),
    (
        "synth: --distance so short the guess is behind the wall",
        "synth {n} --distance 0.05 0.05 --views 3 --width 8 --height 8",
        _error(
            "synth",
            "lights: the initial guess of light 'light' is on or behind the wall in view 1 "
            "(world z = -0.045 m); expected it in front (z > 0): a larger --distance, or a "
            "smaller --light-radius-m or --init-offset-m",
        ),
    ),
    (
        "synth: --tilt-deg nan",
        "synth {n} --tilt-deg nan",
        _error("synth", "--tilt-deg: expected a value in [0, 80] degrees, got nan"),
    ),
    (
        "synth: --tilt-deg -5",
        "synth {n} --tilt-deg -5",
        _error("synth", "--tilt-deg: expected a value in [0, 80] degrees, got -5"),
    ),
    (
        "synth: --roll-deg inf",
        "synth {n} --roll-deg inf",
        _error("synth", "--roll-deg: expected a value in [-180, 180] degrees, got inf"),
    ),
    (
        "synth: --roll-deg 1e308",
        "synth {n} --roll-deg 1e308",
        _error("synth", "--roll-deg: expected a value in [-180, 180] degrees, got 1e+308"),
    ),
    (
        "synth: --width 0",
        "synth {n} --width 0",
        _error("synth", "--width/--height: expected > 0, got 0 x 800"),
    ),
    (
        "synth: --width 10^8",
        "synth {n} --width 100000000",
        _error(
            "synth",
            "--width/--height: expected at most 65535 pixels a side and 100 megapixels, "
            "got 100000000 x 800",
        ),
    ),
    (
        "synth: 400 megapixels",
        "synth {n} --width 20000 --height 20000",
        _error(
            "synth",
            "--width/--height: expected at most 65535 pixels a side and 100 megapixels, "
            "got 20000 x 20000",
        ),
    ),
    (
        "synth: --height 1.5",
        "synth {n} --height 1.5",
        _usage("synth", "argument --height: invalid int value: '1.5'"),
    ),
    (
        "synth: --height -1",
        "synth {n} --height -1",
        _error("synth", "--width/--height: expected > 0, got 1200 x -1"),
    ),
    (
        "synth: --fx 0",
        "synth {n} --fx 0",
        _error(
            "synth",
            "--fx: expected 52.49 to 1.375e+05 px (a field of view of 0.5 to 170 degrees "
            "across the 1200-pixel width), got 0",
        ),
    ),
    (
        "synth: --fx 1e300",
        "synth {n} --fx 1e300",
        _error(
            "synth",
            "--fx: expected 52.49 to 1.375e+05 px (a field of view of 0.5 to 170 degrees "
            "across the 1200-pixel width), got 1e+300",
        ),
    ),
    (
        "synth: --fy nan",
        "synth {n} --fy nan",
        _error(
            "synth",
            "--fy: expected 35 to 9.167e+04 px (a field of view of 0.5 to 170 degrees "
            "across the 800-pixel height), got nan",
        ),
    ),
    (
        "synth: --cx 1e9",
        "synth {n} --cx 1e9",
        _error(
            "synth", "--cx: expected a principal point inside the image, 0 to 1200 px, got 1e+09"
        ),
    ),
    (
        "synth: --cy -1",
        "synth {n} --cy -1",
        _error("synth", "--cy: expected a principal point inside the image, 0 to 800 px, got -1"),
    ),
    (
        "synth: --distortion of 3",
        "synth {n} --distortion 1 2 3",
        _error("synth", "--distortion: expected 0, 4, 5 or 8 coefficients, got 3"),
    ),
    (
        "synth: --distortion nan",
        "synth {n} --distortion nan 0 0 0",
        _error("synth", "--distortion: expected finite values, got NaN or infinity"),
    ),
    (
        "synth: --distortion 1e300",
        "synth {n} --distortion 1e300 0 0 0",
        _error(
            "synth",
            "--distortion: 1e+300 0 0 0: expected a distortion that grows with the radius and "
            "scales it by 0.2 to 5 out to the image's corners",
        ),
    ),
    (
        "synth: --distortion folding back",
        "synth {n} --distortion -5 0 0 0",
        _error(
            "synth",
            "--distortion: -5 0 0 0: expected a distortion that grows with the radius and "
            "scales it by 0.2 to 5 out to the image's corners",
        ),
    ),
    (
        "synth: --light nosuch",
        "synth {n} --light nosuch",
        _usage(
            "synth",
            "argument --light: invalid choice: 'nosuch' (choose from 'isotropic', 'cos_power', "
            "'gaussian', 'table', 'table2d', 'ies')",
        ),
    ),
    (
        "synth: --light empty",
        "synth {n} --light ''",
        _usage(
            "synth",
            "argument --light: invalid choice: '' (choose from 'isotropic', 'cos_power', "
            "'gaussian', 'table', 'table2d', 'ies')",
        ),
    ),
    (
        "synth: --half-angle-deg 0",
        "synth {n} --half-angle-deg 0",
        _error("synth", "--half-angle-deg: expected a value in (0, 85) degrees, got 0.0"),
    ),
    (
        "synth: --half-angle-deg nan",
        "synth {n} --half-angle-deg nan",
        _error("synth", "--half-angle-deg: expected a value in (0, 85) degrees, got nan"),
    ),
    (
        "synth: --lights 0",
        "synth {n} --lights 0",
        _error("synth", "--lights: expected an integer >= 1, got 0"),
    ),
    (
        "synth: --light-radius-m reversed",
        "synth {n} --light-radius-m 0.2 0.1",
        _error("synth", "--light-radius-m: expected 0 <= min <= max <= 1, got (0.2, 0.1)"),
    ),
    (
        "synth: --light-radius-m nan",
        "synth {n} --light-radius-m nan 0.1",
        _error("synth", "--light-radius-m: expected two finite numbers (min, max), got (nan, 0.1)"),
    ),
    (
        "synth: --declare-port without --port",
        "synth {n} --declare-port",
        _error("synth", "--declare-port: expected --port D_MM T_MM NG NW (the port to declare)"),
    ),
    (
        "synth: --port negative distance",
        "synth {n} --port -1 10 1.49 1.333",
        _error("synth", "--port: port: distance_m: expected a finite value > 0.0, got -0.001"),
    ),
    (
        "synth: --port three numbers",
        "synth {n} --port 20 10 1.49",
        _usage("synth", "argument --port: expected 4 arguments"),
    ),
    (
        "synth: --port with a bowed wall",
        "synth {n} --port 20 10 1.49 1.333 --bow-mm 3",
        _error("synth", "--port: not rendered with a bowed wall, a texture or a corner"),
    ),
    (
        "synth: --declare-light-port without --light-port",
        "synth {n} --declare-light-port",
        _error(
            "synth",
            "--declare-light-port: expected --light-port D_MM T_MM NG NW (the port to declare)",
        ),
    ),
    (
        "synth: --light-port distance 0",
        "synth {n} --light-port 0 8 1.49 1.333",
        _error("synth", "--light-port: port: distance_m: expected a finite value > 0.0, got 0.0"),
    ),
    (
        "synth: --light-port three numbers",
        "synth {n} --light-port 15 8 1.49",
        _usage("synth", "argument --light-port: expected 4 arguments"),
    ),
    (
        "synth: --light-port with --port",
        "synth {n} --light-port 15 8 1.49 1.333 --port 20 10 1.49 1.333",
        _error(
            "synth",
            "--light-port: not rendered with a camera port, a bowed wall, a texture or a corner",
        ),
    ),
    (
        "synth: --light-port with --wall plastic",
        "synth {n} --light-port 15 8 1.49 1.333 --wall plastic",
        _error("synth", "--light-port: not rendered with a non-Lambertian wall or 'paper'"),
    ),
    (
        "synth: --init-offset-m -1",
        "synth {n} --init-offset-m -1",
        _error("synth", "--init-offset-m: expected a finite value >= 0, got -1.0"),
    ),
    (
        "synth: --init-offset-m 1e9",
        "synth {n} --init-offset-m 1e9",
        _error("synth", "--init-offset-m: expected at most 5 m, got 1e+09"),
    ),
    (
        "synth: --init-offset-deg nan",
        "synth {n} --init-offset-deg nan",
        _error("synth", "--init-offset-deg: expected a finite value >= 0, got nan"),
    ),
    (
        "synth: --init-offset-deg 1e9",
        "synth {n} --init-offset-deg 1e9",
        _error("synth", "--init-offset-deg: expected at most 180 degrees, got 1e+09"),
    ),
    (
        "synth: --bit-depth 8",
        "synth {n} --bit-depth 8",
        _usage("synth", "argument --bit-depth: invalid choice: 8 (choose from 10, 12, 14, 16)"),
    ),
    (
        "synth: --black-level -1",
        "synth {n} --black-level -1",
        _error("synth", "--black-level: expected a value in [0, 16383) for 14 bits, got -1.0"),
    ),
    (
        "synth: --black-level nan",
        "synth {n} --black-level nan",
        _error("synth", "--black-level: expected a value in [0, 16383) for 14 bits, got nan"),
    ),
    (
        "synth: --full-well-e 0",
        "synth {n} --full-well-e 0",
        _error("synth", "--full-well-e: expected a value > 0, got 0.0"),
    ),
    (
        "synth: --full-well-e 1e300",
        "synth {n} --full-well-e 1e300",
        _error("synth", "--full-well-e: expected at most 1e+07 electrons, got 1e+300"),
    ),
    (
        "synth: --read-noise-e nan",
        "synth {n} --read-noise-e nan",
        _error("synth", "--read-noise-e: expected a value >= 0, got nan"),
    ),
    (
        "synth: --read-noise-e 1e300",
        "synth {n} --read-noise-e 1e300",
        _error(
            "synth", "--read-noise-e: expected at most the full well (20000 electrons), got 1e+300"
        ),
    ),
    (
        "synth: --exposure-target 0",
        "synth {n} --exposure-target 0",
        _error("synth", "--exposure-target: expected a value > 0, got 0.0"),
    ),
    (
        "synth: --exposure-target 1e300",
        "synth {n} --exposure-target 1e300",
        _error(
            "synth", "--exposure-target: expected at most 10 (values above 1 saturate), got 1e+300"
        ),
    ),
    (
        "synth: --noise with a value",
        "synth {n} --noise=yes",
        _usage("synth", "argument --noise/--no-noise: ignored explicit argument 'yes'"),
    ),
    (
        "synth: --sensor nosuch",
        "synth {n} --sensor nosuch",
        _usage(
            "synth",
            "argument --sensor: invalid choice: 'nosuch' (choose from 'radiance', 'cos4', "
            "'paper', 'map')",
        ),
    ),
    (
        "synth: --vignetting nan",
        "synth {n} --vignetting nan",
        _error("synth", "--vignetting: expected one or more finite coefficients, got (nan,)"),
    ),
    (
        "synth: --vignetting negative fall-off",
        "synth {n} --vignetting -5 0",
        _error(
            "synth",
            "--vignetting: the fall-off reaches -3.99 inside the image; expected V > 0 everywhere",
        ),
    ),
    (
        "synth: --vignetting with --sensor cos4",
        "synth {n} --vignetting 0 --sensor cos4",
        _error("synth", "--vignetting: applies to --sensor map only, got --sensor cos4"),
    ),
    (
        "synth: --wall nosuch",
        "synth {n} --wall nosuch",
        _usage(
            "synth",
            "argument --wall: invalid choice: 'nosuch' (choose from 'lambertian', 'plastic', "
            "'oren_nayar')",
        ),
    ),
    (
        "synth: --roughness without --wall plastic",
        "synth {n} --roughness 0.2",
        _error("synth", "--roughness: applies to the plastic wall only, got the lambertian wall"),
    ),
    (
        "synth: --roughness 0",
        "synth {n} --wall plastic --roughness 0",
        _error("synth", "--roughness: expected a value in [0.02, 1], got 0"),
    ),
    (
        "synth: --ior nan",
        "synth {n} --wall plastic --ior nan",
        _error("synth", "--ior: expected a value in [1.05, 3], got nan"),
    ),
    (
        "synth: --albedo 2",
        "synth {n} --wall plastic --albedo 2",
        _error("synth", "--albedo: expected a value in [0.001, 1], got 2"),
    ),
    (
        "synth: --albedo with --wall oren_nayar",
        "synth {n} --wall oren_nayar --albedo 0.5",
        _error("synth", "--albedo: applies to the plastic wall only, got the oren_nayar wall"),
    ),
    (
        "synth: --sigma-deg -1",
        "synth {n} --wall oren_nayar --sigma-deg -1",
        _error("synth", "--sigma-deg: expected a value in [0, 60] degrees, got -1"),
    ),
    (
        "synth: --sigma-deg without --wall oren_nayar",
        "synth {n} --sigma-deg 10",
        _error(
            "synth", "--sigma-deg: applies to the oren_nayar wall only, got the lambertian wall"
        ),
    ),
    (
        "synth: --pose-noise-mm -1",
        "synth {n} --pose-noise-mm -1",
        _error("synth", "--pose-noise-mm: expected a value >= 0, got -1"),
    ),
    (
        "synth: --pose-noise-mm 1e9",
        "synth {n} --pose-noise-mm 1e9",
        _error("synth", "--pose-noise-mm: expected at most 100 mm, got 1e+09"),
    ),
    (
        "synth: --pose-error-mm behind the wall",
        "synth {n} --distance 0.01 0.01 --pose-error-mm 50 --views 3 --width 8 --height 8",
        _error(
            "synth",
            "--pose-error-mm: the error of 50 mm puts a measured camera on or behind the wall "
            "(the true camera is 0.0103 m in front of it); expected a sigma much smaller than "
            "the distance to the wall",
        ),
    ),
    (
        "synth: --pose-noise-deg nan",
        "synth {n} --pose-noise-deg nan",
        _error("synth", "--pose-noise-deg: expected a finite value >= 0, got nan"),
    ),
    (
        "synth: --pose-noise-deg 1e9",
        "synth {n} --pose-noise-deg 1e9",
        _error("synth", "--pose-noise-deg: expected at most 10 degrees, got 1e+09"),
    ),
    (
        "synth: --ambient inf",
        "synth {n} --ambient inf",
        _error("synth", "--ambient: expected a finite value >= 0, got inf"),
    ),
    (
        "synth: --ambient 1e300",
        "synth {n} --ambient 1e300",
        _error("synth", "--ambient: expected at most 10, got 1e+300"),
    ),
    (
        "synth: --undeclared-vignetting nan",
        "synth {n} --undeclared-vignetting nan 0",
        _error(
            "synth", "--undeclared-vignetting: expected two finite numbers k1 k2, got (nan, 0.0)"
        ),
    ),
    (
        "synth: --undeclared-vignetting with --sensor cos4",
        "synth {n} --undeclared-vignetting 0 0 --sensor cos4",
        _error(
            "synth", "--undeclared-vignetting: applies to --sensor radiance only, got --sensor cos4"
        ),
    ),
    (
        "synth: --rid-rim -2",
        "synth {n} --rid-rim -2",
        _error("synth", "--rid-rim: expected a finite value >= 0, got -2"),
    ),
    (
        "synth: --rid-rim 1e300",
        "synth {n} --rid-rim 1e300",
        _error("synth", "--rid-rim: expected at most 10, got 1e+300"),
    ),
    (
        "synth: --rid-rim on an isotropic light",
        "synth {n} --rid-rim 0.5 --light isotropic",
        _error(
            "synth",
            "--rid-rim: expected a light with a half-intensity angle, got --light isotropic",
        ),
    ),
    (
        "synth: --gamma 0",
        "synth {n} --gamma 0",
        _error("synth", "--gamma: expected a finite value > 0, got 0"),
    ),
    (
        "synth: --gamma 1e9",
        "synth {n} --gamma 1e9",
        _error("synth", "--gamma: expected a value in [0.1, 10], got 1e+09"),
    ),
    (
        "synth: --pose-error-mm nan",
        "synth {n} --pose-error-mm nan",
        _error("synth", "--pose-error-mm: expected a finite value >= 0, got nan"),
    ),
    (
        "synth: --pose-error-mm 1e9",
        "synth {n} --pose-error-mm 1e9",
        _error("synth", "--pose-error-mm: expected at most 100 mm, got 1e+09"),
    ),
    (
        "synth: --pose-error-deg -1",
        "synth {n} --pose-error-deg -1",
        _error("synth", "--pose-error-deg: expected a finite value >= 0, got -1"),
    ),
    (
        "synth: --pose-error-deg 1e9",
        "synth {n} --pose-error-deg 1e9",
        _error("synth", "--pose-error-deg: expected at most 10 degrees, got 1e+09"),
    ),
    (
        "synth: --bow-mm 1000",
        "synth {n} --bow-mm 1000",
        _error("synth", "--bow-mm: expected a value within +-100 mm, got 1000"),
    ),
    (
        "synth: --declare-wall-mesh without a bow",
        "synth {n} --declare-wall-mesh",
        _error(
            "synth",
            "--declare-wall-mesh: expected a bowed wall to declare (--bow-mm MM, MM != 0): "
            "the plane z = 0 needs no mesh",
        ),
    ),
    (
        "synth: --albedo-texture 1",
        "synth {n} --albedo-texture 1",
        _error("synth", "--albedo-texture: expected a value in [0, 1), got 1"),
    ),
    (
        "synth: --attenuation nan",
        "synth {n} --attenuation nan",
        _error("synth", "--attenuation: expected a finite value >= 0, got nan"),
    ),
    (
        "synth: --attenuation 100",
        "synth {n} --attenuation 100",
        _error("synth", "--attenuation: expected at most 2 per metre, got 100"),
    ),
    (
        "synth: --declare-medium without water",
        "synth {n} --declare-medium given",
        _error(
            "synth",
            "--declare-medium: given: expected --attenuation C > 0 or --backscatter BETA > 0 "
            "(the medium to declare)",
        ),
    ),
    (
        "synth: --backscatter with another sensor model",
        "synth {n} --backscatter 0.5 --sensor cos4",
        _error("synth", "--backscatter: applies to the radiance sensor model only, got 'cos4'"),
    ),
    (
        "synth: --corner nan",
        "synth {n} --corner nan 0.5 0.8",
        _error("synth", "--corner: expected a distance D of 0.05 to 5 m, got nan"),
    ),
    (
        "synth: --corner of depth 0",
        "synth {n} --corner 0.7 0 0.8",
        _error("synth", "--corner: expected a depth of 0.01 to 5 m, got 0"),
    ),
    (
        "synth: --corner of albedo 1",
        "synth {n} --corner 0.7 0.5 1",
        _error("synth", "--corner: expected an albedo in (0, 1), got 1"),
    ),
    (
        "synth: --corner with another sensor model",
        "synth {n} --corner 0.7 0.5 0.8 --sensor cos4",
        _error("synth", "--corner: applies to the radiance sensor model only, got 'cos4'"),
    ),
    (
        "synth: --declare-surroundings without --corner",
        "synth {n} --declare-surroundings",
        _error(
            "synth",
            "--declare-surroundings: expected --corner D DEPTH ALBEDO (the surfaces to declare)",
        ),
    ),
    (
        "synth: --phase-g 1.5",
        "synth {n} --phase-g 1.5",
        _error("synth", "--phase-g: expected a value in [-0.99, 0.99], got 1.5"),
    ),
    (
        "synth: --attenuation two values",
        "synth {n} --attenuation 0.4 0.1",
        _error("synth", "--attenuation: expected 1 value or 3 (R G B), got 2"),
    ),
    (
        "synth: --backscatter a negative channel",
        "synth {n} --backscatter 0.1 -1 0.1",
        _error("synth", "--backscatter: expected a finite value >= 0, got -1"),
    ),
    (
        "synth: --colour two values",
        "synth {n} --attenuation 0.4 0.12 0.06 --colour 1 1",
        _usage("synth", "argument --colour: expected 3 arguments"),
    ),
    (
        "synth: --colour 0",
        "synth {n} --attenuation 0.4 0.12 0.06 --colour 1 0 1",
        _error("synth", "--colour: expected finite values > 0, got 0"),
    ),
    (
        "synth: --colour without a colour dataset",
        "synth {n} --colour 1 0.9 0.7",
        _error(
            "synth",
            "--colour: applies to a colour dataset (three --attenuation or --backscatter "
            "values, R G B) only",
        ),
    ),
    (
        "synth: --corner in a colour dataset",
        "synth {n} --attenuation 0.4 0.12 0.06 --corner 0.7 0.5 0.8",
        _error(
            "synth",
            "--corner: not in a colour dataset (three --attenuation or --backscatter values, "
            "R G B): its bounce light is computed for one water, and the joint solve of colour "
            "channels does not model surroundings",
        ),
    ),
    (
        "synth: --declare-albedo-map given a value",
        "synth {n} --declare-albedo-map=yes",
        _usage("synth", "argument --declare-albedo-map: ignored explicit argument 'yes'"),
    ),
    (
        "synth: --dark-frames without room light",
        "synth {n} --dark-frames",
        _error(
            "synth",
            "--dark-frames: expected room light to photograph (--ambient FRACTION > 0): "
            "without it a light-off photo is black",
        ),
    ),
    (
        "synth: --real-world with a scene option",
        "synth {n} --real-world --ambient 0.1",
        _error(
            "synth",
            "--ambient: does not apply with --real-world (its scene is the preset's; --views, "
            "--width, --height, --seed, --force and --quiet do)",
        ),
    ),
    (
        "synth: --real-world --views 2",
        "synth {n} --real-world --views 2",
        _error("synth", "--views: expected 3 to 50 views, got 2"),
    ),
    (
        "synth: --format jpg",
        "synth {n} --format jpg",
        _usage("synth", "argument --format: invalid choice: 'jpg' (choose from 'png', 'tiff')"),
    ),
    (
        "synth: --seed -1",
        "synth {n} --seed -1",
        _error("synth", "--seed: expected an integer >= 0, got -1"),
    ),
    (
        "synth: --seed x",
        "synth {n} --seed x",
        _usage("synth", "argument --seed: invalid int value: 'x'"),
    ),
    (
        "synth: --force with a value",
        "synth {n} --force=1",
        _usage("synth", "argument --force: ignored explicit argument '1'"),
    ),
    (
        "synth: --quiet with a value",
        "synth {n} --quiet=1",
        _usage("synth", "argument --quiet: ignored explicit argument '1'"),
    ),
    # --------------------------------------------------------------------- calibrate
    (
        "calibrate: no --out",
        "calibrate {d}/project.json",
        _usage("calibrate", "the following arguments are required: --out"),
    ),
    (
        "calibrate: project missing",
        "calibrate {t}/nope.json --out {n}.json",
        _error("calibrate", "{t}/nope.json: project file not found"),
    ),
    (
        "calibrate: project a folder",
        "calibrate {k}/dir.json --out {n}.json",
        _error("calibrate", "{k}/dir.json: is a folder; expected a project file"),
    ),
    (
        "calibrate: project binary garbage",
        "calibrate {k}/bin.json --out {n}.json",
        _error(
            "calibrate",
            "{k}/bin.json: the project file is not UTF-8 text (byte 2): save it as UTF-8",
        ),
    ),
    (
        "calibrate: project empty",
        "calibrate {k}/empty.json --out {n}.json",
        _error("calibrate", "{k}/empty.json:1: not valid JSON: Expecting value"),
    ),
    (
        "calibrate: --out a folder",
        "calibrate {d}/project.json --out {k}/dir.json",
        _error(
            "calibrate", "{k}/dir.json: --out: is a folder; expected the path of a file to write"
        ),
    ),
    (
        "calibrate: --out the project",
        "calibrate {d}/project.json --out {d}/project.json",
        _error(
            "calibrate",
            "{d}/project.json: --out: is the project file, an input of the project; write "
            "elsewhere",
        ),
    ),
    (
        "calibrate: --out an image",
        "calibrate {d}/project.json --out {d}/images/view_00.png",
        _error(
            "calibrate",
            "{d}/images/view_00.png: --out: is image view_00, an input of the project; write "
            "elsewhere",
        ),
    ),
    (
        "calibrate: --out the camera file",
        "calibrate {d}/project.json --out {d}/camera.yaml",
        _error(
            "calibrate",
            "{d}/camera.yaml: --out: is the camera file, an input of the project; write elsewhere",
        ),
    ),
    (
        "calibrate: --out in a missing folder",
        "calibrate {d}/project.json --out {t}/no/r.json",
        _error(
            "calibrate", "{t}/no/r.json: --out: the folder {t}/no does not exist; create it first"
        ),
    ),
    (
        "calibrate: --report the images",
        "calibrate {d}/project.json --out {n}.json --report {d}/images --force",
        _error(
            "calibrate",
            "{d}/images: --report: holds image view_00, an input of the project; choose another "
            "folder",
        ),
    ),
    (
        "calibrate: --report a file",
        "calibrate {d}/project.json --out {n}.json --report {k}/pic.png",
        _error("calibrate", "{k}/pic.png: --report: is a file; expected a folder to write into"),
    ),
    (
        "calibrate: --report not empty",
        "calibrate {d}/project.json --out {n}.json --report {k}",
        _error("calibrate", "{k}: --report: the folder is not empty; use --force to write into it"),
    ),
    (
        "calibrate: --quiet with a value",
        "calibrate {d}/project.json --out {n}.json --quiet=1",
        _usage("calibrate", "argument --quiet: ignored explicit argument '1'"),
    ),
    (
        "calibrate: --force with a value",
        "calibrate {d}/project.json --out {n}.json --force=1",
        _usage("calibrate", "argument --force: ignored explicit argument '1'"),
    ),
    (
        "calibrate: --allow-misfit with a value",
        "calibrate {d}/project.json --out {n}.json --allow-misfit=no",
        _usage("calibrate", "argument --allow-misfit: ignored explicit argument 'no'"),
    ),
    # -------------------------------------------------------------------------- plan
    (
        "plan: project missing",
        "plan {t}/nope.json",
        _error("plan", "{t}/nope.json: project file not found"),
    ),
    (
        "plan: --result missing",
        "plan {d}/project.json --result {t}/nope.json",
        _error("plan", "{t}/nope.json: result file not found"),
    ),
    (
        "plan: --result binary garbage",
        "plan {d}/project.json --result {k}/bin.json",
        _error(
            "plan", "{k}/bin.json: the result file is not UTF-8 text (byte 2): save it as UTF-8"
        ),
    ),
    (
        "plan: --result a folder",
        "plan {d}/project.json --result {k}/dir.json",
        _error("plan", "{k}/dir.json: is a folder; expected a result file"),
    ),
    (
        "plan: --n 0",
        "plan {d}/project.json --n 0",
        _error("plan", "--n: expected 1 to 20 views (plan again after taking them), got 0"),
    ),
    (
        "plan: --n -3",
        "plan {d}/project.json --n -3",
        _error("plan", "--n: expected 1 to 20 views (plan again after taking them), got -3"),
    ),
    (
        "plan: --n x",
        "plan {d}/project.json --n x",
        _usage("plan", "argument --n: invalid int value: 'x'"),
    ),
    (
        "plan: --wall-size 0",
        "plan {d}/project.json --wall-size 0",
        _error("plan", "--wall-size: expected the wall's width in m (> 0), got 0.0"),
    ),
    (
        "plan: --wall-size nan",
        "plan {d}/project.json --wall-size nan",
        _error("plan", "--wall-size: expected the wall's width in m (> 0), got nan"),
    ),
    (
        "plan: --wall-size -inf",
        "plan {d}/project.json --wall-size=-inf",
        _error("plan", "--wall-size: expected the wall's width in m (> 0), got -inf"),
    ),
    (
        "plan: --out the project, --force",
        "plan {d}/project.json --out {d}/project.json --force",
        _error(
            "plan",
            "{d}/project.json: --out: is the project file, an input of the project; write "
            "elsewhere",
        ),
    ),
    (
        "plan: --out the result, --force",
        "plan {d}/project.json --result {r} --out {r} --force",
        _error("plan", "{r}: --out: is the result file, an input of the project; write elsewhere"),
    ),
    (
        "plan: --out an existing file",
        "plan {d}/project.json --out {d}/truth.json",
        _error("plan", "{d}/truth.json: --out: exists; use --force to replace it"),
    ),
    (
        "plan: --out a folder",
        "plan {d}/project.json --out {k}/dir.json",
        _error("plan", "{k}/dir.json: --out: is a folder; expected the path of a file to write"),
    ),
    (
        "plan: --out in a missing folder",
        "plan {d}/project.json --out {t}/no/p.json",
        _error("plan", "{t}/no/p.json: --out: the folder {t}/no does not exist; create it first"),
    ),
    (
        "plan: --force with a value",
        "plan {d}/project.json --force=1",
        _usage("plan", "argument --force: ignored explicit argument '1'"),
    ),
    # ------------------------------------------------------------------------ render
    (
        "render: no --result",
        "render {d}/project.json --out {n}",
        _usage("render", "the following arguments are required: --result"),
    ),
    (
        "render: project a folder",
        "render {k}/dir.json --result {r} --out {n}",
        _error("render", "{k}/dir.json: is a folder; expected a project file"),
    ),
    (
        "render: --result empty",
        "render {d}/project.json --result {k}/empty.json --out {n}",
        _error("render", "{k}/empty.json:1: not valid JSON: Expecting value"),
    ),
    (
        "render: --result a folder",
        "render {d}/project.json --result {k}/dir.json --out {n}",
        _error("render", "{k}/dir.json: is a folder; expected a result file"),
    ),
    (
        "render: --out the dataset, --force",
        "render {d}/project.json --result {r} --out {d} --force",
        _error(
            "render",
            "{d}: --out: holds the project file, an input of the project; choose another folder",
        ),
    ),
    (
        "render: --out the result",
        "render {d}/project.json --result {r} --out {r}",
        _error("render", "{r}: --out: is a file; expected a folder to write into"),
    ),
    (
        "render: --out not empty",
        "render {d}/project.json --result {r} --out {k}",
        _error("render", "{k}: --out: the folder is not empty; use --force to write into it"),
    ),
    (
        "render: --force with a value",
        "render {d}/project.json --result {r} --out {n} --force=1",
        _usage("render", "argument --force: ignored explicit argument '1'"),
    ),
    # ------------------------------------------------------------------------ export
    (
        "export: no --format",
        "export {r} --out {n}.yaml",
        _usage("export", "the following arguments are required: --format"),
    ),
    (
        "export: result a folder",
        "export {k}/dir.json --format opencv --out {n}.yaml",
        _error("export", "{k}/dir.json: is a folder; expected a result file"),
    ),
    (
        "export: result binary garbage",
        "export {k}/bin.json --format opencv --out {n}.yaml",
        _error(
            "export", "{k}/bin.json: the result file is not UTF-8 text (byte 2): save it as UTF-8"
        ),
    ),
    (
        "export: result empty",
        "export {k}/empty.json --format opencv --out {n}.yaml",
        _error("export", "{k}/empty.json:1: not valid JSON: Expecting value"),
    ),
    (
        "export: --format nosuch",
        "export {r} --format nosuch --out {n}.yaml",
        _usage(
            "export",
            "argument --format: invalid choice: 'nosuch' (choose from 'opencv', 'blender', "
            "'mitsuba', 'ros', 'ies', 'ldt')",
        ),
    ),
    (
        "export: --format empty",
        "export {r} --format '' --out {n}.yaml",
        _usage(
            "export",
            "argument --format: invalid choice: '' (choose from 'opencv', 'blender', "
            "'mitsuba', 'ros', 'ies', 'ldt')",
        ),
    ),
    (
        "export: --out a folder",
        "export {r} --format opencv --out {k}/dir.json",
        _error("export", "{k}/dir.json: --out: is a folder; expected the path of a file to write"),
    ),
    (
        "export: --out the result, --force",
        "export {r} --format opencv --out {r} --force",
        _error("export", "{r}: --out: is the result file, an input of the export; write elsewhere"),
    ),
    (
        "export: --out the project's camera, --force",
        "export {r} --format opencv --out {d}/camera.yaml --project {d}/project.json --force",
        _error(
            "export",
            "{d}/camera.yaml: --out: is the camera file, an input of the export; write elsewhere",
        ),
    ),
    (
        "export: --light nosuch",
        "export {r} --format ies --out {n}.ies --light nosuch",
        _error("export", "{r}: no light named 'nosuch': expected one of 'light'"),
    ),
    (
        "export: --light empty",
        "export {r} --format ldt --out {n}.ldt --light ''",
        _error("export", "{r}: no light named '': expected one of 'light'"),
    ),
    (
        "export: --project missing",
        "export {r} --format ies --out {n}.ies --project {t}/nope.json",
        _error("export", "{t}/nope.json: project file not found"),
    ),
    (
        "export: --project a folder",
        "export {r} --format ies --out {n}.ies --project {k}/dir.json",
        _error("export", "{k}/dir.json: is a folder; expected a project file"),
    ),
    (
        "export: --project binary garbage",
        "export {r} --format ies --out {n}.ies --project {k}/bin.json",
        _error(
            "export", "{k}/bin.json: the project file is not UTF-8 text (byte 2): save it as UTF-8"
        ),
    ),
    (
        "export: --format opencv into a .png",
        "export {r} --format opencv --out {n}.png",
        _error(
            "export",
            "{n}.png: --out: expected a .yaml, .yml, .xml or .json file for --format opencv, "
            "got .png",
        ),
    ),
    (
        "export: --format blender into a .yaml",
        "export {r} --format blender --out {n}.yaml",
        _error("export", "{n}.yaml: --out: expected a .py file for --format blender, got .yaml"),
    ),
    (
        "export: --format mitsuba without a suffix",
        "export {r} --format mitsuba --out {n}",
        _error("export", "{n}: --out: expected a .xml file for --format mitsuba, got no suffix"),
    ),
    (
        "export: --light with --format opencv",
        "export {r} --format opencv --out {n}.yaml --light light",
        _error("export", "--light: applies to --format ies or ldt only, not opencv"),
    ),
    (
        "export: --wall-albedo nan",
        "export {r} --format mitsuba --out {n}.xml --wall-albedo nan",
        _error("export", "--wall-albedo: expected the wall's albedo in (0, 1], got nan"),
    ),
    (
        "export: --wall-albedo 0",
        "export {r} --format blender --out {n}.py --wall-albedo 0",
        _error("export", "--wall-albedo: expected the wall's albedo in (0, 1], got 0.0"),
    ),
    (
        "export: --wall-albedo with --format opencv",
        "export {r} --format opencv --out {n}.yaml --wall-albedo 0.5",
        _error("export", "--wall-albedo: applies to --format mitsuba or blender only, not opencv"),
    ),
    (
        "export: --project a result",
        "export {r} --format ies --out {n}.ies --project {r}",
        _error("export", "{r}: a result file of lightcal calibrate, not a project file"),
    ),
    (
        "export: --out empty",
        "export {r} --format opencv --out ''",
        _usage("export", "argument --out: expected a path, got ''"),
    ),
    (
        "plan: --n a billion",
        "plan {d}/project.json --n 1000000000",
        _error(
            "plan", "--n: expected 1 to 20 views (plan again after taking them), got 1000000000"
        ),
    ),
    (
        "plan: --result a project",
        "plan {d}/project.json --result {d}/project.json",
        _error(
            "plan",
            "{d}/project.json: a project file, not a result: expected the result JSON of "
            "lightcal calibrate",
        ),
    ),
    (
        "calibrate: a PNG as the project",
        "calibrate {k}/pic.png --out {n}.json",
        _error("calibrate", "{k}/pic.png: a PNG image; expected a project file (a text file)"),
    ),
    (
        "calibrate: --out the truth file (not a result)",
        "calibrate {d}/project.json --out {d}/truth.json",
        _error(
            "calibrate",
            "{d}/truth.json: --out: exists and is not a lightcal result; use --force to replace it",
        ),
    ),
    (
        "calibrate: --out empty",
        "calibrate {d}/project.json --out ''",
        _usage("calibrate", "argument --out: expected a path, got ''"),
    ),
    (
        "render: --result a PNG",
        "render {d}/project.json --result {k}/pic.png --out {n}",
        _error("render", "{k}/pic.png: a PNG image; expected a result file (a text file)"),
    ),
    (
        "export: --force with a value",
        "export {r} --format opencv --out {n}.yaml --force=1",
        _usage("export", "argument --force: ignored explicit argument '1'"),
    ),
    # ------------------------------------------------------------------------- board
    (
        "board: no --out",
        "board {k}/aruco.yaml",
        _usage("board", "the following arguments are required: --out"),
    ),
    (
        "board: LAYOUT missing",
        "board {t}/nope.yaml --out {n}.pdf",
        _error("board", "{t}/nope.yaml: board file not found"),
    ),
    (
        "board: LAYOUT binary garbage",
        "board {k}/bin.json --out {n}.pdf",
        _error(
            "board", "{k}/bin.json: the board file is not UTF-8 text (byte 2): save it as UTF-8"
        ),
    ),
    (
        "board: LAYOUT a camera file",
        "board {d}/camera.yaml --out {n}.pdf",
        _error(
            "board",
            "{d}/camera.yaml: an OpenCV camera file, not a board file: expected a board file "
            "(type aruco_grid, charuco, chessboard or markers)",
        ),
    ),
    (
        "board: LAYOUT empty",
        "board '' --out {n}.pdf",
        _usage("board", "argument LAYOUT: expected a path, got ''"),
    ),
    (
        "board: --out a PNG",
        "board {k}/aruco.yaml --out {n}.png",
        _error("board", "{n}.png: --out: unsupported suffix '.png': expected .pdf"),
    ),
    (
        "board: --out exists",
        "board {k}/aruco.yaml --out {k}/pic.png",
        _error("board", "{k}/pic.png: --out: exists; use --force to replace it"),
    ),
    (
        "board: --out the board file, --force",
        "board {k}/aruco.yaml --out {k}/aruco.yaml --force",
        _error(
            "board",
            "{k}/aruco.yaml: --out: is the board file, an input of the PDF; write elsewhere",
        ),
    ),
    (
        "board: --out in a missing folder",
        "board {k}/aruco.yaml --out {t}/no/b.pdf",
        _error("board", "{t}/no/b.pdf: --out: the folder {t}/no does not exist; create it first"),
    ),
    (
        "board: --paper b5",
        "board {k}/aruco.yaml --out {n}.pdf --paper b5",
        _usage(
            "board",
            "argument --paper: invalid choice: 'b5' (choose from 'a4', 'a3', 'a2', 'a1', 'a0', "
            "'letter', 'tabloid')",
        ),
    ),
    (
        "board: --paper too small",
        "board {k}/aruco.yaml --out {n}.pdf --paper a3",
        _error(
            "board",
            "--paper: the board with its white margin needs 990.0 mm x 730.0 mm of paper inside "
            "the margins and text, more than a3 gives: use a0",
        ),
    ),
    (
        "board: --force with a value",
        "board {k}/aruco.yaml --out {n}.pdf --force=1",
        _usage("board", "argument --force: ignored explicit argument '1'"),
    ),
    # -------------------------------------------------------------------------- init
    (
        "init: no --camera",
        "init {d}/images --board {k}/aruco.yaml",
        _usage("init", "the following arguments are required: --camera"),
    ),
    (
        "init: IMAGE_DIR a file",
        "init {d}/project.json --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.json",
        _error("init", "{d}/project.json: not a folder: expected a folder of images of the wall"),
    ),
    (
        "init: IMAGE_DIR without images",
        "init {k}/empty_dir --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.json",
        _error(
            "init",
            "{k}/empty_dir: no images found: expected image files (.png, .jpg, .tif, .tiff, "
            ".npy, .exr or camera raw such as .dng, .cr2, .nef, .arw) directly in the folder",
        ),
    ),
    (
        "init: IMAGE_DIR without markers",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.json",
        _error(
            "init",
            "{d}/images: no usable images: all 4 were rejected (view_00.png: found 0 markers, "
            "need at least 4; view_01.png: found 0 markers, need at least 4; view_02.png: found "
            "0 markers, need at least 4; view_03.png: found 0 markers, need at least 4)",
        ),
    ),
    (
        "init: --camera a PNG",
        "init {d}/images --camera {k}/pic.png --board {k}/aruco.yaml --out {n}.json",
        _error(
            "init",
            "{k}/pic.png: unsupported file suffix '.png': expected .yaml, .yml, .xml, .json or a "
            "COLMAP cameras .txt",
        ),
    ),
    (
        "init: --camera a folder",
        "init {d}/images --camera {k}/dir.json --board {k}/aruco.yaml --out {n}.json",
        _error("init", "{k}/dir.json: is a folder; expected a camera file"),
    ),
    (
        "init: --camera binary garbage",
        "init {d}/images --camera {k}/bin.json --board {k}/aruco.yaml --out {n}.json",
        _error(
            "init", "{k}/bin.json: the camera file is not UTF-8 text (byte 2): save it as UTF-8"
        ),
    ),
    (
        "init: --board a PNG",
        "init {d}/images --camera {d}/camera.yaml --board {k}/pic.png --out {n}.json",
        _error(
            "init",
            "{k}/pic.png: unsupported board file suffix '.png': expected .json, .yaml or .yml",
        ),
    ),
    (
        "init: --board a chessboard",
        "init {d}/images --camera {d}/camera.yaml --board {k}/chess.yaml --out {n}.json",
        _error(
            "init",
            "{k}/chess.yaml: a chessboard has no markers, so it gives no camera pose on the "
            "wall: expected an aruco_grid, charuco or markers board",
        ),
    ),
    (
        "init: --board binary garbage",
        "init {d}/images --camera {d}/camera.yaml --board {k}/bin.json --out {n}.json",
        _error("init", "{k}/bin.json: the board file is not UTF-8 text (byte 2): save it as UTF-8"),
    ),
    (
        "init: --light-ies missing",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.json "
        "--light-ies {t}/nope.ies",
        _error("init", "{t}/nope.ies: light file not found"),
    ),
    (
        "init: --light-ies a PNG",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.json "
        "--light-ies {k}/pic.png",
        _error("init", "{k}/pic.png: unsupported light file suffix '.png': expected .ies or .ldt"),
    ),
    (
        "init: --half-angle-deg nan",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.json "
        "--half-angle-deg nan",
        _error("init", "--half-angle-deg: expected a value in (0, 90) degrees, got nan"),
    ),
    (
        "init: --half-angle-deg 95",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.json "
        "--half-angle-deg 95",
        _error("init", "--half-angle-deg: expected a value in (0, 90) degrees, got 95"),
    ),
    (
        "init: --half-angle-deg with --light-ies",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --half-angle-deg 10 "
        "--light-ies {t}/nope.ies",
        _usage("init", "argument --light-ies: not allowed with argument --half-angle-deg"),
    ),
    (
        "init: --initial-position nan",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.json "
        "--initial-position nan 0 0",
        _error("init", "--initial-position: expected three finite numbers (metres), got nan 0 0"),
    ),
    (
        "init: --initial-position of 2",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --initial-position 0 0",
        _usage("init", "argument --initial-position: expected 3 arguments"),
    ),
    (
        "init: --initial-axis nan",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.json "
        "--initial-axis nan 0 1",
        _error("init", "--initial-axis: expected three finite numbers, got nan 0 1"),
    ),
    (
        "init: --out an existing project",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {d}/project.json",
        _error("init", "{d}/project.json: --out: exists; use --force to replace it"),
    ),
    (
        "init: --out the camera, --force",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {d}/camera.yaml "
        "--force",
        _error(
            "init",
            "{d}/camera.yaml: --out: is input camera.yaml, an input of the project; write "
            "elsewhere",
        ),
    ),
    (
        "init: --out a PNG",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.png",
        _error(
            "init",
            "{n}.png: --out: unsupported project file suffix '.png': expected .json, .yaml or .yml",
        ),
    ),
    (
        "init: --out a folder",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {k}/dir.json",
        _error("init", "{k}/dir.json: --out: is a folder; expected the path of a file to write"),
    ),
    (
        "init: --out in a missing folder",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {t}/no/p.json",
        _error("init", "{t}/no/p.json: --out: the folder {t}/no does not exist; create it first"),
    ),
    (
        "init: --min-markers 0",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.json "
        "--min-markers 0",
        _error("init", "--min-markers: expected an integer >= 1, got 0"),
    ),
    (
        "init: --mask-margin-px 1e9",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.json "
        "--mask-margin-px 1e9",
        _error("init", "--mask-margin-px: expected a padding of 0 to 100 pixels, got 1e+09"),
    ),
    (
        "init: --mask-margin-px -1",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.json "
        "--mask-margin-px -1",
        _error("init", "--mask-margin-px: expected a padding of 0 to 100 pixels, got -1"),
    ),
    (
        "init: --max-rms-px 0",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.json "
        "--max-rms-px 0",
        _error("init", "--max-rms-px: expected a finite value > 0 pixels, got 0"),
    ),
    (
        "init: --black-level -1",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.json "
        "--black-level -1",
        _error("init", "--black-level: expected a finite value >= 0, got -1"),
    ),
    (
        "init: --white-level inf",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.json "
        "--white-level inf",
        _error("init", "--white-level: expected a finite value > 0, got inf"),
    ),
    (
        "init: --white-level below --black-level",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.json "
        "--black-level 100 --white-level 50",
        _error("init", "--white-level: expected a value above --black-level (100), got 50"),
    ),
    (
        "init: --pose-floor-mm nan",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.json "
        "--pose-floor-mm nan",
        _error("init", "--pose-floor-mm: expected a finite value >= 0 mm, got nan"),
    ),
    (
        "init: --board the same file twice",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --board {k}/aruco.yaml "
        "--out {n}.json",
        _error("init", "{k}/aruco.yaml: given twice as a board file (also as {k}/aruco.yaml)"),
    ),
    (
        "init: --response missing",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.json "
        "--response {t}/nope.json",
        _error("init", "{t}/nope.json: file not found"),
    ),
    (
        "init: --response binary garbage",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.json "
        "--response {k}/bin.json",
        _error(
            "init",
            "{k}/bin.json: the response curve file is not UTF-8 text (byte 2): save it as UTF-8",
        ),
    ),
    (
        "init: --response empty",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --response ''",
        _usage("init", "argument --response: expected a path, got ''"),
    ),
    (
        "init: --response with --assume-linear",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --assume-linear "
        "--response {t}/nope.json",
        _usage("init", "argument --response: not allowed with argument --assume-linear"),
    ),
    (
        "init: --assume-linear with a value",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --assume-linear=1",
        _usage("init", "argument --assume-linear: ignored explicit argument '1'"),
    ),
    (
        "init: --pose-floor-deg -1",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --out {n}.json "
        "--pose-floor-deg -1",
        _error("init", "--pose-floor-deg: expected a finite value >= 0 degrees, got -1"),
    ),
    (
        "init: --force with a value",
        "init {d}/images --camera {d}/camera.yaml --board {k}/aruco.yaml --force=1",
        _usage("init", "argument --force: ignored explicit argument '1'"),
    ),
    # ------------------------------------------------------------------------ camera
    (
        "camera: no action",
        "camera",
        _usage("camera", "the following arguments are required: ACTION"),
    ),
    (
        "camera: unknown action",
        "camera nosuch",
        _usage(
            "camera",
            "argument ACTION: invalid choice: 'nosuch' (choose from 'calibrate', 'import')",
        ),
    ),
    (
        "camera calibrate: no IMAGES",
        "camera calibrate --board {k}/chess.yaml --out {n}.yaml",
        _usage("camera calibrate", "the following arguments are required: IMAGES"),
    ),
    (
        "camera calibrate: image missing",
        "camera calibrate {t}/nope.png --board {k}/chess.yaml --out {n}.yaml",
        _error("camera", "{t}/nope.png: image file not found"),
    ),
    (
        "camera calibrate: a folder without images",
        "camera calibrate {k}/empty_dir --board {k}/chess.yaml --out {n}.yaml",
        _error(
            "camera",
            "{k}/empty_dir: no images found: expected image files (.png, .jpg, .tif, .tiff, "
            ".npy, .exr or camera raw such as .dng, .cr2, .nef, .arw) directly in the folder",
        ),
    ),
    (
        "camera calibrate: photos without the board",
        "camera calibrate {d}/images --board {k}/chess.yaml --out {n}.yaml",
        _error(
            "camera",
            "images: 0 usable views of the board, need at least 3 (rejected: view_00.png: no "
            "chessboard with 9x6 inner corners found; view_01.png: no chessboard with 9x6 inner "
            "corners found; view_02.png: no chessboard with 9x6 inner corners found; "
            "view_03.png: no chessboard with 9x6 inner corners found)",
        ),
    ),
    (
        "camera calibrate: --board missing",
        "camera calibrate {d}/images --board {t}/nope.yaml --out {n}.yaml",
        _error("camera", "{t}/nope.yaml: board file not found"),
    ),
    (
        "camera calibrate: --board an ArUco grid",
        "camera calibrate {d}/images --board {k}/aruco.yaml --out {n}.yaml",
        _error(
            "camera",
            "{k}/aruco.yaml: an ArUco grid gives too few points per view for intrinsics: "
            "expected a chessboard or charuco board",
        ),
    ),
    (
        "camera calibrate: --board a folder",
        "camera calibrate {d}/images --board {k}/dir.json --out {n}.yaml",
        _error("camera", "{k}/dir.json: is a folder; expected a board file"),
    ),
    (
        "camera calibrate: --out a PNG",
        "camera calibrate {d}/images --board {k}/chess.yaml --out {n}.png",
        _error(
            "camera", "{n}.png: unsupported file suffix '.png': expected .yaml, .yml, .xml or .json"
        ),
    ),
    (
        "camera calibrate: --out the board",
        "camera calibrate {d}/images --board {k}/chess.yaml --out {k}/chess.yaml",
        _error(
            "camera",
            "{k}/chess.yaml: --out: is the board file, an input of the calibration; write "
            "elsewhere",
        ),
    ),
    (
        "camera calibrate: --out a photo",
        "camera calibrate {d}/images --board {k}/chess.yaml --out {d}/images/view_00.png",
        _error(
            "camera",
            "{d}/images/view_00.png: --out: is image view_00.png, an input of the calibration; "
            "write elsewhere",
        ),
    ),
    (
        "camera calibrate: --out in a missing folder",
        "camera calibrate {d}/images --board {k}/chess.yaml --out {t}/no/c.yaml",
        _error("camera", "{t}/no/c.yaml: --out: the folder {t}/no does not exist; create it first"),
    ),
    (
        "camera calibrate: --n-dist 3",
        "camera calibrate {d}/images --board {k}/chess.yaml --out {n}.yaml --n-dist 3",
        _usage("camera calibrate", "argument --n-dist: invalid choice: 3 (choose from 4, 5, 8)"),
    ),
    (
        "camera calibrate: --max-rms-px nan",
        "camera calibrate {d}/images --board {k}/chess.yaml --out {n}.yaml --max-rms-px nan",
        _error("camera", "--max-rms-px: expected a finite value > 0 pixels, got nan"),
    ),
    (
        "camera calibrate: --max-rms-px -1",
        "camera calibrate {d}/images --board {k}/chess.yaml --out {n}.yaml --max-rms-px -1",
        _error("camera", "--max-rms-px: expected a finite value > 0 pixels, got -1"),
    ),
    (
        "camera import: --out its input, --force",
        "camera import {d}/camera.yaml --out {d}/camera.yaml --force",
        _error(
            "camera",
            "{d}/camera.yaml: --out: is the camera file, an input of the import; write elsewhere",
        ),
    ),
    (
        "camera calibrate: --out the board, --force",
        "camera calibrate {d}/images --board {k}/chess.yaml --out {k}/chess.yaml --force",
        _error(
            "camera",
            "{k}/chess.yaml: --out: is the board file, an input of the calibration; write "
            "elsewhere",
        ),
    ),
    (
        "camera import: no --out",
        "camera import {d}/camera.yaml",
        _usage("camera import", "the following arguments are required: --out"),
    ),
    (
        "camera import: file missing",
        "camera import {t}/nope.yaml --out {n}.yaml",
        _error("camera", "{t}/nope.yaml: camera file not found"),
    ),
    (
        "camera import: a PNG",
        "camera import {k}/pic.png --out {n}.yaml",
        _error(
            "camera",
            "{k}/pic.png: unsupported file suffix '.png': expected .yaml, .yml, .xml, .json or a "
            "COLMAP cameras .txt",
        ),
    ),
    (
        "camera import: a folder",
        "camera import {k}/dir.json --out {n}.yaml",
        _error("camera", "{k}/dir.json: is a folder; expected a camera file"),
    ),
    (
        "camera import: binary garbage",
        "camera import {k}/bin.json --out {n}.yaml",
        _error(
            "camera", "{k}/bin.json: the camera file is not UTF-8 text (byte 2): save it as UTF-8"
        ),
    ),
    (
        "camera import: empty",
        "camera import {k}/empty.json --out {n}.yaml",
        _error("camera", "{k}/empty.json: empty file: expected a mapping of keys"),
    ),
    (
        "camera import: no matrix",
        "camera import {k}/nomatrix.yml --out {n}.yaml",
        _error(
            "camera",
            "{k}/nomatrix.yml: camera_matrix: missing key: expected one of camera_matrix, K, "
            "cameraMatrix",
        ),
    ),
    (
        "camera import: --out without a suffix",
        "camera import {d}/camera.yaml --out {n}",
        _error("camera", "{n}: unsupported file suffix '': expected .yaml, .yml, .xml or .json"),
    ),
    (
        "camera import: --out itself",
        "camera import {d}/camera.yaml --out {d}/camera.yaml",
        _error(
            "camera",
            "{d}/camera.yaml: --out: is the camera file, an input of the import; write elsewhere",
        ),
    ),
    (
        "camera import: --out a folder",
        "camera import {d}/camera.yaml --out {k}/dir.json",
        _error("camera", "{k}/dir.json: --out: is a folder; expected the path of a file to write"),
    ),
    (
        "camera import: --camera-id of a YAML file",
        "camera import {d}/camera.yaml --out {n}.yaml --camera-id 2",
        _error(
            "camera",
            "--camera-id: applies only to a COLMAP cameras.txt, got camera.yaml (it holds one "
            "camera)",
        ),
    ),
    (
        "camera import: --camera-id -1",
        "camera import {k}/cameras.txt --out {n}.yaml --camera-id -1",
        _error("camera", "{k}/cameras.txt: --camera-id -1 not found: the file has ids 1"),
    ),
    (
        "camera import: --camera-id x",
        "camera import {k}/cameras.txt --out {n}.yaml --camera-id x",
        _usage("camera import", "argument --camera-id: invalid int value: 'x'"),
    ),
    # --------------------------------------------------------------------------- app
    (
        "app: project missing",
        "app {t}/nope.json",
        _error("app", "{t}/nope.json: project file not found"),
    ),
    (
        "app: project a folder",
        "app {k}/dir.json",
        _error("app", "{k}/dir.json: is a folder; expected a project file"),
    ),
    (
        "app: project binary garbage",
        "app {k}/bin.json --fresh",
        _error(
            "app", "{k}/bin.json: the project file is not UTF-8 text (byte 2): save it as UTF-8"
        ),
    ),
    (
        "app: --port -1",
        "app {d}/project.json --port -1",
        _error("app", "--port: expected a TCP port from 0 to 65535, got -1"),
    ),
    (
        "app: --port 70000",
        "app {d}/project.json --port 70000",
        _error("app", "--port: expected a TCP port from 0 to 65535, got 70000"),
    ),
    (
        "app: --port x",
        "app {d}/project.json --port x",
        _usage("app", "argument --port: invalid int value: 'x'"),
    ),
    (
        "app: --host with spaces",
        "app {d}/project.json --host 'not a host'",
        _error("app", "--host: expected an IP address or a host name, got 'not a host'"),
    ),
    (
        "app: --host 999.1.1.1",
        "app {d}/project.json --host 999.1.1.1",
        _error("app", "--host: expected an IP address or a host name, got '999.1.1.1'"),
    ),
    (
        "app: --session the project",
        "app {d}/project.json --session {d}/project.json",
        _error(
            "app",
            "{d}/project.json: --session: is the project file, an input of the app; write "
            "elsewhere",
        ),
    ),
    (
        "app: --session an image",
        "app {d}/project.json --session {d}/images/view_00.png",
        _error(
            "app",
            "{d}/images/view_00.png: --session: is image view_00, an input of the app; write "
            "elsewhere",
        ),
    ),
    (
        "app: --session the truth file with --demo",
        "app {d}/project.json --demo --session {d}/truth.json",
        _error(
            "app",
            "{d}/truth.json: --session: is the truth file, an input of the app; write elsewhere",
        ),
    ),
    (
        "app: --session a folder",
        "app {d}/project.json --session {k}/dir.json",
        _error("app", "{k}/dir.json: --session: is a folder; expected the path of a file to write"),
    ),
    (
        "app: --session in a missing folder",
        "app {d}/project.json --session {t}/no/s.json",
        _error(
            "app", "{t}/no/s.json: --session: the folder {t}/no does not exist; create it first"
        ),
    ),
    (
        "app: --state-dir a file",
        "app {d}/project.json --state-dir {k}/pic.png",
        _error("app", "{k}/pic.png: --state-dir: is not a folder; expected a folder to write into"),
    ),
    (
        "app: --demo without truth.json",
        "app {k}/notruth/project.json --demo",
        _error("app", "{k}/notruth/truth.json: truth file not found (demo mode needs truth.json)"),
    ),
    (
        "app: --demo with a value",
        "app {d}/project.json --demo=1",
        _usage("app", "argument --demo: ignored explicit argument '1'"),
    ),
    (
        "app: --fresh with a value",
        "app {d}/project.json --fresh=1",
        _usage("app", "argument --fresh: ignored explicit argument '1'"),
    ),
    # ------------------------------------------------------------------ schema, warmup
    (
        "schema: nosuch",
        "schema nosuch",
        _usage(
            "schema", "argument which: invalid choice: 'nosuch' (choose from 'project', 'result')"
        ),
    ),
    (
        "schema: empty",
        "schema ''",
        _usage("schema", "argument which: invalid choice: '' (choose from 'project', 'result')"),
    ),
    (
        "schema: two",
        "schema project result",
        _usage("", "unrecognized arguments: result"),
    ),
    (
        "warmup: --force with a value",
        "warmup --force=1",
        _usage("warmup", "argument --force: ignored explicit argument '1'"),
    ),
    ("warmup: an argument", "warmup now", _usage("", "unrecognized arguments: now")),
]


def _no_server(*args: object, **kwargs: object) -> None:
    raise AssertionError("the app's arguments were accepted: it would start a server")


@pytest.mark.parametrize(("case", "argv", "expected"), CASES, ids=[c[0] for c in CASES])
def test_bad_arguments(
    dataset: Path,
    result_file: Path,
    kit: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    case: str,
    argv: str,
    expected: tuple[str, bool],
) -> None:
    import lightcal_app.server

    monkeypatch.setattr(lightcal_app.server, "build_app", _no_server)
    monkeypatch.setattr(lightcal_app.server, "serve_forever", _no_server)
    fill = {"d": dataset, "r": result_file, "k": kit, "t": tmp_path, "n": tmp_path / "new"}
    folders = (dataset, kit, result_file.parent)
    before = [_hashes(f) for f in folders]
    line, usage = expected
    capsys.readouterr()
    words = shlex.split(argv.format(**fill))
    if usage:
        with pytest.raises(SystemExit) as info:
            main(words)
        code = info.value.code
    else:
        code = main(words)
    err = capsys.readouterr().err
    assert "internal error" not in err
    assert code == 2, err
    lines = err.splitlines()
    if not usage:
        assert len(lines) == 1, err
    assert lines[-1] == line.format(**fill)
    assert [_hashes(f) for f in folders] == before
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # nothing written, no temporary


def test_every_subcommand_and_option_has_a_case() -> None:
    """Each subcommand, and each option in its --help, appears in a case above."""
    import argparse

    from lightcal.cli.main import build_parser

    def parsers(parser: argparse.ArgumentParser, name: str):
        yield name, parser
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for sub, p in action.choices.items():
                    yield from parsers(p, f"{name} {sub}".strip())

    argvs = [argv for _, argv, _ in CASES]
    missing = []
    for name, parser in parsers(build_parser(), ""):
        mine = [a for a in argvs if (a + " ").startswith(name + " ")] if name else argvs
        if not mine:
            missing.append(name)
            continue
        for action in parser._actions:
            if not name or isinstance(action, argparse._HelpAction):
                continue  # (lightcal's own --version and --debug take no value)
            options = action.option_strings
            if options and not any(o in a.replace("=", " ").split() for a in mine for o in options):
                missing.append(f"{name} {options[0]}")
    assert missing == []
