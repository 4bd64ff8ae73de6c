"""Whole-process times of the commands a user waits for: start-up and the sample calibration.

    .venv/bin/python benchmarks/startup.py              # 5 runs per row (about a minute)
    .venv/bin/python benchmarks/startup.py --runs 3

Each row runs the real command in a fresh process, as a user does, from a temporary
folder, with this checkout first on PYTHONPATH (the `lightcal` script beside the Python
running this, else `python -m lightcal`). After one warm-up run (numba's kernel cache and
the OS file cache filled), it prints the median wall time of the runs, their CPU time
(user + sys) and the largest peak resident memory, each process's own (`ru_maxrss` of
`os.wait4`, as `/usr/bin/time` reports it), beside the target of issue 12. Nothing is
asserted; the load average before and after is printed (the machine may be shared).

- `lightcal --version`: the version line; the parser is built (every subcommand
  registered);
- `lightcal --help`: the command list;
- `lightcal calibrate`: `lightcal calibrate sample_data/project.json --out TMP --quiet`,
  end to end: imports, reading the 12 images and masks, selection, the model, the solve,
  the fit test, the result file.
- `lightcal app` to the URL: `lightcal app sample_data/project.json --fresh` on a free
  port (its session in a temporary folder), from the process start until the printed
  URL answers an HTTP GET with the page (issue 27's warm start, target < 5 s); the
  process is then stopped with SIGINT. Its CPU and memory are not measured.
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class Row:
    label: str
    args: tuple[str, ...]
    target_s: float


@dataclass(frozen=True)
class Timing:
    wall_s: float
    cpu_s: float
    peak_mb: float


def lightcal_command() -> list[str]:
    """The `lightcal` script beside this Python, else `python -m lightcal`."""
    script = shutil.which("lightcal", path=str(Path(sys.executable).parent))
    return [script] if script else [sys.executable, "-m", "lightcal"]


def run_once(command: list[str], cwd: Path, env: dict[str, str]) -> Timing:
    """Run `command` to its end: wall time, CPU time and peak RSS of that process alone."""
    start = time.perf_counter()
    proc = subprocess.Popen(
        command, cwd=cwd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(command)}: exit {proc.returncode}\n{err}")
    # ru_maxrss: kilobytes on Linux, bytes on macOS.
    peak_mb = usage.ru_maxrss / (1e6 if sys.platform == "darwin" else 1e3)
    return Timing(wall, usage.ru_utime + usage.ru_stime, peak_mb)


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def app_to_url(lightcal: list[str], project: str, tmp: Path, env: dict[str, str]) -> float:
    """Seconds from `lightcal app` starting to its printed URL serving the page."""
    port = free_port()
    session = tmp / f"app-{port}.session.json"
    command = [*lightcal, "app", project, "--port", str(port), "--fresh"]
    command += ["--session", str(session), "--state-dir", str(tmp / "state")]
    start = time.perf_counter()
    proc = subprocess.Popen(
        command, cwd=tmp, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )
    try:
        assert proc.stdout is not None
        for line in proc.stdout:
            if " open http" in line:
                url = line.split(" open ", 1)[1].split()[0]
                break
        else:
            raise SystemExit(f"{' '.join(command)}: ended without a URL (exit {proc.wait()})")
        with urllib.request.urlopen(url, timeout=60) as response:
            response.read()
        return time.perf_counter() - start
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5, help="timed runs per row (5)")
    args = parser.parse_args()

    env = dict(os.environ)
    # As on a user's machine: byte code cached (a sandbox's PYTHONDONTWRITEBYTECODE would
    # recompile lightcal's ~90 modules, about 0.15 s, in every run).
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(REPO), str(REPO / "app"), *filter(None, [env.get("PYTHONPATH")])]
    )
    lightcal = lightcal_command()
    with tempfile.TemporaryDirectory(prefix="lightcal-startup-") as tmp:
        project = str(REPO / "sample_data" / "project.json")
        rows = (
            Row("lightcal --version", ("--version",), 0.3),
            Row("lightcal --help", ("--help",), 0.3),
            Row(
                "lightcal calibrate (sample, --quiet)",
                ("calibrate", project, "--out", str(Path(tmp) / "result.json"), "--quiet"),
                1.5,
            ),
        )
        print(f"{' '.join(lightcal)}; {args.runs} runs per row after one warm-up")
        print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
        print(f"{'row':<38} {'wall s':>8} {'target':>8} {'CPU s':>7} {'peak MB':>8}")
        for row in rows:
            command = [*lightcal, *row.args]
            run_once(command, Path(tmp), env)  # warm-up
            timings = [run_once(command, Path(tmp), env) for _ in range(args.runs)]
            wall = statistics.median(t.wall_s for t in timings)
            cpu = statistics.median(t.cpu_s for t in timings)
            peak = max(t.peak_mb for t in timings)
            mark = "" if wall < row.target_s else "  over target"
            print(
                f"{row.label:<38} {wall:8.3f} {'< ' + str(row.target_s):>8} {cpu:7.2f} "
                f"{peak:8.0f}{mark}"
            )
        app_to_url(lightcal, project, Path(tmp), env)  # warm-up
        wall = statistics.median(
            app_to_url(lightcal, project, Path(tmp), env) for _ in range(args.runs)
        )
        mark = "" if wall < 5.0 else "  over target"
        print(f"{'lightcal app (sample) to its URL':<38} {wall:8.3f} {'< 5.0':>8}{mark}")
        print(f"load average after:  {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
