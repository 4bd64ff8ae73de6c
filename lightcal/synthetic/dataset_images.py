"""The images of a synthetic dataset, view by view (`lightcal.synthetic.dataset`).

Each view's expected signal is its imaging's (`lightcal.synthetic.imaging`): the beam,
then the room light and the undeclared fall-off; the sensor (`apply_sensor`) makes the raw
values, written as `images/view_NN.png` (`.tif`); with dark frames, the room light alone
through the same sensor, `images/view_NN_dark.png`, with its own noise stream. A colour
dataset (`lightcal.synthetic.colour`) has one imaging per channel: each channel goes
through the sensor on its own (the stream's draws channel after channel) and the view is
one 3-channel image.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lightcal.core.scene import View
from lightcal.io.atomic import atomic_write_bytes
from lightcal.synthetic.colour import stack_channels
from lightcal.synthetic.dataset_files import (
    DARK_SUFFIX,
    IMAGE_SUFFIX,
    IMAGES_DIR,
    ImageFormat,
    encode_image,
    pose_spec,
    view_geometry,
)
from lightcal.synthetic.imaging import AmbientLevels, Imaging
from lightcal.synthetic.scenes import SensorConfig, apply_sensor

__all__ = ["WrittenImages", "write_images"]


@dataclass(frozen=True)
class WrittenImages:
    """What `write_images` wrote.

    Attributes:
        paths: One image per view.
        views: truth.json's entry of each view.
        channels: Per view, the per-channel fields of a colour dataset's truth
            (`peak_signal_dn`, `saturated_pixels` lists); empty for one channel.
    """

    paths: list[Path]
    views: list[dict[str, Any]]
    channels: list[dict[str, list[Any]]]


def write_images(
    folder: Path,
    *,
    imagings: list[Imaging],
    ambients: list[AmbientLevels] | None,
    views: list[View],
    measured: list[View],
    times_s: NDArray[np.float64],
    sensor: SensorConfig,
    gamma: float,
    image_format: ImageFormat,
    dark_frames: bool,
    rngs: tuple[np.random.Generator, np.random.Generator],
    progress: Callable[[str], None] | None,
) -> WrittenImages:
    """Render, expose and write every view's image (and dark frame).

    Args:
        folder: The dataset folder (its `images/` exists).
        imagings: One per channel (one: a single-channel dataset).
        ambients: Each channel's room light, or None without.
        views: The true views.
        measured: The views the project states.
        times_s: (n,) exposure times, s.
        sensor: The sensor.
        gamma: The response curve's G (`Departures.gamma`).
        image_format: "png" or "tiff".
        dark_frames: Also write each view's light-off photo (with room light).
        rngs: The sensor's noise stream and the dark frames'.
        progress: Called with one line per image.
    """
    rng_sensor, rng_dark = rngs
    colour = len(imagings) > 1
    n = len(views)
    digits = max(2, len(str(n - 1)))
    suffix = IMAGE_SUFFIX[image_format]
    out = WrittenImages([], [], [])
    for i, view in enumerate(views):
        started = time.perf_counter()
        name = f"view_{i:0{digits}d}"
        planes, dark_planes, peaks, saturated_counts = [], [], [], []
        valid = 0
        for k, imaging in enumerate(imagings):
            level = 0.0 if ambients is None else ambients[k].levels_dn[i]
            beam = imaging.beam(view)
            signal, sensor_input = imaging.expose(beam, level, view)
            dn, saturated = apply_sensor(sensor_input, sensor, rng_sensor, gamma=gamma)
            planes.append(dn)
            if k == 0:
                valid = int(signal.count())
            peaks.append(float(signal.max()) if valid else 0.0)
            saturated_counts.append(int(np.count_nonzero(saturated)))
            if dark_frames and ambients is not None:  # the room light alone
                _, dark_input = imaging.expose(beam * 0.0, level, view)
                dark_dn, _ = apply_sensor(dark_input, sensor, rng_dark, gamma=gamma)
                dark_planes.append(dark_dn)
        path = folder / IMAGES_DIR / f"{name}{suffix}"
        image = stack_channels(planes) if colour else planes[0]
        atomic_write_bytes(path, encode_image(image, image_format))
        out.paths.append(path)
        dark: dict[str, str] = {}
        if dark_planes:
            dark["dark"] = f"{IMAGES_DIR}/{name}{DARK_SUFFIX}{suffix}"
            dark_image = stack_channels(dark_planes) if colour else dark_planes[0]
            atomic_write_bytes(folder / dark["dark"], encode_image(dark_image, image_format))
        out.views.append(
            {
                "name": name,
                "path": f"{IMAGES_DIR}/{name}{suffix}",
                **dark,
                "T_camera_world": pose_spec(view).model_dump(exclude_none=True),
                "T_camera_world_measured": pose_spec(measured[i]).model_dump(exclude_none=True),
                "center_world_m": view.center_world.tolist(),
                **view_geometry(view),
                "exposure_time_s": float(times_s[i]),
                "exposure": view.exposure,
                "peak_signal_dn": peaks[0],
                "valid_pixels": valid,
                "saturated_pixels": saturated_counts[0],
            }
        )
        if colour:
            out.channels.append({"peak_signal_dn": peaks, "saturated_pixels": saturated_counts})
        if progress is not None:
            done = out.views[-1]
            progress(
                f"{name}{suffix} {i + 1}/{n}: distance {done['distance_m']:.2f} m, tilt "
                f"{done['tilt_deg']:.1f} deg, exposure 1/{1.0 / times_s[i]:.0f} s, peak "
                f"{max(peaks):.0f} DN above black, {sum(saturated_counts)} "
                f"saturated ({time.perf_counter() - started:.1f} s)"
            )
    return out
