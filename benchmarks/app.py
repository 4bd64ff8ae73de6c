"""How fast the calibration app is (printed, no assertions).

    .venv/bin/python benchmarks/app.py [PROJECT] [--steps N] [--no-browser]

Measures, on the sample project (sample_data/project.json, else a synthetic 12-image
800 x 600 project made in a temporary folder):

- launch: `build_app` (read the project and images, select pixels, first redraw);
- page: from launch until a headless Chromium shows the interactive panel (when
  /usr/bin/chromium and Playwright are there);
- step: one solver iteration with the residual overlays of every image re-rendered and
  sent, measured server-side from the Step request until that iteration is drawn
  (target: under 200 ms for 12 images), split into solver, pictures and sending;
- the size of the pictures sent (long side and JPEG bytes);
- the report download: zip size and time, screen-size figures and full size (after Run).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from lightcal_app.server import LightcalApp, build_app, default_project_path  # noqa: E402

FLAGS = [
    "--no-sandbox",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--disable-quic",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
]


def sample_project(tmp: Path) -> Path:
    path = default_project_path()
    if path.is_file():
        return path
    from tests.app_fixtures import make_project

    print(f"{path} is missing: using a synthetic 12-image 800 x 600 project")
    return make_project(tmp / "sample", n_views=12, width=800, height=600, n_per_image=100).path


def time_page(app: LightcalApp) -> float | None:
    """Seconds until a headless Chromium shows the panel, or None without a browser."""
    if not Path("/usr/bin/chromium").exists():
        return None
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        return None
    t0 = time.perf_counter()
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path="/usr/bin/chromium", args=FLAGS)
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        page.goto(app.url)
        page.get_by_text("Connecting...").wait_for(state="hidden", timeout=180_000)
        page.get_by_role("button", name="Back to the project's initial guess").wait_for(
            timeout=180_000
        )
        elapsed = time.perf_counter() - t0
        browser.close()
    return elapsed


def time_steps(app: LightcalApp, n: int) -> list[dict[str, float]]:
    """Per step: seconds from the request until the iteration is drawn, and parts."""
    st = app.state
    ctl = app.controller
    out = []
    for _ in range(n):
        with st.lock:
            target = (st.history[-1].iteration + 1) if st.history else 1
            gen = st.session_gen
        t0 = time.perf_counter()
        ctl.step()

        def drawn(g: int = gen, t: int = target) -> bool:
            return st.drawn >= (g, t) or st.session_gen != g

        with st.cond:
            st.cond.wait_for(drawn, 60)
        total = time.perf_counter() - t0
        # The redraw that showed this iteration (the Plan tab's read-out redraws after it).
        timings = dict(ctl.redrawer.iteration_timings.get((gen, target), ctl.timings))
        out.append({"total_s": total, **timings})
        app.wait_idle(60)
        if st.solver_state != "paused":
            break
    return out


def time_report(app: LightcalApp) -> None:
    """The report download (Result tab): its size and time at screen size (the default)
    and at the CLI's print size, after Run to the end. Target: < 8 MB on the sample."""
    from lightcal_app.results import report_zip_bytes

    app.controller.set_pace(0.0)
    app.controller.run()
    app.wait_idle(300)
    st = app.state
    model, result = app.controller.solve.model, st.result
    if model is None or result is None:
        print("report: no result to report on")
        return
    sizes = {}
    for full in (False, True):
        t0 = time.perf_counter()
        content = report_zip_bytes(st.project, st.loaded, model, result, full_size=full)
        sizes[full] = len(content)
        what = "full-size figures" if full else "screen-size figures (default)"
        took = time.perf_counter() - t0
        print(f"report zip, {what}: {len(content) / 1e6:.1f} MB in {took:.1f} s")
    print(f"report zip: full size / default = {sizes[True] / sizes[False]:.1f}x; target < 8 MB")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("project", nargs="?", type=Path)
    parser.add_argument("--steps", type=int, default=6)
    parser.add_argument("--no-browser", action="store_true")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="lightcal-bench-") as tmp_name:
        tmp = Path(tmp_name)
        path = args.project or sample_project(tmp)
        t0 = time.perf_counter()
        app = build_app(path, port=0, session_path=False, state_dir=tmp / "state")
        app.wait_idle(120)
        launch = time.perf_counter() - t0
        try:
            n_img = len(app.state.project.names)
            cam = app.state.loaded.camera
            print(f"project: {path} ({n_img} images, {cam.width} x {cam.height})")
            print(f"launch (load, select, first redraw): {launch:.2f} s")
            page = None if args.no_browser else time_page(app)
            if page is not None:
                print(f"page interactive in a headless Chromium: {page:.2f} s after the server")
            app.controller.set_overlay("residual")
            app.wait_idle(60)
            steps = time_steps(app, args.steps)
            first, rest = steps[0], steps[1:] or steps
            print(
                f"first step (builds the model, iteration 0 and 1): {first['total_s'] * 1e3:.0f} ms"
            )
            med = {k: statistics.median(s[k] for s in rest) for k in rest[0]}
            print(
                f"one step with all {n_img} residual overlays: "
                f"median {med['total_s'] * 1e3:.0f} ms "
                f"(pictures {med['pictures_s'] * 1e3:.0f} ms, sending {med['send_s'] * 1e3:.0f} "
                f"ms, rest: solver iteration) over {len(rest)} steps; target < 200 ms"
            )
            time_report(app)
            rgb = app.controller.scene.frusta[0].image
            _, jpeg = cv2.imencode(".jpg", np.ascontiguousarray(rgb[..., ::-1]))
            print(
                f"pictures sent: {rgb.shape[1]} x {rgb.shape[0]} px, about "
                f"{len(jpeg) / 1e3:.0f} kB JPEG each (rendered at binning "
                f"{app.controller.overlays.geo.render_binning})"
            )
        finally:
            app.close()


if __name__ == "__main__":
    main()
