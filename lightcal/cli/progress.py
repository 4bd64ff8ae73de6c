"""Terminal progress for long CLI work (rich), quiet when not a terminal.

`console` (stderr) is where commands print their progress and messages, `output`
(stdout) their answer. A reader that
closes it early (`lightcal calibrate ... 2>&1 | head -3`) silences it, and the command
goes on: it writes its files and exits with its own code (rich's default ends the
program with exit 1, which lost the solve and its result).
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING

from rich.console import Console

from lightcal.cli.main import silence

if TYPE_CHECKING:  # rich.progress is imported when a bar is drawn (a terminal, not --quiet)
    from rich.progress import Progress, TaskID


class _Console(Console):
    """rich's Console, except on a broken pipe: the rest goes to os.devnull, no exit."""

    def on_broken_pipe(self) -> None:
        """The stream's reader has gone: what is not written yet and all that follows
        goes nowhere (quiet where the stream cannot be redirected); the command goes on.
        The progress display and prints share this (`Progress(console=console)`)."""
        del self._buffer[:]
        if not silence(self.file):
            self.quiet = True


console = _Console(stderr=True)
"""Progress, iterations, warnings: what the command says while it works (stderr)."""

output = _Console()
"""The command's answer (the calibrated pose, its sigmas, the status): stdout, so that
`lightcal calibrate ... > pose.txt` keeps it; a closed pipe is silenced like stderr."""


class StageProgress:
    """A `progress(stage, done, total)` callable showing one bar per stage."""

    def __init__(self, progress: Progress | None) -> None:
        self._progress = progress
        self._tasks: dict[str, TaskID] = {}

    def __call__(self, stage: str, done: int, total: int) -> None:
        if self._progress is None:
            return
        if stage not in self._tasks:
            self._tasks[stage] = self._progress.add_task(stage, total=total)
        self._progress.update(self._tasks[stage], completed=done, total=total)


def _bar(*, label_width: int) -> Progress:
    """One transient bar per task on stderr: label, bar, done/total, elapsed time."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    return Progress(
        TextColumn(f"{{task.description:<{label_width}}}"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total}"),
        TimeElapsedColumn(),
        console=console,
        transient=True,
    )


@contextmanager
def stage_progress(*, enabled: bool = True) -> Iterator[StageProgress]:
    if not enabled or not sys.stderr.isatty():
        yield StageProgress(None)
        return
    with _bar(label_width=18) as progress:
        yield StageProgress(progress)


def ensure_kernels(*, quiet: bool = False) -> None:
    """Compile the numba kernels now, with a progress line, unless they are cached.

    The first command after an install would otherwise compile them silently inside its
    work (minutes on a small machine, which looks like a hang). One line on stderr says
    what happens even with `quiet`; the families follow as a bar on a terminal, as
    lines otherwise.
    """
    from lightcal.warmup import kernels_ready, warm_up

    if kernels_ready():
        return
    console.print(
        "compiling the numba kernels (once per install; `lightcal warmup` does it ahead)",
        highlight=False,
    )
    if quiet:
        warm_up()
        return
    if sys.stderr.isatty():
        with _bar(label_width=36) as bar:
            task = bar.add_task("compiling kernels", total=1)

            def show(label: str, done: int, total: int) -> None:
                bar.update(task, description=label, completed=done, total=total)

            seconds = warm_up(show)
    else:

        def show(label: str, done: int, total: int) -> None:
            if done < total:
                console.print(f"compiling kernels {done + 1}/{total}: {label}", highlight=False)

        seconds = warm_up(show)
    console.print(f"kernels compiled in {seconds:.0f} s (cached from now on)", highlight=False)
