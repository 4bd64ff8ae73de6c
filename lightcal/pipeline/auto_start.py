"""The automatic initial guess of a project's light: `lightcal.core.beam_start` on the
project's images as loaded (docs/model.md, "Initial guess")."""

from __future__ import annotations

import numpy as np

from lightcal.core.beam_start import BeamGuess, Sighting, guess_from_sightings, sight_beam
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
        sighting = sight_beam(values, usable, loaded.camera, project.views[i], image=i)
        if sighting is not None:
            out.append(sighting)
    return out


def beam_guess(project: Project, loaded: LoadedImages) -> BeamGuess | None:
    """The light's position and axis (camera frame) from its beam in the images; None
    when no image shows one. One light: with several, their spots cannot be told apart."""
    return guess_from_sightings(beam_sightings(project, loaded))
