"""A/B of the renderer against another checkout of lightcal (before/after a change).

Run `python benchmarks/render_ab.py OLD_CHECKOUT [--rounds 3]`, e.g. after
`git worktree add --detach /tmp/old <commit>`. Each round runs the same measurements in
a fresh subprocess for the old tree and for this one, alternately, on one thread
(NUMBA_NUM_THREADS=1) and in CPU seconds (`time.process_time`), so that a shared
machine disturbs both sides alike; the first run of a tree compiles its kernels
(minutes), which is not timed. Rows (3000 x 2000 distorted camera, cos^m light):

- full frame, and full frame at binning 4 (`render_image`);
- `render_pixels` of 200k random pixels (footprints included);
- `shade` of 200k precomputed footprints, without and with the gradients.

Printed: the median over rounds of each side's best-of times, the ratio new / old, and
whether the two trees rendered bit-identical full frames. Nothing is asserted.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def _best_cpu_ms(fn: Callable[[], object], repeats: int) -> float:
    out = math.inf
    for _ in range(repeats):
        t = time.process_time()
        fn()
        out = min(out, time.process_time() - t)
    return out * 1e3


def child(image_out: str) -> None:
    """Measure in this process (the tree on PYTHONPATH); print the figures as JSON."""
    import numpy as np

    from lightcal.core.camera import Camera
    from lightcal.core.footprint import pixel_footprints
    from lightcal.core.pose import axis_from_angles, rotation_from_axis
    from lightcal.core.render import render_image, render_pixels, shade
    from lightcal.core.rid import CosPowerRID
    from lightcal.core.scene import Light, Rig, View

    w, h = 3000, 2000
    cam = Camera.from_params(
        fx=2700, fy=2700, cx=(w - 1) / 2, cy=(h - 1) / 2, width=w, height=h,
        dist=(-0.08, 0.02, 2e-4, -1e-4),
    )  # fmt: skip
    light = Light(
        CosPowerRID.from_half_angle(math.radians(30.0)),
        np.array([0.1, -0.03, 0.01]),
        rotation_from_axis(axis_from_angles(0.08, -0.06)),
        scale=1000.0,
    )
    rig = Rig.single(light)
    view = View.looking_at(np.array([0.3, -0.2, 1.4]), np.array([0.05, 0.1, 0.0]), exposure=1.7)
    rng = np.random.default_rng(1)
    px = np.stack([rng.integers(0, w, 200_000), rng.integers(0, h, 200_000)], axis=1)
    fp = pixel_footprints(cam, view, px)
    render_image(cam, view, rig)  # warm: kernels loaded, corner grid cached
    render_image(cam, view, rig, binning=4)
    render_pixels(cam, view, rig, px)
    shade(fp, view, rig, want_grad=True)
    figures = {
        "full frame": _best_cpu_ms(lambda: render_image(cam, view, rig), 9),
        "full frame, binning 4": _best_cpu_ms(lambda: render_image(cam, view, rig, binning=4), 9),
        "render_pixels 200k": _best_cpu_ms(lambda: render_pixels(cam, view, rig, px), 5),
        "shade 200k": _best_cpu_ms(lambda: shade(fp, view, rig), 5),
        "shade + gradients 200k": _best_cpu_ms(lambda: shade(fp, view, rig, want_grad=True), 5),
    }
    np.save(image_out, render_image(cam, view, rig).filled(np.nan))
    print(json.dumps(figures))


def _run(tree: Path, image_out: Path) -> dict[str, float]:
    env = dict(os.environ, PYTHONPATH=str(tree), NUMBA_NUM_THREADS="1")
    done = subprocess.run(
        [sys.executable, __file__, "--child", str(image_out)],
        cwd=tempfile.gettempdir(),
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("old", nargs="?", type=Path, help="the other checkout (its root)")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--child", metavar="IMAGE", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        child(args.child)
        return 0
    if args.old is None or not (args.old / "lightcal").is_dir():
        parser.error("OLD: expected the root of another lightcal checkout")
    import numpy as np

    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    print(f"old: {args.old}\nnew: {REPO}\n(first runs compile each tree's kernels: not timed)")
    with tempfile.TemporaryDirectory() as tmp:
        images = {"old": Path(tmp) / "old.npy", "new": Path(tmp) / "new.npy"}
        trees = {"old": args.old.resolve(), "new": REPO}
        for side in ("old", "new"):
            _run(trees[side], images[side])  # compile, untimed
        runs: dict[str, list[dict[str, float]]] = {"old": [], "new": []}
        for _ in range(args.rounds):
            for side in ("old", "new"):
                runs[side].append(_run(trees[side], images[side]))
        a, b = np.load(images["old"]), np.load(images["new"])
        same = a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
    print(f"{'row (one thread, CPU ms)':<26} {'old':>9} {'new':>9}  new/old")
    for key in runs["old"][0]:
        old = statistics.median(r[key] for r in runs["old"])
        new = statistics.median(r[key] for r in runs["new"])
        print(f"{key:<26} {old:9.1f} {new:9.1f}  {new / old:6.3f}")
    print(f"full frames bit-identical: {same}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
