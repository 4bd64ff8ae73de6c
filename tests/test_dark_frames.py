"""Light-off photos (`images[i].dark`): read as the image, checked, subtracted, their noise
added to the noise model; `lightcal synth --dark-frames` and a calibration with room light
(issue 25)."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from lightcal.cli.main import main
from lightcal.errors import InputError
from lightcal.io.project import load_project
from lightcal.pipeline import image_data, load_images, noise_floor
from lightcal.pipeline.select import declared_noise

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data"
GAIN, READ_VARIANCE = 0.5, 4.0


def _write_project(folder: Path, images: list[dict], **sensor) -> Path:
    """A tiny project (8 x 6 camera 1 m from the wall, an isotropic light) of `images`."""
    doc = {
        "camera": {"fx": 10.0, "fy": 10.0, "cx": 3.5, "cy": 2.5, "width": 8, "height": 6},
        "sensor": {"noise": {"gain": GAIN, "read_variance": READ_VARIANCE}, **sensor},
        "images": [
            {
                "T_camera_world": {"R": [[1, 0, 0], [0, -1, 0], [0, 0, -1]], "t": [0, 0, 1]},
                "exposure": 1.0,
                **im,
            }
            for im in images
        ],
        "lights": [{"rid": {"type": "isotropic"}, "initial": {"position_m": [0.1, 0.0, 0.0]}}],
    }
    path = folder / "project.json"
    path.write_text(json.dumps(doc))
    return path


def _photos(folder: Path) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(3)
    image = 40.0 + rng.uniform(0.0, 20.0, (6, 8))
    dark = 5.0 + rng.uniform(-1.0, 1.0, (6, 8))
    image[1, 2] = 100.0  # saturated in the image
    dark[4, 5] = 100.0  # and in the light-off photo
    np.save(folder / "a.npy", image)
    np.save(folder / "a_dark.npy", dark)
    return image, dark


def test_the_light_off_photo_is_subtracted_and_its_noise_added(tmp_path: Path) -> None:
    image, dark = _photos(tmp_path)
    project = load_project(
        _write_project(tmp_path, [{"path": "a.npy", "dark": "a_dark.npy"}], white_level=100.0)
    )
    assert project.dark_paths == [tmp_path / "a_dark.npy"]
    loaded = load_images(project)
    (img,) = loaded.images
    np.testing.assert_array_equal(img.values, image - dark)
    assert np.argwhere(img.saturated).tolist() == [[1, 2], [4, 5]]
    assert loaded.dark_levels == [pytest.approx(float(dark.mean()))]
    # Variance of image - dark: the image's a (beam + d) + c plus the dark's a d + c.
    level = float(dark.mean())
    noise = (GAIN, 2 * READ_VARIANCE + 2 * GAIN * level)
    assert declared_noise(project, loaded.dark_level(0)) == pytest.approx(noise)
    assert declared_noise(project) == (GAIN, READ_VARIANCE)
    assert noise_floor(project, img, dark_level=level) == pytest.approx(5 * math.sqrt(noise[1]))
    data = image_data(project, loaded, 0)
    assert data.noise == pytest.approx(noise)
    np.testing.assert_allclose(data.sigma, np.sqrt(GAIN * data.observed + noise[1]))

    without = load_images(load_project(_write_project(tmp_path, [{"path": "a.npy"}])))
    assert without.dark_levels == [None] and without.dark_level(0) is None
    np.testing.assert_array_equal(without.images[0].values, image)


def _load_error(path: Path) -> str:
    with pytest.raises(InputError) as info:
        load_images(load_project(path))
    return str(info.value)


def test_a_missing_or_self_dark_or_one_of_another_kind_is_refused(tmp_path: Path) -> None:
    _photos(tmp_path)
    path = _write_project(tmp_path, [{"path": "a.npy", "dark": "nope.npy"}])
    assert _load_error(path) == (
        f"{path}: images[0].dark: light-off photo not found: {tmp_path / 'nope.npy'}"
    )
    path = _write_project(tmp_path, [{"path": "a.npy", "dark": "./a.npy"}])
    assert _load_error(path) == (
        f"{path}: images[0].dark: the same file as images[0].path (a.npy); expected a photo "
        "of the same view with the light off"
    )
    (tmp_path / "raw.dng").write_bytes(b"raw")
    (tmp_path / "raw_dark.jpg").write_bytes(b"jpeg")
    path = _write_project(tmp_path, [{"path": "raw.dng", "dark": "raw_dark.jpg"}])
    assert _load_error(path) == (
        f"{path}: images[0].dark: raw_dark.jpg is a developed image (not camera raw) but its "
        "image raw.dng is a camera raw file; expected the light-off photo stored as its image "
        "is (same camera output)"
    )
    path = _write_project(tmp_path, [{"path": "a.npy", "dark": "raw.dng"}])
    assert _load_error(path) == (
        f"{path}: images[0].dark: raw.dng is a camera raw file but its image a.npy is a "
        "developed image (not camera raw); expected the light-off photo stored as its image "
        "is (same camera output)"
    )


def test_a_dark_of_another_size_depth_or_with_nan_is_refused(tmp_path: Path) -> None:
    _photos(tmp_path)
    np.save(tmp_path / "small.npy", np.zeros((3, 4)))
    path = _write_project(tmp_path, [{"path": "a.npy", "dark": "small.npy"}])
    assert _load_error(path) == (
        f"{tmp_path / 'small.npy'}: the light-off photo is 4x3 pixels but its image a.npy is "
        "8x6; expected the same size"
    )
    nan = np.zeros((6, 8))
    nan[2, 3] = math.nan
    np.save(tmp_path / "nan.npy", nan)
    path = _write_project(tmp_path, [{"path": "a.npy", "dark": "nan.npy"}])
    assert _load_error(path) == (
        f"{tmp_path / 'nan.npy'}: 1 pixel values are NaN or infinite; expected finite linear values"
    )
    cv2.imwrite(str(tmp_path / "b.png"), np.full((6, 8), 30000, np.uint16))
    cv2.imwrite(str(tmp_path / "b_dark.png"), np.full((6, 8), 12, np.uint8))
    path = _write_project(tmp_path, [{"path": "b.png", "dark": "b_dark.png"}], assume_linear=True)
    assert _load_error(path) == (
        f"{tmp_path / 'b_dark.png'}: the light-off photo has 8 bits per sample but its image "
        "b.png has 16 bits per sample; expected the same camera output"
    )


def test_a_dark_taken_with_other_settings_is_refused(tmp_path: Path) -> None:
    """The sample's view_01.png (1/30 s) as the light-off photo of view_00 (1/100 s)."""
    for name in ("view_00.png", "view_01.png"):
        (tmp_path / "images").mkdir(exist_ok=True)
        shutil.copy(SAMPLE / "images" / name, tmp_path / "images" / name)
    shutil.copy(SAMPLE / "camera.yaml", tmp_path / "camera.yaml")
    shutil.copy(SAMPLE / "light.ies", tmp_path / "light.ies")
    doc = json.loads((SAMPLE / "project.json").read_text())
    image = dict(doc["images"][0], dark="images/view_01.png")
    image.pop("mask")
    path = tmp_path / "project.json"
    path.write_text(json.dumps(dict(doc, images=[image])))
    dark = tmp_path / "images" / "view_01.png"
    assert _load_error(path) == (
        f"{dark}: the light-off photo's exposure time differs from its image view_00.png's: "
        "0.0333333 s (its EXIF) against 0.01 s (declared for the image); expected a "
        "light-off photo taken with the image's settings"
    )
    image.pop("exposure")  # then the image's EXIF is compared
    path.write_text(json.dumps(dict(doc, images=[image])))
    assert _load_error(path) == (
        f"{dark}: the light-off photo's exposure time differs from its image view_00.png's: "
        "0.0333333 s (its EXIF) against 0.01 s (the image's EXIF); expected a light-off "
        "photo taken with the image's settings"
    )


# A well-determined dataset (little noise, precise poses) with room light at 5 % of the
# beam's peak: what is left of the error is the room light's.
SYNTH = [
    *("--ambient", "0.05", "--full-well-e", "400000"),
    *("--pose-noise-mm", "0.1", "--pose-noise-deg", "0.01"),
    *("--views", "8", "--width", "600", "--height", "400", "--quiet", "--seed", "0"),
]


def _pose_error(result: Path, truth: dict) -> tuple[float, float]:
    """(position error mm, axis error deg) of a result's light against the truth."""
    light = json.loads(result.read_text())["lights"][0]
    true = truth["lights"][0]
    a, b = np.array(light["axis_camera"]), np.array(true["axis_camera"])
    cos = float(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)))
    position_mm = 1000.0 * float(
        np.linalg.norm(np.subtract(light["position_m"], true["position_m"]))
    )
    return position_mm, math.degrees(math.acos(min(1.0, cos)))


def test_synth_dark_frames_make_room_light_calibrate_to_the_truth(tmp_path: Path) -> None:
    out = tmp_path / "ds"
    assert main(["synth", str(out), *SYNTH, "--dark-frames"]) == 0
    truth = json.loads((out / "truth.json").read_text())
    assert truth["departures"]["ambient"]["fraction"] == 0.05
    project = load_project(out / "project.json")
    assert [p.name for p in project.dark_paths if p] == [f"view_{i:02d}_dark.png" for i in range(8)]
    assert [v["dark"] for v in truth["views"]] == [
        f"images/view_{i:02d}_dark.png" for i in range(8)
    ]
    assert (
        main(["calibrate", str(out / "project.json"), "--out", str(tmp_path / "r.json"), "--quiet"])
        == 0
    )
    position_mm, axis_deg = _pose_error(tmp_path / "r.json", truth)
    print(f"with the light-off photos: {position_mm:.2f} mm, {axis_deg:.3f} deg")
    assert position_mm < 2.0 and axis_deg < 0.1
    fit = json.loads((tmp_path / "r.json").read_text())["fit"]
    assert fit["adequate"] and fit["chi2_per_dof"] < 1.2  # the dark's noise is in the model

    # The same data without the light-off photos: the room light pulls the light away.
    doc = json.loads((out / "project.json").read_text())
    for im in doc["images"]:
        del im["dark"]
    (out / "no_dark.json").write_text(json.dumps(doc))
    code = main(
        ["calibrate", str(out / "no_dark.json"), "--out", str(tmp_path / "n.json"), "--quiet"]
    )
    assert code == 3  # the fit test finds the room light
    position_mm, axis_deg = _pose_error(tmp_path / "n.json", truth)
    print(f"without them: {position_mm:.1f} mm, {axis_deg:.2f} deg")
    assert position_mm > 20.0


def test_the_app_state_loads_a_project_with_light_off_photos(tmp_path: Path) -> None:
    from lightcal_app.state import AppState

    out = tmp_path / "ds"
    small = ["--views", "3", "--width", "80", "--height", "60"]
    assert main(["synth", str(out), *SYNTH, *small, "--dark-frames"]) == 0
    project = load_project(out / "project.json")
    state = AppState(project, load_images(project))
    with state.lock:
        assert state.project.dark_paths == project.dark_paths
        values = state.loaded.images[0].values
    image = cv2.imread(str(out / "images" / "view_00.png"), cv2.IMREAD_UNCHANGED)
    dark = cv2.imread(str(out / "images" / "view_00_dark.png"), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(values, image.astype(np.float64) - dark)


def test_synth_force_replaces_the_light_off_photos_of_an_earlier_dataset(tmp_path: Path) -> None:
    out = tmp_path / "ds"
    small = ["--views", "2", "--width", "80", "--height", "60", "--quiet"]
    assert main(["synth", str(out), *small, "--ambient", "0.05", "--dark-frames"]) == 0
    names = ["view_00.png", "view_00_dark.png", "view_01.png", "view_01_dark.png"]
    assert sorted(p.name for p in (out / "images").iterdir()) == names
    truth = json.loads((out / "truth.json").read_text())
    black = truth["sensor"]["black_level_dn"]
    for i, level in enumerate(truth["departures"]["ambient"]["levels_dn"]):
        dark = cv2.imread(str(out / "images" / f"view_{i:02d}_dark.png"), cv2.IMREAD_UNCHANGED)
        assert dark.dtype == np.uint16 and dark.shape == (60, 80)
        # The room light alone, with its noise: the mean of 4800 pixels within 1 %.
        assert float(dark.mean()) - black == pytest.approx(level, rel=0.01)
    assert main(["synth", str(out), *small, "--force"]) == 0  # no room light now
    assert sorted(p.name for p in (out / "images").iterdir()) == ["view_00.png", "view_01.png"]
    assert load_project(out / "project.json").dark_paths == [None, None]
