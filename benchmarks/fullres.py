"""Full-resolution projects (issue 12): 12 camera raw files of 6000 x 4000 (printed, no
assertions).

    .venv/bin/python benchmarks/fullres.py [--folder DIR] [--views 12] [--runs 3]

Writes once (and reuses) a project of synthetic Bayer DNGs (`tests/raw_dng.py`, the raw
tests' writer: uncompressed 16-bit CFA, black 64, white 4095) of a 6000 x 4000 camera
(f = 0.94 w, OpenCV distortion) photographing the wall at 0.8-2 m under a cos^m light
(30 deg half angle) 10 cm beside the lens: every Bayer site holds the rendered value
(a grey wall, white balanced), about 70 % of full scale at the brightest, with
Poisson-Gaussian noise. The project reads them as lightcal does by default (the green
sites binned 2 x 2: 3000 x 2000 values per image). Then, each in fresh processes:

- app: `benchmarks/app.py` on the project after a warm-up launch: the launch (open the
  project, select, first redraw; target < 30 s warm) and a Step with all 12 residual
  overlays re-rendered and sent (target < 300 ms);
- calibrate: `lightcal calibrate` with `selection: {strategy: all, binning: 4}`: median
  wall and CPU time of `--runs` runs after a warm-up and the peak RSS (targets < 10 s,
  < 2 GB), with the position and axis error against the truth.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO), str(REPO / "app"), str(REPO / "benchmarks")]

from calibrate import make_camera, make_light, make_views  # noqa: E402
from startup import lightcal_command, run_once  # noqa: E402

WIDTH, HEIGHT = 6000, 4000
BLACK, WHITE = 64, 4095
OPEN_TARGET_S, STEP_TARGET_MS = 30.0, 300.0
CALIBRATE_TARGET_S, CALIBRATE_TARGET_MB = 10.0, 2000.0


def write_project(folder: Path, n_views: int) -> Path:
    """The DNG project in `folder` (made once: an existing project.json is reused)."""
    from lightcal.core.pose import describe_pose
    from lightcal.core.render import render_image
    from lightcal.core.scene import Rig
    from lightcal.io.camera_file import write_camera
    from tests.raw_dng import write_dng

    path = folder / "project.json"
    if path.is_file():
        return path
    (folder / "images").mkdir(parents=True, exist_ok=True)
    camera = make_camera(WIDTH, HEIGHT)
    write_camera(camera, folder / "camera.yaml")
    light = make_light()
    views = make_views(n_views, (0.8, 2.0), seed=5)
    rng = np.random.default_rng(5)
    scale = None
    images = []
    t0 = time.perf_counter()
    for i, view in enumerate(views):
        value = render_image(camera, view, Rig.single(light)).filled(0.0)
        if scale is None:
            scale = 0.7 * (WHITE - BLACK) / float(np.percentile(value, 99.9))
        dn = value * scale
        dn += rng.normal(size=dn.shape) * np.sqrt(0.5 * dn + 4.0)
        mosaic = np.clip(np.round(dn + BLACK), 0, WHITE).astype(np.uint16)
        name = f"images/v{i:02d}.dng"
        write_dng(folder / name, mosaic, black_level=BLACK, white_level=WHITE)
        images.append(
            {
                "path": name,
                "T_camera_world": {
                    "R": view.R_camera_world.tolist(),
                    "t": view.t_camera_world.tolist(),
                },
            }
        )
        print(f"  wrote {name} ({time.perf_counter() - t0:.0f} s)", flush=True)
    project = {
        "version": 1,
        "camera": {"path": "camera.yaml"},
        "images": images,
        "lights": [
            {
                "name": "led",
                "rid": {"type": "half_angle", "half_angle_deg": 30.0},
                "initial": {"position_m": [0.05, 0.0, 0.0]},
            }
        ],
    }
    truth = {
        "lights": [{"name": "led", **describe_pose(light.R_camera_light, light.t_camera_light)}]
    }
    (folder / "truth.json").write_text(json.dumps(truth, indent=1), encoding="utf-8")
    path.write_text(json.dumps(project, indent=1), encoding="utf-8")
    return path


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env.pop("PYTHONDONTWRITEBYTECODE", None)  # as a user's machine: byte code cached
    env["PYTHONPATH"] = os.pathsep.join(
        [str(REPO), str(REPO / "app"), *filter(None, [env.get("PYTHONPATH")])]
    )
    return env


def app_rows(project: Path) -> None:
    """benchmarks/app.py on the project, after a warm-up launch (the OS's file cache and
    numba's kernels warm: 'warm' as the issue means it)."""
    command = [sys.executable, str(REPO / "benchmarks" / "app.py"), str(project), "--no-browser"]
    subprocess.run([*command, "--steps", "1"], env=_env(), capture_output=True, check=True)
    out = subprocess.run(command, env=_env(), capture_output=True, text=True, check=True)
    for line in out.stdout.splitlines():
        print(f"  app: {line}")
    print(f"  targets: open < {OPEN_TARGET_S:g} s warm, Step < {STEP_TARGET_MS:g} ms")


def calibrate_row(project: Path, runs: int) -> None:
    spec = json.loads(project.read_text())
    spec["selection"] = {"strategy": "all", "binning": 4}
    dense = project.with_name("project_all_b4.json")
    dense.write_text(json.dumps(spec, indent=1), encoding="utf-8")
    result = project.with_name("result_all_b4.json")
    command = [*lightcal_command(), "calibrate", str(dense), "--out", str(result), "--quiet"]
    command.append("--force")
    run_once(command, project.parent, _env())  # warm-up
    timings = [run_once(command, project.parent, _env()) for _ in range(runs)]
    res = json.loads(result.read_text())
    truth = json.loads((project.parent / "truth.json").read_text())["lights"][0]
    light = res["lights"][0]
    err_mm = 1e3 * math.dist(light["position_m"], truth["position_m"])
    cos = float(np.dot(light["axis_camera"], truth["axis_camera"]))
    err_deg = math.degrees(math.acos(min(1.0, max(-1.0, cos))))
    pixels = sum(im["pixels"] for im in res["images"])
    print(
        f"  calibrate (strategy all, binning 4; {pixels:,} super-pixels): "
        f"{statistics.median(t.wall_s for t in timings):.2f} s median of {runs} "
        f"(CPU {statistics.median(t.cpu_s for t in timings):.2f} s), peak RSS "
        f"{max(t.peak_mb for t in timings):,.0f} MB; {res['iterations']} iterations, "
        f"{'converged' if res['converged'] else 'NOT converged'}; error {err_mm:.2f} mm, "
        f"{err_deg:.3f} deg"
    )
    print(f"  target: < {CALIBRATE_TARGET_S:g} s, < {CALIBRATE_TARGET_MB:,.0f} MB")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--folder", type=Path, default=Path("/tmp/lightcal-fullres"))
    parser.add_argument("--views", type=int, default=12)
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    load = os.getloadavg()[0]
    print(f"full-resolution project: {os.cpu_count()} CPUs, load average {load:.2f}")
    project = write_project(args.folder, args.views)
    print(f"project: {project} ({args.views} DNGs of {WIDTH} x {HEIGHT})")
    app_rows(project)
    calibrate_row(project, args.runs)


if __name__ == "__main__":
    main()
