"""Signals (issue 28): SIGTERM ends a command as Ctrl-C does (exit 130, "interrupted",
no temporary file left), and Ctrl-C inside a numba call is an interruption, never an
"internal error"."""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import lightcal.cli.main as cli_main
from lightcal.cli.main import is_interruption, main
from lightcal.io import atomic
from lightcal.io.atomic import atomic_create_bytes, atomic_write_bytes


def _leftovers(folder: Path) -> list[Path]:
    """Hidden or temporary files anywhere under `folder`."""
    return [p for p in folder.rglob("*") if p.name.startswith(".") or p.suffix == ".tmp"]


def _dispatcher_error() -> SystemError:
    """What numba's dispatcher raises when Ctrl-C lands in it (its C code returns a
    result with the KeyboardInterrupt set)."""
    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise SystemError(
                "CPUDispatcher(<function binned_noise>) returned a result with an exception set"
            ) from None
    except SystemError as exc:
        return exc


def test_system_error_from_an_interrupt_is_an_interruption() -> None:
    error = _dispatcher_error()
    assert isinstance(error.__context__, KeyboardInterrupt)
    assert is_interruption(error)
    caused = SystemError("wrapped")
    caused.__cause__ = KeyboardInterrupt()
    assert is_interruption(caused)
    assert is_interruption(KeyboardInterrupt())
    assert not is_interruption(SystemError("a real bug"))
    chained = ValueError("outer")
    chained.__context__ = RuntimeError("inner")
    assert not is_interruption(chained)


def test_a_chain_that_loops_ends() -> None:
    first, second = ValueError("a"), ValueError("b")
    first.__context__, second.__context__ = second, first
    assert not is_interruption(first)


def _run_raising(
    error: BaseException, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> tuple[int, str]:
    """main() on a command whose work raises `error`; (exit code, stderr)."""

    def work(args: argparse.Namespace) -> int:
        raise error

    class Parser:
        def parse_args(self, words: list[str]) -> argparse.Namespace:
            return argparse.Namespace(command="calibrate", func=work)

    monkeypatch.setattr(cli_main, "build_parser", Parser)
    code = main(["calibrate", "project.json"])
    return code, capsys.readouterr().err


def test_main_reports_a_numba_interrupt_as_interrupted(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    code, err = _run_raising(_dispatcher_error(), monkeypatch, capsys)
    assert (code, err) == (130, "lightcal calibrate: interrupted\n")


def test_main_still_reports_a_system_error_as_internal(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    code, err = _run_raising(SystemError("a real bug"), monkeypatch, capsys)
    assert code == 1
    assert err.startswith("lightcal calibrate: internal error: SystemError: a real bug (a bug")


def test_main_restores_the_sigterm_handler(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    before = signal.getsignal(signal.SIGTERM)
    seen = []

    def work(args: argparse.Namespace) -> int:
        seen.append(signal.getsignal(signal.SIGTERM))
        return 0

    class Parser:
        def parse_args(self, words: list[str]) -> argparse.Namespace:
            return argparse.Namespace(command="schema", func=work)

    monkeypatch.setattr(cli_main, "build_parser", Parser)
    assert main(["schema"]) == 0
    assert seen == [cli_main._raise_interrupt]
    assert signal.getsignal(signal.SIGTERM) is before


def test_sigterm_while_the_report_is_written_leaves_no_temporary_file(
    tiny_dataset: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """SIGTERM arrives while a report figure's temporary file is full and being synced
    (where the default action left a full-size hidden `.tmp`)."""
    real_fsync = os.fsync
    sent = []

    def fsync_then_sigterm(fd: int) -> None:
        real_fsync(fd)
        if not sent:
            sent.append(fd)
            os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(atomic.os, "fsync", fsync_then_sigterm)
    out, report = tmp_path / "result.json", tmp_path / "report"
    argv = ["calibrate", str(tiny_dataset / "project.json"), "--out", str(out)]
    code = main([*argv, "--report", str(report), "--quiet"])
    assert sent
    assert code == 130
    assert capsys.readouterr().err.endswith("lightcal calibrate: interrupted\n")
    assert _leftovers(tmp_path) == []
    assert _leftovers(tiny_dataset) == []


@pytest.mark.parametrize("write", [atomic_write_bytes, atomic_create_bytes])
def test_atomic_writers_clean_up_after_keyboard_interrupt(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, write: object
) -> None:
    target = tmp_path / "summary.md"

    def interrupted_fsync(fd: int) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(atomic.os, "fsync", interrupted_fsync)
    with pytest.raises(KeyboardInterrupt):
        write(target, b"x" * 100_000)  # type: ignore[operator]
    assert sorted(tmp_path.iterdir()) == []


def test_atomic_write_cleans_up_when_the_data_raises_keyboard_interrupt(tmp_path: Path) -> None:
    target = tmp_path / "summary.md"
    target.write_text("old")

    def chunks() -> object:
        yield b"new, first half"
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        atomic_write_bytes(target, chunks())  # type: ignore[arg-type]
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["summary.md"]


def test_atomic_write_cleans_up_when_the_rename_is_interrupted(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    target = tmp_path / "summary.md"

    def interrupted_replace(src: object, dst: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "replace", interrupted_replace)
    with pytest.raises(KeyboardInterrupt):
        atomic_write_bytes(target, b"new")
    assert list(tmp_path.iterdir()) == []


def test_sigterm_interrupts_synth(tmp_path: Path) -> None:
    """A real process: SIGTERM after the first view is written ends it with 130 and
    "interrupted", leaving no temporary or hidden file."""
    out = tmp_path / "data"
    argv = ["synth", str(out), "--width", "640", "--height", "480", "--views", "1000"]
    process = subprocess.Popen(
        [sys.executable, "-m", "lightcal", *argv],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert process.stderr is not None
    try:
        lines = []
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:  # poll for a progress line: the work has started
            line = process.stderr.readline()
            lines.append(line)
            if not line or " 1/1000:" in line:
                break
        assert lines and " 1/1000:" in lines[-1], lines
        process.send_signal(signal.SIGTERM)
        rest = process.communicate(timeout=60)[1]
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 130, rest
    assert rest.endswith("lightcal synth: interrupted\n"), rest
    assert "internal error" not in rest
    assert _leftovers(tmp_path) == []
