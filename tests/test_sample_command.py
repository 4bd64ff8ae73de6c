"""`lightcal sample PATH` and where the bundled data is found (`lightcal.resources`)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from lightcal import resources
from lightcal.cli.main import main
from lightcal.errors import InputError

REPO = Path(__file__).resolve().parents[1]


def tracked_files(folder: str) -> list[Path]:
    """The files git tracks under the repository's `folder`, relative to it."""
    out = subprocess.run(
        ["git", "ls-files", folder], cwd=REPO, capture_output=True, text=True, check=True
    ).stdout.split()
    return sorted(Path(name).relative_to(folder) for name in out)


def test_checkout_finds_the_top_level_folders() -> None:
    assert resources.sample_project_dir() == REPO / "sample_data"
    assert not resources.sample_project_is_packaged()
    assert resources.data_folder("lightcal_app", "static") == REPO / "static"
    assert (resources.sample_project_dir() / "project.json").is_file()


def test_sample_files_are_the_tracked_files_without_what_use_adds(tmp_path: Path) -> None:
    src = tmp_path / "src"
    shutil.copytree(REPO / "sample_data", src, ignore=shutil.ignore_patterns("__pycache__"))
    (src / "project.session.json").write_text("{}")
    (src / "project.session.json.bad").write_text("{}")
    (src / "__pycache__").mkdir()
    (src / "__pycache__" / "make_sample_data.cpython-311.pyc").write_bytes(b"")
    (src / ".hidden").write_text("")
    assert resources.sample_files(src) == tracked_files("sample_data")


def test_sample_writes_a_new_folder_and_says_what_next(tmp_path: Path, capsys) -> None:
    dest = tmp_path / "a" / "sample"
    assert main(["sample", str(dest)]) == 0
    out = capsys.readouterr().out
    names = tracked_files("sample_data")
    assert resources.sample_files(dest) == names
    for rel in names:
        assert (dest / rel).read_bytes() == (REPO / "sample_data" / rel).read_bytes(), rel
    assert f"wrote {len(names)} files to {dest}" in out
    assert f"lightcal calibrate {dest / 'project.json'} --out result.json" in out
    assert f"lightcal app {dest / 'project.json'}" in out
    assert [p.name for p in dest.parent.iterdir()] == ["sample"]  # no temporary folder left


def test_sample_refuses_a_non_empty_folder_and_force_never_overwrites(
    tmp_path: Path, capsys
) -> None:
    dest = tmp_path / "s"
    dest.mkdir()
    (dest / "camera.yaml").write_text("mine")
    assert main(["sample", str(dest)]) == 2
    assert "not empty" in capsys.readouterr().err
    assert [p.name for p in dest.iterdir()] == ["camera.yaml"]

    assert main(["sample", str(dest), "--force"]) == 0
    out = capsys.readouterr().out
    assert (dest / "camera.yaml").read_text() == "mine"
    assert "kept 1 file as they were: camera.yaml" in out
    (dest / "images" / "view_03.png").unlink()
    copy = resources.write_sample_project(dest, force=True)
    assert copy.written == (Path("images/view_03.png"),)
    assert len(copy.kept) == len(tracked_files("sample_data")) - 1

    (tmp_path / "f").write_text("")
    with pytest.raises(InputError, match="not a folder"):
        resources.write_sample_project(tmp_path / "f", force=True)


def test_sample_into_an_empty_folder(tmp_path: Path) -> None:
    (tmp_path / "e").mkdir()
    copy = resources.write_sample_project(tmp_path / "e")
    assert copy.kept == () and len(copy.written) == len(tracked_files("sample_data"))


def test_an_interrupted_sample_leaves_nothing(tmp_path: Path, monkeypatch) -> None:
    calls = []

    def failing_copy(src: Path, dst: Path) -> None:
        calls.append(src)
        if len(calls) == 5:
            raise OSError("disk full")
        shutil.copyfile(src, dst)

    monkeypatch.setattr(resources.shutil, "copyfile", failing_copy)
    with pytest.raises(OSError, match="disk full"):
        resources.write_sample_project(tmp_path / "s")
    assert list(tmp_path.iterdir()) == []


def test_installed_app_opens_a_copy_of_the_sample_in_the_user_folder(
    tmp_path: Path, monkeypatch, capsys
) -> None:
    from lightcal.cli.app import sample_project_for_app

    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    assert sample_project_for_app() == REPO / "sample_data" / "project.json"  # checkout

    monkeypatch.setattr(resources, "sample_project_is_packaged", lambda: True)
    path = sample_project_for_app()
    assert path == resources.user_sample_dir() / "project.json"
    assert path.is_relative_to(tmp_path / "data" / "lightcal")
    assert resources.sample_files(path.parent) == tracked_files("sample_data")
    assert f"copied the sample project to {path.parent}" in capsys.readouterr().out
    (path.parent / "project.json").write_text("edited")
    assert sample_project_for_app() == path  # the copy is reused, never overwritten
    assert path.read_text() == "edited"
    assert capsys.readouterr().out == ""
