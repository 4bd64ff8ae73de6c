"""The wheel works away from the repository: build it, install it into a fresh venv, then
`lightcal --version`, `lightcal sample`, `lightcal calibrate` on the sample and
`lightcal app` without a project (the packaged sample, its pictures) run there.

How the venv gets its dependencies without the repository. The wheel is installed with
`--no-deps` into a new venv (no `--system-site-packages`). Then, so that pip never sees
(or offers to uninstall) the developer's own install, its third-party dependencies are
added: the running interpreter's site-packages, named as plain paths in a `.pth` file of
the new venv. Python's `site` runs the `.pth` files of site directories only, so the
`.pth` files inside those added paths are never executed; among them is the editable
install's `__editable__.lightcal-*.pth`, whose finder would map `lightcal` to the
repository. The new venv's own site-packages (holding the wheel) also comes first on
`sys.path`. Every command runs from a temporary folder with PYTHONPATH removed, and the
test checks from inside the venv that `lightcal` and `lightcal_app` are the installed
copies, that no `sys.path` entry lies in the repository and that no editable finder is
active.

The wheel is built with plain `pip wheel --no-deps` from a copy of the files git knows
(tracked or new, not ignored), so the checkout gets no build/ folder and no stale file
of an earlier build/ can leak into the wheel. The installed copy compiles its numba
kernels on first use (NUMBA_CACHE_DIR is a temporary folder): most of this test's
minute or two is that compile, hence `slow`.
"""

from __future__ import annotations

import json
import os
import queue
import re
import signal
import site
import subprocess
import sys
import tarfile
import threading
import urllib.request
import zipfile
from collections.abc import Iterable
from pathlib import Path

import pytest

from lightcal import __version__

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[1]
MAX_POSITION_ERROR_M = 5e-3


def git_files(*args: str) -> list[str]:
    out = subprocess.run(
        ["git", *args], cwd=REPO, capture_output=True, text=True, check=True
    ).stdout
    return [name for name in out.split("\0" if "-z" in args else "\n") if name]


def copy_source(dest: Path) -> None:
    """The files git knows (tracked or new, not ignored) copied to `dest`."""
    names = git_files("ls-files", "-z", "--cached", "--others", "--exclude-standard")
    dest.mkdir()
    archive = dest.parent / "source.tar"
    with tarfile.open(archive, "w") as tar:
        for name in names:
            if (REPO / name).is_file():
                tar.add(REPO / name, arcname=name)
    with tarfile.open(archive) as tar:
        tar.extractall(dest, filter="data")
    archive.unlink()


def clean_env() -> dict[str, str]:
    """This environment without PYTHONPATH / PYTHONHOME (which name the repository)."""
    return {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("wheel")
    copy_source(root / "src")
    pip_wheel = [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q"]
    subprocess.run(
        [*pip_wheel, "-w", str(root / "dist"), str(root / "src")], env=clean_env(), check=True
    )
    (path,) = (root / "dist").glob("lightcal-*.whl")
    return path


def tracked(folder: str) -> set[str]:
    return {Path(n).relative_to(folder).as_posix() for n in git_files("ls-files", folder)}


def test_the_wheel_holds_the_packages_and_their_data_and_no_junk(wheel: Path) -> None:
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/")[0] for n in names}
    assert tops == {"lightcal", "lightcal_app", f"lightcal-{__version__}.dist-info"}
    junk = [
        n
        for n in names
        if "__pycache__" in n
        or n.endswith((".pyc", ".session.json", ".tmp"))
        or "test-artifacts" in n
        or n.startswith("tests/")
    ]
    assert junk == []

    def under(prefix: str) -> set[str]:
        return {n.removeprefix(prefix) for n in names if n.startswith(prefix)}

    assert under("lightcal/sample_data/") == tracked("sample_data")
    assert under("lightcal_app/static/") == tracked("static")
    assert "lightcal/py.typed" in names
    size_mb = wheel.stat().st_size / 1e6
    assert size_mb < 30, f"the wheel is {size_mb:.1f} MB"


@pytest.fixture(scope="module")
def venv(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh venv holding the wheel; the dependencies come from this interpreter's
    site-packages without their .pth files (see the module docstring)."""
    root = tmp_path_factory.mktemp("venv") / "v"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(root)], check=True)
    python = root / "bin" / "python"
    purelib = subprocess.run(
        [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    pip_install = [sys.executable, "-m", "pip", "--python", str(python), "install", "-q"]
    subprocess.run(
        [*pip_install, "--no-deps", "--no-index", str(wheel)], env=clean_env(), check=True
    )
    # Only now the dependencies: pip never saw the repository's editable install.
    # (The checkout's own .venv holds them in CI and scripts/test.sh: keep it; a .pth line
    # adds a folder without running the editable install's .pth files inside it.)
    deps = [
        p
        for p in site.getsitepackages()
        if not Path(p).resolve().is_relative_to(REPO)
        or Path(p).resolve().is_relative_to(REPO / ".venv")
    ]
    (Path(purelib) / "lightcal-test-dependencies.pth").write_text("\n".join(deps) + "\n")
    return root


def venv_env(venv: Path, tmp: Path) -> dict[str, str]:
    """The environment of a command in the venv: no PYTHONPATH, the user's folders in
    `tmp`, one numba cache for the module's tests (beside the venv)."""
    env = clean_env()
    env.update(
        XDG_DATA_HOME=str(tmp / "data"),
        XDG_STATE_HOME=str(tmp / "state"),
        XDG_CACHE_HOME=str(tmp / "cache"),
        NUMBA_CACHE_DIR=str(venv.parent / "numba"),
    )
    return env


def run(venv: Path, tmp: Path, *args: str, timeout: float = 900) -> str:
    proc = subprocess.run(
        [str(venv / "bin" / args[0]), *args[1:]],
        cwd=tmp,
        env=venv_env(venv, tmp),
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    assert proc.returncode == 0, f"{args}: {proc.stdout[-2000:]}\n{proc.stderr[-4000:]}"
    return proc.stdout


CHECK_ISOLATION = """
import json, sys
import lightcal, lightcal_app
from lightcal_app.explain import PROJECT_FIGURES, SECTIONS, STATIC_DIR, load_figure
from lightcal.resources import sample_project_dir, sample_project_is_packaged
print(json.dumps({
    "lightcal": lightcal.__file__,
    "lightcal_app": lightcal_app.__file__,
    "sys_path": sys.path,
    "finders": [type(f).__module__ for f in sys.meta_path],
    "static": str(STATIC_DIR),
    "figures": [
        load_figure(f) is not None for _, _, f in SECTIONS if f and f not in PROJECT_FIGURES
    ],
    "sample": str(sample_project_dir()),
    "packaged": sample_project_is_packaged(),
}))
"""


def test_installed_lightcal_runs_away_from_the_repository(venv: Path, tmp_path: Path) -> None:
    info = json.loads(run(venv, tmp_path, "python", "-c", CHECK_ISOLATION))
    for key in ("lightcal", "lightcal_app", "static", "sample"):
        assert Path(info[key]).is_relative_to(venv), (key, info[key])
    # Nothing of the checkout on the path but its .venv's dependencies (CI keeps them there).
    in_repo = [
        p
        for p in info["sys_path"]
        if p
        and Path(p).resolve().is_relative_to(REPO)
        and not Path(p).resolve().is_relative_to(REPO / ".venv")
    ]
    assert in_repo == []
    assert not any("editable" in m for m in info["finders"]), info["finders"]
    assert info["figures"] and all(info["figures"])
    assert info["packaged"]

    assert run(venv, tmp_path, "lightcal", "--version").strip() == f"lightcal {__version__}"
    assert run(venv, tmp_path, "python", "-m", "lightcal", "--help").startswith("usage:")

    sample = tmp_path / "s"
    out = run(venv, tmp_path, "lightcal", "sample", str(sample))
    assert f"lightcal calibrate {sample / 'project.json'} --out result.json" in out
    result = tmp_path / "r.json"
    run(
        venv,
        tmp_path,
        "lightcal",
        "calibrate",
        str(sample / "project.json"),
        "--out",
        str(result),
        "--quiet",
    )
    found = json.loads(result.read_text())["lights"][0]["position_m"]
    truth = json.loads((REPO / "sample_data" / "truth.json").read_text())["light"]["position_m"]
    error = sum((a - b) ** 2 for a, b in zip(found, truth, strict=True)) ** 0.5
    assert error < MAX_POSITION_ERROR_M, (found, truth)


def _lines_into(stream: Iterable[str] | None, lines: queue.Queue[str]) -> None:
    for line in stream or ():
        lines.put(line)


def test_installed_app_serves_a_user_copy_of_the_sample(venv: Path, tmp_path: Path) -> None:
    """`lightcal app` without a project: copies the sample out of site-packages, serves
    the page; the autosave lands in the copy, nothing is written into the package."""
    proc = subprocess.Popen(
        [str(venv / "bin" / "lightcal"), "app", "--port", "0"],
        cwd=tmp_path,
        env=venv_env(venv, tmp_path),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    lines: queue.Queue[str] = queue.Queue()
    threading.Thread(target=_lines_into, args=(proc.stdout, lines), daemon=True).start()
    out, url = [], None
    try:
        while url is None:
            try:
                out.append(lines.get(timeout=600))
            except queue.Empty:
                pytest.fail(f"no URL from lightcal app: {out}")
            match = re.search(r"open (http://\S+) in your browser", out[-1])
            url = match.group(1) if match else None
        with urllib.request.urlopen(url, timeout=60) as response:
            assert response.status == 200
            assert b"<html" in response.read().lower()
    finally:
        proc.send_signal(signal.SIGINT)  # Ctrl-C: the app closes and writes its autosave
        try:
            proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    copy = tmp_path / "data" / "lightcal" / f"sample-{__version__}"
    assert any(f"copied the sample project to {copy}" in line for line in out), out
    assert any(f"serving {copy / 'project.json'}" in line for line in out), out
    assert (copy / "project.session.json").is_file()
    package = venv / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}"
    written = [
        p
        for p in (package / "site-packages" / "lightcal" / "sample_data").rglob("*")
        if p.name.endswith(".session.json")
    ]
    assert written == []
