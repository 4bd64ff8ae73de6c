"""Exposure factors of a project: explicit, from settings, from the files' EXIF."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from lightcal.errors import InputError
from lightcal.io.project import load_project

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data"


def _copy_sample(tmp_path: Path) -> tuple[Path, dict]:
    for name in ("images", "masks"):
        shutil.copytree(SAMPLE / name, tmp_path / name)
    for name in ("camera.yaml", "light.ies"):
        shutil.copy(SAMPLE / name, tmp_path / name)
    data = json.loads((SAMPLE / "project.json").read_text())
    return tmp_path / "project.json", data


def test_null_exposure_reads_the_exif_of_the_images(tmp_path: Path) -> None:
    explicit = load_project(SAMPLE / "project.json")
    path, data = _copy_sample(tmp_path)
    for im in data["images"]:
        im.pop("exposure", None)
    path.write_text(json.dumps(data))
    from_exif = load_project(path)
    got = [v.exposure for v in from_exif.views]
    want = [v.exposure for v in explicit.views]
    assert got == pytest.approx(want, rel=1e-9)
    assert len(set(got)) > 1  # the sample views really differ in exposure


def test_an_image_without_exif_among_images_with_settings_is_an_error(tmp_path: Path) -> None:
    path, data = _copy_sample(tmp_path)
    for im in data["images"]:
        im.pop("exposure", None)
    # Strip the EXIF of the second image by re-encoding its pixels alone.
    import cv2

    name = data["images"][1]["path"]
    pixels = cv2.imread(str(tmp_path / name), cv2.IMREAD_UNCHANGED)
    cv2.imwrite(str(tmp_path / name), pixels)
    path.write_text(json.dumps(data))
    with pytest.raises(InputError) as info:
        load_project(path)
    assert str(info.value) == (
        f"{path}: images[1].exposure: not given and {Path(name).name} has no EXIF exposure "
        "time, while other images' exposures come from settings; give the exposure of every image"
    )
