"""The report folder (issue 28): one run's complete report at a time, never a mix of two
runs, never half of one, and nothing else of the user's in the folder touched."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

from lightcal import report
from lightcal.cli.main import main
from lightcal.errors import InputError
from lightcal.io import atomic
from lightcal.io.atomic import LOCK_NAME
from lightcal.io.project import Project, load_project
from lightcal.pipeline import CalibrationResult, LoadedImages, build_model, calibrate, load_images

REPO = Path(__file__).resolve().parents[1]
FIXED = {"convergence.png", "fit_vs_angle.png", "fit_causes.png", "summary.md"}


@dataclass(frozen=True)
class Run:
    """One calibrated project, ready for `write_report`."""

    project: Project
    loaded: LoadedImages
    model: object
    result: CalibrationResult
    files: frozenset[str]  # the names of its report's files

    def write(self, folder: Path, **kwargs: object) -> list[Path]:
        return report.write_report(
            folder,
            self.project,
            self.loaded,
            self.model,  # type: ignore[arg-type]
            self.result,
            **kwargs,  # type: ignore[arg-type]
        )


def _calibrated(project_path: Path) -> Run:
    project = load_project(project_path)
    loaded = load_images(project)
    cal = calibrate(project, loaded, build_model(project, loaded))
    names = project.names
    files = {f"residual_{n}.png" for n in names} | {f"images_{n}.png" for n in names}
    fixed = FIXED if cal.result.fit else {"convergence.png", "summary.md"}
    return Run(project, loaded, cal.model, cal.result, frozenset(files | fixed))


@pytest.fixture(scope="module")
def runs(tiny_dataset: Path) -> tuple[Run, Run]:
    """Two calibrations whose reports have different files: the tiny dataset, and a copy
    of it with its images renamed (`B_view_00`, ...)."""
    doc = json.loads((tiny_dataset / "project.json").read_text())
    for image in doc["images"]:
        image["name"] = f"B_{image['name']}"
    other = tiny_dataset / "project_b.json"
    other.write_text(json.dumps(doc))
    try:
        return _calibrated(tiny_dataset / "project.json"), _calibrated(other)
    finally:
        other.unlink()


def _hidden(folder: Path) -> list[str]:
    """Hidden or temporary entries anywhere under `folder` (staging folders, locks)."""
    return sorted(
        str(p.relative_to(folder))
        for p in folder.rglob("*")
        if p.name.startswith(".") or p.suffix == ".tmp"
    )


def _names(folder: Path) -> set[str]:
    return {p.name for p in folder.iterdir()}


def _listed(folder: Path) -> set[str]:
    """The files the folder's summary.md lists as its report's."""
    return report._report_files(folder)


def test_a_new_folder_appears_complete_and_lists_its_files(
    runs: tuple[Run, Run], tmp_path: Path
) -> None:
    a, _ = runs
    folder = tmp_path / "sub" / "report"
    written = a.write(folder)
    assert {p.name for p in written} == a.files
    assert all(p.parent == folder and p.stat().st_size > 0 for p in written)
    assert _names(folder) == a.files == _listed(folder)
    summary = (folder / "summary.md").read_text()
    assert summary.startswith("# lightcal report: project.json")
    assert summary.endswith("summary.md\n-->\n")
    assert _hidden(tmp_path) == []


def test_the_next_report_replaces_the_earlier_one_and_keeps_the_users_files(
    runs: tuple[Run, Run], tmp_path: Path
) -> None:
    a, b = runs
    folder = tmp_path / "report"
    a.write(folder)
    mine = {"notes.txt": "the user's", "residual_mine.png": "a name like a report's"}
    for name, text in mine.items():
        (folder / name).write_text(text)
    (folder / "sub").mkdir()
    b.write(folder)
    assert _names(folder) == b.files | set(mine) | {"sub"}  # none of a's files is left
    assert _listed(folder) == b.files
    for name, text in mine.items():
        assert (folder / name).read_text() == text
    a.write(folder)  # and back: b's files go
    assert _names(folder) == a.files | set(mine) | {"sub"}
    assert _hidden(tmp_path) == []


def test_a_summary_cannot_make_lightcal_remove_other_files(
    runs: tuple[Run, Run], tmp_path: Path
) -> None:
    """Only names a report's file can have are taken from an earlier summary's list."""
    a, b = runs
    folder = tmp_path / "report"
    a.write(folder)
    summary = folder / "summary.md"
    listed = "notes.txt\n../outside.png\n.hidden\nresidual_view_00.png\n-->"
    summary.write_text(summary.read_text().replace("-->", listed))
    for name in ("notes.txt", ".hidden"):
        (folder / name).write_text("kept")
    (tmp_path / "outside.png").write_text("kept")
    b.write(folder)
    assert _names(folder) == b.files | {"notes.txt", ".hidden"}
    assert (tmp_path / "outside.png").read_text() == "kept"


def test_a_run_whose_folder_appears_meanwhile_leaves_its_own_complete_report(
    runs: tuple[Run, Run], tmp_path: Path
) -> None:
    """Run a's report is renamed into place while run b writes its own aside (b's
    progress callback writes it): b then moves its files in under the lock and removes
    a's. The folder holds b's report only."""
    a, b = runs
    folder = tmp_path / "report"

    def progress(stage: str, done: int, total: int) -> None:
        if stage == "writing figures" and done == total:
            a.write(folder)
            assert _names(folder) == a.files

    b.write(folder, progress=progress)
    assert _names(folder) == b.files == _listed(folder)
    assert _hidden(tmp_path) == []


def test_a_folder_appearing_just_before_the_rename_is_joined(
    runs: tuple[Run, Run], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The folder did not exist when looked at, and another run's report was renamed
    into place just before this one's rename (which then fails): this run moves its
    files in under the lock instead."""
    a, b = runs
    folder = tmp_path / "report"
    a.write(folder)
    real_lexists = os.path.lexists
    looked: list[object] = []

    def lexists_once_false(path: object) -> bool:
        if Path(path) == folder and not looked:  # type: ignore[arg-type]
            looked.append(path)
            return False
        return real_lexists(path)  # type: ignore[arg-type]

    monkeypatch.setattr(atomic.os.path, "lexists", lexists_once_false)
    b.write(folder)
    assert looked
    assert _names(folder) == b.files == _listed(folder)
    assert _hidden(tmp_path) == []


def test_a_writer_waits_for_the_lock_then_writes(
    runs: tuple[Run, Run], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    a, b = runs
    folder = tmp_path / "report"
    a.write(folder)
    lock = folder / LOCK_NAME
    lock.write_text(f"pid {os.getppid()}\nsummary.md\n")  # a live process: the lock holds
    monkeypatch.setattr(atomic, "LOCK_WAIT_S", 30.0)
    released = threading.Timer(0.3, lock.unlink)
    released.start()
    started = time.monotonic()
    try:
        b.write(folder)
    finally:
        released.cancel()
    assert time.monotonic() - started >= 0.3
    assert _names(folder) == b.files
    assert _hidden(tmp_path) == []


def test_a_lock_held_too_long_fails_with_the_process_named_and_changes_nothing(
    runs: tuple[Run, Run], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    a, b = runs
    folder = tmp_path / "report"
    a.write(folder)
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    holder = os.getppid()
    (folder / LOCK_NAME).write_text(f"pid {holder}\n")
    monkeypatch.setattr(atomic, "LOCK_WAIT_S", 0.2)
    with pytest.raises(InputError) as caught:
        b.write(folder)
    assert str(caught.value) == (
        f"{folder / LOCK_NAME}: another lightcal run (process {holder}) is writing into "
        f"{folder}; wait for it to end, or remove this lock file if no such run is going on"
    )
    assert {p.name: p.read_bytes() for p in folder.iterdir() if p.name != LOCK_NAME} == before
    assert _hidden(tmp_path) == [f"report/{LOCK_NAME}"]  # the other run's, untouched


def test_calibrate_says_which_run_holds_the_report_folder(
    tiny_dataset: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """The CLI: one line naming the other process, exit 2; the result is written (it
    comes before the report)."""
    folder = tmp_path / "report"
    folder.mkdir()
    (folder / LOCK_NAME).write_text(f"pid {os.getppid()}\n")
    monkeypatch.setattr(atomic, "LOCK_WAIT_S", 0.2)
    out = tmp_path / "result.json"
    argv = ["calibrate", str(tiny_dataset / "project.json"), "--out", str(out), "--quiet"]
    code = main([*argv, "--report", str(folder), "--force"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.splitlines()[-1] == (
        f"lightcal calibrate: error: {folder / LOCK_NAME}: another lightcal run (process "
        f"{os.getppid()}) is writing into {folder}; wait for it to end, or remove this lock "
        "file if no such run is going on"
    )
    assert json.loads(out.read_text())["lights"]
    assert _names(folder) == {LOCK_NAME}


def test_a_lock_left_by_a_dead_run_is_taken_over_with_its_files(
    runs: tuple[Run, Run], tmp_path: Path
) -> None:
    """A run killed while moving its files in left its lock and some files: the next run
    takes the lock over and removes the files the dead run listed in it."""
    a, b = runs
    folder = tmp_path / "report"
    a.write(folder)
    dead = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        check=True,
        capture_output=True,
        text=True,
    )
    pid = int(dead.stdout)
    (folder / "residual_C_view_00.png").write_bytes(b"half of a dead run's report")
    (folder / LOCK_NAME).write_text(f"pid {pid}\nresidual_C_view_00.png\nsummary.md\n")
    b.write(folder)
    assert _names(folder) == b.files
    assert _hidden(tmp_path) == []


def test_an_interrupted_report_leaves_nothing_new_and_the_earlier_report_whole(
    runs: tuple[Run, Run], tmp_path: Path
) -> None:
    a, b = runs

    def interrupt(stage: str, done: int, total: int) -> None:
        if stage == "writing figures" and done == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        a.write(tmp_path / "new", progress=interrupt)
    assert list(tmp_path.iterdir()) == []
    folder = tmp_path / "report"
    a.write(folder)
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    with pytest.raises(KeyboardInterrupt):
        b.write(folder, progress=interrupt)
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    assert _hidden(tmp_path) == []


def _project_named(tiny_dataset: Path, tmp_path: Path, prefix: str) -> Path:
    """A copy of the tiny project (in its folder) whose images are named `prefix`view_NN."""
    doc = json.loads((tiny_dataset / "project.json").read_text())
    for image in doc["images"]:
        image["name"] = f"{prefix}{image['name']}"
    path = tiny_dataset / f"project_{prefix}{tmp_path.name}.json"
    path.write_text(json.dumps(doc))
    return path


def test_two_real_runs_on_one_report_folder_leave_one_complete_report(
    tiny_dataset: Path, tmp_path: Path
) -> None:
    """Two `lightcal calibrate` processes started together with the same --report: both
    succeed and the folder holds exactly the files of one of them, as its summary lists."""
    projects = [_project_named(tiny_dataset, tmp_path, p) for p in ("A_", "B_")]
    folder = tmp_path / "report"
    try:
        procs = [
            subprocess.Popen(
                [
                    sys.executable,
                    "-m",
                    "lightcal",
                    "calibrate",
                    str(project),
                    "--quiet",
                    "--out",
                    str(tmp_path / f"{project.stem}.json"),
                    "--report",
                    str(folder),
                ],
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
                cwd=REPO,
            )
            for project in projects
        ]
        outcomes = [p.communicate(timeout=300) for p in procs]
    finally:
        for project in projects:
            project.unlink()
    for proc, (_, err) in zip(procs, outcomes, strict=True):
        assert proc.returncode == 0, err
        assert "report written to" in err
    expected = [
        {f"{kind}_{prefix}view_{i:02d}.png" for kind in ("residual", "images") for i in range(4)}
        for prefix in ("A_", "B_")
    ]
    names = _names(folder)
    assert names - FIXED in expected
    assert names == _listed(folder)
    assert _hidden(tmp_path) == []
