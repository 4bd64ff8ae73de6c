"""The result as the page shows it, and the files it can download.

The numbers come from `lightcal.pipeline.summarise` (uncertainties, pose-variety
warnings); the files from `lightcal.io.result_file` (result JSON) and
`lightcal.report.write_report` (the report folder, zipped here).
"""

from __future__ import annotations

import io
import math
import tempfile
import zipfile
from pathlib import Path

from lightcal.core.solver import CalibrationModel
from lightcal.errors import InputError
from lightcal.io.project import Project
from lightcal.io.project_identity import project_identity
from lightcal.io.result_file import project_ports, result_to_file
from lightcal.pipeline import CalibrationResult, LoadedImages
from lightcal.pipeline.albedo_result import albedo_text
from lightcal.pipeline.result_text import axis_text, channel_lines, medium_text, position_text
from lightcal.pipeline.results import stop_reason
from lightcal_app.state import PreviousResult
from lightcal_app.text import md, md_prose


def previous_markdown(previous: PreviousResult) -> str:
    """What the Result tab says of a finished result an edit replaced (kept for undo)."""
    result = previous.result
    lines = [
        f"**Previous result** ({previous.state}, {result.iterations} iterations), kept when "
        "the setup changed; **Restore** brings it back with its settings.  "
    ]
    for lr in result.lights:
        lines.append(f"{md(lr.name)}: position {md_prose(position_text(lr))}  ")
        if axis_text(lr):
            lines.append(f"axis {md_prose(axis_text(lr))}  ")
    return "\n".join(lines)


MISFIT_WORDS = (
    "but the fit test found a misfit that moves the pose beyond its statistical sigma "
    "(the Result tab says what and how much; the sigmas include it)"
)
"""What the Solve tab's status and the Result tab's head add to "converged" when the fit
test has a finding: one status in both tabs, as `lightcal calibrate` prints it."""


def result_markdown(result: CalibrationResult | None, *, state: str) -> str:
    """The Result panel's text."""
    if result is None:
        return (
            "No result yet. Press **Step** or **Run** in the Solve tab; the estimate with its "
            "uncertainties (1 sigma) appears here when the solver pauses or finishes."
        )
    if result.converged and not result.fit_adequate:
        head = f"converged, {MISFIT_WORDS}"
    elif result.converged:
        head = "converged"
    elif state in ("paused", "running"):
        head = f"not converged ({state}: the estimate so far)"
    else:
        head = "not converged"
    lines = [
        f"**{head}**: {md_prose(stop_reason(result.status, result.message))}  ",
        f"{result.iterations} iterations, {sum(result.pixels_used)} pixels, cost {result.cost:.6g}",
        "",
    ]
    for lr in result.lights:
        p, sp = lr.pose.t_camera_light, lr.sigma.t_camera_light
        ax, sax = lr.pose.axis_camera, lr.sigma.axis_camera
        lines += [
            f"#### {md(lr.name)} ({lr.pose_kind})",
            "| quantity | value | ± 1 sigma |",
            "|---|---|---|",
        ]
        for k, axis_name in enumerate("xyz"):
            lines.append(f"| position {axis_name} (mm) | {p[k] * 1e3:+.3f} | {sp[k] * 1e3:.2g} |")
        if lr.pose_kind != "isotropic":
            for k, axis_name in enumerate("xyz"):
                lines.append(f"| axis {axis_name} | {ax[k]:+.5f} | {sax[k]:.2g} |")
            lines.append(
                "| axis from optical axis (deg) | "
                f"{lr.pose.axis_angle_from_optical_axis_deg:.3f} "
                f"| {lr.sigma.axis_angle_from_optical_axis_deg:.2g} |"
            )
            lines.append(f"| roll (deg) | {lr.pose.roll_deg:+.3f} | {lr.sigma.roll_deg:.2g} |")
            lines.append(f"| pitch (deg) | {lr.pose.pitch_deg:+.3f} | {lr.sigma.pitch_deg:.2g} |")
        lines += _scale_rows(result, lr.name, lr.scale, lr.scale_sigma)
        lines.append("")
    lines += _wall_and_fit(result)
    if result.warnings:
        lines.append("#### ⚠ Warnings")
        lines += [f"- {md_prose(w)}" for w in result.warnings]
        lines.append("")
    lines += ["#### Images", "| image | pixels | RMS (pixel values) |", "|---|---|---|"]
    for name, n, rms in zip(
        result.image_names, result.pixels_used, result.per_image_rms, strict=True
    ):
        rms_text = f"{rms:.4g}" if math.isfinite(rms) else "-"
        lines.append(f"| {md(name)} | {n} | {rms_text} |")
    return "\n".join(lines)


def _scale_rows(result: CalibrationResult, light: str, scale: float, sigma: float) -> list[str]:
    """A light's scale row: one per colour channel solved jointly (`sensor.channels`)."""
    if not result.channels:
        return [f"| scale | {scale:.5g} | {sigma:.2g} |"]
    rows = []
    for ch in result.channels:
        if light in ch["scales"]:
            s = ch["scale_sigmas"].get(light)
            sigma_text = f"{math.nan if s is None else s:.2g}"
            rows.append(f"| scale ({md(ch['name'])}) | {ch['scales'][light]:.5g} | {sigma_text} |")
    return rows


def channels_markdown(result: CalibrationResult) -> list[str]:
    """Each colour channel's lights' scales, water and room light with their sigmas, as
    `lightcal calibrate` prints them (`channel_lines`); nothing without channels."""
    if not result.channels:
        return []
    lines = ["", "#### Colour channels", "Each has its own (the light's pose is one for all):"]
    lines += [f"- {md_prose(line)}" for line in channel_lines(result.channels)]
    return [*lines, ""]


def _wall_and_fit(result: CalibrationResult) -> list[str]:
    """The wall model with its parameters, the water (as `lightcal calibrate` prints it;
    nothing in air), the wall's albedo map (when estimated) and the fit test's verdict."""
    wall = result.wall
    sig = wall.get("sigma", {})
    lines = [f"#### Wall: {wall.get('model', 'lambertian')}"]
    params = [(k, v) for k, v in wall.items() if isinstance(v, float)]
    if params:
        lines += ["| parameter | value | ± 1 sigma |", "|---|---|---|"]
        for k, v in params:
            s = f"{sig[k]:.2g}" if k in sig else "fixed"
            lines.append(f"| {k} | {v:.4g} | {s} |")
    lines += channels_markdown(result)
    water = None if result.channels else medium_text(result.medium)  # the channels' lines
    if water is not None:
        lines += ["", f"Water: {md_prose(water.removeprefix('medium: '))}", ""]
    if result.albedo_map is not None:  # as `lightcal calibrate` prints it
        albedo = albedo_text(result.albedo_map).removeprefix("wall albedo map: ")
        lines += ["", f"Wall albedo map: {md_prose(albedo)}", ""]
    fit = result.fit
    if fit:
        if not fit["adequate"]:
            lines.append(
                "Fit: **⚠ a misfit moves the pose beyond its statistical sigma** (the sigmas "
                "below include it):"
            )
            lines += [f"- {md_prose(f)}" for f in fit["findings"]]
        elif fit.get("explained_by_noise", True):
            lines.append("Fit: **explained by the noise**.")
        else:
            lines.append(
                "Fit: **not explained by the noise**, but nothing found moves the pose beyond "
                "its sigma (the sigmas include the misfit)."
            )
        lines += [f"- note: {md_prose(n)}" for n in fit.get("notes", [])]
        lines.append("")
    if result.uncertainty_terms:
        lines.append("Sigmas include:")
        lines += [f"- {md_prose(t)}" for t in result.uncertainty_terms]
    lines.append("")
    return lines


def result_json_bytes(result: CalibrationResult, project: Project) -> bytes:
    """The result file (`lightcal calibrate --out` format) as bytes."""
    file = result_to_file(
        result,
        project=project.path,
        project_id=project_identity(project),
        ports=project_ports(project),
    )
    return (file.model_dump_json(indent=2) + "\n").encode()


EXPORT_SUFFIX = {
    "opencv": ".yaml",
    "blender": ".py",
    "mitsuba": ".xml",
    "ies": ".ies",
    "ldt": ".ldt",
}
"""The file each `lightcal export` format writes (Mitsuba's comes zipped with its textures)."""


def export_download(result: CalibrationResult, project: Project, fmt: str) -> tuple[str, bytes]:
    """(file name, bytes) of `lightcal export --format fmt --project ...` on this result.

    The lights' RIDs come from the result where estimated, else from the project; a
    Mitsuba scene with its textures comes as a zip.
    """
    from lightcal.io.export import FORMATS, export_files
    from lightcal.io.export_light_port import light_ports_of
    from lightcal.io.export_lights import with_given_rids
    from lightcal.io.result_file import ResultFile

    if fmt not in FORMATS:
        raise InputError("export format", f"expected one of {', '.join(FORMATS)}, got {fmt!r}")
    stem = project.path.stem
    result_file = ResultFile.model_validate_json(result_json_bytes(result, project))
    rids = {u.initial.name: u.initial.rid for u in project.lights}
    result_file = with_given_rids(result_file, rids)
    main = Path(f"{stem}.{fmt}{EXPORT_SUFFIX[fmt]}")
    # a medium that scatters: its scattering coefficient needs the wall's albedo
    rho = None if project.surroundings is None else project.surroundings.wall_albedo
    # the project's camera and its ports, as `--project` gives them (the CLI's `export`)
    ports = light_ports_of([(u.initial.name, u.initial.port) for u in project.lights])
    files = export_files(
        result_file, fmt, main, source=f"{stem}.result.json", wall_albedo=rho,
        camera=project.camera, port=project.camera_port, light_ports=ports,
    )  # fmt: skip
    if len(files) == 1:
        return main.name, files[main]
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for path, content in files.items():
            zf.writestr(path.name, content)
    return f"{stem}.{fmt}.zip", buf.getvalue()


def report_zip_bytes(
    project: Project,
    loaded: LoadedImages,
    model: CalibrationModel,
    result: CalibrationResult,
    *,
    full_size: bool = False,
) -> bytes:
    """The report folder (`lightcal calibrate --report`) plus the result JSON, zipped.
    The per-image figures at screen size (`write_report`'s image_scale 1: the sample's
    zip 9 MB instead of 37 MB), or at the CLI's print size with `full_size`."""
    from lightcal.io.figures import PRINT_SCALE
    from lightcal.report import write_report

    buf = io.BytesIO()
    with tempfile.TemporaryDirectory(prefix="lightcal-report-") as tmp:
        folder = Path(tmp) / "report"
        scale = PRINT_SCALE if full_size else 1.0
        files = write_report(folder, project, loaded, model, result, image_scale=scale)
        with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
            for f in files:
                zf.write(f, f"report/{f.name}")
            zf.writestr("report/result.json", result_json_bytes(result, project))
    return buf.getvalue()
