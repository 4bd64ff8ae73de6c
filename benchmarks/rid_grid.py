"""Table RIDs on the fast paths: the uniform grid against the exact table and cos^m.

Run `python benchmarks/rid_grid.py [--rounds 3]` (about a minute once the kernels are
compiled). One process, one thread (NUMBA_NUM_THREADS=1, set before numba loads), CPU
seconds (`time.process_time`), the scene of `benchmarks/render.py` at 3000 x 2000:

- full frame (`render_image`, warm: the corner grid cached);
- `shade` of 300,000 random pixels with the footprints given, without and with the
  gradients (the solver's inner call);

for cos^m, the symmetric and the 2-D table on their grids (`RID.data`, what lightcal
renders with) and evaluated exactly (`RID.exact_data`, the knot interpolation: the code
path before the grids). The rounds alternate the RIDs; each figure is the median over
rounds of the best of `--repeats` calls, and the ratio to cos^m is printed (issue
target: <= 1.3). Then the grids' accuracy against the exact interpolation over the
frame (max |f_grid - f_exact|, f(0) = 1) and over 10^6 random directions within the
tables' range (value and angular derivatives). Nothing is asserted.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np
from render import make_rid, make_scene, random_pixels
from render_ab import _best_cpu_ms

WIDTH, HEIGHT = 3000, 2000
N_PIXELS = 300_000
NAMES = ("cos_power", "table_1d", "table_1d_exact", "table_2d", "table_2d_exact")


def measure(rounds: int, repeats: int) -> dict[str, dict[str, float]]:
    """{rid name: {"frame", "shade", "grad": median best CPU ms}}."""
    from lightcal.core import render

    scenes = {name: make_scene(WIDTH, HEIGHT, name) for name in NAMES}
    camera, view, _ = scenes["cos_power"]
    pixels = random_pixels(WIDTH, HEIGHT, N_PIXELS)
    fp = render.pixel_footprints(camera, view, pixels)
    for _, _, rig in scenes.values():  # compile / load every kernel first
        render.render_image(camera, view, rig)
        render.shade(fp, view, rig, want_grad=True)
        render.shade(fp, view, rig)
    times: dict[str, dict[str, list[float]]] = {
        n: {"frame": [], "shade": [], "grad": []} for n in NAMES
    }
    for _ in range(rounds):
        for name in NAMES:
            rig = scenes[name][2]
            t = times[name]
            calls = {
                "frame": lambda rig=rig: render.render_image(camera, view, rig),
                "shade": lambda rig=rig: render.shade(fp, view, rig),
                "grad": lambda rig=rig: render.shade(fp, view, rig, want_grad=True),
            }
            for key, call in calls.items():
                t[key].append(_best_cpu_ms(call, repeats))
    return {n: {k: statistics.median(v) for k, v in t.items()} for n, t in times.items()}


def accuracy() -> list[str]:
    """Lines: the grids against the exact tables, over the frame and random directions."""
    from lightcal.core import render, rid_eval

    lines = []
    for name in ("table_1d", "table_2d"):
        camera, view, rig = make_scene(WIDTH, HEIGHT, name)
        _, _, rig_exact = make_scene(WIDTH, HEIGHT, f"{name}_exact")
        fast = render.render_image(camera, view, rig).data
        exact = render.render_image(camera, view, rig_exact).data
        rel = np.abs(fast - exact).max() / np.abs(exact).max()
        rid = make_rid(name)
        rng = np.random.default_rng(3)
        n = 1_000_000
        theta_last = float(rid.data().theta_knots[-1])
        theta = np.arccos(rng.uniform(math.cos(theta_last), 1.0, n))
        phi = rng.uniform(-math.pi, 3 * math.pi, n)
        f, f_t, f_p = rid_eval.rid_eval_many(theta, phi, rid.data())
        e, e_t, e_p = rid_eval.rid_eval_many(theta, phi, rid.exact_data())
        lines.append(
            f"{name}: frame max |grid - exact| / max = {rel:.1e}; at 10^6 directions "
            f"max |df| = {np.abs(f - e).max():.1e}, "
            f"99th pct {np.quantile(np.abs(f - e), 0.99):.1e}; "
            f"max |d df/dtheta| = {np.abs(f_t - e_t).max():.1e} (max |df/dtheta| "
            f"{np.abs(e_t).max():.2f}); max |d df/dphi| = {np.abs(f_p - e_p).max():.1e} "
            f"(max |df/dphi| {np.abs(e_p).max():.2f})"
        )
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    import numba

    load = os.getloadavg()[0]
    print(
        f"table RIDs, {WIDTH} x {HEIGHT}, {N_PIXELS:,} pixels for shade; "
        f"{numba.get_num_threads()} thread; {args.rounds} rounds; load average {load:.2f}"
    )
    res = measure(args.rounds, args.repeats)
    base = res["cos_power"]
    head = f"{'RID':<16}{'full frame ms':>16}{'shade ms':>14}{'with grad ms':>16}"
    print(head)
    print("-" * len(head))
    for name, r in res.items():
        cells = [f"{r[k]:9.1f} {r[k] / base[k]:4.2f}x" for k in ("frame", "shade", "grad")]
        print(f"{name:<16}{cells[0]:>16}{cells[1]:>14}{cells[2]:>16}")
    print("(ratio: to cos^m in the same run; *_exact: the knot interpolation, before the grids)")
    for line in accuracy():
        print(line)
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
