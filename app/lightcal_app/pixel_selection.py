"""The pixels the app's solve uses: the project's selection with the user's changes.

The user may change the strategy (globally or for one image), draw include/exclude
regions and click single pixels. All of it goes through `lightcal.pipeline.image_data`
on a copy of the project whose selection options and regions are the user's, so the
app selects exactly as `lightcal calibrate` would with the same settings. Clicked pixels
are added to the strategy's pixels when they are candidates (not saturated, masked,
below the noise floor or excluded).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from lightcal.core.problem import ImageData
from lightcal.core.selection import SelectionOptions
from lightcal.io.project import Project, RegionSpec
from lightcal.pipeline import LoadedImages, image_data
from lightcal_app.state import SelectionSettings, UserRegion


def region_spec(region: UserRegion) -> RegionSpec:
    """The project-file form of a user region."""
    return RegionSpec(
        kind=region.kind,
        include=region.include,
        images=None if region.image is None else [region.image],
        points=[list(p) for p in region.points],
    )


def project_with_selection(
    project: Project, settings: SelectionSettings, regions: list[UserRegion]
) -> Project:
    """A copy of `project` whose selection is `settings` plus the user's regions."""
    spec_sel = project.spec.selection.model_copy(
        update={
            "strategy": settings.strategy,
            "n_per_image": settings.n_per_image,
            "grid_step": settings.grid_step,
            "binning": settings.binning,
            "seed": settings.seed,
            "regions": [*project.spec.selection.regions, *(region_spec(r) for r in regions)],
        }
    )
    spec = project.spec.model_copy(update={"selection": spec_sel})
    options = SelectionOptions(
        strategy=settings.strategy,
        n_per_image=settings.n_per_image,
        grid_step=settings.grid_step,
        binning=settings.binning,
        seed=settings.seed,
        min_signal=project.selection.min_signal,
    )
    return replace(project, spec=spec, selection=options)


def effective_binning(settings: SelectionSettings) -> int:
    """Binning of the selected pixels' grid: b for strategy "all", else 1."""
    return settings.binning if settings.strategy == "all" else 1


def select_image(
    project: Project,
    loaded: LoadedImages,
    index: int,
    settings: SelectionSettings,
    regions: list[UserRegion],
    points: list[tuple[int, int]],
) -> ImageData:
    """The selected pixels of one image as solver input (may hold no pixel).

    Args:
        project: the project as loaded.
        loaded: its images.
        index: which image.
        settings: the selection settings for this image.
        regions: the user regions (all of them; those of other images are ignored).
        points: clicked full-resolution pixels of this image.
    """
    p = project_with_selection(project, settings, regions)
    clicked = np.array(points, dtype=np.int64).reshape(-1, 2) // effective_binning(settings)
    return image_data(p, loaded, index, extra_pixels=clicked)


def footprint_centers(data: ImageData) -> np.ndarray:
    """(N, 3) mean of each selected pixel's footprint corners on the wall, m."""
    if len(data.footprints) == 0:
        return np.zeros((0, 3))
    corners = data.footprints.corners_world  # (N, K, 4, 3)
    return np.asarray(corners.reshape(corners.shape[0], -1, 3).mean(axis=1))
