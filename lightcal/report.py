"""Calibration reports: full-image renders, residual maps and the convergence plot.

`render_views` renders every image of a project with the calibrated lights;
`write_report` writes, per image, the residual map (real minus rendered, diverging
colours with a scale) and the real and rendered images side by side, plus the
convergence plot and a short Markdown summary, into a folder that shows one complete
report at a time (written aside, moved in at the end).
"""

from __future__ import annotations

import functools
import math
import os
import re
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from lightcal.core.albedo_map import AlbedoMap, with_albedo
from lightcal.core.bounce_image import BounceImages
from lightcal.core.medium import AIR, Medium
from lightcal.core.port_render import render_view_image, room_light_view
from lightcal.core.problem import with_view
from lightcal.core.scene import Rig, View
from lightcal.core.solver import CalibrationModel
from lightcal.core.surroundings import Surroundings
from lightcal.core.wall import LAMBERTIAN, WallReflectance
from lightcal.io.atomic import atomic_folder, atomic_write_text, signals_held
from lightcal.io.cause_figure import cause_figure
from lightcal.io.escaping import markdown_prose, markdown_text
from lightcal.io.figures import (
    PRINT_SCALE,
    angle_residual_figure,
    convergence_figure,
    image_pair_figure,
    residual_figure,
    write_png,
)
from lightcal.io.outputs import inside, safe_names
from lightcal.io.project import Project
from lightcal.pipeline import CalibrationResult, LoadedImages, ProgressFn, vignetting_for
from lightcal.pipeline.albedo_result import albedo_image, albedo_text
from lightcal.pipeline.channel_result import channel_scenes_at, estimated_surroundings
from lightcal.pipeline.fall_off_result import ambient_text, fall_off_text
from lightcal.pipeline.result_text import axis_text, medium_text, position_text
from lightcal.pipeline.results import stop_reason

FIGURE_THREADS = min(2, os.cpu_count() or 1)
"""Images whose figures `write_report` makes at once."""


def render_views(
    project: Project,
    loaded: LoadedImages,
    rig: Rig,
    *,
    gains: list[float] | None = None,
    offset: float = 0.0,
    progress: ProgressFn | None = None,
    wall: WallReflectance = LAMBERTIAN,
    medium: Medium = AIR,
    fall_off: np.ndarray | None = None,
    ambient: float = 0.0,
    albedo: AlbedoMap | None = None,
    channels: Sequence[tuple[Rig, Medium, float]] = (),
    surroundings: Surroundings | None = None,
) -> list[np.ma.MaskedArray]:
    """Render every project image with `rig` on `wall` through `medium`: (H, W) masked
    arrays. `ambient`, an estimated room light (value at exposure and gain 1), adds
    gain x exposure x it; `fall_off` (H, W), an estimated fall-off V, multiplies the
    values above the offset, as does an estimated albedo map `albedo` at each pixel's
    wall point (the wall's light: not the water's veil). With colour channels solved
    jointly, `channels` gives each channel's (rig, medium, ambient), used for the images
    of that channel instead. `surroundings`: the bounce's (the project's when None; the
    result's albedos when it estimated them)."""
    out = []
    n = len(project.views)
    vignetting = vignetting_for(project, loaded.camera)
    room_factor = room_light_view(
        loaded.camera, project.spec.sensor.model, vignetting, project.camera_port
    )
    bounces = None
    surroundings = surroundings or project.surroundings
    if surroundings is not None:  # one bounce map for every view
        bounces = BounceImages(
            loaded.camera,
            project.views,
            surroundings,
            sensor=project.spec.sensor.model,
            vignetting=vignetting,
        )
    base = (rig, medium, ambient)
    for i, view in enumerate(project.views):
        if progress is not None:
            progress("rendering", i, n)
        rig, medium, ambient = channels[project.channel_index(i)] if channels else base
        g = 1.0 if gains is None else gains[i]
        seen = with_view(view, exposure=view.exposure * g)
        bounce: float | np.ndarray = 0.0  # the surroundings' light, as the model adds it
        if bounces is not None:  # (the wall's: the same without the veil)
            bounce = bounces.image(i, seen, rig, medium)

        def through(
            medium: Medium,
            seen: View = seen,
            bounce: float | np.ndarray = bounce,
            g: float = g,
            view: View = view,
            rig: Rig = rig,
            ambient: float = ambient,
        ) -> np.ma.MaskedArray:
            values = bounce + render_view_image(
                loaded.camera,
                seen,
                rig,
                port=project.camera_port,
                mesh=project.wall_mesh,
                sensor=project.spec.sensor.model,
                vignetting=vignetting,
                offset=0.0,
                rid_subsamples=project.solver.rid_subsamples,
                wall=wall,
                medium=medium,
            )
            if ambient != 0.0:  # through the lens's fall-off
                room = g * view.exposure * ambient
                values = values + (room if room_factor is None else room * room_factor)
            return values if fall_off is None else values * fall_off

        if albedo is None:
            out.append(offset + through(medium))
        else:
            factor = albedo_image(albedo, loaded.camera, view)
            out.append(offset + with_albedo(through, medium, factor))
    if progress is not None:
        progress("rendering", n, n)
    return out


def write_report(
    folder: str | Path,
    project: Project,
    loaded: LoadedImages,
    model: CalibrationModel,
    result: CalibrationResult,
    *,
    progress: ProgressFn | None = None,
    image_scale: float = PRINT_SCALE,
) -> list[Path]:
    """Write the report into `folder`; returns the files written (in `folder`).

    `image_scale`: the per-image figures' pixels per layout point (2, the default, for
    print; 1 makes them a quarter of the pixels and bytes: the app's report download).

    The report is written aside and moved in complete (`lightcal.io.atomic.atomic_folder`):
    a new folder appears with every file or not at all (an interruption removes the
    partial one). Into an existing folder, the files move in under a lock, one run at a
    time: those of an earlier report written there (listed at the end of its summary.md)
    that this one does not write are removed, and nothing else in the folder is touched.
    Two runs given the same folder leave the complete report of one of them, never a mix.
    """
    out = Path(folder)
    out.parent.mkdir(parents=True, exist_ok=True)
    x = np.asarray(result.x)
    rig = model.layout.rig(x)
    names = project.names
    gains_by_name = dict(zip(result.image_names, result.gains, strict=True))
    gains = [gains_by_name.get(n, 1.0) for n in names]
    renders = render_views(
        project,
        loaded,
        rig,
        gains=gains,
        offset=result.offset,
        progress=progress,
        wall=model.layout.wall_of(x),
        medium=model.layout.medium_of(x),
        fall_off=(
            None
            if model.layout.fall_off_unknown is None
            else model.layout.fall_off_unknown.image(x[model.layout.fall_off])
        ),
        ambient=model.layout.ambient(x),
        albedo=model.albedo_map(x),
        channels=channel_scenes_at(model, x),
        surroundings=estimated_surroundings(model.surroundings, result.surroundings),
    )
    files = safe_names(names)  # image names come from the data: one plain part each

    def figures(folder: Path, i: int) -> tuple[list[Path], float]:
        """Image i's residual map and real/rendered pair, written; and its RMS."""
        # The user's masks (markers, stray light) are not wall: not in the residuals.
        img, excluded, rendered = loaded.images[i], loaded.excluded[i], renders[i]
        hidden = img.saturated | np.ma.getmaskarray(rendered)
        if excluded is not None:
            hidden = hidden | excluded
        real = np.ma.masked_array(img.values, mask=hidden)
        residual = real - rendered
        rms = float(np.sqrt(np.ma.mean(residual**2))) if residual.count() else math.nan
        title = f"{names[i]}: real - rendered (RMS {rms:.4g})"
        maps = inside(folder, f"residual_{files[i]}.png")
        write_png(maps, residual_figure(residual, title=title, scale=image_scale))
        pair = inside(folder, f"images_{files[i]}.png")
        write_png(pair, image_pair_figure(real, rendered, title=names[i], scale=image_scale))
        return [maps, pair], rms

    written: list[Path] = []
    with atomic_folder(out, earlier_files=_report_files) as staging:
        rms_rows = []
        # Two images at a time: the colour maps, resampling and PNG encoding run in NumPy
        # and OpenCV, which release the interpreter (the sample's 24 figures: 2.8 -> 1.7-1.9 s).
        with ThreadPoolExecutor(max_workers=FIGURE_THREADS) as pool:
            try:
                done = pool.map(functools.partial(figures, staging), range(len(names)))
                for i, (paths, rms) in enumerate(done):
                    if progress is not None:
                        progress("writing figures", i, len(names))
                    written.extend(paths)
                    rms_rows.append((names[i], rms))
            except BaseException:  # no figure may be written once the folder is removed
                with signals_held():
                    pool.shutdown(wait=True, cancel_futures=True)
                raise
        if progress is not None:
            progress("writing figures", len(names), len(names))
        p = staging / "convergence.png"
        write_png(
            p,
            convergence_figure(
                [h.cost for h in result.history],
                earlier=result.start_costs,
                earlier_label="the first solve, on a subsample (cost x m / its pixels)",
            ),
        )
        written.append(p)
        if result.fit:
            p = staging / "fit_vs_angle.png"
            write_png(p, angle_residual_figure(result.fit))
            written.append(p)
            causes = cause_figure(result.fit)
            if causes is not None:
                p = staging / "fit_causes.png"
                write_png(p, causes)
                written.append(p)
        if result.albedo_map is not None:
            p = staging / "albedo_map.png"
            write_png(p, albedo_figure(result.albedo_map, image_scale))
            written.append(p)
        p = staging / SUMMARY
        written.append(p)
        summary = _summary_markdown(project, result, rms_rows)
        atomic_write_text(p, summary + _file_list([w.name for w in written]))
    return [out / p.name for p in written]


SUMMARY = "summary.md"
"""The report's summary, which also lists the report's files (`_file_list`)."""

_FILE_LIST = "<!-- lightcal report files (the next report written here replaces them):"

_REPORT_FILE = re.compile(
    r"(residual|images)_[A-Za-z0-9._+-]+\.png|(convergence|fit_vs_angle|fit_causes)\.png"
    r"|summary\.md"
)
"""The names a report's files can have (what `_report_files` may name)."""


def _file_list(names: list[str]) -> str:
    """The end of summary.md: the report's files, in a comment Markdown does not show."""
    return "\n".join(["", _FILE_LIST, *names, "-->", ""])


def _report_files(folder: Path) -> set[str]:
    """The files of the report in `folder`, as its summary.md lists them (none when
    there is no summary, or it comes from a lightcal that did not list them): only names
    a report's file can have."""
    summary = folder / SUMMARY
    try:
        if not summary.is_file() or summary.stat().st_size > 10_000_000:
            return set()
        text = summary.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return set()
    start = text.rfind(_FILE_LIST)
    if start < 0:
        return set()
    listed = text[start + len(_FILE_LIST) :].partition("-->")[0].split()
    return {name for name in listed if _REPORT_FILE.fullmatch(name)}


def _summary_markdown(
    project: Project, result: CalibrationResult, rms_rows: list[tuple[str, float]]
) -> str:
    lines = [f"# lightcal report: {markdown_text(project.path.name)}", ""]
    status = "converged" if result.converged else "NOT converged"
    lines.append(
        f"Solver {status} after {result.iterations} iterations: "
        f"{markdown_prose(stop_reason(result.status, result.message))}; "
        f"{sum(result.pixels_used)} pixels; {result.time_s:.2f} s."
    )
    lines.append("")
    for lr in result.lights:
        lines.append(f"## {markdown_text(lr.name)} ({markdown_text(lr.pose_kind)})")
        lines.append("")
        lines.append(f"- position (camera frame): {position_text(lr)}")
        if axis_text(lr):
            ax = lr.pose.axis_camera
            lines.append(f"- axis: {axis_text(lr)}")
            lines.append(f"- axis vector (camera frame): ({ax[0]:.5f}, {ax[1]:.5f}, {ax[2]:.5f})")
        lines.append(f"- scale {lr.scale:.6g} ± {lr.scale_sigma:.2g}")
        lines.append("")
    lines.extend(_fit_lines(result))
    if result.warnings:
        lines.append("## Warnings")
        lines.append("")
        lines.extend(f"- {markdown_prose(w)}" for w in result.warnings)
        lines.append("")
    lines.append("## Images")
    lines.append("")
    lines.append("| image | pixels used | RMS at selected pixels | RMS over the image |")
    lines.append("|---|---|---|---|")
    sel_rms = dict(zip(result.image_names, result.per_image_rms, strict=True))
    used = dict(zip(result.image_names, result.pixels_used, strict=True))
    for name, rms in rms_rows:
        sel = sel_rms.get(name, math.nan)
        lines.append(f"| {markdown_text(name)} | {used.get(name, 0)} | {sel:.4g} | {rms:.4g} |")
    lines.append("")
    lines.append("![convergence](convergence.png)")
    lines.append("")
    if result.start:
        drawn = " (its iterations are the grey curve)" if result.start_costs else ""
        lines.append(f"Iteration 0 is {markdown_prose(result.start)}{drawn}.")
        lines.append("")
    return "\n".join(lines)


def _fit_lines(result: CalibrationResult) -> list[str]:
    """The wall model and the fit test, for the summary."""
    lines = ["## Wall and fit", ""]
    wall = result.wall
    params = ", ".join(
        f"{k} {v:.4g}" + (f" ± {wall['sigma'][k]:.2g}" if k in wall.get("sigma", {}) else "")
        for k, v in wall.items()
        if isinstance(v, float)
    )
    lines.append(
        f"- wall: {markdown_text(wall.get('model', 'lambertian'))}"
        + (f" ({params})" if params else "")
    )
    medium = medium_text(result.medium)
    if medium is not None:
        lines.append(f"- {medium}")
    if result.fall_off is not None:
        lines.append(f"- {markdown_prose(fall_off_text(result.fall_off))}")
    if result.ambient is not None:
        lines.append(f"- {markdown_prose(ambient_text(result.ambient, result.ambient_sigma))}")
    if result.albedo_map is not None:
        lines.append(f"- {markdown_prose(albedo_text(result.albedo_map))}")
    fit = result.fit
    if fit:
        if not fit["adequate"]:
            verdict = "a misfit that moves the pose beyond its statistical sigma"
        elif fit.get("explained_by_noise", True):
            verdict = "explained by the noise"
        else:
            verdict = "not explained by the noise, but no misfit moves the pose beyond its sigma"
        ratio = fit["chi2"] / fit["expected_chi2"] if fit.get("expected_chi2") else math.nan
        lines.append(
            f"- fit: {verdict} (noise from {fit['noise_source']}; chi2 {fit['chi2']:.4g}, "
            f"expected {fit['expected_chi2']:.4g}, ratio {ratio:.3f})"
        )
        lines.extend(f"  - {markdown_prose(f)}" for f in fit["findings"])
        lines.extend(f"  - note: {markdown_prose(n)}" for n in fit.get("notes", []))
    if result.uncertainty_terms:
        lines.append("- the sigmas include:")
        lines.extend(f"  - {markdown_prose(t)}" for t in result.uncertainty_terms)
    lines.append("")
    if fit:
        lines.append("![residuals against angle](fit_vs_angle.png)")
        lines.append("")
        if fit.get("causes"):
            lines.append("![how far each candidate cause would move the pose](fit_causes.png)")
            lines.append("")
    if result.albedo_map is not None:
        lines.append("![the wall's estimated albedo over its mean](albedo_map.png)")
        lines.append("")
    return lines


def albedo_figure(summary: dict, scale: float) -> np.ndarray:
    """The estimated albedo map (over its mean, minus 1) on the wall, world y up."""
    values = np.array(
        [[np.nan if v is None else v - 1.0 for v in row] for row in summary["values"]]
    )[::-1]
    mm = summary["spacing_m"] * 1000
    return residual_figure(
        np.ma.masked_invalid(values),
        title=f"wall albedo / mean - 1 (nodes every {mm:.3g} mm, world y up)",
        unit="",
        scale=scale,
    )
