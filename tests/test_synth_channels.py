"""`lightcal synth`'s colour datasets (`lightcal.synthetic.colour`): three `--attenuation`
or `--backscatter` values make 3-channel 16-bit images, each channel in its own water
with its own noise, `--colour` the channels' relative light scales.

Checked here: the planes hold the right channel (the R/G ratio of a noise-free dataset is
the one the truth's geometry predicts, computed here from truth.json alone), the noise is
independent between channels, truth.json's and the project's per-channel entries, the
refusals, and the acceptance: `lightcal calibrate` of a colour dataset in water whose
attenuation and backscatter differ per channel lands on the light and on each channel's
water.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from lightcal.cli.main import main
from lightcal.core.camera import Camera
from lightcal.errors import InputError
from lightcal.io.images import read_image
from lightcal.io.medium_spec import MediumSpec
from lightcal.io.project import load_project
from lightcal.synthetic.colour import ColourChannels
from lightcal.synthetic.dataset import SynthConfig, read_truth, write_dataset
from lightcal.synthetic.departures import Departures
from lightcal.synthetic.scenes import SceneConfig, SensorConfig
from tests.departure_suite import camera

C_RGB = (0.4, 0.12, 0.06)
BETA_RGB = (0.8, 0.24, 0.12)
COLOUR = (1.0, 0.94, 0.75)
TINY = ["--views", "3", "--width", "64", "--height", "48", "--quiet"]
COLOUR_WATER = ["--attenuation", *map(str, C_RGB)]


def _small_camera() -> Camera:
    return Camera.from_params(fx=144.0, fy=144.0, cx=79.5, cy=59.5, width=160, height=120)


def _colour_config(sensor: SensorConfig, **changes) -> SynthConfig:
    base = {
        "camera": _small_camera(),
        "scene": SceneConfig(n_views=3, distance_range_m=(0.8, 1.5)),
        "sensor": sensor,
        "seed": 3,
        "channels": ColourChannels(attenuation_per_m=C_RGB, colour=COLOUR),
    }
    return SynthConfig(**{**base, **changes})


def _path_lengths(truth: dict, i: int, uv: np.ndarray) -> np.ndarray:
    """(n,) d_light + d_camera to the wall point of pixels `uv` (n, 2) of view i, from
    truth.json alone (a camera without distortion, one light, the wall z = 0)."""
    cam, view = truth["camera"], truth["views"][i]
    assert not any(cam["dist"])
    R = np.array(view["T_camera_world"]["R"])
    t = np.array(view["T_camera_world"]["t"])
    K = np.array([[cam["fx"], cam["skew"], cam["cx"]], [0.0, cam["fy"], cam["cy"]], [0, 0, 1]])
    rays = (R.T @ np.linalg.solve(K, np.c_[uv, np.ones(len(uv))].T)).T
    centre = -R.T @ t
    points = centre + (-centre[2] / rays[:, 2])[:, None] * rays
    light = R.T @ (np.array(truth["lights"][0]["position_m"]) - t)
    return np.linalg.norm(points - centre, axis=1) + np.linalg.norm(points - light, axis=1)


@pytest.mark.parametrize("image_format", ["png", "tiff"])
def test_each_plane_is_its_channel_in_its_water(tmp_path: Path, image_format: str) -> None:
    """A noise-free 16-bit colour dataset: every view a 3-channel uint16 image whose
    R/G and B/G ratios are colour_R/colour_G exp(-(c_R - c_G)(d_light + d_camera)) to
    1e-3 at every pixel above 3000 DN in each channel (rounding: <= 3.3e-4; the geometry
    computed here from truth.json)."""
    sensor = SensorConfig(bit_depth=16, noise=False)
    dataset = write_dataset(tmp_path / "ds", _colour_config(sensor, image_format=image_format))
    truth = read_truth(dataset.truth_path)
    black, white = truth["sensor"]["black_level_dn"], truth["sensor"]["white_level_dn"]
    assert [ch["name"] for ch in truth["channels"]] == ["R", "G", "B"]
    assert [ch["medium"]["attenuation_per_m"] for ch in truth["channels"]] == list(C_RGB)
    for i, path in enumerate(dataset.image_paths):
        if image_format == "png":
            raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        else:
            import tifffile

            raw = tifffile.imread(path)[..., ::-1]  # R, G, B samples -> B, G, R
        assert raw.dtype == np.uint16 and raw.shape == (120, 160, 3)
        planes = {
            ch: read_image(path, channel=ch, black_level=black, white_level=white).values
            for ch in "RGB"
        }
        assert np.array_equal(planes["R"] + black, raw[..., 2].astype(np.float64))
        bright = np.argwhere(np.min([planes[ch] for ch in "RGB"], axis=0) > 3000.0)
        assert len(bright) > 1000
        uv = bright[:, ::-1].astype(np.float64)
        d = _path_lengths(truth, i, uv)
        rows, cols = bright[:, 0], bright[:, 1]
        for ch, k in (("R", 0), ("B", 2)):
            expected = COLOUR[k] / COLOUR[1] * np.exp(-(C_RGB[k] - C_RGB[1]) * d)
            ratio = planes[ch][rows, cols] / planes["G"][rows, cols]
            assert np.max(np.abs(ratio / expected - 1.0)) < 1e-3, (ch, i)


def test_the_noise_is_independent_between_channels(tmp_path: Path) -> None:
    """Residuals of a noisy colour dataset against its noise-free twin (same seed): R, G
    and B uncorrelated (|r| < 0.1), each of the sensor model's size."""
    noisy = write_dataset(tmp_path / "noisy", _colour_config(SensorConfig()))
    clean = write_dataset(tmp_path / "clean", _colour_config(SensorConfig(noise=False)))
    truth = read_truth(noisy.truth_path)
    gain = truth["sensor"]["noise_model"]["gain"]
    read_variance = truth["sensor"]["noise_model"]["read_variance"]
    for a, b in zip(noisy.image_paths, clean.image_paths, strict=True):
        x = cv2.imread(str(a), cv2.IMREAD_UNCHANGED).astype(np.float64)
        y = cv2.imread(str(b), cv2.IMREAD_UNCHANGED).astype(np.float64)
        lit = np.all(y - truth["sensor"]["black_level_dn"] > 50.0, axis=-1)
        assert lit.sum() > 5000
        expected = y[lit] - truth["sensor"]["black_level_dn"]
        z = (x[lit] - y[lit]) / np.sqrt(gain * expected + read_variance)  # (n, 3) B, G, R
        r = np.corrcoef(z.T)
        assert np.all(np.abs(r[np.triu_indices(3, 1)]) < 0.1), r
        assert np.all(np.abs(z.std(axis=0) - 1.0) < 0.1), z.std(axis=0)


def test_truth_and_project_of_a_declared_colour_dataset(tmp_path: Path) -> None:
    """--declare-medium given: the project solves R, G, B with the true water per channel;
    truth.json has the per-channel water and scales (the light's scale times the relative
    colour), the departures' lists, and each view's per-channel peaks."""
    out = tmp_path / "ds"
    argv = ["synth", str(out), *TINY, *COLOUR_WATER, "--backscatter", *map(str, BETA_RGB)]
    argv += ["--phase-g", "0.8", "--colour", "2", "1.88", "1.5", "--declare-medium", "given"]
    assert main(argv) == 0
    truth = read_truth(out / "truth.json")
    light = truth["lights"][0]
    assert light["channels"] == ["R", "G", "B"]
    colour = [ch["colour"] for ch in truth["channels"]]
    assert colour == pytest.approx([1.0, 0.94, 0.75])  # over its largest value
    assert light["scale"][1] / light["scale"][0] == pytest.approx(0.94)
    for k, ch in enumerate(truth["channels"]):
        assert ch["scales"] == [light["scale"][k]]
        assert ch["medium"] == {
            "attenuation_per_m": C_RGB[k],
            "backscatter_per_m": BETA_RGB[k],
            "phase_g": 0.8,
        }
    departures = truth["departures"]
    assert departures["attenuation"]["coefficient_per_m"] == list(C_RGB)
    assert departures["backscatter"]["beta_per_m"] == list(BETA_RGB)
    assert departures["backscatter"]["channels"] == ["R", "G", "B"]
    assert all(len(view["peak_signal_dn"]) == 3 for view in truth["views"])
    doc = json.loads((out / "project.json").read_text())
    assert doc["sensor"]["channels"] == ["R", "G", "B"]
    assert doc["medium"] == {
        "attenuation_per_m": list(C_RGB),
        "backscatter_per_m": list(BETA_RGB),
        "phase_g": 0.8,
        "estimate": [],
    }
    project = load_project(out / "project.json")
    assert [m.initial.attenuation_per_m for m in project.media] == list(C_RGB)


def test_estimated_starts_from_a_rough_guess_and_undeclared_reads_luminance(
    tmp_path: Path,
) -> None:
    """--declare-medium estimated: c from 0.2 and beta from 0.5 /m in every channel;
    without --declare-medium the project reads one channel (the luminance) in air."""
    water = [*COLOUR_WATER, "--backscatter", *map(str, BETA_RGB)]
    assert main(["synth", str(tmp_path / "e"), *TINY, *water, "--declare-medium", "estimated"]) == 0
    medium = json.loads((tmp_path / "e" / "project.json").read_text())["medium"]
    assert medium["attenuation_per_m"] == [0.2] * 3 and medium["backscatter_per_m"] == [0.5] * 3
    assert medium["estimate"] == ["attenuation_per_m", "backscatter_per_m"]
    assert main(["synth", str(tmp_path / "u"), *TINY, *water]) == 0
    doc = json.loads((tmp_path / "u" / "project.json").read_text())
    assert "channels" not in doc["sensor"] and doc["sensor"]["channel"] == "auto"
    assert doc["medium"]["attenuation_per_m"] == 0.0 and doc["medium"]["estimate"] == []
    image = cv2.imread(str(tmp_path / "u" / "images" / "view_00.png"), cv2.IMREAD_UNCHANGED)
    assert image.dtype == np.uint16 and image.shape == (48, 64, 3)
    assert load_project(tmp_path / "u" / "project.json").channels == ()


def test_room_light_and_dark_frames_in_colour(tmp_path: Path) -> None:
    """--ambient per channel (F times that channel's median-image beam peak) and colour
    light-off photos; the same configuration writes the same bytes."""
    argv = [*TINY, *COLOUR_WATER, "--ambient", "0.1", "--dark-frames", "--format", "tiff"]
    assert main(["synth", str(tmp_path / "a"), *argv]) == 0
    assert main(["synth", str(tmp_path / "b"), *argv]) == 0
    truth = read_truth(tmp_path / "a" / "truth.json")
    ambient = truth["departures"]["ambient"]
    assert ambient["channels"] == ["R", "G", "B"] and len(ambient["levels_dn"]) == 3
    for k, ch in enumerate(truth["channels"]):
        per_exposure = 0.1 * ambient["reference_peak_dn"][k] / ambient["reference_exposure"][k]
        assert ambient["per_exposure_dn"][k] == pytest.approx(per_exposure)
        assert ch["ambient_per_exposure_dn"] == ambient["per_exposure_dn"][k]
    assert ambient["per_exposure_dn"][0] < ambient["per_exposure_dn"][2]  # red absorbed most
    dark = tmp_path / "a" / "images" / "view_00_dark.tif"
    means = [read_image(dark, channel=ch, black_level=512.0).values.mean() for ch in "RGB"]
    levels = [ambient["levels_dn"][k][0] for k in range(3)]
    assert means == pytest.approx(levels, rel=0.05)
    for p in sorted((tmp_path / "a").rglob("*")):
        if p.is_file():
            assert p.read_bytes() == (tmp_path / "b" / p.relative_to(tmp_path / "a")).read_bytes()


# ------------------------------------------------------------------------------ refusals

_COLOUR_DS = "a colour dataset (three --attenuation or --backscatter values, R G B)"


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--attenuation", "0.1", "0.2"], "--attenuation: expected 1 value or 3 (R G B), got 2"),
        (
            ["--backscatter", "0.1", "0.2", "0.3", "0.4"],
            "--backscatter: expected 1 value or 3 (R G B), got 4",
        ),
        (
            ["--attenuation", "0.1", "-0.2", "0.3"],
            "--attenuation: expected a finite value >= 0, got -0.2",
        ),
        (
            ["--attenuation", "0.1", "0.2", "3"],
            "--attenuation: expected at most 2 per metre, got 3",
        ),
        (
            ["--attenuation", "0.1", "--backscatter", "0.1", "nan", "0.3"],
            "--backscatter: expected a finite value >= 0, got nan",
        ),
        (["--colour", "1", "1", "1"], f"--colour: applies to {_COLOUR_DS} only"),
        ([*COLOUR_WATER, "--colour", "1", "0", "1"], "--colour: expected finite values > 0, got 0"),
        (
            [*COLOUR_WATER, "--colour", "1", "-1", "1"],
            "--colour: expected finite values > 0, got -1",
        ),
        (
            [*COLOUR_WATER, "--colour", "1", "0.001", "1"],
            "--colour: expected values within a factor 100 of each other (a channel 100 times "
            "darker holds no beam), got 1 0.001 1",
        ),
        (
            [*COLOUR_WATER, "--corner", "0.7", "0.5", "0.8"],
            f"--corner: not in {_COLOUR_DS}: its bounce light is computed for one water, and "
            "the joint solve of colour channels does not model surroundings",
        ),
        (
            [*COLOUR_WATER, "--declare-albedo-map", "--declare-medium", "estimated"],
            f"--declare-albedo-map: not with --declare-medium in {_COLOUR_DS}: its project "
            "solves the channels jointly (sensor.channels), which does not model an albedo map",
        ),
        (
            ["--backscatter", "0.1", "0.2", "0.3", "--sensor", "cos4"],
            "--backscatter: applies to the radiance sensor model only, got 'cos4'",
        ),
        (
            ["--attenuation", "0", "0", "0", "--declare-medium", "given"],
            "--declare-medium: given: expected --attenuation C > 0 or --backscatter BETA > 0 "
            "(the medium to declare)",
        ),
    ],
)
def test_refusals_name_the_option(tmp_path: Path, capsys, extra: list[str], message: str) -> None:
    capsys.readouterr()
    assert main(["synth", str(tmp_path / "ds"), *TINY, *extra]) == 2
    assert capsys.readouterr().err.splitlines() == [f"lightcal synth: error: {message}"]
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("changes", "source", "detail"),
    [
        (
            {"departures": Departures(attenuation_per_m=0.1)},
            "departures",
            "with channels the water is per channel (channels.attenuation_per_m, "
            "channels.backscatter_per_m); expected departures without attenuation and "
            "backscatter",
        ),
        (
            {"departures": Departures(corner=(0.7, 0.5, 0.8))},
            "corner",
            "not in a colour dataset: the bounce light is computed for one water, and the "
            "joint solve of colour channels does not model surroundings",
        ),
        (
            {
                "albedo_map": True,
                "channels": ColourChannels(attenuation_per_m=C_RGB, declare=True),
                "medium": MediumSpec(attenuation_per_m=list(C_RGB)),
            },
            "albedo_map",
            "not beside declared colour channels: the joint solve of sensor.channels does not "
            "model an albedo map",
        ),
    ],
)
def test_the_configuration_refuses_what_cannot_be_coloured(changes, source, detail) -> None:
    with pytest.raises(InputError) as info:
        _colour_config(SensorConfig(), **changes)
    assert (str(info.value.source), info.value.detail) == (source, detail)


# ---------------------------------------------------------------------------- acceptance


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory) -> tuple[dict, dict, int]:
    """`lightcal synth` colour data in water absorbing and scattering per channel (the
    medium accuracy suite's camera, 1600 pixels an image), `lightcal calibrate`d."""
    root = tmp_path_factory.mktemp("colour")
    cam = camera()
    argv = ["synth", str(root / "ds"), "--quiet", "--seed", "5", "--width", "480", "--height"]
    argv += ["360", "--fx", "432", "--cx", "239.5", "--cy", "179.5", "--distortion"]
    argv += [*map(str, cam.dist_opencv[:5]), *COLOUR_WATER, "--backscatter"]
    argv += [*map(str, BETA_RGB), "--phase-g", "0.8", "--colour", *map(str, COLOUR)]
    assert main([*argv, "--declare-medium", "estimated"]) == 0
    project = root / "ds" / "project.json"
    truth = read_truth(root / "ds" / "truth.json")
    assert truth["camera"]["fx"] == cam.fx and truth["camera"]["dist"][:2] == [-0.05, 0.01]
    doc = json.loads(project.read_text())
    doc.setdefault("selection", {})["n_per_image"] = 1600
    project.write_text(json.dumps(doc))
    out = root / "result.json"
    code = main(["calibrate", str(project), "--out", str(out), "--quiet"])
    return json.loads(out.read_text()), truth, code


def test_calibrating_colour_water_lands_on_the_light_and_each_channel(calibrated) -> None:
    """ACCEPTANCE: one light pose from R, G and B within 3 mm and 0.2 deg of the truth,
    each channel's c within 5 % and beta within 10 % (from 0.2 and 0.5 /m), each scale
    within 1 %; exit code 0."""
    result, truth, code = calibrated
    assert code == 0, result["warnings"]
    light, true_light = result["lights"][0], truth["lights"][0]
    position_m = np.linalg.norm(np.subtract(light["position_m"], true_light["position_m"]))
    cos = np.clip(np.dot(light["axis_camera"], true_light["axis_camera"]), -1.0, 1.0)
    assert position_m < 0.003
    assert np.degrees(np.arccos(cos)) < 0.2
    assert [ch["name"] for ch in result["channels"]] == ["R", "G", "B"]
    for ch, true_ch in zip(result["channels"], truth["channels"], strict=True):
        medium, water = ch["medium"], true_ch["medium"]
        assert medium["attenuation_per_m"] == pytest.approx(water["attenuation_per_m"], rel=0.05)
        assert medium["backscatter_per_m"] == pytest.approx(water["backscatter_per_m"], rel=0.1)
        assert 0.0 < medium["sigma"]["attenuation_per_m"] < 0.01
        assert list(ch["scales"].values()) == pytest.approx(true_ch["scales"], rel=0.01)
