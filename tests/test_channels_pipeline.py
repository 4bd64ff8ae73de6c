"""Colour photos through water whose attenuation differs by channel, calibrated in one
solve (`sensor.channels: [R, G, B]`) as a user would: 16-bit colour PNGs, the project
file, `lightcal calibrate`, `lightcal render`, `lightcal export`.

The photos are `lightcal synth`'s colour data (`SynthConfig.channels`: each channel in
its own water through synth's own imaging, noise drawn per channel); the independent
check is Mitsuba's (`tests/test_rgb_water_mitsuba.py`).
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from lightcal.cli.main import main
from lightcal.io.medium_spec import MediumSpec
from lightcal.synthetic.colour import ColourChannels
from lightcal.synthetic.dataset import SynthConfig, read_truth, write_dataset
from tests.departure_suite import camera

C_RGB = (0.4, 0.12, 0.06)  # /m: ocean water absorbs red most


def _colour_project(root: Path, *, seed: int = 5) -> Path:
    """A colour dataset in that water whose project solves the channels, c estimated
    from 0.2 /m in every channel."""
    config = SynthConfig(
        camera=camera(),
        seed=seed,
        channels=ColourChannels(attenuation_per_m=C_RGB, colour=(1.0, 0.94, 0.75), declare=True),
        medium=MediumSpec(attenuation_per_m=[0.2] * 3, estimate=["attenuation_per_m"]),
    )
    project = write_dataset(root / "ds", config).project_path
    doc = json.loads(project.read_text())
    assert doc["sensor"]["channels"] == ["R", "G", "B"]
    doc.setdefault("selection", {})["n_per_image"] = 800
    project.write_text(json.dumps(doc))
    return project


@pytest.fixture(scope="module")
def solved_files(tmp_path_factory) -> tuple[Path, Path, int]:
    """(project, result file, calibrate's exit code)."""
    root = tmp_path_factory.mktemp("rgb")
    project = _colour_project(root)
    out = root / "result.json"
    code = main(["calibrate", str(project), "--out", str(out), "--quiet"])
    return project, out, code


@pytest.fixture(scope="module")
def solved(solved_files) -> tuple[dict, dict, str]:
    project, out, code = solved_files
    truth = read_truth(project.parent / "truth.json")
    return json.loads(out.read_text()), truth, str(code)


def test_render_draws_each_channel_with_its_scale_and_water(solved_files, tmp_path) -> None:
    """`lightcal render` of the joint result: every channel's rendered image matches its
    photo (median ratio within 1 %); with the first channel's scale and water for all
    (the old way) the blue images would be far off."""
    import tifffile

    from lightcal.io.images import read_image
    from lightcal.io.outputs import safe_names

    project, out, _ = solved_files
    renders = tmp_path / "renders"
    assert main(["render", str(project), "--result", str(out), "--out", str(renders)]) == 0
    doc = json.loads(project.read_text())
    black = doc["sensor"].get("black_level", 0.0)
    for ch in "RGB":
        file = safe_names([f"view_03[{ch}]"])[0]
        rendered = tifffile.imread(renders / f"{file}_rendered.tif")
        photo = read_image(project.parent / "images" / "view_03.png", channel=ch).values
        lit = np.isfinite(rendered) & (rendered > 0.2 * np.nanmax(rendered))
        ratio = np.median((photo[lit] - black) / rendered[lit])
        assert ratio == pytest.approx(1.0, abs=0.01), ch


def test_joint_channels_land_on_the_light_and_each_c(solved) -> None:
    """One pose from the three channels: within 3 mm and 0.2 deg; each channel's c
    within 5 %; the fit test finds nothing (exit 0)."""
    result, truth, code = solved
    assert code == "0", result["warnings"]
    light, true_light = result["lights"][0], truth["lights"][0]
    position_m = np.linalg.norm(np.subtract(light["position_m"], true_light["position_m"]))
    cos = np.clip(np.dot(light["axis_camera"], true_light["axis_camera"]), -1.0, 1.0)
    axis_deg = np.degrees(np.arccos(cos))
    assert position_m < 0.003
    assert axis_deg < 0.2
    channels = result["channels"]
    assert [ch["name"] for ch in channels] == ["R", "G", "B"]
    for ch, c in zip(channels, C_RGB, strict=True):
        assert ch["medium"]["attenuation_per_m"] == pytest.approx(c, rel=0.05)
        assert 0.0 < ch["medium"]["sigma"]["attenuation_per_m"] < 0.01
    assert result["medium"]["attenuation_per_m"] == channels[0]["medium"]["attenuation_per_m"]
    names = [im["name"] for im in result["images"]]
    assert names[:3] == ["view_00[R]", "view_00[G]", "view_00[B]"]
    # A photo's channels are one exposure from one pose: not repeated views, one pose error.
    assert not any("one camera pose" in w for w in result["warnings"])
    photos = len(names) // 3
    assert any(f"camera poses ({photos} images'" in t for t in result["uncertainty"])


# ------------------------------------------------------------------------- project file


def _channel_doc(**sensor) -> dict:
    from tests.test_project import _doc

    doc = _doc()
    doc["sensor"] = {"channels": ["R", "G", "B"], **sensor}
    return doc


def test_project_has_an_entry_per_photo_and_channel(tmp_path: Path) -> None:
    from lightcal.io.project import load_project
    from tests.test_project import _write, folder

    root = folder.__wrapped__(tmp_path)
    doc = _channel_doc()
    doc["medium"] = {"attenuation_per_m": [0.4, 0.1, 0.05], "estimate": ["attenuation_per_m"]}
    project = load_project(_write(root, doc))
    assert project.names[:4] == ["a[R]", "a[G]", "a[B]", "b[R]"]
    assert project.channel_of == [0, 1, 2] * 3
    assert [project.spec_image(i) for i in range(9)] == [0, 0, 0, 1, 1, 1, 2, 2, 2]
    assert [project.channel_name(i) for i in range(3)] == ["R", "G", "B"]
    assert project.photo_name(4) == "b"
    assert project.views[3] is project.views[4]
    assert [m.initial.attenuation_per_m for m in project.media] == [0.4, 0.1, 0.05]
    assert project.medium is project.media[0]


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            lambda d: d.update(medium={"attenuation_per_m": [0.1, 0.2]}),
            "medium.attenuation_per_m: expected one value per channel of sensor.channels "
            "(R, G, B: 3), got 2",
        ),
        (
            lambda d: (d.pop("sensor"), d.update(medium={"backscatter_per_m": [0.1, 0.2]})),
            "medium.backscatter_per_m: a list gives one value per colour channel; expected a "
            "number, or sensor.channels",
        ),
        (
            lambda d: d["sensor"].update(channel="G"),
            "sensor: channel 'G' beside channels: expected one of the two",
        ),
        (
            lambda d: d["sensor"].update(channels=["R", "R"]),
            "sensor: channels: expected each channel once, got ['R', 'R']",
        ),
        (
            lambda d: d.update(wall={"albedo_map": {"spacing_mm": 100}}),
            "wall.albedo_map: modelled for one channel, not beside sensor.channels; calibrate "
            "each channel on its own (sensor.channel)",
        ),
        (
            lambda d: d["sensor"].update(estimate_offset=True, estimate_ambient=True),
            "sensor.estimate_offset: with sensor.channels and every image at the same "
            "exposure the one offset cannot be told from each channel's room light; expected "
            "estimate_offset false (the room light per channel) or images of different "
            "exposures",
        ),
    ],
)
def test_channel_refusals_name_the_key(tmp_path: Path, change, message) -> None:
    from tests.test_project import _error, folder

    root = folder.__wrapped__(tmp_path)
    doc = _channel_doc()
    change(doc)
    assert _error(root, doc) == f"{root / 'project.json'}: {message}"


def test_export_says_it_carries_the_first_channel(solved_files, tmp_path, capsys) -> None:
    _, out, _ = solved_files
    target = tmp_path / "light.yaml"
    assert main(["export", str(out), "--format", "opencv", "--out", str(target)]) == 0
    err = capsys.readouterr().err
    assert (
        "note: the result has colour channels R, G, B; the export carries the first's (R) "
        "scale and medium, as the result's lights and medium do"
    ) in " ".join(err.split())
    fs = cv2.FileStorage(str(target), cv2.FILE_STORAGE_READ)
    result = json.loads(out.read_text())
    c = fs.getNode("medium").getNode("attenuation_per_m").real()
    assert c == pytest.approx(result["channels"][0]["medium"]["attenuation_per_m"])
