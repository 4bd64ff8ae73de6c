"""The true light of a synthetic data set (`truth.json` beside the project), for demo mode.

Only `lights[]` (or a single `light`) is read: each entry gives `position_m` (camera
frame, m) and either
`R_camera_light` (3 x 3) or `axis_camera` (3,) (the minimal rotation from +z is used).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from lightcal.core.pose import rotation_from_axis
from lightcal.errors import InputError, LightcalError
from lightcal_app.state import LightGuess

TRUTH_NAME = "truth.json"


def truth_path_for(project_path: Path) -> Path:
    """Where a project's truth file sits (beside it)."""
    return project_path.parent / TRUTH_NAME


def read_truth_lights(path: Path) -> list[LightGuess]:
    """The true light poses of a truth file; InputError naming the field on any problem."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError as exc:
        raise InputError(path, "truth file not found (demo mode needs truth.json)") from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(path, f"cannot read the truth file ({exc})") from exc
    except json.JSONDecodeError as exc:
        raise InputError(path, f"not valid JSON: {exc.msg}", line=exc.lineno) from exc
    lights = data.get("lights") if isinstance(data, dict) else None
    if lights is None and isinstance(data, dict) and isinstance(data.get("light"), dict):
        lights = [data["light"]]  # the sample data's truth: one light
    if not isinstance(lights, list) or not lights:
        raise InputError(
            path, "lights: expected a non-empty list of true light poses (or one 'light')"
        )
    out = []
    for j, entry in enumerate(lights):
        field = f"lights[{j}]"
        try:
            if not isinstance(entry, dict):
                raise ValueError("expected an object")
            position = np.asarray(entry["position_m"], dtype=np.float64)
            if position.shape != (3,) or not np.all(np.isfinite(position)):
                raise ValueError("position_m: expected 3 finite numbers")
            if "R_camera_light" in entry:
                R = np.asarray(entry["R_camera_light"], dtype=np.float64)
                if R.shape != (3, 3) or abs(np.linalg.det(R) - 1.0) > 1e-4:
                    raise ValueError("R_camera_light: expected a 3x3 rotation matrix")
            elif "axis_camera" in entry:
                R = rotation_from_axis(np.asarray(entry["axis_camera"], dtype=np.float64))
            else:
                raise ValueError("expected R_camera_light or axis_camera")
        except KeyError as exc:
            raise InputError(path, f"{field}: missing {exc.args[0]}") from exc
        except (ValueError, TypeError, LightcalError) as exc:
            raise InputError(path, f"{field}: {exc}") from exc
        out.append(LightGuess(position, R))
    return out
