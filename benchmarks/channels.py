"""Colour channels solved jointly (`sensor.channels`, issue 26) against one calibration
per channel, on `lightcal synth` colour data in water (c = 0.4 / 0.12 / 0.06 /m, a
coloured wall, noise per channel; 12 views of 480 x 320, 800 pixels an image).

Run `python benchmarks/channels.py` (about a minute on 2 cores). It prints, for the
joint solve and for each channel alone (the project edited to `sensor.channel` and that
channel's c): the wall time of `calibrate_project`, the iterations, the light's error and
its 1-sigma, and the joint solve's time and sigma as ratios to the three separate ones
(measured in the same run). No figure is asserted: the machine may be shared; the load
average is printed.
"""

from __future__ import annotations

import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from lightcal.core.camera import Camera
from lightcal.io.medium_spec import MediumSpec
from lightcal.io.project import load_project
from lightcal.pipeline import calibrate_project
from lightcal.synthetic.colour import ColourChannels
from lightcal.synthetic.dataset import SynthConfig, read_truth, write_dataset

C_RGB = (0.4, 0.12, 0.06)


def _errors(result, truth: dict) -> tuple[float, float, float, float]:
    """(position error, its sigma norm (m), axis error, its sigma (deg))."""
    light = result.lights[0]
    position = float(np.linalg.norm(light.pose.t_camera_light - truth["position_m"]))
    cos = float(np.clip(light.pose.axis_camera @ np.array(truth["axis_camera"]), -1.0, 1.0))
    return (
        position,
        float(np.linalg.norm(light.sigma.t_camera_light)),
        math.degrees(math.acos(cos)),
        math.degrees(float(np.linalg.norm(light.sigma.axis_camera))),
    )


def _run(project: Path, truth: dict) -> tuple[float, int, tuple[float, float, float, float]]:
    start = time.perf_counter()
    _, _, result = calibrate_project(load_project(project))
    return time.perf_counter() - start, result.iterations, _errors(result, truth)


def main() -> int:
    camera = Camera.from_params(fx=432.0, fy=432.0, cx=239.5, cy=159.5, width=480, height=320)
    with tempfile.TemporaryDirectory() as tmp:
        config = SynthConfig(
            camera=camera,
            seed=5,
            channels=ColourChannels(
                attenuation_per_m=C_RGB, colour=(1.0, 0.94, 0.75), declare=True
            ),
            medium=MediumSpec(attenuation_per_m=[0.2] * 3, estimate=["attenuation_per_m"]),
        )
        project = write_dataset(Path(tmp) / "ds", config).project_path
        doc = json.loads(project.read_text())
        doc.setdefault("selection", {})["n_per_image"] = 800
        project.write_text(json.dumps(doc))
        truth = read_truth(project.parent / "truth.json")["lights"][0]
        _run(project, truth)  # compiled kernels and caches warm
        print(f"load average {os.getloadavg()[0]:.2f}; 12 views of 480 x 320, 800 px an image")
        print(
            f"{'solve':10s} {'time s':>7s} {'iter':>5s} {'pos err mm':>11s} {'sigma mm':>9s} "
            f"{'axis err deg':>13s} {'sigma deg':>10s}"
        )
        rows = {"joint": _run(project, truth)}
        for name in ("R", "G", "B"):
            single = json.loads(project.read_text())
            single["sensor"].pop("channels")
            single["sensor"]["channel"] = name
            single["medium"] = {"attenuation_per_m": 0.2, "estimate": ["attenuation_per_m"]}
            path = project.with_name(f"channel_{name}.json")
            path.write_text(json.dumps(single))
            rows[name] = _run(path, truth)
        for name, (seconds, iterations, (p, ps, a, s)) in rows.items():
            print(
                f"{name:10s} {seconds:7.2f} {iterations:5d} {1e3 * p:11.2f} {1e3 * ps:9.2f} "
                f"{a:13.3f} {s:10.3f}"
            )
        separate = sum(rows[n][0] for n in "RGB")
        best_sigma = min(rows[n][2][1] for n in "RGB")
        print(f"joint time / the three separate solves: {rows['joint'][0] / separate:.2f}")
        print(
            f"joint position sigma / the best channel's alone: "
            f"{rows['joint'][2][1] / best_sigma:.2f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
