"""Reading a project's images: linear values (less their light-off photos), user masks,
the matching camera and the vignetting map."""

from __future__ import annotations

import functools
import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lightcal.core.camera import Camera
from lightcal.errors import InputError
from lightcal.io.dark_frames import dark_level, declared_exposure, subtract_dark
from lightcal.io.images import read_image, read_mask
from lightcal.io.linear_image import LinearImage
from lightcal.io.project import Project

READ_THREADS = min(4, os.cpu_count() or 1)
"""Images decoded at once by `load_images`."""

ProgressFn = Callable[[str, int, int], None]
"""progress(stage, done, total): what the pipeline reports while it works."""


@dataclass(frozen=True, eq=False)
class LoadedImages:
    """The project's images read as linear values.

    Attributes:
        images: one `LinearImage` per project image, its light-off photo (`dark`)
            subtracted when it has one.
        excluded: (H, W) bool per image: user mask pixels.
        camera: the intrinsics matching the images as read (binned when the reader binned).
        dark_levels: per image, the mean value of its light-off photo (whose noise adds
            to the image's: `lightcal.pipeline.select.declared_noise`), or None without one.
    """

    images: list[LinearImage]
    excluded: list[np.ndarray | None]
    camera: Camera
    dark_levels: list[float | None] = field(default_factory=list)

    def dark_level(self, index: int) -> float | None:
        """The mean of image `index`'s light-off photo, subtracted from it (None: none)."""
        return self.dark_levels[index] if index < len(self.dark_levels) else None


def load_images(
    project: Project,
    *,
    progress: ProgressFn | None = None,
    meanwhile: Callable[[], object] | None = None,
) -> LoadedImages:
    """Read every image of a project (and its mask) and check sizes against the camera.

    Args:
        project: the project.
        progress: called as images arrive.
        meanwhile: called on this thread once the decoders have started, before their
            results are awaited: work that needs the interpreter (numba's start-up, the
            RID grids) overlaps the decoding, which does not. Its errors propagate.
    """
    sensor = project.spec.sensor
    response = None
    if sensor.response:
        from lightcal.io.response import ResponseCurve

        response = ResponseCurve.load(project.folder / sensor.response)
    paths = project.image_paths

    darks = project.dark_paths or [None] * len(paths)

    def read_one(path: Path, i: int) -> LinearImage:
        return read_image(
            path,
            channel=project.channel_name(i),
            black_level=sensor.black_level,
            white_level=sensor.white_level,
            response=response,
            assume_linear=sensor.assume_linear,
        )

    def read(i: int) -> tuple[LinearImage, np.ndarray | None, float | None]:
        img = read_one(paths[i], i)
        level = None
        dark_path = darks[i]
        if dark_path is not None:  # the light-off photo, read as its image is
            dark = read_one(dark_path, i)
            img = subtract_dark(
                img,
                dark,
                image_path=paths[i],
                dark_path=dark_path,
                declared=declared_exposure(project.spec, project.spec_image(i)),
            )
            level = dark_level(dark)
        # The noise floor's percentile (`select.noise_floor`), on this thread while the
        # image is in cache (a compiled pass that releases the interpreter).
        _ = img.percentile_99
        mask_path = project.mask_paths[i]
        h, w = img.values.shape
        return img, (_read_mask(mask_path, (h, w)) if mask_path is not None else None), level

    images: list[LinearImage] = []
    excluded: list[np.ndarray | None] = []
    levels: list[float | None] = []
    camera = project.camera
    # The decoders (OpenCV, LibRaw, tifffile) release the GIL: a few images at once. Results
    # come back in order, so the first bad file named is the first in the project.
    with ThreadPoolExecutor(max_workers=min(READ_THREADS, max(1, len(paths)))) as pool:
        results = pool.map(read, range(len(paths)))  # submitted now, awaited in order
        if meanwhile is not None:
            meanwhile()
        for i, (img, mask, level) in enumerate(results):
            if progress is not None:
                progress("reading images", i, len(paths))
            h, w = img.values.shape
            if (w, h) != (camera.width, camera.height):
                b = img.binning
                if b > 1 and (w, h) == (camera.width // b, camera.height // b):
                    camera = project.camera.binned(b)
                else:
                    raise InputError(
                        paths[i],
                        f"image is {w}x{h} pixels but the camera intrinsics are for "
                        f"{camera.width}x{camera.height}; expected the same size",
                    )
            images.append(img)
            excluded.append(mask)
            levels.append(level)
    if progress is not None:
        progress("reading images", len(paths), len(paths))
    return LoadedImages(images, excluded, camera, levels)


def prepare_solve(project: Project) -> None:
    """What a solve needs that takes the interpreter's time, for `load_images`'
    `meanwhile` (it then overlaps the image decoding): the lights' RID grids
    (`RID.data`; the first compiled kernel a process calls also starts numba, 0.15-0.2 s)
    and SciPy's optimize module, which the solver imports where it is used (0.1-0.3 s)."""
    for unknown in project.lights:
        unknown.initial.rid.data()
    import scipy.optimize  # noqa: F401


def _read_mask(path, shape: tuple[int, int]) -> np.ndarray:
    mask = read_mask(path)
    if mask.shape != shape:
        raise InputError(
            path,
            f"mask is {mask.shape[1]}x{mask.shape[0]} pixels, "
            f"expected {shape[1]}x{shape[0]} like its image",
        )
    return mask


def vignetting_for(project: Project, camera: Camera) -> np.ndarray | None:
    """The project's (H, W) vignetting map at `camera`'s size, or None (sensor model not
    "map", or no map file). Shared and cached: do not write to it."""
    if project.spec.sensor.model != "map" or project.vignetting_path is None:
        return None
    return _load_vignetting(project.vignetting_path, camera.width, camera.height)


@functools.lru_cache(maxsize=4)
def _load_vignetting(path: Path, width: int, height: int) -> np.ndarray:
    from lightcal.io.vignetting_file import load_vignetting

    return load_vignetting(path, width=width, height=height)
