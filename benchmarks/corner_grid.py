"""The cold corner grid of a 24 MP camera: the per-corner Newton solve against the new one.

Run `python benchmarks/corner_grid.py [--rounds 3] [--width 6000 --height 4000]` (about a
minute or two on 2 cores). `lightcal.core.corner_grid.corner_grid` undistorts every pixel
corner of a camera ((H+1) x (W+1) of them) once per camera; the renderer and the dense
pixel footprints read their corners from it. Three cameras of W x H pixels:

- "sample": `sample_data/camera.yaml` (1200 x 800, read with `lightcal.io`) scaled to
  W x H (fx, fy, skew times W / 1200; the same field of view), its distortion as is
  (k1 -0.08, k2 0.02, p1, p2 ~2e-4, k3 ~1e-4);
- "strong": the same K with a strong wide-angle barrel distortion (`STRONG_DIST`): the
  image corners land 30 % closer to the centre than their rays (distorted radius 0.77
  for 1.11 undistorted); valid everywhere;
- "folded": the same K with k1 = -0.35 alone (and the small p1, p2 of "strong"): the
  radial map r (1 + k1 r^2) folds at r = 0.98, where it reaches 0.65 < 0.77, the
  distorted radius of the image corners: about 7 % of the corners do not undistort
  (`grid_ok` False), and those near the fold are solved by `undistort_normalized` as
  before.

Per camera and round, alternately: "old", the kernel before issue 12 (`old_corner_grid`
below, kept here as the baseline: `undistort_normalized` from the distorted point for
every corner) and "new" (`corner_grid`: each corner seeded from its solved neighbours,
one or two Newton steps). Both allocate their outputs, as a first render does. Wall
seconds (the kernels run on numba's threads) and CPU seconds (all threads: less
disturbed by other work on the machine), medians over the rounds; compilation is
excluded (both run once on a tiny camera first). Printed beside them: old / new, the
largest round-trip error of the new grid over every corner (distort the undistorted
corner, apply K, compare with its pixel (i - 1/2, j - 1/2)), the largest difference to
the old grid in normalised coordinates and the corners whose validity differs.
Nothing is asserted (the machine may be shared: the load average is printed).

First printed: the first touch of a grid's freshly mapped memory (0.4 GB at 24 MP) by a
parallel fill. A process's first grid pays it, old or new (0.35-0.85 s on the shared
2-core VM of benchmarks/README.md's results); the rounds measured after it reuse memory
that earlier grids freed, as a long-lived process (the app) mostly does.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numba
import numpy as np

from lightcal.core.camera import Camera
from lightcal.core.corner_grid import corner_grid
from lightcal.core.distortion import distort_points, undistort_normalized
from lightcal.io.camera_file import read_camera

REPO = Path(__file__).resolve().parent.parent
STRONG_DIST = (-0.4, 0.15, 0.0012, -0.0008, -0.02)
FOLDED_DIST = (-0.35, 0.0, 0.0012, -0.0008)


@numba.njit(parallel=True)
def _old_kernel(K: np.ndarray, dist: np.ndarray, out_xy: np.ndarray, out_ok: np.ndarray) -> None:
    """The corner grid kernel before issue 12, verbatim: a cold Newton solve per corner."""
    n_rows = out_xy.shape[0]
    n_cols = out_xy.shape[1]
    fx = K[0, 0]
    s = K[0, 1]
    cx = K[0, 2]
    fy = K[1, 1]
    cy = K[1, 2]
    for j in numba.prange(n_rows):
        yd = (float(j) - 0.5 - cy) / fy
        for i in range(n_cols):
            xd = (float(i) - 0.5 - cx - s * yd) / fx
            x, y, ok = undistort_normalized(xd, yd, dist)
            out_ok[j, i] = ok
            out_xy[j, i, 0] = x if ok else 0.0
            out_xy[j, i, 1] = y if ok else 0.0


def old_corner_grid(camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """`corner_grid` as it was before issue 12."""
    grid_xy = np.empty((camera.height + 1, camera.width + 1, 2))
    grid_ok = np.empty((camera.height + 1, camera.width + 1), dtype=np.bool_)
    with numba.parallel_chunksize(8):
        _old_kernel(
            np.ascontiguousarray(camera.K), np.ascontiguousarray(camera.dist), grid_xy, grid_ok
        )
    return grid_xy, grid_ok


@numba.njit(parallel=True)
def _fill(out_xy: np.ndarray, out_ok: np.ndarray) -> None:
    for j in numba.prange(out_xy.shape[0]):
        for i in range(out_xy.shape[1]):
            out_xy[j, i, 0] = 0.0
            out_xy[j, i, 1] = 0.0
            out_ok[j, i] = False


def first_touch_s(width: int, height: int) -> float:
    """Seconds to allocate a grid's outputs and write them once in parallel."""
    _fill(np.empty((2, 2, 2)), np.empty((2, 2), dtype=np.bool_))  # compile
    t = time.perf_counter()
    _fill(np.empty((height + 1, width + 1, 2)), np.empty((height + 1, width + 1), dtype=np.bool_))
    return time.perf_counter() - t


def cameras(width: int, height: int) -> dict[str, Camera]:
    """The sample camera scaled to width x height, with its distortion and two strong ones."""
    sample = read_camera(REPO / "sample_data" / "camera.yaml")
    scale = width / sample.width
    K = sample.K.copy()
    K[0, 0] *= scale
    K[0, 1] *= scale
    K[1, 1] *= scale
    K[0, 2] = (K[0, 2] + 0.5) * scale - 0.5
    K[1, 2] = (K[1, 2] + 0.5) * scale - 0.5
    return {
        "sample": Camera(K=K, dist=sample.dist_opencv, width=width, height=height),
        "strong": Camera(K=K, dist=np.array(STRONG_DIST), width=width, height=height),
        "folded": Camera(K=K, dist=np.array(FOLDED_DIST), width=width, height=height),
    }


def round_trip_px(camera: Camera, grid_xy: np.ndarray, grid_ok: np.ndarray) -> float:
    """Largest |pixel(distort(corner)) - corner's pixel| over the valid corners, px."""
    worst = 0.0
    K = camera.K
    for j0 in range(0, grid_xy.shape[0], 256):
        block = grid_xy[j0 : j0 + 256]
        ok = grid_ok[j0 : j0 + 256]
        vv, uu = np.nonzero(ok)
        d = distort_points(np.ascontiguousarray(block[ok]), camera.dist)
        u = K[0, 0] * d[:, 0] + K[0, 1] * d[:, 1] + K[0, 2]
        v = K[1, 1] * d[:, 1] + K[1, 2]
        err = np.maximum(np.abs(u - (uu - 0.5)), np.abs(v - (vv + j0 - 0.5)))
        worst = max(worst, float(err.max(initial=0.0)))
    return worst


def measure(camera: Camera, rounds: int) -> dict[str, Any]:
    """Old and new cold grids of `camera`, alternately; accuracy of the last new one."""
    times: dict[str, list[float]] = {"old": [], "new": [], "old_cpu": [], "new_cpu": []}
    grids: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for _ in range(rounds):
        for name, build in (("old", old_corner_grid), ("new", corner_grid)):
            grids.pop(name, None)  # its memory goes back before the next allocation
            t = time.perf_counter()
            cpu = time.process_time()
            grids[name] = build(camera)
            times[name].append(time.perf_counter() - t)
            times[f"{name}_cpu"].append(time.process_time() - cpu)
    (old_xy, old_ok), (new_xy, new_ok) = grids["old"], grids["new"]
    both = old_ok & new_ok
    return {
        **{f"{key}_s": statistics.median(values) for key, values in times.items()},
        "round_trip_px": round_trip_px(camera, new_xy, new_ok),
        "max_diff": float(np.abs(new_xy[both] - old_xy[both]).max(initial=0.0)),
        "flags_differ": int(np.count_nonzero(old_ok != new_ok)),
        "failed": int(np.count_nonzero(~new_ok)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--width", type=int, default=6000)
    parser.add_argument("--height", type=int, default=4000)
    args = parser.parse_args()
    touch = first_touch_s(args.width, args.height)
    tiny = Camera.from_params(fx=30.0, fy=30.0, cx=9.5, cy=9.5, width=20, height=20)
    old_corner_grid(tiny)  # compile (old) / load the cached kernels (new)
    corner_grid(tiny)
    load = os.getloadavg()
    print(
        f"cold corner grid, {args.width} x {args.height} ({(args.width + 1) * (args.height + 1):,}"
        f" corners); numba {numba.__version__}, {numba.get_num_threads()} threads, "
        f"{numba.threading_layer()}; load average {load[0]:.2f}; median of {args.rounds}"
    )
    print(f"first touch of a fresh grid's memory (both pay it once per process): {touch:.3f} s")
    header = (
        f"{'camera':8} {'old s':>7} {'new s':>7} {'old/new':>8} {'old CPU s':>10} "
        f"{'new CPU s':>10} {'round trip px':>14} {'max |new-old|':>14} {'flags differ':>13} "
        f"{'failed':>8}"
    )
    print(header)
    for name, camera in cameras(args.width, args.height).items():
        r = measure(camera, args.rounds)
        print(
            f"{name:8} {r['old_s']:7.3f} {r['new_s']:7.3f} {r['old_s'] / r['new_s']:7.1f}x "
            f"{r['old_cpu_s']:10.3f} {r['new_cpu_s']:10.3f} {r['round_trip_px']:14.2e} "
            f"{r['max_diff']:14.2e} {r['flags_differ']:13d} {r['failed']:8d}"
        )
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
