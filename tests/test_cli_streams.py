"""The command line's edges: closed pipes and streams, Ctrl-C, internal errors."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import lightcal.cli.schema as schema_cmd
from lightcal.cli.main import main

REPO = Path(__file__).resolve().parents[1]
LIGHTCAL = [sys.executable, "-m", "lightcal"]


def test_a_reader_that_closes_the_pipe_ends_the_command_quietly() -> None:
    proc = subprocess.Popen(
        [*LIGHTCAL, "schema"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=REPO
    )
    assert proc.stdout is not None and proc.stderr is not None
    assert proc.stdout.readline().strip() == b"{"
    proc.stdout.close()  # as `| head -1` does
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == 0
    assert err == ""


@pytest.mark.parametrize("redirect", ["2>&-", ">&- 2>&-", "<&- >&-"])
def test_closed_standard_streams_are_tolerated(redirect: str) -> None:
    cmd = f"{sys.executable} -m lightcal schema {redirect}"
    out = subprocess.run(["bash", "-c", cmd], capture_output=True, text=True, cwd=REPO)
    assert out.returncode == 0, out.stderr
    assert "Traceback" not in out.stderr


def test_ctrl_c_exits_130_without_a_traceback(tmp_path: Path) -> None:
    # A long command: the sample calibrated densely; interrupted after start-up.
    proc = subprocess.Popen(
        [*LIGHTCAL, "synth", str(tmp_path / "d"), "--views", "40", "--width", "1600"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=REPO,
    )
    time.sleep(2.0)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    assert err.splitlines()[-1] == "lightcal synth: interrupted"


def test_an_internal_error_is_one_line_and_the_traceback_comes_with_debug(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def broken(args: object) -> int:
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr(schema_cmd, "run", broken)
    assert main(["schema"]) == 1
    assert capsys.readouterr().err.splitlines() == [
        "lightcal schema: internal error: ZeroDivisionError: division by zero (a bug in "
        "lightcal: run again with --debug for the traceback and report it)"
    ]
    assert main(["schema", "--debug"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("Traceback (most recent call last):")
    assert "ZeroDivisionError: division by zero" in err


def test_ctrl_c_in_a_command_exits_130(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def interrupted(args: object) -> int:
        raise KeyboardInterrupt

    monkeypatch.setattr(schema_cmd, "run", interrupted)
    assert main(["schema"]) == 130
    assert capsys.readouterr().err == "lightcal schema: interrupted\n"


def test_a_file_system_refusal_is_an_input_error_naming_the_file(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def refused(args: object) -> int:
        raise PermissionError(13, "Permission denied", "/data/out/result.json")

    monkeypatch.setattr(schema_cmd, "run", refused)
    assert main(["schema"]) == 2
    assert capsys.readouterr().err == (
        "lightcal schema: error: /data/out/result.json: Permission denied\n"
    )
