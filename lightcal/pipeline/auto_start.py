"""The automatic initial guess of a project's light: `lightcal.core.beam_start` on the
project's images as loaded (docs/model.md, "Initial guess")."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from lightcal.core.beam_start import BeamGuess, Sighting, guess_from_sightings, sight_beam
from lightcal.core.light_axis import rotation_from_axis
from lightcal.errors import InputError
from lightcal.io.project import Project
from lightcal.pipeline.load import LoadedImages


def beam_sightings(project: Project, loaded: LoadedImages) -> list[Sighting]:
    """Where each image shows the beam (images without a spot are left out). Saturated
    pixels count at the brightest value of their image: they are the beam's core."""
    out = []
    for i, image in enumerate(loaded.images):
        values = np.array(image.values, dtype=np.float64)
        if image.saturated.any():
            finite = values[np.isfinite(values)]
            values[image.saturated] = float(finite.max()) if finite.size else np.nan
        excluded = loaded.excluded[i]
        usable = np.ones(values.shape, bool) if excluded is None else ~np.asarray(excluded)
        sighting = sight_beam(
            values, usable, loaded.camera, project.views[i], image=i, mesh=project.wall_mesh
        )
        if sighting is not None:
            out.append(sighting)
    return out


def beam_guess(project: Project, loaded: LoadedImages) -> BeamGuess | None:
    """The light's position and axis (camera frame) from its beam in the images; None
    when no image shows one. One light: with several, their spots cannot be told apart."""
    return guess_from_sightings(beam_sightings(project, loaded))


def with_auto_initial(project: Project, loaded: LoadedImages) -> Project:
    """The project with each light whose file says `initial: auto` put on its beam
    (`beam_guess`): position and axis in the camera frame; the project itself when none
    does. InputError naming the key when no image shows the beam."""
    auto = [j for j, ls in enumerate(project.spec.lights) if ls.initial == "auto"]
    if not auto:
        return project
    guess = beam_guess(project, loaded)
    if guess is None:
        raise InputError(
            project.path,
            f"lights[{auto[0]}].initial: auto: no image shows the light's beam (each is dark, "
            "masked or its spot off the wall); give the light's initial pose",
        )
    lights = list(project.lights)
    for j in auto:
        unknown = lights[j]
        R = rotation_from_axis(guess.axis_camera)
        lights[j] = replace(
            unknown,
            initial=unknown.initial.replace(t_camera_light=guess.position_camera, R_camera_light=R),
        )
    return replace(project, lights=lights)


def auto_initial_lines(project: Project) -> list[str]:
    """What `with_auto_initial` guessed, in words, per light whose file says auto."""
    from lightcal.core.light_axis import paper_angles_from_axis

    out = []
    for ls, unknown in zip(project.spec.lights, project.lights, strict=True):
        if ls.initial != "auto":
            continue
        light = unknown.initial
        roll, pitch = (np.degrees(a) for a in paper_angles_from_axis(light.R_camera_light[:, 2]))
        x, y, z = light.t_camera_light * 1e3
        out.append(
            f"{light.name}: initial: auto: from its beam in the images, position "
            f"({x:+.0f}, {y:+.0f}, {z:+.0f}) mm, axis roll {roll:+.1f} deg, pitch {pitch:+.1f} deg"
        )
    return out
