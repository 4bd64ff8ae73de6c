"""Compiling the numba kernels once, where the user expects to wait, and saying so.

numba compiles a kernel the first time it runs and keeps the machine code on disk
(`cache=True`), so only the first run after an install, an upgrade or a change of the
sources pays: one to a few minutes on two cores. Unannounced, that first run looks hung.

- `warm_up` runs, per kernel family, a tiny synthetic calibration end to end: it writes a
  64 x 48 dataset in a temporary folder (which renders full images), reads it back,
  selects pixels, builds the model, solves a few iterations, tests the fit and, for the
  first family, writes the report. Every kernel a command or the app runs is then in the
  cache, with the argument types real projects give it. It ends by writing a marker
  beside numba's cache listing the kernels it compiled. With two worker processes, the
  kernels every family shares come first (the flux kernels in one worker, the full-image
  renderer in the other), then the families side by side: 130-200 s on two cores.
- `kernels_ready` reads that marker back and asks numba's cache whether each listed
  kernel is still there and matches its source; it takes a few milliseconds. The marker
  also holds a digest of `lightcal.core`'s sources (`sources_digest`): numba checks only
  a kernel's own file, so after an edit of a helper in another file the digest differs,
  the kernels are not ready, and `warm_up` flushes the listed kernels' cache first.
- `lightcal warmup` (run by `scripts/setup.sh`) and the first `calibrate`, `render`,
  `init` or `app` without a ready cache run `warm_up` with a progress line.

numba's cache objects (`Dispatcher._cache`) are not public API: if they change, the check
says "ready" and numba compiles silently, as before.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from lightcal.warmup_families import DENSE, FAMILIES, Family

MARKER_NAME = "lightcal-warmup.json"
"""The marker file, beside numba's cache of the kernels package."""

WarmupProgress = Callable[[str, int, int], None]
"""progress(family, done, total): called before each family and once at the end."""

__all__ = ["FAMILIES", "Family", "WarmupProgress", "kernels_ready", "warm_up"]


def _dispatchers() -> dict[str, Any]:
    """Every numba dispatcher with a disk cache in the loaded lightcal modules, by
    'module:name'."""
    from numba.core.dispatcher import Dispatcher

    out: dict[str, Any] = {}
    for name, module in list(sys.modules.items()):
        if not (name == "lightcal" or name.startswith("lightcal.")) or module is None:
            continue
        for attr, obj in vars(module).items():
            if (
                isinstance(obj, Dispatcher)
                and obj.__module__ == name
                and getattr(getattr(obj, "_cache", None), "_cache_path", None)
            ):
                out[f"{name}:{attr}"] = obj
    return out


def _marker_path() -> Path | None:
    """Where numba caches the renderer's kernels, and so the marker; None if unknown."""
    try:
        from lightcal.core.kernels.image import render_image_fused

        dispatcher: Any = render_image_fused
        return Path(dispatcher._cache._cache_path) / MARKER_NAME
    except (AttributeError, ImportError):  # numba's internals moved
        return None


def _cached(dispatcher: Any) -> bool:
    """Whether numba's disk cache holds compiled code for `dispatcher`'s current source."""
    return bool(dispatcher._cache._cache_file._load_index())


def sources_digest() -> str:
    """A digest of every module of `lightcal.core`, where all the compiled kernels live.

    numba's cache checks only the stamp of a kernel's own source file, not of the helpers
    it inlines from other files: after an edit of, say, `rid_grid.py`, the kernels of
    `kernels/image.py` would load their old machine code. The warm-up marker records this
    digest; a different one makes the kernels not ready and `warm_up` flush their cache.
    """
    root = Path(__file__).resolve().parent / "core"
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()[:16]


def _read_marker(marker: Path) -> dict[str, Any] | None:
    """The marker's content, or None when it is missing or unreadable."""
    try:
        data = json.loads(marker.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _listed_dispatcher(qualified: str) -> Any:
    """The dispatcher a marker names as 'module:name', or None when the module no longer
    has it (ImportError, ValueError: as importlib and the split raise them)."""
    module_name, attr = qualified.split(":", 1)
    return getattr(importlib.import_module(module_name), attr, None)


def kernels_ready() -> bool:
    """True when the kernels `warm_up` compiles are all in numba's cache, compiled from
    the present sources (or when numba's cache cannot be inspected); False before the
    first warm-up or after a change."""
    marker = _marker_path()
    if marker is None:
        return True
    data = _read_marker(marker)
    if data is None or data.get("sources") != sources_digest():
        return False
    try:
        names = data["kernels"]
    except (KeyError, TypeError):
        return False
    try:
        for qualified in names:
            dispatcher = _listed_dispatcher(qualified)
            if dispatcher is None or not _cached(dispatcher):
                return False
    except (AttributeError, ImportError, ValueError):
        return True
    return True


def _write_dataset(folder: Path, family: Family) -> Path:
    """A tiny synthetic dataset for `family`; returns its project file."""
    from lightcal.core.camera import Camera
    from lightcal.synthetic.dataset import SynthConfig, write_dataset
    from lightcal.synthetic.departures import Departures
    from lightcal.synthetic.scenes import RigConfig, SceneConfig

    w, h = family.size
    f = 0.95 * w
    camera = Camera.from_params(
        fx=f, fy=f, cx=(w - 1) / 2, cy=(h - 1) / 2, width=w, height=h, dist=(-0.1, 0.02, 0, 0, 0)
    )
    synth: dict[str, Any] = dict(family.synth or {})
    # Departures: the camera behind a port, the lights behind theirs.
    ports = {name: synth.pop(name) for name in ("port", "light_port") if name in synth}
    if ports:
        synth["departures"] = Departures(**ports)
    config = SynthConfig(
        camera=camera,
        scene=SceneConfig(n_views=4),
        rig=RigConfig(n_lights=family.n_lights, model=family.light_model),  # type: ignore[arg-type]
        seed=1,
        **synth,
    )
    dataset = write_dataset(folder, config)
    project = json.loads(dataset.project_path.read_text(encoding="utf-8"))
    project["solver"] = {"max_iterations": 3}
    # 120 pixels: below the footprint kernel's parallel chunk (256), as in the paper (100).
    project["selection"] = family.selection or {"strategy": "random", "n_per_image": 120}
    if family.wall is not None:
        project["wall"] = family.wall
    if family.medium is not None:
        project["medium"] = family.medium
    if not family.noise_model:
        project["sensor"].pop("noise", None)
    dataset.project_path.write_text(json.dumps(project), encoding="utf-8")
    return dataset.project_path


def _shade_stored_quads(project_path: Path) -> None:
    """The flux of super-pixels whose footprints keep their quads (a sparse binned
    `pixel_footprints`), as the intrinsics' uncertainty renders its perturbed cameras."""
    import numpy as np

    from lightcal.core.footprint import pixel_footprints
    from lightcal.core.render import light_flux
    from lightcal.io.project import load_project

    project = load_project(project_path)
    camera, view = project.camera, project.views[0]
    # A sparse set of super-pixels: read directly, not from the camera's corner grid.
    v, u = np.mgrid[0 : camera.height // 2 : 8, 0 : camera.width // 2 : 8]
    pixels = np.stack([u.ravel(), v.ravel()], axis=1).astype(np.int64)
    moved = camera.with_intrinsic_params(camera.intrinsic_params * (1.0 + 1e-7))  # no grid
    footprints = pixel_footprints(moved, view, pixels, binning=2)
    for unknown in project.lights:
        light_flux(footprints, view, unknown.initial)


def _calibrate(project_path: Path, report_dir: Path | None) -> None:
    """The pipeline of `lightcal calibrate` on one project (and its report)."""
    from lightcal.io.project import load_project
    from lightcal.pipeline import build_model, calibrate, load_images

    project = load_project(project_path)
    loaded = load_images(project)
    model = build_model(project, loaded)
    cal = calibrate(project, loaded, model)
    if report_dir is not None:
        from lightcal.report import write_report

        write_report(report_dir, project, loaded, cal.model, cal.result)


def _compile_flux_kernels() -> int:
    """The flux kernels every family calls (the quad loop and the wall fast paths with
    and without gradients: serial, on the thread pool, on the corner grid) by `shade` on
    a synthetic view; returns the process id. The longest chain of the compile: run
    first, on its own, so that no two workers compile it side by side."""
    import math

    import numpy as np

    from lightcal.core.camera import Camera
    from lightcal.core.footprint import pixel_footprints
    from lightcal.core.kernels import flux
    from lightcal.core.pose import axis_from_angles, rotation_from_axis
    from lightcal.core.render import shade
    from lightcal.core.rid import CosPowerRID
    from lightcal.core.scene import Light, Rig, View

    w, h = DENSE
    camera = Camera.from_params(
        fx=0.95 * w, fy=0.95 * w, cx=(w - 1) / 2, cy=(h - 1) / 2, width=w, height=h,
        dist=(-0.1, 0.02, 0, 0, 0),
    )  # fmt: skip
    view = View.looking_at(np.array([0.2, -0.1, 1.2]), np.array([0.0, 0.05, 0.0]))
    light = Light(
        CosPowerRID.from_half_angle(math.radians(30.0)),
        np.array([0.1, -0.03, 0.01]),
        rotation_from_axis(axis_from_angles(0.05, -0.04)),
        scale=1.0,
    )
    rig = Rig.single(light)
    v, u = np.mgrid[0 : camera.height, 0 : camera.width]
    every = np.stack([u.ravel(), v.ravel()], axis=1).astype(np.int64)
    serial_work = flux.SERIAL_WORK
    try:
        for pixels, serial in ((every[::97], True), (every[::97], False), (every, True)):
            flux.SERIAL_WORK = serial_work if serial else 0
            footprints = pixel_footprints(camera, view, pixels)
            for want_grad in (False, True):
                shade(footprints, view, rig, want_grad=want_grad)
    finally:
        flux.SERIAL_WORK = serial_work
    return os.getpid()


def _compile_render_kernels(folder: Path) -> int:
    """The full-image renderer (what writing every family's dataset runs); returns the
    process id."""
    _write_dataset(folder / "data", FAMILIES[0])
    return os.getpid()


SHARED_LABEL = "shared kernels: the flux + the renderer"
"""The progress label of the stage that compiles what every family shares."""


def _run_family(family: Family, folder: Path) -> int:
    """Compile one family's kernels by its synthetic calibration; returns the process id."""
    project_path = _write_dataset(folder / "data", family)
    from lightcal.core.kernels import flux

    serial_work = flux.SERIAL_WORK
    if family.parallel:
        flux.SERIAL_WORK = 0
    try:
        _calibrate(project_path, folder / "report" if family.report else None)
        if family.parallel:
            _shade_stored_quads(project_path)
    finally:
        flux.SERIAL_WORK = serial_work
    return os.getpid()


def _run_family_in_worker(family: Family, folder: Path) -> int:
    """`_run_family` as a worker process runs it (a module-level name that pickles, looked
    up in the worker's own import of this module)."""
    return _run_family(family, folder)


def default_jobs() -> int:
    """Processes that compile at once: one per core, at most two (the first two families
    take most of the time; more processes would compile the same shared kernels again)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return max(1, min(2, cores or 1))


TICK_S = 3.0
"""How often the progress line says how many kernels are cached while workers compile."""


class KernelCounter:
    """How many of lightcal's numba kernels the worker processes have put in numba's disk
    cache so far (read from the cache's index files: a few ms)."""

    def __init__(self) -> None:
        import pkgutil

        import lightcal.core

        for info in pkgutil.walk_packages(lightcal.core.__path__, "lightcal.core."):
            try:
                importlib.import_module(info.name)  # defines its kernels; compiles nothing
            except Exception:  # a module that cannot load here counts no kernel
                continue
        self.dispatchers = list(_dispatchers().values())
        self.start = self.cached()

    def cached(self) -> int:
        """How many of the kernels numba's cache holds now."""
        count = 0
        for d in self.dispatchers:
            try:
                count += _cached(d)
            except Exception:  # an index being written right now: counted next time
                continue
        return count

    def text(self) -> str:
        """How many kernels were compiled since the counter was made, in words."""
        k = max(self.cached() - self.start, 0)
        return f"{k} kernel{'s' if k != 1 else ''} compiled so far"


def _compile_in_processes(tmp: Path, jobs: int, progress: WarmupProgress | None) -> bool:
    """Compile the shared kernels, then the families, in `jobs` worker processes; numba's
    cache on disk is what they leave behind. False if the workers could not run (then the
    caller compiles everything itself)."""
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    total = len(FAMILIES)
    try:
        context = multiprocessing.get_context("spawn")  # no fork of a threaded process
        pool = ProcessPoolExecutor(max_workers=jobs, mp_context=context)
    except Exception:  # no processes here (a sandbox, no /dev/shm): compile in-process
        return False
    try:
        # First what every family shares, the flux and the renderer side by side: workers
        # that took families at once would compile the same kernels in each.
        counter = KernelCounter() if progress is not None else None

        def tell(label: str, done: int) -> None:
            # The kernels the workers have put in numba's cache so far: the line moves
            # every few seconds, not once per family (the shared stage alone takes
            # minutes on a busy two-core machine).
            if progress is not None and counter is not None:
                progress(f"{label} ({counter.text()})", done, total)

        shared = [pool.submit(_compile_flux_kernels), pool.submit(_compile_render_kernels, tmp)]
        while True:
            tell(SHARED_LABEL, 0)
            finished, unfinished = wait(shared, timeout=TICK_S)
            for future in finished:
                future.result()
            if not unfinished:
                break
        pending = {
            pool.submit(_run_family_in_worker, family, tmp / f"family{i}"): family
            for i, family in enumerate(FAMILIES)
        }
        done = 0
        while pending:
            running = [f.label for f in list(pending.values())[:jobs]]
            tell(" + ".join(running), done)
            finished, _ = wait(pending, timeout=TICK_S, return_when=FIRST_COMPLETED)
            for future in finished:
                del pending[future]
                future.result()
                done += 1
    except BaseException as exc:
        # Interrupted (a SIGINT sent to this process alone, as a supervisor or a test
        # does) or failed: the workers would compile on for minutes after this process
        # ended. They are stopped now; a failure compiles in-process instead.
        _stop_workers(pool)
        if isinstance(exc, Exception):
            return False
        raise
    pool.shutdown(wait=True)
    return True


def _stop_workers(pool: Any) -> None:
    """Terminate a ProcessPoolExecutor's worker processes and drop its queued work.
    (`_processes` is the executor's own table; without it the workers finish.)"""
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        process.terminate()
    pool.shutdown(wait=False, cancel_futures=True)


def _flush_stale_kernels(sources: str) -> None:
    """Empty numba's cache of every kernel a marker lists when the marker was written for
    other sources than `sources` (`sources_digest`): they are compiled again from the
    present ones. No marker (a fresh install) flushes nothing."""
    marker = _marker_path()
    data = None if marker is None else _read_marker(marker)
    if data is None or data.get("sources") == sources:
        return
    for qualified in data.get("kernels", []):
        try:
            dispatcher = _listed_dispatcher(str(qualified))
            if dispatcher is not None:
                dispatcher._cache.flush()
        except (AttributeError, ImportError, ValueError, OSError):
            continue  # renamed or moved since: nothing cached under the old name is loaded


def warm_up(progress: WarmupProgress | None = None, *, jobs: int | None = None) -> float:
    """Compile every kernel family (see the module docstring); returns the seconds taken.

    With `jobs` > 1 (default: `default_jobs()`), worker processes compile the families
    side by side first (see the module docstring); then this process runs every
    family once more, which loads their kernels from numba's cache (a few seconds) and
    compiles whatever a worker left out. Writes only in a temporary folder and numba's
    cache (and the marker beside it).
    """
    start = time.perf_counter()
    jobs = default_jobs() if jobs is None else max(1, jobs)
    total = len(FAMILIES)
    # The sources as they are now: the marker must not claim an edit made while compiling.
    sources = sources_digest()
    _flush_stale_kernels(sources)
    with tempfile.TemporaryDirectory(prefix="lightcal-warmup-") as tmp:
        parallel = jobs > 1 and _compile_in_processes(Path(tmp) / "workers", jobs, progress)
        for i, family in enumerate(FAMILIES):
            if progress is not None and not parallel:
                progress(family.label, i, total)
            _run_family(family, Path(tmp) / f"family{i}")
    if progress is not None:
        progress("done", total, total)
    marker = _marker_path()
    if marker is not None:
        compiled = sorted(name for name, d in _dispatchers().items() if _cached(d))
        try:
            tmp_marker = marker.with_suffix(".tmp")
            content = {"sources": sources, "kernels": compiled}
            tmp_marker.write_text(json.dumps(content, indent=1), encoding="utf-8")
            tmp_marker.replace(marker)
        except OSError:
            pass  # a read-only cache: numba could not write there either
    return time.perf_counter() - start
