"""The `lightcal` command: one subcommand per module of this package.

Each subcommand module defines `register(subparsers)`, which adds its parser and sets
`func` to a function taking the parsed arguments and returning the exit code. Errors in
the user's input (`LightcalError`) are caught here, once, and printed as one line.
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import importlib
import os
import signal
import sys
import threading
import traceback
from collections.abc import Iterator, Sequence
from pathlib import Path
from types import FrameType
from typing import IO

from lightcal import __version__
from lightcal.cli import collector
from lightcal.errors import LightcalError

# Subcommand modules, in the order `lightcal --help` lists them.
SUBCOMMANDS = (
    "sample",
    "synth",
    "calibrate",
    "plan",
    "render",
    "export",
    "schema",
    "init",
    "board",
    "camera",
    "response",
    "app",
    "warmup",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="lightcal",
        description="Calibrate the pose of a light source relative to the camera it is mounted on.",
    )
    parser.add_argument("--version", action="version", version=f"lightcal {__version__}")
    parser.add_argument(
        "--debug", action="store_true", help="print the traceback of an internal error"
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in SUBCOMMANDS:
        try:
            module = importlib.import_module(f"lightcal.cli.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"lightcal.cli.{name}":
                continue  # not built yet
            raise
        module.register(sub)
    return parser


def _usable_streams() -> None:
    """Closed standard streams (`2>&-`) become os.devnull: nothing here may crash on them."""
    for name in ("stdout", "stderr"):
        stream = getattr(sys, name)
        if stream is None or getattr(stream, "closed", False):
            setattr(sys, name, Path(os.devnull).open("w", encoding="utf-8"))  # noqa: SIM115


def _say(line: str) -> None:
    """One line on stderr, whatever became of it."""
    try:
        print(line, file=sys.stderr, flush=True)
    except (OSError, ValueError):
        silence(sys.stderr)


def silence(stream: IO[str]) -> bool:
    """After a broken pipe: the rest of `stream` (and its flush at exit) goes nowhere.

    Its file descriptor becomes os.devnull, so the command goes on and nothing it writes
    there fails again (nor does the interpreter's flush at exit, which would turn the
    exit code into 120). Returns whether it could be done (not for a stream without a
    file descriptor).
    """
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
    except OSError:
        return False
    try:
        os.dup2(devnull, stream.fileno())
    except (OSError, ValueError):
        return False
    finally:
        os.close(devnull)
    return True


def _flush_or_silence() -> None:
    """stdout and stderr flushed; the one whose reader has gone (a broken pipe) silenced."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            silence(stream)


_SIGNALS = (signal.SIGINT, signal.SIGTERM)

_command = "lightcal"
"""The command being run (`lightcal calibrate`): what `_interrupted_exit` names."""


def _raise_interrupt(signum: int, frame: FrameType | None) -> None:
    """SIGTERM's (and SIGINT's) handler while a command runs: Ctrl-C, KeyboardInterrupt
    in the main thread."""
    raise KeyboardInterrupt


@contextlib.contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """While a command runs, SIGTERM (`kill`, a service manager, a CI timeout) ends it as
    Ctrl-C does: the code unwinds, temporary files are removed and the command says
    "interrupted" with exit code 130, instead of dying at once (-15) with a hidden `.tmp`
    of its output left behind. SIGINT raises KeyboardInterrupt too (whatever `entry` set
    for the exit). A signal the parent set to be ignored (`nohup`, `cmd &`) stays
    ignored. The previous handlers come back afterwards. Only in the main thread (Python
    delivers signals there; tests may call `main` from others).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {}
    for signum in _SIGNALS:
        if signal.getsignal(signum) is not signal.SIG_IGN:
            previous[signum] = signal.signal(signum, _raise_interrupt)
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, signal.SIG_DFL if handler is None else handler)


def is_interruption(exc: BaseException) -> bool:
    """Whether `exc` is, or was caused while handling, a KeyboardInterrupt.

    Ctrl-C (or SIGTERM) arriving while a numba kernel is being dispatched makes Python
    raise the KeyboardInterrupt inside the dispatcher's C code, which then reports
    `SystemError: CPUDispatcher(<kernel>) returned a result with an exception set`: the
    KeyboardInterrupt is that error's `__context__` (or `__cause__`). It is an
    interruption, not a bug in lightcal.
    """
    seen: set[int] = set()
    pending: list[BaseException] = [exc]
    while pending:
        current = pending.pop()
        if id(current) in seen:
            continue
        seen.add(id(current))
        if isinstance(current, KeyboardInterrupt):
            return True
        pending.extend(e for e in (current.__cause__, current.__context__) if e is not None)
    return False


def main(argv: Sequence[str] | None = None) -> int:
    """Run one `lightcal` command; returns its exit code.

    0 success, 1 a solve that did not converge or an internal error, 2 an input error
    (`lightcal <command>: error: <file>[:<line>]: <what was expected>`) or a usage error
    (argparse's `usage:` lines), 3 a misfit (see `lightcal calibrate`), 130 Ctrl-C or
    SIGTERM (`lightcal <command>: interrupted`, temporary files removed; through `entry`
    also when the signal comes after the work, while the process exits).

    A reader that closes a pipe early: when the command's output is what it reads
    (`lightcal schema | head -1`), the command ends quietly with 0. Progress and
    messages on stderr (`lightcal calibrate ... 2>&1 | head -3`) are dropped from then
    on, and the command goes on: it writes its files and exits with its own code.
    """
    global _command
    _usable_streams()
    command = _command = "lightcal"
    words = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in words  # anywhere: `lightcal calibrate ... --debug` too
    words = [w for w in words if w != "--debug"]
    try:
        with _sigterm_as_interrupt():
            parser = build_parser()
            args = parser.parse_args(words)
            command = _command = f"lightcal {args.command}"
            return int(args.func(args))
    except KeyboardInterrupt:
        _say(f"{command}: interrupted")
        return 130
    except Exception as exc:
        if not is_interruption(exc):  # (an error while unwinding from Ctrl-C is Ctrl-C)
            return _report_error(exc, command, debug=debug)
        _say(f"{command}: interrupted")
        return 130


def _report_error(exc: Exception, command: str, *, debug: bool) -> int:
    """Say what went wrong in one line (see `main`); returns the exit code."""
    if isinstance(exc, LightcalError):
        _say(f"{command}: error: {exc}")
        return 2
    if isinstance(exc, BrokenPipeError):
        _flush_or_silence()
        return 0
    if isinstance(exc, OSError):  # the file system said no (permissions, a full disk, ...)
        where = exc.filename if exc.filename is not None else "a file"
        _say(f"{command}: error: {where}: {exc.strerror or exc}")
        return 2
    # an internal error: one line, the traceback on request
    if debug:
        traceback.print_exception(exc)
    _say(
        f"{command}: internal error: {type(exc).__name__}: {exc} "
        "(a bug in lightcal: run again with --debug for the traceback and report it)"
    )
    return 1


def entry() -> int:
    """The `lightcal` command itself (console script, `python -m lightcal`): `main`, with
    the garbage collector set for a short command, then frozen for the interpreter's exit
    (`lightcal.cli.collector`: the exit took 0.25-0.45 s of a 1.7 s command, ~0.05 s
    frozen). Nothing is lost: lightcal closes what it writes before `main` returns,
    atexit handlers and the flush of the standard streams still run, and the memory goes
    back with the process. `lightcal app` sets the collector for a server once it has
    started. `main` itself leaves the collector alone (tests call it many times in one
    process).

    Signals outside `main`'s work (`_interrupted_exit`): Ctrl-C or SIGTERM before the
    command starts, after it has returned or during the interpreter's exit ends the
    process at once with "lightcal <command>: interrupted" and 130, never a traceback
    nor -15 (the command's files are complete and closed by then; stdout is flushed).
    Once the standard streams are flushed for the last time (`_final_flush`, lightcal's
    last atexit step), the command is over: a signal then is ignored, and the command's
    own exit code stands. The handlers stay for the rest of the process (a test calling
    `entry` must restore them).
    """
    _interrupt_ends_the_process()
    collector.for_a_command()
    code = main()
    collector.for_the_exit()
    return code


def _interrupt_ends_the_process() -> None:
    """SIGINT and SIGTERM end the process as `_interrupted_exit` says, from now on (`main`
    raises KeyboardInterrupt instead while the command runs); unless ignored by the
    parent."""
    if threading.current_thread() is not threading.main_thread():
        return
    for signum in _SIGNALS:
        if signal.getsignal(signum) is not signal.SIG_IGN:
            signal.signal(signum, _interrupted_exit)
    atexit.register(_final_flush)


def _interrupted_exit(signum: int, frame: FrameType | None) -> None:
    """A signal outside the command's work: "interrupted", stdout flushed, exit 130 now
    (nothing else to unwind: no command is writing; the interpreter's own exit, which a
    signal would otherwise cut with a traceback or -15, is skipped)."""
    try:
        with contextlib.suppress(Exception):  # a stream busy in the code interrupted, or broken
            _say(f"{_command}: interrupted")
            sys.stdout.flush()
    finally:
        os._exit(130)


def _final_flush() -> None:
    """The last words of the process: the standard streams flushed (a broken pipe
    silenced), then SIGINT and SIGTERM ignored for the rest of the interpreter's exit
    (its teardown, which may not run the Python code that says "interrupted"; and any
    atexit step registered before `entry`)."""
    _flush_or_silence()
    for signum in _SIGNALS:
        if signal.getsignal(signum) is _interrupted_exit:
            signal.signal(signum, signal.SIG_IGN)


if __name__ == "__main__":
    sys.exit(entry())
