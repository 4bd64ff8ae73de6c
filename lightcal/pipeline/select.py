"""Pixel selection: which pixels of an image the solver sees, with their values and
noise sigmas, as `ImageData`."""

from __future__ import annotations

import math

import numpy as np

from lightcal.core.problem import ImageData, poisson_gaussian_sigma
from lightcal.core.selection import (
    Region,
    bin_values,
    binned_candidates,
    candidate_mask,
    select_pixels,
)
from lightcal.core.surroundings import screened_footprints
from lightcal.core.wall_mesh import wall_footprints
from lightcal.io.linear_image import LinearImage
from lightcal.io.project import Project
from lightcal.pipeline.load import LoadedImages, vignetting_for


def regions_for(project: Project, image_index: int) -> list[Region]:
    """The project's selection regions that apply to one image."""
    names = {project.names[image_index], project.photo_name(image_index)}  # with a channel
    out = []
    for r in project.spec.selection.regions:
        if r.images is None or names & set(r.images):
            out.append(Region(r.kind, np.array(r.points, dtype=np.float64), r.include))
    return out


def declared_noise(project: Project, dark_level: float | None = None) -> tuple[float, float] | None:
    """The Poisson-Gaussian noise (gain, read_variance) of one image's pixel values, or
    None when the project declares no noise model.

    The sensor's model, and for an image less its light-off photo of mean level d (in
    value units) the dark photo's own noise and the room light's shot noise in the image:
    the read variance becomes 2 read_variance + 2 gain d (docs/model.md, "Light-off
    photos").
    """
    noise = project.spec.sensor.noise
    if noise is None:
        return None
    if dark_level is None:
        return noise.gain, noise.read_variance
    return noise.gain, 2.0 * noise.read_variance + 2.0 * noise.gain * max(dark_level, 0.0)


def noise_floor(project: Project, image: LinearImage, *, dark_level: float | None = None) -> float:
    """Values at or below are too dark to use: the project's min_signal, else the offset
    plus 5 read-noise sigmas (`declared_noise`: the light-off photo's noise included), else
    1 % of the image's 99th percentile."""
    sel = project.selection
    if sel.min_signal is not None:
        return sel.min_signal
    sensor = project.spec.sensor
    noise = declared_noise(project, dark_level)
    if noise is not None:
        return sensor.offset + 5.0 * math.sqrt(noise[1])
    p99 = image.percentile_99
    return sensor.offset + 0.01 * p99 if p99 is not None else 0.0


def image_data(
    project: Project,
    loaded: LoadedImages,
    index: int,
    *,
    pixels: np.ndarray | None = None,
    extra_pixels: np.ndarray | None = None,
) -> ImageData:
    """The selected pixels of one image as solver input.

    Args:
        project: the project.
        loaded: its images.
        index: which image.
        pixels: (N, 2) explicit pixel choice (in the binned grid); default: the project's
            selection strategy.
        extra_pixels: (K, 2) pixels (in the binned grid, e.g. clicked by a user) added to
            the selection when they are candidates (valid, unsaturated, above the noise
            floor, inside the regions and masks); the random strategy's cut to N never
            drops them. Others are ignored.
    """
    img = loaded.images[index]
    view = project.views[index]
    sel = project.selection
    b = selection_binning(project)
    cand = candidates(project, loaded, index)
    values = img.values
    if b > 1:
        cand = binned_candidates(cand, b)
        values = bin_values(values, b)
    if pixels is None:
        pixels = select_pixels(cand, sel, image_index=index, oversample=1.5)
    extra = _candidates_among(cand, extra_pixels)
    if extra.size:
        pixels = np.unique(np.concatenate([np.asarray(pixels, np.int64), extra]), axis=0)
    vignetting = vignetting_for(project, loaded.camera)
    fp = wall_footprints(
        loaded.camera,
        view,
        pixels,
        mesh=project.wall_mesh,
        sensor=project.spec.sensor.model,
        vignetting=vignetting,
        binning=b,
        port=project.camera_port,
    )
    usable = fp.valid
    if project.surroundings is not None:  # the surfaces as the camera sees them: unmodelled
        usable = usable & ~screened_footprints(
            project.surroundings, view.center_world, fp.corners_world
        )
    keep = np.nonzero(usable)[0]
    if sel.strategy == "random" and keep.size > sel.n_per_image:
        # A random N of the valid ones (not the first N: pixels are sorted by row),
        # plus the extra pixels.
        is_extra = _rows_in(fp.pixels[keep], extra)
        rng = np.random.default_rng([sel.seed, index, 1])
        chosen = rng.permutation(keep[~is_extra])[: sel.n_per_image]
        keep = np.sort(np.concatenate([chosen, keep[is_extra]]))
    if keep.size < len(fp):  # else every pixel is kept: no copy
        fp = fp.subset(keep)
    px = fp.pixels
    observed = values[px[:, 1], px[:, 0]]
    noise = declared_noise(project, loaded.dark_level(index))
    name, channel = project.names[index], project.channel_index(index)
    if noise is None:
        return ImageData(name, view, fp, observed, np.ones(len(observed)), channel=channel)
    # A super-pixel value is the mean of b^2 pixels: its variance is 1 / b^2 of theirs.
    per_value = (noise[0] / (b * b), noise[1] / (b * b))
    sigma = poisson_gaussian_sigma(observed - project.spec.sensor.offset, per_value)
    return ImageData(name, view, fp, observed, sigma, per_value, channel)


def selection_binning(project: Project) -> int:
    """The super-pixel side the selection works in (binning applies to `all` only)."""
    sel = project.selection
    return sel.binning if sel.strategy == "all" else 1


def candidates(project: Project, loaded: LoadedImages, index: int) -> np.ndarray:
    """(H, W) pixels of image `index` the solver may use: valid, unsaturated, above the
    noise floor, outside the masks and inside the regions (full-resolution grid)."""
    img = loaded.images[index]
    return candidate_mask(
        img.values,
        saturated=img.saturated,
        excluded=loaded.excluded[index],
        regions=regions_for(project, index),
        min_signal=noise_floor(project, img, dark_level=loaded.dark_level(index)),
    )


def _candidates_among(cand: np.ndarray, pixels: np.ndarray | None) -> np.ndarray:
    """(M, 2) unique int64 rows of `pixels` (K, 2) inside the (H, W) mask `cand` and True."""
    if pixels is None:
        return np.zeros((0, 2), np.int64)
    p = np.asarray(pixels, dtype=np.int64).reshape(-1, 2)
    h, w = cand.shape
    p = p[(p[:, 0] >= 0) & (p[:, 0] < w) & (p[:, 1] >= 0) & (p[:, 1] < h)]
    p = p[cand[p[:, 1], p[:, 0]]]
    return np.unique(p, axis=0) if p.size else np.zeros((0, 2), np.int64)


def _rows_in(rows: np.ndarray, table: np.ndarray) -> np.ndarray:
    """(N,) which rows of `rows` (N, 2) appear in `table` (M, 2) (int64 pixel indices)."""
    if table.size == 0:
        return np.zeros(len(rows), dtype=bool)
    return np.isin(_pixel_keys(rows), _pixel_keys(table))


def _pixel_keys(pixels: np.ndarray) -> np.ndarray:
    """(N,) one int64 per (u, v) row of `pixels` (N, 2), u, v < 2^31."""
    p = np.asarray(pixels, dtype=np.int64)
    return (p[:, 1] << 32) + p[:, 0]
