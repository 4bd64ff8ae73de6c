"""`lightcal response`: a camera's response curve from an exposure bracket (issue 25):
recovered from a bracket rendered with a known tone curve, and every bad input refused
before the fit with a message naming it."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from lightcal.cli.main import main
from lightcal.io.response import ResponseCurve
from lightcal.io.response_figure import srgb_to_linear

TIMES = (1 / 250, 1 / 60, 1 / 15, 1 / 4)


def _srgb_encode(linear: np.ndarray) -> np.ndarray:
    v = np.clip(linear, 0.0, 1.0)
    encoded = np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)
    return np.round(encoded * 255).astype(np.uint8)


@pytest.fixture(scope="module")
def bracket(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Four photos of one scene (irradiance over 3 decades, a different mix per channel)
    at 1/250 to 1/4 s, encoded with the sRGB curve."""
    folder = tmp_path_factory.mktemp("bracket")
    rows, cols = np.indices((120, 160))
    radiance = 10 ** (-3.0 + 3.0 * cols / 159)[..., None] * np.array([0.6, 1.0, 0.8])
    radiance = radiance * (1 + 0.2 * np.sin(rows / 7.0))[..., None]
    paths = []
    for k, t in enumerate(TIMES):
        path = folder / f"shot_{k}.png"
        cv2.imwrite(str(path), _srgb_encode(radiance * t * 4.0))
        paths.append(path)
    return paths


def test_the_fitted_curve_is_the_tone_curve_the_photos_were_made_with(
    bracket: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out, plot = tmp_path / "response.json", tmp_path / "response.png"
    times = [str(t) for t in TIMES]
    argv = ["response", *map(str, bracket), "--out", str(out), "--times", *times]
    assert main([*argv, "--plot", str(plot)]) == 0
    curve = ResponseCurve.load(out)
    codes = np.arange(20, 241)
    truth = srgb_to_linear(codes) / srgb_to_linear(np.array([128]))[0]
    for c in range(3):
        fitted = curve.values[codes, c] / curve.values[128, c]
        assert np.max(np.abs(np.log(fitted / truth))) < 0.05, c  # measured <= 3.1 % (20-240)
    said = capsys.readouterr().err
    assert f"response of 4 photos (0.004 to 0.25 s) written to {out}" in said
    picture = cv2.imread(str(plot))
    assert picture is not None and picture.shape[1] == 1280


@pytest.mark.parametrize(
    ("case", "args", "expected"),
    [
        (
            "one photo",
            ["{a}", "--out", "{t}/r.json", "--times", "1"],
            "IMAGE: expected at least 2 photos of an exposure bracket, got 1",
        ),
        (
            "times miscounted",
            ["{a}", "{b}", "--out", "{t}/r.json", "--times", "1"],
            "--times: expected 2 exposure times, one per photo, got 1",
        ),
        (
            "a zero time",
            ["{a}", "{b}", "--out", "{t}/r.json", "--times", "1", "0"],
            "--times: expected exposure times in seconds, finite and > 0",
        ),
        (
            "one time twice",
            ["{a}", "{b}", "--out", "{t}/r.json", "--times", "0.5", "0.5"],
            "--times: every photo has the exposure time 0.5 s: expected a bracket of different "
            "exposure times",
        ),
        (
            "no EXIF",
            ["{a}", "{b}", "--out", "{t}/r.json"],
            "{a}: no exposure time in its EXIF: give every photo's with --times",
        ),
        (
            "a photo twice",
            ["{a}", "{a}", "--out", "{t}/r.json", "--times", "1", "2"],
            "IMAGE: a photo is given twice: expected each photo once",
        ),
        (
            "--out a .yaml",
            ["{a}", "{b}", "--out", "{t}/r.yaml", "--times", "1", "2"],
            "{t}/r.yaml: --out: expected a .json or .npy file, got r.yaml",
        ),
        (
            "--out a photo",
            ["{a}", "{b}", "--out", "{a}", "--times", "1", "2", "--force"],
            "{a}: --out: is a photo of the bracket, an input of the fit; write elsewhere",
        ),
        (
            "a 16-bit photo",
            ["{a}", "{t}/deep.png", "--out", "{t}/r.json", "--times", "1", "2"],
            "{t}/deep.png: 16-bit values: expected an 8-bit photo (a 16-bit or float image is "
            "linear already and needs no response curve)",
        ),
        (
            "not an image",
            ["{a}", "{t}/text.png", "--out", "{t}/r.json", "--times", "1", "2"],
            "{t}/text.png: not an image OpenCV can read; expected an 8-bit photo (JPEG, PNG, TIFF)",
        ),
        (
            "another size",
            ["{a}", "{t}/small.png", "--out", "{t}/r.json", "--times", "1", "2"],
            "{t}/small.png: 16 x 12 pixels, expected 160 x 120 like shot_0.png",
        ),
    ],
)
def test_bad_brackets_are_refused_before_the_fit(
    bracket: list[Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    case: str,
    args: list[str],
    expected: str,
) -> None:
    cv2.imwrite(str(tmp_path / "deep.png"), np.full((120, 160), 4000, np.uint16))
    (tmp_path / "text.png").write_text("not a picture")
    cv2.imwrite(str(tmp_path / "small.png"), np.zeros((12, 16, 3), np.uint8))
    fill = {"a": bracket[0], "b": bracket[1], "t": tmp_path}
    argv = ["response", *(a.format(**fill) for a in args)]
    capsys.readouterr()
    assert main(argv) == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        "lightcal response: error: " + expected.format(**{str(k): v for k, v in fill.items()})
    )
    assert not (tmp_path / "r.json").exists()
