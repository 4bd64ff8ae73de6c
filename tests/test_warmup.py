"""The kernel warm-up: it compiles what the commands use, and says so when it runs."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import lightcal.warmup as warmup
from lightcal.cli import progress as cli_progress
from lightcal.cli.main import main

REPO = Path(__file__).resolve().parents[1]

# After warm_up, run the sample's calibration (as given, and dense with binning) and its
# report in the same process and list every kernel signature compiled after the warm-up.
_COVERAGE_SCRIPT = textwrap.dedent(
    """
    import json, shutil, sys, tempfile
    from pathlib import Path
    import lightcal.warmup as W
    tmp = Path(tempfile.mkdtemp())
    W._marker_path = lambda: tmp / "marker.json"
    W.warm_up()
    def snapshot():
        return {k: set(map(str, d.signatures)) for k, d in W._dispatchers().items()}
    before = snapshot()
    from lightcal.io.project import load_project
    from lightcal.pipeline import build_model, calibrate, load_images
    from lightcal.report import write_report
    sample = tmp / "sample"
    shutil.copytree(sys.argv[1], sample)
    for i, selection in enumerate([None, {"strategy": "all", "binning": 8}]):
        if selection is not None:
            src = json.loads((sample / "project.json").read_text())
            src["selection"] = selection
            (sample / "project.json").write_text(json.dumps(src))
        project = load_project(sample / "project.json")
        loaded = load_images(project)
        model = build_model(project, loaded)
        cal = calibrate(project, loaded, model)
        write_report(tmp / f"report{i}", project, loaded, cal.model, cal.result)
    after = snapshot()
    print(json.dumps(sorted(k for k in after if after[k] - before.get(k, set()))))
    """
)


def test_warm_up_compiles_every_kernel_the_sample_calibration_and_report_use() -> None:
    out = subprocess.run(
        [sys.executable, "-c", _COVERAGE_SCRIPT, str(REPO / "sample_data")],
        capture_output=True,
        text=True,
        check=True,
        cwd=REPO,
    )
    new = json.loads(out.stdout.strip().splitlines()[-1])
    assert new == [], f"compiled after the warm-up: {new}"


@pytest.fixture
def marker(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    path = tmp_path / "lightcal-warmup.json"
    monkeypatch.setattr(warmup, "_marker_path", lambda: path)
    return path


def test_kernels_ready_reads_the_marker_and_numbas_cache(marker: Path) -> None:
    from lightcal.core.camera import Camera
    from lightcal.core.render import render_image
    from lightcal.core.rid import CosPowerRID
    from lightcal.core.scene import Light, Rig, View

    camera = Camera.from_params(fx=30.0, fy=30.0, cx=7.5, cy=5.5, width=16, height=12)
    view = View.looking_at(np.array([0.0, 0.0, 1.0]), np.zeros(3))
    light = Light(CosPowerRID(2.0), np.array([0.1, 0.0, 0.0]), np.eye(3), scale=1.0)
    render_image(camera, view, Rig.single(light))  # the fused kernel is in the cache now

    assert not warmup.kernels_ready()  # no marker: never warmed up
    marker.write_text("{not json", encoding="utf-8")
    assert not warmup.kernels_ready()
    sources = warmup.sources_digest()
    fused = ["lightcal.core.kernels.image:render_image_fused"]
    marker.write_text(json.dumps({"sources": sources, "kernels": fused}), encoding="utf-8")
    assert warmup.kernels_ready()
    marker.write_text(
        json.dumps({"sources": sources, "kernels": ["lightcal.core.kernels.image:no_such_kernel"]}),
        encoding="utf-8",
    )
    assert not warmup.kernels_ready()  # renamed since: warm up again
    # Compiled from other sources (a helper edited in another file: numba would not see it).
    marker.write_text(json.dumps({"sources": "0" * 16, "kernels": fused}), encoding="utf-8")
    assert not warmup.kernels_ready()
    marker.write_text(json.dumps({"kernels": fused}), encoding="utf-8")  # before the digest
    assert not warmup.kernels_ready()


def test_sources_digest_follows_every_core_module(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import shutil

    package = tmp_path / "lightcal"
    shutil.copytree(
        REPO / "lightcal" / "core", package / "core", ignore=shutil.ignore_patterns("__pycache__")
    )
    shutil.copy(REPO / "lightcal" / "warmup.py", package / "warmup.py")
    monkeypatch.setattr(warmup, "__file__", str(package / "warmup.py"))
    before = warmup.sources_digest()
    assert before == warmup.sources_digest()
    helper = package / "core" / "rid_grid.py"
    helper.write_text(helper.read_text(encoding="utf-8") + "\n# edited\n", encoding="utf-8")
    assert warmup.sources_digest() != before


_STALE_MODULE = textwrap.dedent(
    """
    import numba

    @numba.njit(cache=True)
    def twice(x):
        return 2.0 * x
    """
)


def test_warm_up_flushes_the_cache_of_kernels_compiled_from_other_sources(
    tmp_path: Path, marker: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "stale_kernels_mod.py").write_text(_STALE_MODULE, encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    import importlib

    module = importlib.import_module("stale_kernels_mod")
    assert module.twice(2.0) == 4.0
    assert warmup._cached(module.twice)  # in numba's cache on disk
    listed = {"kernels": ["stale_kernels_mod:twice"]}
    marker.write_text(json.dumps({"sources": warmup.sources_digest(), **listed}), "utf-8")
    warmup._flush_stale_kernels(warmup.sources_digest())
    assert warmup._cached(module.twice)  # same sources: kept
    marker.write_text(json.dumps({"sources": "0" * 16, **listed}), "utf-8")
    warmup._flush_stale_kernels(warmup.sources_digest())
    assert not warmup._cached(module.twice)  # other sources: flushed
    marker.unlink()
    # No marker (a fresh install): nothing to flush.
    warmup._flush_stale_kernels(warmup.sources_digest())


def test_ensure_kernels_says_what_it_compiles(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    calls: list[tuple[str, int, int]] = []

    def fake_warm_up(progress=None) -> float:  # the real one is tested above
        for i, label in enumerate(("sparse pixels", "wall models")):
            calls.append((label, i, 2))
            progress(label, i, 2)
        progress("done", 2, 2)
        return 83.4

    monkeypatch.setattr(warmup, "kernels_ready", lambda: False)
    monkeypatch.setattr(warmup, "warm_up", fake_warm_up)
    cli_progress.ensure_kernels()
    err = capsys.readouterr().err
    assert err.splitlines() == [
        "compiling the numba kernels (once per install; `lightcal warmup` does it ahead)",
        "compiling kernels 1/2: sparse pixels",
        "compiling kernels 2/2: wall models",
        "kernels compiled in 83 s (cached from now on)",
    ]
    assert len(calls) == 2


def test_ensure_kernels_is_silent_when_cached(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def fail(progress=None) -> float:
        raise AssertionError("warm_up must not run when the kernels are cached")

    monkeypatch.setattr(warmup, "kernels_ready", lambda: True)
    monkeypatch.setattr(warmup, "warm_up", fail)
    cli_progress.ensure_kernels()
    assert main(["warmup"]) == 0
    assert capsys.readouterr().err.splitlines() == ["kernels already compiled and cached"]


TWO_FAMILIES = (
    warmup.Family("sparse", size=(32, 24)),
    warmup.Family("isotropic", size=(32, 24), light_model="isotropic"),
)


def test_warm_up_in_two_processes_reports_both_families_then_done(
    marker: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Two worker processes compile the shared kernels, then take the families side by
    side (the progress names both); then this process runs them again from the cache and
    writes the marker."""
    monkeypatch.setattr(warmup, "FAMILIES", TWO_FAMILIES)
    seen_in_process: list[str] = []
    run_family = warmup._run_family

    def counting(family: warmup.Family, folder: Path) -> int:
        seen_in_process.append(family.label)
        return run_family(family, folder)

    monkeypatch.setattr(warmup, "_run_family", counting)  # the workers use the real one
    calls: list[tuple[str, int, int]] = []
    warmup.warm_up(lambda *a: calls.append(a), jobs=2)
    # The kernels every family shares, then the families side by side; every line
    # says how many kernels the workers have compiled so far (it moves every few s).
    labels = [c[0] for c in calls]
    assert labels[0] == f"{warmup.SHARED_LABEL} (0 kernels compiled so far)"
    families = [k for k, label in enumerate(labels) if label.startswith("sparse + isotropic")]
    assert families and all(c[1] == 0 for c in calls[: families[0]])
    assert all(label.startswith(warmup.SHARED_LABEL) for label in labels[: families[0]])
    counts = [int(re.search(r"\((\d+) kernels? compiled so far\)", lb)[1]) for lb in labels[:-1]]
    assert counts == sorted(counts)  # (0 here: the kernels are cached already)
    assert ("sparse", 0, 2) not in calls  # the workers ran: no in-process fallback
    assert calls[-1] == ("done", 2, 2)
    assert [c[1] for c in calls] == sorted(c[1] for c in calls)  # done only grows
    assert seen_in_process == ["sparse", "isotropic"]  # the in-process pass, from the cache
    assert (
        "lightcal.core.kernels.image:render_image_fused"
        in json.loads(marker.read_text())["kernels"]
    )


def test_warm_up_compiles_in_process_when_workers_cannot_start(
    marker: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import multiprocessing

    def no_processes(method: str) -> None:
        raise OSError("no /dev/shm here")

    monkeypatch.setattr(warmup, "FAMILIES", TWO_FAMILIES)
    monkeypatch.setattr(multiprocessing, "get_context", no_processes)
    calls: list[tuple[str, int, int]] = []
    warmup.warm_up(lambda *a: calls.append(a), jobs=2)
    assert calls == [("sparse", 0, 2), ("isotropic", 1, 2), ("done", 2, 2)]
    assert marker.is_file()


def test_default_jobs_is_one_per_core_at_most_two(monkeypatch: pytest.MonkeyPatch) -> None:
    import os

    for cores, jobs in ((1, 1), (2, 2), (16, 2)):
        monkeypatch.setattr(os, "sched_getaffinity", lambda pid, n=cores: set(range(n)))
        assert warmup.default_jobs() == jobs


_INTERRUPTED_SCRIPT = textwrap.dedent(
    """
    import lightcal.warmup as W
    if __name__ == "__main__":
        W.warm_up(lambda family, done, total: print("compiling", flush=True), jobs=2)
    """
)


@pytest.mark.skipif(sys.platform != "linux", reason="reads the process table with ps")
def test_an_interrupted_warm_up_leaves_no_compiling_workers(tmp_path: Path) -> None:
    """A SIGINT sent to the warm-up's process alone (a supervisor, a test harness; a
    terminal's Ctrl-C reaches the whole group) ends it at once and its worker processes
    with it; they used to compile on for minutes, orphaned."""
    import os
    import signal
    import time

    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))  # a cold cache: busy
    proc = subprocess.Popen(
        [sys.executable, "-c", _INTERRUPTED_SCRIPT],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )

    def workers() -> list[str]:
        table = subprocess.run(["ps", "-eo", "ppid,args"], capture_output=True, text=True)
        return [
            line
            for line in table.stdout.splitlines()
            if line.split(None, 1)[0] == str(proc.pid) and "multiprocessing.spawn" in line
        ]

    try:
        assert proc.stdout is not None and proc.stdout.readline().startswith("compiling")
        deadline = time.monotonic() + 60
        while not workers() and time.monotonic() < deadline:
            time.sleep(0.2)
        assert workers(), "the warm-up started no worker processes"
        spawned = subprocess.run(["pgrep", "-P", str(proc.pid)], capture_output=True, text=True)
        children = [int(p) for p in spawned.stdout.split()]
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=30) != 0  # ended by the interrupt, not after the compile
        time.sleep(1.0)
        alive = []
        for pid in children:
            try:
                os.kill(pid, 0)
                state = Path(f"/proc/{pid}/stat").read_text().split()[2]
                if state != "Z":
                    alive.append(pid)
            except (ProcessLookupError, FileNotFoundError):
                pass
        assert alive == [], f"worker processes still running: {alive}"
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_the_kernel_counter_counts_what_the_workers_cached_since_it_started(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The progress line's count: kernels found in numba's cache that were not there when
    the counter was made (the workers write the cache; the parent reads its index)."""
    cached: set[int] = set()
    monkeypatch.setattr(warmup, "_cached", lambda d: id(d) in cached)
    counter = warmup.KernelCounter()
    kernels = counter.dispatchers
    assert len(kernels) > 20  # every kernel of lightcal.core, imported (none compiled)
    assert counter.text() == "0 kernels compiled so far"
    cached.add(id(kernels[0]))
    assert counter.text() == "1 kernel compiled so far"
    cached.update(id(k) for k in kernels[1:5])
    assert counter.text() == "5 kernels compiled so far"


def test_a_family_calibrates_on_a_wall_given_as_a_mesh(tmp_path: Path) -> None:
    """The ray-mesh intersection kernels are compiled by `lightcal warmup` too: one family
    declares its wall as a mesh file, and its calibration runs through them."""
    from lightcal.core import mesh_kernels

    (family,) = [f for f in warmup.FAMILIES if (f.synth or {}).get("declare_wall_mesh")]
    project = warmup._write_dataset(tmp_path / "data", family)
    mesh = json.loads(project.read_text())["wall"]["mesh"]
    assert (project.parent / mesh).is_file()
    warmup._calibrate(project, None)
    assert mesh_kernels.intersect_rays.signatures and mesh_kernels.bucket_rays.signatures


def test_a_family_calibrates_a_light_behind_a_flat_port(tmp_path: Path) -> None:
    """`lightcal warmup` compiles the light's port kernels: one family's light shines
    through a declared port, in water that scatters (its veil), every pixel (the
    parallel twins) and a report."""
    from lightcal.core.kernels import port_flux, port_veil, port_water

    (family,) = [f for f in warmup.FAMILIES if (f.synth or {}).get("declare_light_port")]
    project = warmup._write_dataset(tmp_path / "data", family)
    assert json.loads(project.read_text())["lights"][0]["port"]["distance_mm"] == 15.0
    warmup._calibrate(project, tmp_path / "report")  # the family's report: whole images
    assert port_flux._pixels_parallel.signatures and port_water._attenuate_parallel.signatures
    assert port_veil._rays_parallel.signatures and port_veil._rays_serial.signatures


def test_a_family_calibrates_behind_a_camera_port_and_renders_through_it(tmp_path: Path) -> None:
    """`lightcal warmup` compiles the whole image through the camera's port (the fused
    kernel the report and the page's overlays run): one family's camera looks through a
    declared port and writes its report."""
    from lightcal.core.kernels import port_image

    (family,) = [f for f in warmup.FAMILIES if (f.synth or {}).get("declare_port")]
    project = warmup._write_dataset(tmp_path / "data", family)
    assert json.loads(project.read_text())["camera"]["port"]["distance_mm"] == 20.0
    warmup._calibrate(project, tmp_path / "report")
    assert port_image.render_image_port_fused.signatures
