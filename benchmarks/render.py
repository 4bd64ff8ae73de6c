"""Speed and memory of the renderer: full frames, pixel sets, against the NumPy baseline.

Run `python benchmarks/render.py` (about 2 minutes on 2 cores) or `--quick` for a small
smoke run. Every figure comes from a fresh subprocess, so that its peak memory (the
kernel's VmHWM from /proc/self/status, which sees numba's allocations, unlike
tracemalloc) belongs to that measurement alone:

- compile: the first calls with an empty numba cache (NUMBA_CACHE_DIR set to a new
  directory), minus the same calls warm: the one-off cost after an install;
- full frame: `render_image` of a W x H image (symmetric RID, distortion on).
  "cold" is the first render of the camera (including its undistorted corner grid, not
  the compilation: the kernels are loaded from the cache first), "warm" the best of
  several renders with the grid cached (the solver and the app render the same camera
  again and again);
- pixels: `render_pixels` of N random pixels of that camera (cold: first call; warm:
  best of several), and `shade` with the footprints precomputed, as the solver calls it,
  without and with the gradients;
- medium: the full frame and `shade` with gradients in air and in water (one light,
  c = 0.3 /m), and their ratio (the issue's target: within 2x); the full frame with
  backscatter too (beta = 0.6 /m, g = 0.8);
- baseline: `lightcal.core.render_reference`, the plain vectorised NumPy implementation
  of the same model, timed on a subset (a band of rows, or a random subset of the pixels)
  and scaled to the full count: the printout says which.

No figure is asserted: the machine may be shared, and the load average is printed with
the results. Timings are wall-clock seconds (`time.perf_counter`).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parent.parent
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

FULL_SIZE = (6000, 4000)
QUICK_SIZE = (600, 400)
PIXEL_COUNTS = (1_200, 4_500_000)
QUICK_PIXEL_COUNTS = (1_200, 45_000)
RIDS = ("cos_power", "table_1d", "table_2d")


# ---------------------------------------------------------------------------------------
# The scene (built inside each subprocess).
# ---------------------------------------------------------------------------------------


def exact_table(table: Any) -> Any:
    """`table` rendered by its exact knot interpolation (`RID.exact_data`), not its grid:
    the "before" of the grid resampling, measured in the same run."""
    from lightcal.core.rid import RID

    class ExactTableRID(RID):
        symmetric = table.symmetric

        def data(self) -> Any:
            return table.exact_data()

    return ExactTableRID()


def make_rid(rid_name: str) -> Any:
    """The benchmark's light profiles: cos^m (35 degree half angle), a symmetric table
    (18 angles to 85 degrees), a 2-D table (18 angles x 24 azimuths, lopsided), and the
    two tables evaluated exactly (`table_1d_exact`, `table_2d_exact`)."""
    from lightcal.core.rid import CosPowerRID, SymmetricTableRID, Table2DRID

    if rid_name == "cos_power":
        return CosPowerRID.from_half_angle(math.radians(35.0))
    theta = np.linspace(0.0, math.radians(85.0), 18)
    if rid_name.startswith("table_1d"):
        rid: Any = SymmetricTableRID(theta, np.cos(theta) ** 2.5 + 0.02)
    elif rid_name.startswith("table_2d"):
        phi = np.radians(np.arange(0.0, 360.0, 15.0))
        tt, pp = np.meshgrid(theta, phi)
        rid = Table2DRID(
            theta, phi, np.cos(tt) ** 2.5 * (1.0 + 0.4 * np.sin(tt) * np.cos(pp)) + 0.02
        )
    else:
        raise ValueError(f"rid_name: expected one of {RIDS}, got {rid_name!r}")
    return exact_table(rid) if rid_name.endswith("_exact") else rid


def make_scene(width: int, height: int, rid_name: str) -> tuple[Any, Any, Any]:
    """A distorted camera 1.6 m from the wall, tilted, and one symmetric light beside it.

    Returns:
        (camera, view, rig).
    """
    from lightcal.core.camera import Camera
    from lightcal.core.scene import Light, Rig, View

    focal_px = 0.9 * width
    camera = Camera.from_params(
        fx=focal_px,
        fy=focal_px,
        cx=(width - 1) / 2 + 3.0,
        cy=(height - 1) / 2 - 2.0,
        width=width,
        height=height,
        dist=(-0.12, 0.05, 0.001, -0.0005, -0.01),
    )
    view = View.looking_at(np.array([0.25, -0.15, 1.6]), np.array([0.0, 0.1, 0.0]))
    rid = make_rid(rid_name)
    tilt = 0.12
    R_camera_light = np.array(
        [
            [1.0, 0.0, 0.0],
            [0.0, math.cos(tilt), -math.sin(tilt)],
            [0.0, math.sin(tilt), math.cos(tilt)],
        ]
    )
    light = Light(rid, np.array([0.12, -0.04, 0.02]), R_camera_light, scale=2.5)
    return camera, view, Rig.single(light)


def random_pixels(width: int, height: int, n: int, seed: int = 7) -> np.ndarray:
    """(n, 2) distinct random (u, v) pixel indices."""
    rng = np.random.default_rng(seed)
    flat = rng.choice(width * height, size=n, replace=False)
    return np.stack([flat % width, flat // width], axis=1).astype(np.int64)


# ---------------------------------------------------------------------------------------
# Measurements (each runs in its own subprocess: `--measure NAME ...`).
# ---------------------------------------------------------------------------------------


def peak_rss_mb() -> float:
    """The process's peak resident set size (VmHWM), MB."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _timed(fn: Any) -> tuple[float, Any]:
    t0 = time.perf_counter()
    result = fn()
    return time.perf_counter() - t0, result


def _best(fn: Any, repeats: int) -> float:
    return _best_cpu(fn, repeats)[0]


def _best_cpu(fn: Any, repeats: int) -> tuple[float, float]:
    """(wall, CPU) seconds of the fastest of `repeats` calls; CPU: all threads."""
    best = (math.inf, math.inf)
    for _ in range(repeats):
        c0 = time.process_time()
        wall, _ = _timed(fn)
        best = min(best, (wall, time.process_time() - c0))
    return best


def _warm_kernels() -> None:
    """Load (or compile) every kernel on a tiny scene, so later timings exclude it."""
    from lightcal.core import render

    for rid_name in RIDS:
        camera, view, rig = make_scene(64, 48, rid_name)
        render.render_image(camera, view, rig)
        pixels = random_pixels(64, 48, 50)
        fp = render.pixel_footprints(camera, view, pixels)
        render.shade(fp, view, rig)
        render.shade(fp, view, rig, want_grad=True)


def measure_compile() -> dict[str, Any]:
    """First calls with an empty cache (the caller sets NUMBA_CACHE_DIR) minus warm calls."""
    t_import, _ = _timed(lambda: __import__("lightcal.core.render"))
    t_first, _ = _timed(_warm_kernels)
    t_warm = _best(_warm_kernels, 3)
    return {"import_s": t_import, "first_s": t_first, "warm_s": t_warm}


def measure_image(width: int, height: int, rid_name: str, repeats: int) -> dict[str, Any]:
    """Cold and warm `render_image` of the full frame, and the process's peak memory."""
    import numba

    from lightcal.core import render

    _warm_kernels()
    camera, view, rig = make_scene(width, height, rid_name)
    rss_before = peak_rss_mb()
    t_cold, img = _timed(lambda: render.render_image(camera, view, rig))
    t_warm, cpu_warm = _best_cpu(lambda: render.render_image(camera, view, rig), repeats)
    peak = peak_rss_mb()
    del img
    # The corner grid alone (what "cold" adds), after the peak was read.
    t_grid, _ = _timed(lambda: render.corner_grid(camera))
    return {
        "cold_s": t_cold,
        "warm_s": t_warm,
        "warm_cpu_s": cpu_warm,
        "grid_s": t_grid,
        "peak_mb": peak,
        "peak_before_mb": rss_before,
        "threads": numba.get_num_threads(),
        "threading_layer": numba.threading_layer(),
    }


def measure_pixels(width: int, height: int, rid_name: str, n: int, repeats: int) -> dict[str, Any]:
    """`render_pixels` cold and warm, `shade` warm with and without gradients."""
    from lightcal.core import render

    _warm_kernels()
    camera, view, rig = make_scene(width, height, rid_name)
    pixels = random_pixels(width, height, n)
    rss_before = peak_rss_mb()
    t_cold, _ = _timed(lambda: render.render_pixels(camera, view, rig, pixels))
    t_warm = _best(lambda: render.render_pixels(camera, view, rig, pixels), repeats)
    t_fp, fp = _timed(lambda: render.pixel_footprints(camera, view, pixels))
    t_shade, cpu_shade = _best_cpu(lambda: render.shade(fp, view, rig), repeats)
    t_grad, cpu_grad = _best_cpu(lambda: render.shade(fp, view, rig, want_grad=True), repeats)
    return {
        "cold_s": t_cold,
        "warm_s": t_warm,
        "footprints_s": t_fp,
        "shade_s": t_shade,
        "shade_cpu_s": cpu_shade,
        "shade_grad_s": t_grad,
        "shade_grad_cpu_s": cpu_grad,
        "peak_mb": peak_rss_mb(),
        "peak_before_mb": rss_before,
    }


def measure_baseline_image(width: int, height: int, rid_name: str, rows: int) -> dict[str, Any]:
    """`render_image_reference` on the first `rows` rows of the frame (a cropped camera)."""
    from lightcal.core.camera import Camera
    from lightcal.core.render_reference import render_image_reference

    camera, view, rig = make_scene(width, height, rid_name)
    band = Camera(K=camera.K, dist=camera.dist, width=width, height=rows)
    render_image_reference(band, view, rig, chunk_rows=8)  # warm the RID evaluator
    t = _best(lambda: render_image_reference(band, view, rig, chunk_rows=8), 2)
    return {"seconds": t, "pixels": width * rows, "peak_mb": peak_rss_mb()}


def measure_baseline_pixels(width: int, height: int, rid_name: str, n: int) -> dict[str, Any]:
    """`render_pixels_reference` on n random pixels."""
    from lightcal.core.render_reference import render_pixels_reference

    camera, view, rig = make_scene(width, height, rid_name)
    pixels = random_pixels(width, height, n)
    render_pixels_reference(camera, view, rig, pixels[:10])
    t = _best(lambda: render_pixels_reference(camera, view, rig, pixels), 2)
    return {"seconds": t, "pixels": n, "peak_mb": peak_rss_mb()}


def measure_mitsuba(width: int, height: int, spp: int) -> dict[str, Any]:
    """The scene of `tests/mitsuba_peer.py` by lightcal and by Mitsuba 3 (`scalar_rgb`)."""
    from tests.mitsuba_peer import compare

    r = compare(width, height, spp)
    return {
        "ours_s": r.ours_s,
        "mitsuba_s": r.mitsuba_s,
        "scale": r.scale,
        "median_rel": r.median_rel,
        "p99_rel": r.p99_rel,
        "lit": r.lit,
        "peak_mb": peak_rss_mb(),
    }


def measure_medium(width: int, height: int, n: int, repeats: int) -> dict[str, Any]:
    """In air and in water (c = 0.3 /m, `lightcal.core.medium`): the full frame warm
    (`render_image`, also with backscatter) and `shade` with gradients of n pixels (the
    solver's call), each the best of `repeats` interleaved runs (so a load change hits
    all alike)."""
    from lightcal.core import render
    from lightcal.core.medium import Medium

    _warm_kernels()
    camera, view, rig = make_scene(width, height, "cos_power")
    water = Medium(0.3)
    murky = Medium(0.3, 0.6, 0.8)  # with backscatter
    fp = render.pixel_footprints(camera, view, random_pixels(width, height, n))
    calls = {
        "image_air_s": lambda: render.render_image(camera, view, rig),
        "image_water_s": lambda: render.render_image(camera, view, rig, medium=water),
        "image_murky_s": lambda: render.render_image(camera, view, rig, medium=murky),
        "shade_air_s": lambda: render.shade(fp, view, rig, want_grad=True),
        "shade_water_s": lambda: render.shade(fp, view, rig, want_grad=True, medium=water),
    }
    for call in calls.values():
        call()  # the medium's kernels loaded
    best = dict.fromkeys(calls, math.inf)
    for _ in range(repeats):
        for name, call in calls.items():
            best[name] = min(best[name], _timed(call)[0])
    return {**best, "pixels": n, "peak_mb": peak_rss_mb()}


MEASURES: dict[str, Callable[..., dict[str, Any]]] = {
    "mitsuba": measure_mitsuba,
    "medium": measure_medium,
    "compile": measure_compile,
    "image": measure_image,
    "pixels": measure_pixels,
    "baseline_image": measure_baseline_image,
    "baseline_pixels": measure_baseline_pixels,
}


# ---------------------------------------------------------------------------------------
# The driver: one subprocess per measurement, then the table.
# ---------------------------------------------------------------------------------------


def run_measure(name: str, *args: Any, env: dict[str, str] | None = None) -> dict[str, Any]:
    """Run one measurement in a fresh interpreter and return its JSON result."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--measure", name, *map(str, args)]
    proc = subprocess.run(
        cmd, capture_output=True, text=True, env={**os.environ, **(env or {})}, check=False
    )
    if proc.returncode != 0:
        raise RuntimeError(f"measurement {name} {args} failed:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


@dataclass
class Row:
    what: str
    pixels: int
    seconds: float
    peak_mb: float | None
    baseline_s: float | None
    note: str = ""
    cpu_s: float | None = None

    def cells(self) -> list[str]:
        mpx = self.pixels / self.seconds / 1e6
        ratio = "" if self.baseline_s is None else f"{self.baseline_s / self.seconds:,.0f}x"
        peak = "" if self.peak_mb is None else f"{self.peak_mb:,.0f}"
        cpu = "" if self.cpu_s is None else f"{self.cpu_s:.4f}"
        return [
            self.what,
            f"{self.pixels:,}",
            f"{self.seconds:.4f}",
            cpu,
            f"{mpx:,.2f}",
            peak,
            ratio,
            self.note,
        ]


def print_table(rows: list[Row]) -> None:
    head = ["measurement", "pixels", "seconds", "CPU s", "Mpx/s", "peak MB", "vs NumPy", "note"]
    table = [head] + [r.cells() for r in rows]
    widths = [max(len(line[i]) for line in table) for i in range(len(head))]
    for k, line in enumerate(table):
        print(
            "  ".join(
                cell.ljust(widths[i]) if i in (0, 7) else cell.rjust(widths[i])
                for i, cell in enumerate(line)
            )
        )
        if k == 0:
            print("  ".join("-" * w for w in widths))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a small smoke run (seconds)")
    parser.add_argument("--measure", nargs="+", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)

    if args.measure:
        name, *rest = args.measure
        values = [int(x) if x.lstrip("-").isdigit() else x for x in rest]
        print(json.dumps(MEASURES[name](*values)))
        return 0

    width, height = QUICK_SIZE if args.quick else FULL_SIZE
    counts = QUICK_PIXEL_COUNTS if args.quick else PIXEL_COUNTS
    repeats = 3 if args.quick else 5
    baseline_rows = 16 if args.quick else 32
    baseline_subset = 20_000 if args.quick else 100_000

    import numba

    load_before = os.getloadavg()
    print(
        f"lightcal renderer benchmark: {width} x {height} frame, distortion on; "
        f"numba {numba.__version__}, {os.cpu_count()} CPUs; "
        f"load average {load_before[0]:.2f} (the machine may be shared)"
    )
    with tempfile.TemporaryDirectory() as cache_dir:
        comp = run_measure("compile", env={"NUMBA_CACHE_DIR": cache_dir})
    print(
        f"numba compilation (empty cache, all renderer kernels): "
        f"{comp['first_s'] - comp['warm_s']:.1f} s; import {comp['import_s']:.2f} s"
    )

    rows: list[Row] = []
    for rid_name in RIDS:
        img = run_measure("image", width, height, rid_name, repeats)
        base = run_measure("baseline_image", width, height, rid_name, baseline_rows)
        base_full = base["seconds"] * (width * height) / base["pixels"]
        n_px = width * height
        label = f"full frame, {rid_name}"
        rows.append(
            Row(
                f"{label}: cold",
                n_px,
                img["cold_s"],
                img["peak_mb"],
                base_full,
                f"incl. corner grid {img['grid_s']:.2f} s",
            )
        )
        rows.append(
            Row(
                f"{label}: warm",
                n_px,
                img["warm_s"],
                None,
                base_full,
                f"{img['threads']} threads ({img['threading_layer']}); "
                f"{2 * n_px / img['warm_cpu_s'] / 1e6:.0f} Mpx/s at 2 x its CPU rate",
                cpu_s=img["warm_cpu_s"],
            )
        )
        rows.append(
            Row(
                f"{label}: NumPy baseline",
                n_px,
                base_full,
                base["peak_mb"],
                base_full,
                f"measured on {baseline_rows} rows, scaled",
            )
        )
        for n in counts:
            pix = run_measure("pixels", width, height, rid_name, n, repeats)
            sub = min(n, baseline_subset)
            bp = run_measure("baseline_pixels", width, height, rid_name, sub)
            bfull = bp["seconds"] * n / sub
            scaled = "" if sub == n else f"measured on {sub:,} pixels, scaled"
            rows.append(
                Row(
                    f"{n:,} pixels, {rid_name}: render_pixels cold",
                    n,
                    pix["cold_s"],
                    pix["peak_mb"],
                    bfull,
                    f"footprints {pix['footprints_s']:.3f} s",
                )
            )
            rows.append(
                Row(
                    f"{n:,} pixels, {rid_name}: render_pixels warm",
                    n,
                    pix["warm_s"],
                    None,
                    bfull,
                    "",
                )
            )
            rows.append(
                Row(
                    f"{n:,} pixels, {rid_name}: shade (footprints given)",
                    n,
                    pix["shade_s"],
                    None,
                    None,
                    "the solver's inner call",
                    cpu_s=pix["shade_cpu_s"],
                )
            )
            rows.append(
                Row(
                    f"{n:,} pixels, {rid_name}: shade with gradients",
                    n,
                    pix["shade_grad_s"],
                    None,
                    None,
                    "",
                    cpu_s=pix["shade_grad_cpu_s"],
                )
            )
            rows.append(
                Row(
                    f"{n:,} pixels, {rid_name}: NumPy baseline",
                    n,
                    bfull,
                    bp["peak_mb"],
                    bfull,
                    scaled,
                )
            )
    print()
    print_table(rows)
    med = run_measure("medium", width, height, counts[-1], repeats)
    print()
    print(
        f"medium (water, c = 0.3 /m) against air, cos_power: full frame {width} x {height} "
        f"warm {med['image_air_s']:.3f} s in air, {med['image_water_s']:.3f} s in water "
        f"({med['image_water_s'] / med['image_air_s']:.2f}x), {med['image_murky_s']:.3f} s "
        f"with backscatter ({med['image_murky_s'] / med['image_air_s']:.1f}x: 24 nodes a "
        f"pixel); shade with gradients of "
        f"{med['pixels']:,} pixels {med['shade_air_s']:.3f} s in air, "
        f"{med['shade_water_s']:.3f} s in water "
        f"({med['shade_water_s'] / med['shade_air_s']:.2f}x; target: within 2x)"
    )
    if importlib.util.find_spec("mitsuba") is not None:
        # An independent renderer as a peer: the same image, the same light.
        mw, mh = (240, 180) if args.quick else (960, 720)
        spp = 16 if args.quick else 64
        m = run_measure("mitsuba", mw, mh, spp)
        print()
        print(
            f"Mitsuba 3 as a peer ({mw} x {mh}, spot light, Lambertian wall, {spp} samples "
            f"per pixel, scalar_rgb): lightcal {m['ours_s'] * 1e3:.1f} ms, Mitsuba "
            f"{m['mitsuba_s']:.2f} s ({m['mitsuba_s'] / m['ours_s']:.0f}x); over "
            f"{m['lit']:,} lit pixels Mitsuba / lightcal = {m['scale']:.6f} (albedo / pi = "
            f"{0.5 / math.pi:.6f}), median relative difference {m['median_rel']:.1e}, 99th "
            f"percentile {m['p99_rel']:.1e} (Mitsuba's sampling noise; the spot's kinks)"
        )
    else:
        print()
        print("Mitsuba 3 not installed (`pip install .[reference]`): no peer row")
    load_after = os.getloadavg()
    print()
    print(
        "CPU s: process time of all threads in the timed call. On an idle machine a 2-thread "
        "render gets CPU s ~ 2 x seconds;\nless means other processes held the cores, and "
        "'2 x its CPU rate' (pixels per CPU second, times 2 cores) is what 2 free cores give."
    )
    print(
        "peak MB: the whole measuring process's VmHWM (Python, numpy, numba and the "
        "kernels' buffers included), one fresh process per measurement."
    )
    print(
        f"load average during the run: {load_before[0]:.2f} -> {load_after[0]:.2f} "
        f"on {os.cpu_count()} CPUs; targets (issue): full frame >= 100 Mpx/s warm, "
        "<= 1,500 MB peak."
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
