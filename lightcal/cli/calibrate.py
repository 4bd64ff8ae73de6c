"""`lightcal calibrate PROJECT --out result.json [--report DIR]`."""

from __future__ import annotations

import argparse
from pathlib import Path

from lightcal.cli.progress import console, stage_progress
from lightcal.core.solver import IterationReport


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("calibrate", help="estimate the light pose(s) of a project")
    p.add_argument("project", type=Path, help="project file (JSON or YAML)")
    p.add_argument("--out", type=Path, required=True, help="result JSON to write")
    p.add_argument("--report", type=Path, help="folder for residual maps, renders, plots")
    p.add_argument("--quiet", action="store_true", help="print only errors and the summary")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from lightcal.io.project import load_project
    from lightcal.io.result_file import result_to_file, write_result
    from lightcal.pipeline import build_model, load_images, solve_project, summarise

    project = load_project(args.project)
    with stage_progress(enabled=not args.quiet) as progress:
        loaded = load_images(project, progress=progress)
        model = build_model(project, loaded, progress=progress)

    def on_iteration(rep: IterationReport) -> None:
        if not args.quiet:
            console.print(
                f"iteration {rep.iteration:3d}  cost {rep.cost:.6e}  "
                f"|grad| {rep.gradient_norm:.3e}  evaluations {rep.nfev}"
                + ("  (weights from the rendered values)" if rep.reweighted else ""),
                highlight=False,
            )

    if not args.quiet:
        console.print(
            f"{len(model.images)} images, {model.m} pixels, {model.layout.n} parameters",
            highlight=False,
        )

    def on_start(k: int, n: int) -> None:
        if not args.quiet and n > 1:
            what = "the initial guess" if k == 0 else "a random start near it"
            console.print(f"start {k + 1} of {n}: {what}", highlight=False)

    outcome = solve_project(project, model, on_iteration=on_iteration, on_start=on_start)
    result = summarise(model, outcome)
    write_result(result_to_file(result, project=project.path), args.out)
    for lr in result.lights:
        pos = ", ".join(f"{v:+.4f}" for v in lr.pose.position_m)
        ax = ", ".join(f"{v:+.4f}" for v in lr.pose.axis_camera)
        console.print(f"{lr.name}: position [{pos}] m, axis [{ax}]", highlight=False)
    for w in result.warnings:
        console.print(f"warning: {w}", style="yellow", highlight=False)
    if args.report is not None:
        from lightcal.report import write_report

        with stage_progress(enabled=not args.quiet) as progress:
            write_report(args.report, project, loaded, model, result, progress=progress)
        console.print(f"report written to {args.report}", highlight=False)
    status = "converged" if result.converged else "did not converge"
    console.print(f"{status}: {result.message}; result written to {args.out}", highlight=False)
    return 0 if result.converged else 1
