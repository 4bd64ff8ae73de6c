"""The pixels the app's solve uses: the project's selection with the user's changes.

The user may change the strategy (globally or for one image), draw include/exclude
regions and click single pixels. All of it goes through `lightcal.calibration.image_data`
on a copy of the project whose selection options and regions are the user's, so the
app selects exactly as `lightcal calibrate` would with the same settings. Clicked pixels
are added to the strategy's pixels when they are candidates (not saturated, masked,
below the noise floor or excluded).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from app.state import SelectionSettings, UserRegion
from lightcal.calibration import LoadedImages, image_data, noise_floor, regions_for
from lightcal.core.problem import ImageData
from lightcal.core.selection import SelectionOptions, binned_candidates, candidate_mask
from lightcal.io.project import Project, RegionSpec


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


def candidate_points(
    project: Project, loaded: LoadedImages, index: int, points: np.ndarray, binning: int
) -> np.ndarray:
    """The clicked pixels that may enter the calibration, in the (binned) grid.

    Args:
        project: the project with the user's selection (`project_with_selection`).
        loaded: its images.
        index: which image.
        points: (K, 2) clicked full-resolution pixels (u, v).
        binning: b of the selection grid.

    Returns:
        (M, 2) int64 unique (binned) pixel indices that are candidates.
    """
    img = loaded.images[index]
    cand = candidate_mask(
        img.values,
        saturated=img.saturated,
        excluded=loaded.excluded[index],
        regions=regions_for(project, index),
        min_signal=noise_floor(project, img),
    )
    if binning > 1:
        cand = binned_candidates(cand, binning)
    p = np.asarray(points, dtype=np.int64).reshape(-1, 2) // binning
    h, w = cand.shape
    inside = (p[:, 0] >= 0) & (p[:, 0] < w) & (p[:, 1] >= 0) & (p[:, 1] < h)
    p = p[inside]
    p = p[cand[p[:, 1], p[:, 0]]]
    return np.unique(p, axis=0) if p.size else np.zeros((0, 2), np.int64)


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
    data = image_data(p, loaded, index)
    if not points:
        return data
    b = effective_binning(settings)
    extra = candidate_points(p, loaded, index, np.array(points), b)
    if extra.size == 0:
        return data
    both = np.unique(np.concatenate([data.footprints.pixels, extra]), axis=0)
    # Explicit pixels are kept as given (the random strategy would cut them to N).
    explicit = p if settings.strategy != "random" else _as_grid(p)
    return image_data(explicit, loaded, index, pixels=both)


def _as_grid(project: Project) -> Project:
    return replace(project, selection=replace(project.selection, strategy="grid"))


def footprint_centres(data: ImageData) -> np.ndarray:
    """(N, 3) mean of each selected pixel's footprint corners on the wall, m."""
    if len(data.footprints) == 0:
        return np.zeros((0, 3))
    corners = data.footprints.corners_world  # (N, K, 4, 3)
    return np.asarray(corners.reshape(corners.shape[0], -1, 3).mean(axis=1))
