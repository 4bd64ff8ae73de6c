"""`lightcal export RESULT --format F --out PATH`: hand a result to other tools.

Formats (`lightcal.io.export`): `opencv` (FileStorage YAML), `blender` (Python snippet),
`mitsuba` (Mitsuba 3 scene XML), `ros` (launch XML + URDF), `ies` / `ldt` (the estimated
RID as a photometric file).
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from lightcal.cli.arguments import path_arg

if TYPE_CHECKING:
    from lightcal.io.export_light_port import LightPort
    from lightcal.io.result_file import ResultFile

FORMATS = ("opencv", "blender", "mitsuba", "ros", "ies", "ldt")

#: The file name endings each format's --out may have (what the tools that read them expect).
SUFFIXES = {
    "opencv": (".yaml", ".yml", ".xml", ".json"),
    "blender": (".py",),
    "mitsuba": (".xml",),
    "ros": (".xml",),
    "ies": (".ies",),
    "ldt": (".ldt",),
}


def _either(words: tuple[str, ...]) -> str:
    """ "a", "a or b", "a, b or c"."""
    return words[0] if len(words) == 1 else f"{', '.join(words[:-1])} or {words[-1]}"


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "export",
        help="write a result as OpenCV YAML, a Blender snippet, Mitsuba XML, ROS, IES or LDT",
    )
    p.add_argument("result", type=path_arg, help="result JSON of calibrate")
    p.add_argument("--format", required=True, choices=FORMATS, help="what to write")
    p.add_argument("--out", type=path_arg, required=True, help="the file to write")
    p.add_argument("--light", default=None, help="the light to write as ies/ldt")
    p.add_argument(
        "--project",
        type=path_arg,
        default=None,
        help="take the RID of lights the calibration did not estimate from this project, "
        "and give the Mitsuba sensor and the Blender camera its intrinsics",
    )
    p.add_argument(
        "--wall-albedo",
        type=float,
        default=None,
        metavar="RHO",
        help="the wall's diffuse reflectance, for mitsuba's and blender's scattering "
        "coefficient sigma_s = beta RHO / pi of a result whose medium scatters (default: "
        "the project's surroundings.wall_albedo)",
    )
    p.add_argument("--force", action="store_true", help="replace an existing file")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from lightcal.errors import InputError
    from lightcal.io.export import export_files, export_result
    from lightcal.io.outputs import check_output_file, project_inputs
    from lightcal.io.result_file import ports_left_out, read_result

    # Before any work: the options fit the format, and --out is never a file this export
    # reads (the result, the project and the files it names, such as a light's IES),
    # even with --force.
    inputs = {args.result.resolve(): "the result file"}
    project = None
    if args.project is not None:
        from lightcal.io.project import load_project

        project = load_project(args.project)
        inputs.update(project_inputs(project))
    check_output_file(args.out, option="--out", inputs=inputs, inputs_of="the export")
    suffixes = SUFFIXES[args.format]
    if args.out.suffix.lower() not in suffixes:
        raise InputError(
            args.out,
            f"--out: expected a {_either(suffixes)} file for --format {args.format}, "
            f"got {args.out.suffix or 'no suffix'}",
        )
    if args.light is not None and args.format not in ("ies", "ldt"):
        raise InputError("--light", f"applies to --format ies or ldt only, not {args.format}")
    if args.wall_albedo is not None and args.format not in ("mitsuba", "blender"):
        raise InputError(
            "--wall-albedo", f"applies to --format mitsuba or blender only, not {args.format}"
        )
    from lightcal.io.export_medium import check_wall_albedo, export_medium

    check_wall_albedo(args.wall_albedo)
    result = read_result(args.result)
    medium = export_medium(result, args.result)  # a broken medium: refused before writing
    camera = None if project is None else project.camera
    from lightcal.io.export_light_port import light_ports_of

    port = None if project is None else project.camera_port
    light_ports = light_ports_of(
        [] if project is None else [(u.initial.name, u.initial.port) for u in project.lights]
    )
    wall_albedo = args.wall_albedo
    if wall_albedo is None and project is not None and project.surroundings is not None:
        wall_albedo = project.surroundings.wall_albedo
    if project is not None:
        from lightcal.cli.progress import ensure_kernels
        from lightcal.io.project_identity import check_result_of

        check_result_of(project, args.result, result.project_id)
        from lightcal.io.export import with_given_rids

        ensure_kernels()  # analytic RIDs are sampled with the compiled evaluator
        rids = {unknown.initial.name: unknown.initial.rid for unknown in project.lights}
        result = with_given_rids(result, rids)
    # The files --out refers to (Mitsuba's textures, beside it) are no input either.
    if args.format == "mitsuba" and project is None:
        from lightcal.cli.progress import ensure_kernels

        ensure_kernels()  # the RID texture is evaluated with the compiled table evaluator
    files = export_files(
        result,
        args.format,
        args.out,
        source=args.result,
        light_name=args.light,
        camera=camera,
        wall_albedo=wall_albedo,
        port=port,
        light_ports=light_ports,
    )
    for path in list(files)[1:]:
        check_output_file(path, option="--out", inputs=inputs, inputs_of="the export")
    written = export_result(
        result,
        args.format,
        args.out,
        source=args.result,
        light_name=args.light,
        camera=camera,
        wall_albedo=wall_albedo,
        port=port,
        light_ports=light_ports,
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
    if medium is not None and args.format in ("ies", "ldt"):
        print(
            f"note: the result's medium ({medium.text()}) has no place in an "
            f"{args.format.upper()} file: it holds the light's RID only",
            file=sys.stderr,
        )
    elif medium is not None and medium.scatters and args.format in ("mitsuba", "blender"):
        where = "--wall-albedo" if args.wall_albedo is not None else "surroundings.wall_albedo"
        print(
            f"note: the medium's scattering coefficient is beta rho / pi with the wall's "
            f"albedo rho = {wall_albedo:g} ({where}): give the scene's wall that albedo",
            file=sys.stderr,
        )
    if project is None and result.ports is not None:
        print(f"note: {ports_left_out(result.ports)}", file=sys.stderr)
    if port is not None and args.format in ("opencv", "ros"):
        print(
            "note: camera.port: the poses are in the frame of the camera in its housing, "
            "whose intrinsics are those in air, behind the port (the file says so)",
            file=sys.stderr,
        )
    _light_port_notes(args, result, light_ports)
    if result.channels:  # colour channels solved jointly: the files hold one channel
        names = [str(ch.get("name")) for ch in result.channels]
        print(
            f"note: the result has colour channels {', '.join(names)}; the export carries "
            f"the first's ({names[0]}) scale and medium, as the result's lights and medium do",
            file=sys.stderr,
        )
    return 0


def _light_port_notes(
    args: argparse.Namespace, result: ResultFile, light_ports: dict[str, LightPort]
) -> None:
    """The notes of lights behind flat ports (`lights[i].port`) on stderr: their poses
    are the emitters' and their RIDs the emitters' in air."""
    if args.format in ("opencv", "ros"):
        for light in result.lights:
            if light.name in light_ports:
                print(
                    f"note: {light_ports[light.name].key}: the pose of {light.name!r} is its "
                    "emitter's, behind its port, and its RID the emitter's in air (the file "
                    "says so)",
                    file=sys.stderr,
                )
    elif args.format in ("ies", "ldt"):
        from lightcal.io.export import select_light

        light = select_light(result, args.result, args.light)
        if light.name in light_ports:
            print(
                f"note: {light_ports[light.name].key}: the RID written is the emitter's in "
                "air, behind its port (as a goniophotometer measures it out of the housing); "
                "in the water the port narrows the beam, which the file cannot hold",
                file=sys.stderr,
            )
