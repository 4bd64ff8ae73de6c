"""`lightcal calibrate PROJECT --out result.json [--report DIR]`.

The result is written first, then the report. The report folder shows one run's
complete report, never a mix (`lightcal.report.write_report`): written into a hidden
sibling folder and renamed into place when complete; into an existing folder (--force,
or another run's report that appeared meanwhile) its files move in under a lock file
naming the process, replacing those of the earlier report (listed in its summary.md)
and nothing else. A second run finding the lock held waits for it (at most 30 s), then
fails with a message naming the other process. An interruption (Ctrl-C, SIGTERM) leaves
the complete result, if it was written, and no partial report.

Progress and messages go to stderr; a reader closing it early (`2>&1 | head -3`) does
not stop the solve: the result and report are written and the exit code is the same.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from lightcal.cli.arguments import path_arg

if TYPE_CHECKING:
    from lightcal.core.solver import IterationReport


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("calibrate", help="estimate the light pose(s) of a project")
    p.add_argument("project", type=path_arg, help="project file (JSON or YAML)")
    p.add_argument("--out", type=path_arg, required=True, help="result JSON to write")
    p.add_argument(
        "--report",
        type=path_arg,
        help="folder for residual maps, renders, plots; written aside and moved in "
        "complete (an earlier report's files there are replaced, other files kept; "
        "one run at a time)",
    )
    p.add_argument("--quiet", action="store_true", help="print only errors and the summary")
    p.add_argument(
        "--force",
        action="store_true",
        help="write the report into a non-empty --report folder; replace an --out that is "
        "not an earlier result (an earlier result is always replaced)",
    )
    p.add_argument(
        "--allow-misfit",
        action="store_true",
        help="exit 0 even when the fit test fails (default: exit 3, see docs/model.md)",
    )
    p.set_defaults(func=run)


#: Exit code when the solve converged but a misfit could move the pose beyond its
#: statistical sigma (a finding of the fit test; docs/model.md).
EXIT_MISFIT = 3


def run(args: argparse.Namespace) -> int:
    from lightcal.cli.progress import console, ensure_kernels, output, stage_progress
    from lightcal.errors import InputError
    from lightcal.io.outputs import check_output_file, check_output_folder, project_inputs
    from lightcal.io.project import load_project
    from lightcal.io.project_identity import project_identity
    from lightcal.io.result_file import (
        is_result_file,
        project_ports,
        result_to_file,
        write_result,
    )
    from lightcal.pipeline import build_model, calibrate, load_images
    from lightcal.pipeline.auto_start import auto_initial_lines, with_auto_initial
    from lightcal.pipeline.load import prepare_solve
    from lightcal.pipeline.port_text import port_lines
    from lightcal.pipeline.result_text import light_lines, medium_text
    from lightcal.pipeline.results import stop_reason
    from lightcal.pipeline.solve import start_words

    project = load_project(args.project)
    # Before any work: a long solve must not end in an unwritable or forbidden path.
    inputs = project_inputs(project)
    check_output_file(args.out, option="--out", inputs=inputs)
    if args.out.exists() and not args.force and not is_result_file(args.out):
        # An earlier result is replaced (a solve run again); any other file is the user's.
        raise InputError(
            args.out, "--out: exists and is not a lightcal result; use --force to replace it"
        )
    if args.report is not None:
        check_output_folder(args.report, option="--report", inputs=inputs, force=args.force)
    ensure_kernels(quiet=args.quiet)
    with stage_progress(enabled=not args.quiet) as progress:
        loaded = load_images(project, progress=progress, meanwhile=lambda: prepare_solve(project))
        guessed = with_auto_initial(project, loaded)
        model = build_model(guessed, loaded, progress=progress)
    if guessed is not project and not args.quiet:
        for line in auto_initial_lines(guessed):
            console.print(line, highlight=False, soft_wrap=True)
    project = guessed

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
        lights = [u.initial for u in project.lights]
        for line in port_lines(project.camera_port, lights):  # what bends the rays
            console.print(line, highlight=False, soft_wrap=True)

    def on_start(k: int, n: int) -> None:
        if not args.quiet and n > 1:
            console.print(start_words(k, n), highlight=False)

    def on_stage(text: str) -> None:
        if not args.quiet:
            console.print(text, highlight=False)

    cal = calibrate(
        project, loaded, model, on_iteration=on_iteration, on_start=on_start, on_stage=on_stage
    )
    model, result = cal.model, cal.result
    write_result(
        result_to_file(
            result,
            project=project.path,
            project_id=project_identity(project),
            ports=project_ports(project),
        ),
        args.out,
    )
    for lr in result.lights:
        for line in light_lines(lr):
            output.print(line, highlight=False, soft_wrap=True)
    if result.wall.get("model") != "lambertian":
        params = ", ".join(f"{k} {v:.4g}" for k, v in result.wall.items() if isinstance(v, float))
        output.print(f"wall: {result.wall['model']} ({params})", highlight=False)
    if result.channels is not None:  # each its scales, medium and room light
        from lightcal.pipeline.result_text import channel_lines

        for line in channel_lines(result.channels):
            output.print(line, highlight=False, soft_wrap=True)
    medium = None if result.channels is not None else medium_text(result.medium)
    if medium is not None:
        output.print(medium, highlight=False)
    if result.fall_off is not None:
        from lightcal.pipeline.fall_off_result import fall_off_text

        output.print(fall_off_text(result.fall_off), highlight=False, soft_wrap=True)
    if result.ambient is not None and result.channels is None:
        from lightcal.pipeline.fall_off_result import ambient_text

        output.print(ambient_text(result.ambient, result.ambient_sigma), highlight=False)
    if result.albedo_map is not None:
        from lightcal.pipeline.albedo_result import albedo_text

        output.print(albedo_text(result.albedo_map), highlight=False, soft_wrap=True)
    if result.surroundings is not None:
        from lightcal.pipeline.result_text import surroundings_text

        output.print(surroundings_text(result.surroundings), highlight=False, soft_wrap=True)
    if cal.outcome.f_scale_used is not None:
        solver = project.spec.solver
        how = "auto, from the linear solve's residuals" if solver.f_scale == "auto" else "given"
        output.print(
            f"robust loss {solver.loss}: f_scale = {cal.outcome.f_scale_used:.4g} ({how})",
            highlight=False,
        )
    if result.uncertainty_terms:
        output.print("the sigmas include:", highlight=False)
        for term in result.uncertainty_terms:
            output.print(f"  {term}", highlight=False, soft_wrap=True)
    for w in result.warnings:
        console.print(f"warning: {w}", style="yellow", highlight=False)
    if args.report is not None:
        from lightcal.report import write_report

        with stage_progress(enabled=not args.quiet) as progress:
            write_report(args.report, project, loaded, model, result, progress=progress)
        console.print(f"report written to {args.report}", highlight=False)
    status = "converged" if result.converged else "not converged"
    reason = stop_reason(result.status, result.message)
    if result.undetermined:
        status = "not converged (undetermined)"
        reason = "; ".join(result.undetermined)
    output.print(
        f"{status}: {reason}; result written to {args.out}", highlight=False, soft_wrap=True
    )
    if not result.converged:
        return 1
    if not result.fit_adequate:
        console.print(
            "the fit test found a misfit that moves the pose beyond its statistical sigma "
            "(see the misfit warnings); the sigma above includes it"
            + ("" if args.allow_misfit else f"; exit code {EXIT_MISFIT} (--allow-misfit: 0)"),
            style="yellow",
            highlight=False,
        )
        if not args.allow_misfit:
            return EXIT_MISFIT
    return 0
