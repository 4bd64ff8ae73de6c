"""`lightcal --help` and `--version` start without the numerical stack.

Building the parser imports every subcommand module; each registers its arguments with
cheap imports only and imports its machinery inside its run function. The check is on
the modules a real `python -m lightcal` process imports (`-X importtime` lists every
one), not on time: `benchmarks/startup.py` times it.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from lightcal import __version__

REPO = Path(__file__).resolve().parents[1]

#: Top-level packages that --help / --version must not import (each costs 0.1 - 1 s).
HEAVY = ("numpy", "scipy", "numba", "cv2", "viser", "rawpy", "tifffile", "PIL", "pydantic")


def run_lightcal(*args: str) -> tuple[str, set[str]]:
    """stdout of `python -X importtime -m lightcal ARGS` and the top-level modules it imported."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(REPO), str(REPO / "app"), *filter(None, [env.get("PYTHONPATH")])]
    )
    env["COLUMNS"] = "100"
    proc = subprocess.run(
        [sys.executable, "-X", "importtime", "-m", "lightcal", *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
        check=True,
    )
    imported = {
        line.rsplit("|", 1)[1].strip().split(".")[0]
        for line in proc.stderr.splitlines()
        if line.startswith("import time:") and line.count("|") == 2
    }
    assert "lightcal" in imported, proc.stderr[-2000:]
    return proc.stdout, imported


@pytest.mark.parametrize(
    "args",
    [("--version",), ("--help",), ("calibrate", "--help"), ("app", "--help"), ("sample", "--help")],
)
def test_help_and_version_do_not_import_the_numerical_stack(args: tuple[str, ...]) -> None:
    out, imported = run_lightcal(*args)
    if args == ("--version",):
        assert out.strip() == f"lightcal {__version__}"
    else:
        assert out.startswith("usage: lightcal")
    if args == ("--help",):
        for command in ("sample", "synth", "calibrate", "render", "schema", "init", "camera"):
            assert command in out
    assert sorted(imported.intersection(HEAVY)) == []


def test_the_command_entry_runs_main_then_freezes_the_collector(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`lightcal` (console script, `python -m lightcal`) is `entry`: main's exit code, full
    collections made rarer while it runs, the collector frozen for the exit (the
    interpreter's final collections skipped); `main` alone leaves the collector as is."""
    import atexit
    import gc
    import signal

    import lightcal.cli.main as cli_main
    from lightcal.cli.main import entry, main

    thresholds = gc.get_threshold()
    frozen = gc.get_freeze_count()
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    monkeypatch.setattr(sys, "argv", ["lightcal", "schema"])
    try:
        assert main(["schema"]) == 0
        assert gc.get_threshold() == thresholds and gc.get_freeze_count() == frozen
        assert entry() == 0
        assert '"title"' in capsys.readouterr().out
        assert gc.get_threshold() == (700, 10, 100)
        assert gc.get_freeze_count() > frozen
    finally:
        gc.unfreeze()
        gc.set_threshold(*thresholds)
        # entry() installs the end-of-process signal handlers and its last atexit step:
        # this process is pytest's, whose Ctrl-C must stay pytest's.
        for signum, handler in handlers.items():
            signal.signal(signum, handler)
        atexit.unregister(cli_main._final_flush)


def test_the_solver_imports_scipy_optimize_while_the_images_decode() -> None:
    """`lightcal calibrate`'s modules leave scipy.optimize (0.1-0.3 s) to
    `pipeline.load.prepare_solve`, which runs while the images decode."""
    code = (
        "import sys\n"
        "import lightcal.cli.calibrate, lightcal.io.project, lightcal.pipeline\n"
        "import lightcal.pipeline.results, lightcal.core.solver, lightcal.core.rid\n"
        "print('scipy.optimize' in sys.modules)\n"
        "from lightcal.io.project import load_project\n"
        "from lightcal.pipeline.load import prepare_solve\n"
        f"prepare_solve(load_project({str(REPO / 'sample_data' / 'project.json')!r}))\n"
        "print('scipy.optimize' in sys.modules)\n"
    )
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split() == ["False", "True"]
