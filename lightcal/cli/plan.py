"""`lightcal plan PROJECT [--result RESULT] [--n 3] [--out plan.json] [--force]`: the best
next camera poses (lightcal.pipeline.plan), with the predicted sigmas before and after."""

from __future__ import annotations

import argparse

from lightcal.cli.arguments import path_arg


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("plan", help="suggest the next camera poses that shrink the uncertainty")
    p.add_argument("project", type=path_arg, help="project file (JSON or YAML)")
    p.add_argument(
        "--result", type=path_arg, help="result JSON of a solve (default: initial guess)"
    )
    p.add_argument("--n", type=int, default=3, help="how many views to suggest (default 3)")
    p.add_argument("--wall-size", type=float, default=3.0, help="wall width/height, m (3)")
    p.add_argument("--out", type=path_arg, help="write the plan as JSON here")
    p.add_argument("--force", action="store_true", help="replace an existing --out file")
    p.set_defaults(func=run)


MAX_VIEWS = 20
"""The most views one plan suggests: each is chosen given the ones before it, and a
plan is meant to be taken, then planned again from the new estimate."""

_NOISE_WORDS = {
    "model": "the sensor's noise model (sensor.noise of the project)",
    "image": "estimated from each image (Poisson-Gaussian); sigmas in mm and deg",
}


def _sig(entries: list[dict]) -> str:
    parts = []
    for e in entries:
        text = f"{e['light']}: position {1000 * e['position_sigma_m']:.2f} mm"
        if e["axis_sigma_deg"] is not None:
            text += f", axis {e['axis_sigma_deg']:.3f} deg"
        parts.append(text)
    return "; ".join(parts)


def run(args: argparse.Namespace) -> int:
    import json
    import math

    from lightcal.cli.progress import console, ensure_kernels, stage_progress
    from lightcal.errors import InputError
    from lightcal.io.atomic import atomic_create_bytes, atomic_write_bytes
    from lightcal.io.outputs import check_output_file, project_inputs
    from lightcal.io.project import load_project
    from lightcal.io.project_identity import check_result_of
    from lightcal.io.result_file import read_result
    from lightcal.pipeline import build_model, load_images, measurements_for
    from lightcal.pipeline.auto_start import with_auto_initial
    from lightcal.pipeline.plan import (
        PlanGrid,
        noise_variance,
        plan_to_dict,
        plan_views,
        start_vector,
    )

    if not 1 <= args.n <= MAX_VIEWS:
        raise InputError(
            "--n", f"expected 1 to {MAX_VIEWS} views (plan again after taking them), got {args.n}"
        )
    if not math.isfinite(args.wall_size) or args.wall_size <= 0:
        raise InputError(
            "--wall-size", f"expected the wall's width in m (> 0), got {args.wall_size}"
        )
    project = load_project(args.project)
    if args.out is not None:
        inputs = project_inputs(project)
        if args.result is not None:
            inputs[args.result.resolve()] = "the result file"
        check_output_file(args.out, option="--out", inputs=inputs, force=args.force)
    names = x = None
    if args.result is not None:
        res = read_result(args.result)
        check_result_of(project, args.result, res.project_id)
        names, x = res.parameters.names, res.parameters.x
    ensure_kernels()
    with stage_progress() as progress:
        loaded = load_images(project, progress=progress)
        project = with_auto_initial(project, loaded)
        model = build_model(project, loaded, progress=progress)
        x0 = start_vector(model, names, x, args.result)
        grid = PlanGrid(wall_size_m=args.wall_size)
        s2 = None
        if args.result is None:
            # Before a solve the residuals are the guess's misfit, not noise: s^2 is
            # the pixels' mean noise variance from their noise models (pipeline.plan).
            meas = measurements_for(project, loaded, model)
            s2 = noise_variance(model, meas.noise)
            if s2 is not None:
                console.print(f"noise: {_NOISE_WORDS[meas.noise_source]}", highlight=False)
            else:
                s2 = 1.0
                console.print(
                    "noise: no noise model (the sensor's or estimated from the images): "
                    "the sigmas are for a pixel noise of 1 (image units)",
                    style="yellow",
                    highlight=False,
                )
        current, planned = plan_views(
            model,
            x0,
            loaded.camera,
            n=args.n,
            grid=grid,
            noise_scale2=s2,
            progress=progress,
            mesh=project.wall_mesh,
            port=project.camera_port,
        )
    light_names = [u.initial.name for u in model.unknowns]
    plan = plan_to_dict(current, planned, light_names)
    console.print(f"now: {_sig(plan['current'])}", highlight=False)  # type: ignore[arg-type]
    for v in plan["views"]:  # type: ignore[attr-defined]
        console.print(f"{v['rank']}. {v['instruction']}", highlight=False)
        console.print(f"   after: {_sig(v['after'])}", highlight=False)
    if args.out is not None:
        data = (json.dumps(plan, indent=2) + "\n").encode()
        try:
            (atomic_write_bytes if args.force else atomic_create_bytes)(args.out, data)
        except FileExistsError:  # appeared while planning
            raise InputError(args.out, "--out: exists; use --force to replace it") from None
        console.print(f"plan written to {args.out}", highlight=False)
    return 0
