"""The explanation panel: what lightcal computes, in words and pictures.

The pictures are PNGs in the repository's `static/` folder, drawn by
`static/make_figures.py` (NumPy and OpenCV only). A missing picture is replaced by a
line saying how to draw it. Two are drawn from the project shown (`PROJECT_FIGURES`): its
lights' profiles and its views' distances and tilts.
"""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np

from lightcal.io.figures import profile_figure, views_figure
from lightcal.io.project import Project
from lightcal.resources import data_folder

STATIC_DIR = data_folder("lightcal_app", "static")  # installed: package data; checkout: static/

SECTIONS: tuple[tuple[str, str, str | None], ...] = (
    (
        "What is calibrated",
        "A light is mounted rigidly on a camera. Its pose relative to the camera, "
        "`T_camera_light` (position p_cl in metres and the direction of its axis), is the "
        "same in every photo. Photos of a flat white wall (z = 0) from several known camera "
        "poses show the light's pattern; lightcal moves a model light until the rendered "
        "photos match the real ones (after Song et al. 2020). Frames: the camera's is "
        "OpenCV's (x right, y down, z forward); the world's wall is z = 0 with its normal "
        "+z towards the cameras; a view T_camera_world = (R_i, t_i) maps X_c = R_i X_w + t_i.",
        "frames.png",
    ),
    (
        "One pixel's footprint",
        "Each pixel's four corners are undistorted and cast as rays onto the wall; they "
        "outline a small quad, the pixel's footprint. A pixel whose corner ray misses the "
        "wall is masked, never guessed. Pixel (u, v) has its centre at integer (u, v) and "
        "its corners at u ± 1/2, v ± 1/2; a corner's ray d = R_i^T K^-1 (u, v, 1) "
        "(undistorted) meets the wall at C_i + λ d with λ = -C_iz / d_z > 0.",
        "footprint.png",
    ),
    (
        "Light reaching the footprint",
        "Seen from the light, the footprint covers a solid angle Omega_Q (computed exactly). "
        "The flux is I0 f Omega_Q, with f the light's relative intensity towards the "
        "footprint; divided by the footprint's area it gives the irradiance, and the "
        "Lambertian wall turns it into the radiance the pixel sees: "
        "Φ_Q = I0 f(θ, φ) Ω_Q, E = Φ_Q / A_Q, and the pixel value "
        "m = k g_i V(u, v) ρ E / π + b (k the scale, g_i the image's exposure, V the "
        "camera's fall-off, ρ the wall's albedo, b the offset; with the Solve tab's albedo "
        "map, ρ a(x, y): the wall's unevenness, estimated with the light).",
        "solid_angle.png",
    ),
    (
        "The light's angular profile (RID)",
        "f(theta) falls off with the angle from the light's axis. The cones in the 3D view "
        "show where it is half (half-intensity angle) and 1 % (cut-off). A profile can come "
        "from a formula, a table, or an IES/LDT file (Files tab).",
        "rid.png",
    ),
    (
        "Your views",
        "Each dot is one photo of this project: how far its camera was from the wall and how "
        "far its optical axis tilted from the wall's normal. A spread in both is what pins "
        "the light down (one distance and one angle leave the position along the light's "
        "axis and its brightness entangled); the **Plan** tab suggests the views that add "
        "most.",
        "views",
    ),
    (
        "Fitting",
        "The solver (least squares) changes the light's position, axis and brightness scale "
        "to make rendered pixel values equal the real ones at the selected pixels (Pixels "
        "tab). The residual maps show what is left; the result lists each number with its "
        "1-sigma uncertainty and warns when the photos lack distance or angle variety. In "
        "the residual maps red means the real image is brighter than the rendered one, "
        "blue darker; after Run they are flat (noise only).",
        "residual.png",
    ),
)


def load_figure(name: str) -> np.ndarray | None:
    """(H, W, 3) uint8 RGB of a static picture, or None when missing or unreadable."""
    path = STATIC_DIR / name
    if not path.is_file():
        return None
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        return None
    return np.ascontiguousarray(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))


def rid_curves(project: Project) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """The project's lights' profiles for `profile_figure`: (label, angles 0-90 deg,
    relative intensity); a light without rotational symmetry gives two azimuths."""
    theta_deg = np.linspace(0.0, 90.0, 181)
    theta = np.radians(theta_deg)
    curves = []
    for u in project.lights:
        rid = u.initial.rid
        name = u.initial.name
        if rid.symmetric:
            half_deg = math.degrees(rid.half_angle_rad)
            half = f" (half at {half_deg:.1f} deg)" if half_deg < 90.0 else " (isotropic)"
            curves.append((f"{name}{half}", theta_deg, rid(theta)))
        else:
            for phi_deg in (0.0, 90.0):
                phi = np.full_like(theta, math.radians(phi_deg))
                curves.append((f"{name}, azimuth {phi_deg:.0f} deg", theta_deg, rid(theta, phi)))
    return curves


def project_rid_figure(project: Project) -> np.ndarray:
    """(H, W, 3) the project's RIDs, laid out for the panel's width: 600 pixels shown
    in about 360, so that the text is about 12 pixels tall on the page."""
    return profile_figure(
        rid_curves(project), title="this project's lights", size=(300, 210), scale=2
    )


def view_geometry(project: Project) -> tuple[np.ndarray, np.ndarray]:
    """(N,) each view's distance from the wall (m, its camera centre's z) and (N,) the tilt
    of its optical axis from the wall's normal (deg)."""
    distance = np.array([float(v.center_world[2]) for v in project.views])
    # The optical axis in the world is the third row of R_camera_world; the camera looks
    # towards -z (the wall's normal points at the cameras).
    axis_z = np.array([float(v.R_camera_world[2, 2]) for v in project.views])
    return distance, np.degrees(np.arccos(np.clip(-axis_z, -1.0, 1.0)))


def project_views_figure(project: Project) -> np.ndarray:
    """(H, W, 3) the project's views as distance against tilt (`view_geometry`), at the
    panel's scale (600 pixels shown in about 360)."""
    distance, tilt = view_geometry(project)
    return views_figure(distance, tilt, project.names, title="this project's views")


PROJECT_FIGURES = {"rid.png": project_rid_figure, "views": project_views_figure}
"""The sections' figures drawn from the project shown, by their SECTIONS key."""


def add_explanation(gui: Any, project: Project | None = None) -> dict[str, Any]:
    """Add the explanation's folders to the current GUI container; with `project`, the
    figures of `PROJECT_FIGURES` show that project (its lights, its views).

    Returns:
        those figures' image handles by key (none without a project), for `set_project`.
    """
    handles: dict[str, Any] = {}
    for k, (title, body, figure) in enumerate(SECTIONS):
        with gui.add_folder(title, expand_by_default=k == 0):
            gui.add_markdown(body)
            if figure in PROJECT_FIGURES:
                if project is not None:
                    drawn = PROJECT_FIGURES[figure](project)
                    handles[figure] = gui.add_image(drawn, format="png")
            elif figure is not None:
                rgb = load_figure(figure)
                if rgb is None:
                    gui.add_markdown(
                        f"*(picture {figure} missing: run `python static/make_figures.py`)*"
                    )
                else:
                    gui.add_image(rgb, format="png")
    return handles
