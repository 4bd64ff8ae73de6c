"""Honesty of the reported sigma and of the fit test on data lightcal's model did not make.

Issue 24: a calibration must report a sigma that covers its real error, and a fit test
that names the real cause. Each row is one dataset, calibrated in-process as
`lightcal calibrate` does (`calibrate_project`), against its truth.json:

- the Mitsuba 3 scenarios of `tests/mitsuba_datasets.py` (clean, painted, ambient,
  vignetting, interreflection, bowed, albedo, medium, murky_albedo: 12 views of
  480 x 320, the realistic 14-bit sensor), rendered once into `--root` and reused;
- where `lightcal synth` has the departure options (`--ambient`, `--undeclared-vignetting`,
  `--rid-rim`, `--gamma`, `--pose-error-mm/--pose-error-deg`, `--bow-mm`,
  `--albedo-texture`, `--attenuation`), the same departures rendered by lightcal's own
  model (`--light table`, the same size), and a plain `synth` row.

Columns: the position error |t - t_true| (mm), the reported 1-sigma (the norm of the
position's sigma vector, mm) and their ratio; the axis error (deg), its sigma (the norm
of the axis vector's sigma, deg) and their ratio; the exit code the CLI would give
(1 not converged, 3 the fit not explained by the noise, 0); the render and calibration
times. Under the table, per dataset: the fit test's findings (shortened), the result's
other warnings, the causes it flagged (`*` material), the wall it chose, and its
`uncertainty_terms`. Nothing is asserted: it prints figures.

    .venv/bin/python benchmarks/honesty.py                  # renders 1-2 min once, then ~5 s
    .venv/bin/python benchmarks/honesty.py --quick          # 6 views of 240 x 160
    .venv/bin/python benchmarks/honesty.py --only clean,ambient --seeds 0 1 2
    .venv/bin/python benchmarks/honesty.py --fresh          # render again (lightcal changed)

The datasets are kept in `--root` (default /tmp/lightcal-honesty): a Mitsuba dataset is
rendered again when its options or `tests/mitsuba_datasets.py`'s generator change, a
`synth` one when its options change; `--fresh` renders them all again.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import os
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

os.environ.setdefault("OMP_WAIT_POLICY", "passive")

EXIT_NOT_CONVERGED = 1
EXIT_MISFIT = 3  # lightcal.cli.calibrate.EXIT_MISFIT

SYNTH_DEPARTURES: dict[str, list[str]] = {
    "synth": [],
    "synth ambient": ["--ambient", "0.05"],
    "synth vignetting": ["--undeclared-vignetting", "-0.25", "0.05"],
    "synth rid_rim": ["--rid-rim", "0.1"],
    "synth gamma": ["--gamma", "1.1"],
    "synth pose_error": ["--pose-error-mm", "2", "--pose-error-deg", "0.2"],
    "synth bowed": ["--bow-mm", "5"],
    "synth albedo": ["--albedo-texture", "0.1"],
    "synth medium": ["--attenuation", "0.2"],
}
"""`lightcal synth` departures (rows) and their options, values like the Mitsuba ones."""


@dataclass(frozen=True)
class Row:
    name: str
    position_error_mm: float
    position_sigma_mm: float
    axis_error_deg: float
    axis_sigma_deg: float
    exit_code: int
    render_s: float
    calibrate_s: float
    findings: list[str]
    warnings: list[str]
    causes: list[str]
    wall: str
    terms: list[str]


def _synth_options() -> set[str]:
    """The option strings `lightcal synth` accepts."""
    from lightcal.cli.main import main

    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.suppress(SystemExit):
        main(["synth", "--help"])
    return {word.rstrip(",") for word in out.getvalue().split() if word.startswith("--")}


def _synth_dataset(root: Path, name: str, options: list[str], args: argparse.Namespace) -> Path:
    """A `lightcal synth` dataset (written once per option set into `root`)."""
    from lightcal.cli.main import main

    argv = [
        "--light",
        "table",
        "--views",
        str(args.views),
        "--width",
        str(args.width),
        "--height",
        str(args.height),
        "--seed",
        str(args.seed),
        "--quiet",
        *options,
    ]
    folder = (
        root / f"{name.replace(' ', '-')}-s{args.seed}-v{args.views}-{args.width}x{args.height}"
    )
    stamp = folder / "argv.json"
    if stamp.is_file() and json.loads(stamp.read_text()) == argv:
        return folder / "project.json"
    with contextlib.redirect_stdout(io.StringIO()):
        code = main(["synth", str(folder), *argv, "--force"])
    if code != 0:
        raise RuntimeError(f"lightcal synth {' '.join(argv)} exited with {code}")
    stamp.write_text(json.dumps(argv))
    return folder / "project.json"


def _shorten(text: str, n: int) -> str:
    return text if len(text) <= n else text[: n - 3] + "..."


def calibrate_row(name: str, project_path: Path) -> Row:
    """Calibrate a dataset in-process and compare with its truth."""
    from lightcal.io.project import load_project
    from lightcal.pipeline import calibrate_project

    truth = json.loads((project_path.parent / "truth.json").read_text(encoding="utf-8"))
    true_light = truth["lights"][0]
    t0 = time.perf_counter()
    _, _, result = calibrate_project(load_project(project_path))
    calibrate_s = time.perf_counter() - t0
    light = result.lights[0]
    position_error = np.linalg.norm(light.pose.t_camera_light - np.array(true_light["position_m"]))
    cos_axis = float(np.clip(light.pose.axis_camera @ np.array(true_light["axis_camera"]), -1, 1))
    if not result.converged:
        code = EXIT_NOT_CONVERGED
    elif not result.fit_adequate:
        code = EXIT_MISFIT
    else:
        code = 0
    fit = result.fit or {}
    causes = [
        str(c.get("cause")) + ("*" if c.get("material") else "")
        for c in fit.get("causes", [])
        if isinstance(c, dict) and (c.get("significant") or c.get("material"))
    ]
    findings = [str(f) for f in fit.get("findings", [])]
    warnings = [w for w in result.warnings if not any(f in w for f in findings)]
    mitsuba = truth.get("mitsuba", {})
    render_s = float(mitsuba.get("render_s", math.nan))
    return Row(
        name=name,
        position_error_mm=1000.0 * float(position_error),
        position_sigma_mm=1000.0 * float(np.linalg.norm(light.sigma.t_camera_light)),
        axis_error_deg=math.degrees(math.acos(cos_axis)),
        axis_sigma_deg=math.degrees(float(np.linalg.norm(light.sigma.axis_camera))),
        exit_code=code,
        render_s=render_s,
        calibrate_s=calibrate_s,
        findings=findings,
        warnings=warnings,
        causes=causes,
        wall=str(result.wall.get("model", "?")),
        terms=list(result.uncertainty_terms),
    )


def _ratio(error: float, sigma: float) -> str:
    return f"{error / sigma:7.2f}" if sigma > 0.0 else "      -"


def print_table(rows: list[Row]) -> None:
    print(
        f"| {'dataset':22s} | pos err mm | sigma mm | ratio | axis err deg | sigma deg "
        f"| ratio | exit | render s | calib s |"
    )
    print(
        f"|{'-' * 24}|-----------:|---------:|------:|-------------:|----------:|------:"
        "|-----:|---------:|--------:|"
    )
    for r in rows:
        render = f"{r.render_s:8.1f}" if math.isfinite(r.render_s) else "       -"
        print(
            f"| {r.name:22s} | {r.position_error_mm:10.3f} | {r.position_sigma_mm:8.3f} "
            f"|{_ratio(r.position_error_mm, r.position_sigma_mm)}| {r.axis_error_deg:12.4f} "
            f"| {r.axis_sigma_deg:9.4f} |{_ratio(r.axis_error_deg, r.axis_sigma_deg)}"
            f"| {r.exit_code:4d} | {render} | {r.calibrate_s:7.1f} |"
        )
    print()
    for r in rows:
        print(f"{r.name}: wall {r.wall}; flagged causes: {', '.join(r.causes) or 'none'}")
        for f in r.findings:
            print(f"    finding: {_shorten(f, 150)}")
        for w in r.warnings:
            print(f"    warning: {_shorten(w, 150)}")
        for t in r.terms:
            print(f"    sigma term: {_shorten(t, 150)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, default=Path("/tmp/lightcal-honesty"))
    parser.add_argument("--quick", action="store_true", help="6 views of 240 x 160")
    parser.add_argument("--only", default="", help="comma-separated dataset names")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--sensor", choices=("realistic", "clean"), default="realistic")
    parser.add_argument("--no-mitsuba", action="store_true")
    parser.add_argument("--no-synth", action="store_true")
    parser.add_argument("--fresh", action="store_true", help="render the datasets in --root again")
    args = parser.parse_args()
    if args.fresh and args.root.is_dir():
        for folder in args.root.iterdir():
            if (folder / "truth.json").is_file():  # only datasets: nothing else is removed
                shutil.rmtree(folder)
    args.views, args.width, args.height = (6, 240, 160) if args.quick else (12, 480, 320)
    only = {s.strip() for s in args.only.split(",") if s.strip()}
    started = time.perf_counter()
    print(
        f"honesty.py {time.strftime('%Y-%m-%d %H:%M')}, {args.views} views of "
        f"{args.width} x {args.height}, {args.sensor} sensor, seeds {args.seeds}, "
        f"load {os.getloadavg()[0]:.1f}"
    )

    jobs: list[tuple[str, Any]] = []
    if not args.no_mitsuba:
        try:
            import mitsuba

            from tests.mitsuba_datasets import SCENARIOS, cached_dataset, mitsuba_variant
        except ImportError as exc:
            print(f"Mitsuba 3 rows skipped: {exc} (pip install .[reference])")
        else:
            print(f"Mitsuba {mitsuba.__version__}, variant {mitsuba_variant()}")
            for scenario in SCENARIOS:
                if only and scenario not in only:
                    continue
                jobs.append(
                    (
                        scenario,
                        lambda seed, s=scenario: cached_dataset(
                            args.root,
                            s,
                            seed=seed,
                            views=args.views,
                            width=args.width,
                            height=args.height,
                            sensor=args.sensor,
                        ),
                    )
                )
    if not args.no_synth:
        known = _synth_options()
        for name, options in SYNTH_DEPARTURES.items():
            if only and name not in only:
                continue
            missing = [o for o in options if o.startswith("--") and o not in known]
            if missing:
                print(f"{name}: skipped, lightcal synth has no {' '.join(missing)}")
                continue
            extra = ["--bit-depth", "16", "--no-noise"] if args.sensor == "clean" else []

            def make(seed: int, name: str = name, options: list[str] = options + extra) -> Path:
                args.seed = seed
                return _synth_dataset(args.root, name, options, args)

            jobs.append((name, make))

    rows: list[Row] = []
    for seed in args.seeds:
        for name, make in jobs:
            t0 = time.perf_counter()
            label = name if len(args.seeds) == 1 else f"{name} s{seed}"
            try:
                project = make(seed)
                ready_s = time.perf_counter() - t0
                rows.append(calibrate_row(label, project))
            except Exception as exc:  # a row that fails is reported, the others still run
                print(f"  {label}: failed: {type(exc).__name__}: {exc}", flush=True)
                continue
            print(
                f"  {label}: dataset ready in {ready_s:.1f} s, calibrated in "
                f"{rows[-1].calibrate_s:.1f} s",
                flush=True,
            )
    print()
    print_table(rows)
    print(
        f"\n{len(rows)} datasets, {time.perf_counter() - started:.0f} s, "
        f"load {os.getloadavg()[0]:.1f}"
    )


if __name__ == "__main__":
    main()
