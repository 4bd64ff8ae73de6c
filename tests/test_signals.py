"""Signals (issue 28): SIGTERM ends a command as Ctrl-C does (exit 130, "interrupted",
no temporary file left), and Ctrl-C inside a numba call is an interruption, never an
"internal error"."""

from __future__ import annotations

import argparse
import json
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
    sent: list[int] = []

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


# --- signals after the result is written, and while the process exits -----------------

REPO = Path(__file__).resolve().parents[1]

#: `python -c` driver: `lightcal ARGS` as the console script runs it (`entry`), with the
#: process sending itself SIGNAL at MOMENT (deterministic, no sleeps):
#: report - while the report's second figure is written (the result is complete);
#: print - as "report written to ..." is about to be printed;
#: returned - after `main` returned (`entry` freezes the collector);
#: atexit - in an atexit step of the interpreter's exit (one registered by the command);
#: teardown - after lightcal's last flush (an atexit step registered before `entry`);
#: start - before the command starts (`entry` sets the collector).
DRIVER = """
import atexit, os, signal, sys
moment, signum = sys.argv[1], getattr(signal, sys.argv[2])

def send(*args, **kwargs):
    os.kill(os.getpid(), signum)

import lightcal.cli.collector as collector
import lightcal.report as report
from lightcal.cli import progress
from lightcal.cli.main import entry

if moment == "report":
    real_png, pngs = report.write_png, []
    def write_png(path, rgb):
        real_png(path, rgb)
        pngs.append(path)
        if len(pngs) == 2:
            send()
    report.write_png = write_png
elif moment == "print":
    real_print = progress.console.print
    def console_print(*args, **kwargs):
        if str(args[0]).startswith("report written to"):
            send()
        real_print(*args, **kwargs)
    progress.console.print = console_print
elif moment in ("returned", "atexit"):
    real_exit = collector.for_the_exit
    def for_the_exit():
        send() if moment == "returned" else atexit.register(send)
        real_exit()
    collector.for_the_exit = for_the_exit
elif moment == "teardown":
    atexit.register(send)
elif moment == "start":
    real_start = collector.for_a_command
    def for_a_command():
        send()
        real_start()
    collector.for_a_command = for_a_command
sys.argv = ["lightcal", *sys.argv[3:]]
sys.exit(entry())
"""


def _calibrate_with(
    moment: str, signame: str, tiny_dataset: Path, tmp_path: Path
) -> tuple[int, str, Path, Path, str]:
    """Run the driver on `lightcal calibrate` of the tiny dataset with a report; (exit
    code, stderr, result path, report path, stdout: the pose and the status)."""
    out, folder = tmp_path / "result.json", tmp_path / "report"
    argv = ["calibrate", str(tiny_dataset / "project.json"), "--out", str(out)]
    proc = subprocess.run(
        [sys.executable, "-c", DRIVER, moment, signame, *argv, "--report", str(folder)],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=300,
    )
    return proc.returncode, proc.stderr, out, folder, proc.stdout


def _complete_result(path: Path) -> bool:
    from lightcal.io.result_file import read_result

    return read_result(path).converged


def _report_files(folder: Path) -> set[str]:
    from lightcal.report import _report_files

    return _report_files(folder)


@pytest.mark.parametrize("signame", ["SIGTERM", "SIGINT"])
@pytest.mark.parametrize("moment", ["report", "print", "returned", "atexit"])
def test_a_signal_after_the_result_exits_130_and_says_interrupted(
    moment: str, signame: str, tiny_dataset: Path, tmp_path: Path
) -> None:
    code, err, out, folder, _ = _calibrate_with(moment, signame, tiny_dataset, tmp_path)
    assert code == 130, err
    assert err.splitlines()[-1] == "lightcal calibrate: interrupted", err
    assert "Traceback" not in err and "internal error" not in err
    assert _complete_result(out)
    if moment == "report":  # no half report: the folder never appeared
        assert not folder.exists()
    else:
        assert {p.name for p in folder.iterdir()} == _report_files(folder) != set()
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize("signame", ["SIGTERM", "SIGINT"])
def test_a_signal_after_the_last_flush_leaves_the_commands_exit_code(
    signame: str, tiny_dataset: Path, tmp_path: Path
) -> None:
    """The command is over (its output flushed): the signal is ignored, never -15 nor a
    traceback."""
    code, err, out, _, answer = _calibrate_with("teardown", signame, tiny_dataset, tmp_path)
    assert code == 0, err
    assert "interrupted" not in err and "Traceback" not in err
    assert "; result written to " in " ".join(answer.split())
    assert _complete_result(out)
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize("signame", ["SIGTERM", "SIGINT"])
def test_a_signal_before_the_command_starts_exits_130(
    signame: str, tiny_dataset: Path, tmp_path: Path
) -> None:
    code, err, out, folder, _ = _calibrate_with("start", signame, tiny_dataset, tmp_path)
    assert (code, err) == (130, "lightcal: interrupted\n")
    assert not out.exists() and not folder.exists()


def test_a_signal_while_the_report_moves_in_waits_for_it(
    tiny_dataset: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """SIGTERM while a report's files move into an existing folder: held until they are
    all in, then the command ends as interrupted; the folder holds the whole report."""
    folder = tmp_path / "report"
    folder.mkdir()
    (folder / "notes.txt").write_text("the user's")
    real_move_in = atomic._move_in
    sent: list[int] = []

    def move_in_after_sigterm(*args: object) -> None:
        os.kill(os.getpid(), signal.SIGTERM)
        sent.append(signal.SIGTERM)
        real_move_in(*args)  # type: ignore[arg-type]

    monkeypatch.setattr(atomic, "_move_in", move_in_after_sigterm)
    out = tmp_path / "result.json"
    argv = ["calibrate", str(tiny_dataset / "project.json"), "--out", str(out), "--quiet"]
    code = main([*argv, "--report", str(folder), "--force"])
    assert sent
    assert (code, capsys.readouterr().err.splitlines()[-1]) == (
        130,
        "lightcal calibrate: interrupted",
    )
    files = _report_files(folder)
    assert "summary.md" in files
    assert {p.name for p in folder.iterdir()} == files | {"notes.txt"}
    assert _leftovers(tmp_path) == []


def test_signals_held_raises_them_after_the_block() -> None:
    steps = []
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)  # (`entry` sets its own)
    try:
        with pytest.raises(KeyboardInterrupt), atomic.signals_held():
            os.kill(os.getpid(), signal.SIGINT)
            steps.append("the block ran on")
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, previous)
    assert steps == ["the block ran on"]


# --- a reader that closes the pipe early ----------------------------------------------


@pytest.mark.parametrize("streams", ["stderr", "stdout and stderr", "stdout"])
@pytest.mark.parametrize("max_iterations", [None, 1])
def test_a_reader_closing_the_pipe_loses_no_result(
    streams: str, max_iterations: int | None, tiny_dataset: Path, tmp_path: Path
) -> None:
    """`lightcal calibrate ... 2>&1 | head -0`: the pipe's reader is gone before the first
    line. The solve goes on, the result and the report are written whole, and the exit
    code is the command's own (0; 1 for a solve stopped by max_iterations)."""
    project = tiny_dataset / "project.json"
    if max_iterations is not None:
        doc = json.loads(project.read_text())
        doc["solver"]["max_iterations"] = max_iterations
        project = tiny_dataset / f"project_{tmp_path.name}.json"
        project.write_text(json.dumps(doc))
    out, folder = tmp_path / "result.json", tmp_path / "report"
    argv = ["calibrate", str(project), "--out", str(out), "--report", str(folder)]
    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader has gone: every write to the pipe fails with EPIPE
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "lightcal", *argv],
            stdout=write_end if "stdout" in streams else subprocess.DEVNULL,
            stderr=write_end if "stderr" in streams else subprocess.DEVNULL,
            cwd=REPO,
            timeout=300,
        )
    finally:
        os.close(write_end)
        if max_iterations is not None:
            project.unlink()
    assert proc.returncode == (0 if max_iterations is None else 1)
    from lightcal.io.result_file import read_result

    result = read_result(out)
    assert result.converged is (max_iterations is None)
    files = _report_files(folder)
    assert "summary.md" in files and {p.name for p in folder.iterdir()} == files
    assert _leftovers(tmp_path) == []


def test_calibrate_piped_to_head_writes_its_result(tiny_dataset: Path, tmp_path: Path) -> None:
    """The shell's own `| head -1`, stdout and stderr both piped."""
    out, folder = tmp_path / "result.json", tmp_path / "report"
    cmd = (
        f"{sys.executable} -m lightcal calibrate {tiny_dataset / 'project.json'} "
        f"--out {out} --report {folder} 2>&1 | head -1; exit ${{PIPESTATUS[0]}}"
    )
    proc = subprocess.run(
        ["bash", "-c", cmd], capture_output=True, text=True, cwd=REPO, timeout=300
    )
    assert proc.returncode == 0, proc.stdout
    assert proc.stdout.count("\n") == 1
    assert _complete_result(out)
    assert {p.name for p in folder.iterdir()} == _report_files(folder) != set()


def _is_devnull(stream: object) -> bool:
    return os.path.samestat(os.fstat(stream.fileno()), Path(os.devnull).stat())  # type: ignore[attr-defined]


def test_the_console_survives_a_broken_pipe_in_prints_and_the_progress_display() -> None:
    """rich's Console ends the program with exit 1 on a broken pipe; lightcal's silences
    the stream (os.devnull) and goes on, for prints and the progress bars alike."""
    from rich.progress import Progress

    from lightcal.cli.progress import _Console

    read_end, write_end = os.pipe()
    os.close(read_end)
    with os.fdopen(write_end, "w") as stream:
        console = _Console(file=stream, force_terminal=True, width=80)
        console.print("4 images, 400 pixels, 6 parameters")
        assert _is_devnull(stream)
        with Progress(console=console, transient=True) as bar:
            task = bar.add_task("writing figures", total=3)
            for i in range(3):
                bar.update(task, completed=i + 1)
        console.print("converged")
        assert not console.quiet

    read_end, write_end = os.pipe()
    os.close(read_end)
    with os.fdopen(write_end, "w") as stream:
        console = _Console(file=stream, force_terminal=True, width=80)
        with Progress(console=console, transient=True) as bar:  # the bar breaks the pipe
            task = bar.add_task("writing figures", total=3)
            bar.update(task, completed=3)
            bar.refresh()
        assert _is_devnull(stream)
        console.print("converged")
