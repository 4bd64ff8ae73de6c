"""`lightcal render PROJECT --result result.json --out DIR`: render full images."""

from __future__ import annotations

import argparse

from lightcal.cli.arguments import path_arg


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("render", help="render a project's images with calibrated lights")
    p.add_argument("project", type=path_arg)
    p.add_argument("--result", type=path_arg, required=True, help="result JSON of calibrate")
    p.add_argument("--out", type=path_arg, required=True, help="folder for the renders")
    p.add_argument(
        "--force", action="store_true", help="write into a non-empty --out (replacing renders)"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import io

    import numpy as np
    import tifffile

    from lightcal.cli.progress import console, ensure_kernels, stage_progress
    from lightcal.core.medium import medium_from_description
    from lightcal.core.scene import Rig
    from lightcal.core.wall import wall_from_description
    from lightcal.errors import InputError
    from lightcal.io.atomic import atomic_write_bytes
    from lightcal.io.figures import image_pair_figure, write_png
    from lightcal.io.outputs import (
        check_output_file,
        check_output_folder,
        inside,
        project_inputs,
        safe_names,
    )
    from lightcal.io.project import load_project
    from lightcal.io.project_identity import check_result_of
    from lightcal.io.result_file import read_result
    from lightcal.pipeline import load_images
    from lightcal.pipeline.channel_result import channel_scenes, estimated_surroundings
    from lightcal.pipeline.fall_off_result import fall_off_map
    from lightcal.report import render_views

    project = load_project(args.project)
    result = read_result(args.result)
    check_result_of(project, args.result, result.project_id)
    by_name = {lr.name: lr for lr in result.lights}
    lights = []
    for unknown in project.lights:
        lr = by_name.get(unknown.initial.name)
        if lr is None:
            raise InputError(args.result, f"no result for light {unknown.initial.name!r}")
        lights.append(  # the project's light (its RID and port) at the result's pose
            unknown.initial.replace(
                t_camera_light=np.array(lr.position_m),
                R_camera_light=np.array(lr.R_camera_light),
                scale=lr.scale,
                name=lr.name,
            )
        )
    gains = {im.name: im.gain for im in result.images}
    try:
        wall = wall_from_description(result.wall)
    except ValueError as exc:
        raise InputError(args.result, f"wall: {exc}") from exc
    try:
        medium = medium_from_description(result.medium)
        channels = channel_scenes(result.channels, lights, project.channels)
        surroundings = estimated_surroundings(project.surroundings, result.surroundings)
    except ValueError as exc:
        raise InputError(args.result, str(exc)) from exc
    try:  # the sensor terms the result estimated (checked before any work)
        fall_off_map(result.fall_off, project.camera.width, project.camera.height)
    except ValueError as exc:
        raise InputError(args.result, str(exc)) from exc
    # Before any work: --out holds no input of the project, and no render replaces the
    # result file (even with --force).
    check_output_folder(args.out, option="--out", inputs=project_inputs(project), force=args.force)
    files = safe_names(project.names)  # image names come from the data: one plain part each
    if args.out.is_dir():
        for file in files:
            for kind in ("rendered.tif", "compare.png"):
                check_output_file(
                    inside(args.out, f"{file}_{kind}"),
                    option="--out",
                    inputs={args.result.resolve(): "the result file"},
                    inputs_of="the render",
                )
    ensure_kernels()
    args.out.mkdir(parents=True, exist_ok=True)
    with stage_progress() as progress:
        loaded = load_images(project, progress=progress)
        # On the images' grid (a raw reader's binned one when it binned): r is the same.
        fall_off = fall_off_map(result.fall_off, loaded.camera.width, loaded.camera.height)
        renders = render_views(
            project,
            loaded,
            Rig(tuple(lights)),
            gains=[gains.get(n, 1.0) for n in project.names],
            offset=result.offset,
            progress=progress,
            wall=wall,
            medium=medium,
            fall_off=fall_off,
            ambient=result.ambient or 0.0,
            channels=channels,
            surroundings=surroundings,
        )
    for name, file, img, rendered in zip(project.names, files, loaded.images, renders, strict=True):
        data = np.ma.filled(rendered.astype(np.float32), np.nan)
        buf = io.BytesIO()
        tifffile.imwrite(buf, data)
        atomic_write_bytes(inside(args.out, f"{file}_rendered.tif"), buf.getvalue())
        write_png(
            inside(args.out, f"{file}_compare.png"),
            image_pair_figure(img.values, rendered, title=name),
        )
    console.print(
        f"{len(renders)} renders (32-bit float TIFF, NaN off the wall) written to {args.out}",
        highlight=False,
    )
    return 0
