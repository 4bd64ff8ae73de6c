"""`lightcal export RESULT --format F --out PATH`: hand a result to other tools.

Formats (`lightcal.io.export`): `opencv` (FileStorage YAML), `blender` (Python snippet),
`mitsuba` (Mitsuba 3 scene XML), `ies` / `ldt` (the estimated RID as a photometric file).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

FORMATS = ("opencv", "blender", "mitsuba", "ies", "ldt")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "export", help="write a result as OpenCV YAML, a Blender snippet, Mitsuba XML, IES or LDT"
    )
    p.add_argument("result", type=Path, help="result JSON of calibrate")
    p.add_argument("--format", required=True, choices=FORMATS, help="what to write")
    p.add_argument("--out", type=Path, required=True, help="the file to write")
    p.add_argument("--light", default=None, help="the light to write as ies/ldt")
    p.add_argument(
        "--project",
        type=Path,
        default=None,
        help="take the RID of lights the calibration did not estimate from this project",
    )
    p.add_argument("--force", action="store_true", help="replace an existing file")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from lightcal.io.export import export_files, export_result
    from lightcal.io.outputs import check_output_file, project_inputs
    from lightcal.io.result_file import read_result

    # Before any work: --out is never a file this export reads (the result, the project
    # and the files it names, such as a light's IES), even with --force.
    inputs = {args.result.resolve(): "the result file"}
    project = None
    if args.project is not None:
        from lightcal.io.project import load_project

        project = load_project(args.project)
        inputs.update(project_inputs(project))
    check_output_file(args.out, option="--out", inputs=inputs, inputs_of="the export")
    result = read_result(args.result)
    if project is not None:
        from lightcal.cli.progress import ensure_kernels
        from lightcal.io.project_identity import check_result_of

        check_result_of(project, args.result, result.project_id)
        from lightcal.io.export import with_given_rids

        ensure_kernels()  # analytic RIDs are sampled with the compiled evaluator
        rids = {unknown.initial.name: unknown.initial.rid for unknown in project.lights}
        result = with_given_rids(result, rids)
    # The files --out refers to (Mitsuba's textures, beside it) are no input either.
    files = export_files(result, args.format, args.out, source=args.result, light_name=args.light)
    for path in list(files)[1:]:
        check_output_file(path, option="--out", inputs=inputs, inputs_of="the export")
    written = export_result(
        result,
        args.format,
        args.out,
        source=args.result,
        light_name=args.light,
        force=args.force,
    )
    print(f"{args.format} export written to {', '.join(str(p) for p in written)}")
    coneless = [lr.name for lr in result.lights if lr.pose_kind != "isotropic" and not lr.rid]
    if args.format in ("blender", "mitsuba") and coneless:
        print(
            f"note: no estimated RID for {', '.join(coneless)} in the result: "
            "a 180 degree spot cone (--project PROJECT takes the project's RID)",
            file=sys.stderr,
        )
    return 0
