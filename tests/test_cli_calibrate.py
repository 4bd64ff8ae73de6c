"""`lightcal calibrate`, `lightcal render` and `lightcal schema` end to end on a synth dataset."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import tifffile

from lightcal.cli.main import main
from lightcal.core.render import render_image
from lightcal.core.scene import Light, Rig
from lightcal.io.project import load_project
from lightcal.io.result_file import read_result
from lightcal.pipeline import load_images
from lightcal.pipeline.results import stop_reason
from lightcal.synthetic.dataset import SynthConfig, write_dataset
from lightcal.synthetic.scenes import SceneConfig
from tests import calib_scenes as cs

N_VIEWS = 6


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """A noisy 14-bit synth dataset: 6 views of 320 x 240, one cos^m light."""
    folder = tmp_path_factory.mktemp("cli") / "data"
    config = SynthConfig(camera=cs.small_camera(), scene=SceneConfig(n_views=N_VIEWS), seed=3)
    return write_dataset(folder, config)


def _project_copy(dataset, tmp_path: Path, **changes) -> Path:
    """The dataset's project.json copied into the dataset folder under a new name, changed."""
    doc = json.loads(dataset.project_path.read_text())
    for key, value in changes.items():
        doc.setdefault(key, {}).update(value)
    path = dataset.folder / f"project_{tmp_path.name}.json"
    path.write_text(json.dumps(doc))
    return path


def test_calibrate_with_report(dataset, tmp_path, capsys):
    out = tmp_path / "result.json"
    report = tmp_path / "report"
    code = main(
        ["calibrate", str(dataset.project_path), "--out", str(out), "--report", str(report)]
    )
    captured = capsys.readouterr()
    assert code == 0, captured.err
    result = read_result(out)
    assert result.converged
    assert result.project == str(dataset.project_path.resolve())
    assert len(result.images) == N_VIEWS
    truth = dataset.rig.lights[0]
    est = result.lights[0]
    assert np.linalg.norm(np.array(est.position_m) - truth.t_camera_light) < 0.01
    names = [f"view_{i:02d}" for i in range(N_VIEWS)]
    expected = {f"residual_{n}.png" for n in names} | {f"images_{n}.png" for n in names}
    expected |= {"convergence.png", "summary.md", "fit_vs_angle.png", "fit_causes.png"}
    assert {p.name for p in report.iterdir()} == expected
    for p in report.iterdir():
        assert p.stat().st_size > 0
    summary = (report / "summary.md").read_text()
    assert summary.startswith(f"# lightcal report: {dataset.project_path.name}")
    assert "## light (symmetric)" in summary
    reason = stop_reason(result.status, result.message)
    assert f"Solver converged after {result.iterations} iterations: {reason}; " in summary
    assert "termination condition" not in summary  # SciPy's words stay out of the report
    text = " ".join(captured.err.split())  # rich wraps long lines
    assert "iteration 0 cost" in text
    assert "(weights from the rendered values)" in text  # the noise model re-weights
    assert "start 1 of" not in text  # a single start
    # The command's answer on stdout (`> pose.txt` keeps it), its progress on stderr.
    answer = " ".join(captured.out.split())
    assert "light (symmetric): position " in answer and " mm (camera frame)" in answer
    assert "deg from the optical axis)" in answer and " ± " in answer
    assert "converged: " in answer and "result written to" in answer
    assert "iteration" not in answer and "position " not in text


def test_report_figures_on_threads_equal_the_serial_ones_with_progress(
    dataset, tmp_path, monkeypatch
):
    """write_report makes two images' figures at a time: the files are the one-thread
    files byte for byte, and progress counts the images as their figures are written."""
    from lightcal import report
    from lightcal.pipeline import build_model, calibrate

    project = load_project(dataset.project_path)
    loaded = load_images(project)
    cal = calibrate(project, loaded, build_model(project, loaded))
    calls: list[tuple[str, int, int]] = []
    threaded = report.write_report(
        tmp_path / "threads",
        project,
        loaded,
        cal.model,
        cal.result,
        progress=lambda stage, done, total: calls.append((stage, done, total)),
    )
    monkeypatch.setattr(report, "FIGURE_THREADS", 1)
    serial = report.write_report(tmp_path / "serial", project, loaded, cal.model, cal.result)
    assert [p.name for p in threaded] == [p.name for p in serial]
    for a, b in zip(threaded, serial, strict=True):
        assert a.read_bytes() == b.read_bytes(), a.name
    stages = [c for c in calls if c[0] == "writing figures"]
    assert stages == [("writing figures", i, N_VIEWS) for i in range(N_VIEWS + 1)]


def test_calibrate_quiet_prints_only_the_summary(dataset, tmp_path, capsys):
    out = tmp_path / "result.json"
    assert main(["calibrate", str(dataset.project_path), "--out", str(out), "--quiet"]) == 0
    said = capsys.readouterr()
    assert "iteration" not in said.err + said.out
    assert "converged" in said.out  # the answer, on stdout
    assert out.is_file()


def test_calibrate_stopped_by_max_iterations_exits_1(dataset, tmp_path, capsys):
    project = _project_copy(dataset, tmp_path, solver={"max_iterations": 1})
    out = tmp_path / "result.json"
    code = main(["calibrate", str(project), "--out", str(out), "--quiet"])
    answer = " ".join(capsys.readouterr().out.split())
    assert code == 1
    result = read_result(out)
    assert not result.converged
    assert result.status == 0 and result.iterations == 1
    assert result.message == "stopped after the maximum of 1 iterations"
    assert "not converged: stopped after the maximum of 1 iterations" in answer


def test_calibrate_reports_every_start(dataset, tmp_path, capsys):
    project = _project_copy(dataset, tmp_path, solver={"multistart": 1})
    assert main(["calibrate", str(project), "--out", str(tmp_path / "r.json")]) == 0
    text = " ".join(capsys.readouterr().err.split())
    first = text.index("start 1 of 2: the initial guess")
    second = text.index("start 2 of 2: a random start near it")
    assert first < text.index("iteration 0 cost", first) < second
    assert "iteration 0 cost" in text[second:]


def test_broken_project_exits_2_with_one_line(dataset, tmp_path, capsys):
    doc = json.loads(dataset.project_path.read_text())
    doc["images"][0]["foo"] = 1
    broken = tmp_path / "broken.json"
    broken.write_text(json.dumps(doc))
    out = tmp_path / "result.json"
    code = main(["calibrate", str(broken), "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 2
    assert captured.err == (
        f"lightcal calibrate: error: {broken}: images[0].foo: Extra inputs are not permitted\n"
    )
    assert not out.exists()
    code = main(["calibrate", str(tmp_path / "absent.json"), "--out", str(out)])
    assert code == 2
    assert capsys.readouterr().err == (
        f"lightcal calibrate: error: {tmp_path / 'absent.json'}: project file not found\n"
    )


def test_render_writes_the_calibrated_images(dataset, tmp_path, capsys):
    out = tmp_path / "result.json"
    assert main(["calibrate", str(dataset.project_path), "--out", str(out), "--quiet"]) == 0
    renders = tmp_path / "renders"
    code = main(["render", str(dataset.project_path), "--result", str(out), "--out", str(renders)])
    assert code == 0, capsys.readouterr().err
    names = [f"view_{i:02d}" for i in range(N_VIEWS)]
    assert {p.name for p in renders.iterdir()} == {f"{n}_rendered.tif" for n in names} | {
        f"{n}_compare.png" for n in names
    }
    result = read_result(out)
    lr = result.lights[0]
    light = Light(
        dataset.rig.lights[0].rid,
        np.array(lr.position_m),
        np.array(lr.R_camera_light),
        scale=lr.scale,
    )
    project = load_project(dataset.project_path)
    view = project.views[2]
    gain = result.images[2].gain
    expected = render_image(
        dataset.camera, cs.with_exposure(view, view.exposure * gain), Rig.single(light)
    )
    got = tifffile.imread(renders / "view_02_rendered.tif")
    assert got.dtype == np.float32 and got.shape == (dataset.camera.height, dataset.camera.width)
    np.testing.assert_allclose(got, expected.filled(np.nan).astype(np.float32), rtol=1e-6)
    # The render matches the photograph (black level subtracted on load) up to the noise.
    photo = load_images(project).images[2].values
    lit = got > 0.3 * np.nanmax(got)
    assert lit.sum() > 1000
    assert np.median(np.abs(photo[lit] - got[lit]) / got[lit]) < 0.03


def test_render_needs_a_result_for_every_light(dataset, tmp_path, capsys):
    out = tmp_path / "result.json"
    assert main(["calibrate", str(dataset.project_path), "--out", str(out), "--quiet"]) == 0
    data = json.loads(out.read_text())
    data["lights"][0]["name"] = "other"
    out.write_text(json.dumps(data))
    capsys.readouterr()
    code = main(["render", str(dataset.project_path), "--result", str(out), "--out", str(tmp_path)])
    assert code == 2
    assert capsys.readouterr().err == (
        f"lightcal render: error: {out}: no result for light 'light'\n"
    )


@pytest.mark.parametrize(("which", "title"), [([], "project"), (["result"], "result")])
def test_schema_prints_json_schema(which, title, capsys):
    assert main(["schema", *which]) == 0
    schema = json.loads(capsys.readouterr().out)
    assert schema["title"] == f"lightcal {title} (version 1)"
    assert schema["type"] == "object" and "$defs" in schema


def test_console_script_runs(tmp_path):
    exe = shutil.which("lightcal", path=str(Path(sys.executable).parent))
    cmd = [exe] if exe else [sys.executable, "-m", "lightcal"]
    proc = subprocess.run(
        [*cmd, "schema", "result"], capture_output=True, text=True, timeout=120, check=False
    )
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["title"] == "lightcal result (version 1)"
    proc = subprocess.run(
        [*cmd, "calibrate", str(tmp_path / "none.yaml"), "--out", str(tmp_path / "r.json")],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert proc.returncode == 2
    assert proc.stderr == (
        f"lightcal calibrate: error: {tmp_path / 'none.yaml'}: project file not found\n"
    )


def test_a_large_calibration_says_where_its_iterations_began(
    dataset, tmp_path, capsys, monkeypatch
):
    import importlib

    solve_module = importlib.import_module("lightcal.pipeline.solve")
    monkeypatch.setattr(solve_module, "COARSE_MIN_PIXELS", 1000)  # "large": 1000 pixels
    monkeypatch.setattr(solve_module, "COARSE_PIXELS", 300)
    project = _project_copy(dataset, tmp_path, selection={"strategy": "all", "binning": 4})
    out, report = tmp_path / "result.json", tmp_path / "report"
    code = main(["calibrate", str(project), "--out", str(out), "--report", str(report)])
    captured = capsys.readouterr()
    assert code in (0, 3), captured.err  # 3: the fit test's verdict, not the solve's
    result = read_result(out)
    assert result.converged
    text = " ".join(captured.err.split())  # the console's progress lines
    k = int(text.split("a first solve on one pixel in ")[1].split(" ")[0])
    assert text.index("a first solve on one pixel in") < text.index("iteration 0 cost")
    assert k >= 2 and result.start.startswith(f"the estimate of a first solve on one pixel in {k} ")
    summary = (report / "summary.md").read_text()
    assert f"Iteration 0 is {result.start} (its iterations are the grey curve)." in summary
