"""A small synthetic calibration project for the app's tests and benchmark.

`make_project` renders 16-bit PNG images of a wall lit by one cos-power light from a
few camera poses (different distances and tilts, as the calibration needs), writes the
camera file, a `project.json` whose initial guess is off the truth, and a `truth.json`
(what `lightcal app --demo` shows as the ghost light). Frames and units follow docs/model.md.
"""

from __future__ import annotations

import json
import math
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from lightcal_app import requests as rq
from lightcal_app.solve_service import SolveService
from lightcal_app.state import AppState

from lightcal.core.camera import Camera
from lightcal.core.pose import axis_from_angles, describe_pose, rotation_from_axis
from lightcal.core.render import render_image
from lightcal.core.rid import CosPowerRID
from lightcal.core.scene import Light, Rig, View
from lightcal.io.camera_file import write_camera

TRUE_POSITION_M = (0.10, -0.03, 0.01)
TRUE_AXIS_ANGLES_RAD = (0.08, -0.05)
HALF_ANGLE_DEG = 30.0
INITIAL_POSITION_M = (0.05, 0.0, 0.0)


@dataclass(frozen=True)
class SyntheticProject:
    """What `make_project` wrote.

    Attributes:
        path: the project.json.
        truth_path: the truth.json beside it.
        camera: the intrinsics.
        views: one per image.
        true_light: the light the images were rendered with.
    """

    path: Path
    truth_path: Path
    camera: Camera
    views: list[View]
    true_light: Light


def true_light() -> Light:
    """The light of the synthetic images (camera frame)."""
    return Light(
        CosPowerRID.from_half_angle(math.radians(HALF_ANGLE_DEG)),
        np.array(TRUE_POSITION_M),
        rotation_from_axis(axis_from_angles(*TRUE_AXIS_ANGLES_RAD)),
        scale=1.0,
        name="led",
    )


def make_project(
    folder: Path,
    *,
    n_views: int = 5,
    width: int = 240,
    height: int = 180,
    seed: int = 3,
    n_per_image: int = 60,
) -> SyntheticProject:
    """Write a synthetic project into `folder` (created).

    Args:
        folder: where project.json, camera.yaml, truth.json and images/ go.
        n_views: number of images.
        width, height: image size, pixels.
        seed: seed of the camera poses and exposure jitter.
        n_per_image: pixels the random strategy picks per image.
    """
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "images").mkdir(exist_ok=True)
    rng = np.random.default_rng(seed)
    f = 1.1 * width
    camera = Camera.from_params(
        fx=f,
        fy=f,
        cx=(width - 1) / 2,
        cy=(height - 1) / 2,
        width=width,
        height=height,
        dist=(-0.05, 0.01, 0.0, 0.0, 0.0),
    )
    write_camera(camera, folder / "camera.yaml")
    light = true_light()
    views: list[View] = []
    images = []
    k = None
    for i in range(n_views):
        d = 0.8 + 1.7 * i / max(n_views - 1, 1)
        tilt = rng.uniform(-0.5, 0.5, 2)
        center = np.array([d * math.sin(tilt[0]), d * math.sin(tilt[1]), d * math.cos(tilt[0])])
        target = np.array([0.1, 0.0, 0.0]) + np.r_[rng.normal(0.0, 0.1, 2), 0.0]
        view = View.looking_at(center, target)
        views.append(view)
        img = render_image(camera, view, Rig.single(light)).filled(0.0)
        if k is None:
            k = 0.7 * 60000.0 / float(np.percentile(img, 99.9))
        dn = np.clip(np.round(img * k * (0.8 + 0.4 * rng.random())), 0, 65535).astype(np.uint16)
        cv2.imwrite(str(folder / "images" / f"v{i:02d}.png"), dn)
        images.append(
            {
                "path": f"images/v{i:02d}.png",
                "T_camera_world": {
                    "R": view.R_camera_world.tolist(),
                    "t": view.t_camera_world.tolist(),
                },
            }
        )
    project = {
        "version": 1,
        "camera": {"path": "camera.yaml"},
        "images": images,
        "lights": [
            {
                "name": "led",
                "rid": {"type": "half_angle", "half_angle_deg": HALF_ANGLE_DEG},
                "initial": {"position_m": list(INITIAL_POSITION_M)},
            }
        ],
        "solver": {"estimate_gains": True, "max_iterations": 40},
        "selection": {"n_per_image": n_per_image},
    }
    path = folder / "project.json"
    path.write_text(json.dumps(project, indent=1), encoding="utf-8")
    truth = {
        "lights": [
            {"name": light.name, **describe_pose(light.R_camera_light, light.t_camera_light)}
        ]
    }
    truth_path = folder / "truth.json"
    truth_path.write_text(json.dumps(truth, indent=1), encoding="utf-8")
    return SyntheticProject(path, truth_path, camera, views, light)


def run_requests(solve: SolveService, state: AppState, timeout: float = 60.0) -> None:
    """What the worker does with the solve's requests (Finished), without a thread.

    A session that ended with an outcome says so before its Finished request is queued:
    the loop waits for that request too."""
    deadline = threading.Event()
    handled = False
    for _ in range(int(timeout / 0.01)):
        with state.lock:
            pending = list(state.requests)
            state.requests.clear()
        for req in pending:
            if isinstance(req, rq.Finished):
                solve.finished(req.gen, req.outcome)
                handled = True
        solve.poll()
        session = solve.session
        # (A cancelled solve, "stopped" without an outcome, sends no request.)
        ended = session is not None and session.outcome is not None
        with state.lock:
            shown = handled or state.solver_state in ("converged", "not converged")
        if not solve.running() and not pending and (shown or not ended):
            return
        deadline.wait(0.01)
    raise AssertionError("the solve did not settle")


def run_in_page(app: Any, timeout: float = 300.0) -> Any:
    """Run pressed in a built app (`lightcal_app.server.LightcalApp`) at full pace, as
    its worker runs it: wait for the solve's end and the page to settle; the result."""
    app.controller.set_pace(0.0)
    app.controller.run()
    deadline = time.monotonic() + timeout
    while app.state.solver_state not in ("converged", "not converged"):
        assert time.monotonic() < deadline, "the solve did not end"
        time.sleep(0.05)
    assert app.wait_idle(120.0)
    assert app.state.result is not None
    return app.state.result
