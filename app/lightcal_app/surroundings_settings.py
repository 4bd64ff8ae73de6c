"""The surroundings as the page edits them: the project file's `surroundings:` section
(`lightcal.io.surroundings_spec.SurroundingsSpec`; docs/model.md, "Inter-reflection").

Each edit makes a new section from the one the solve uses now: the wall's albedo, the
mesh's patch side, the bounces kept (`with_values`), one surface's albedo, corner or
edges (`with_surface_values`), a surface removed (`without_surface`: the last one
removed, nothing surrounds the wall) or added (`with_new_surface`). `check_surroundings`
validates a section exactly as the project file's is validated: by the same pydantic
model, then the core's refusals (`build_surroundings`), each error naming the key as the
project file's error would (`surroundings.surfaces[0].albedo: Input should be less than
1`), without the file's path; `check_mesh` refuses a mesh beyond the core's limits, which
the file meets only when its model is built.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from pydantic import ValidationError

from lightcal.core.bounce import GRID_FRACTION, MAX_NODES, MAX_PATCHES
from lightcal.core.bounce_term import MARGIN_M
from lightcal.core.footprint import pixel_footprints
from lightcal.errors import InputError
from lightcal.io.project import Project
from lightcal.io.spec_errors import format_loc
from lightcal.io.surroundings_spec import SurfaceSpec, SurroundingsSpec, build_surroundings

SECTION_KEYS = ("wall_albedo", "patch_m", "bounces")
"""The section's own values the page edits (`surroundings.<key>`)."""
SURFACE_KEYS = ("albedo", "corner_m", "edge_u_m", "edge_v_m")
"""A surface's values the page edits (`surroundings.surfaces[k].<key>`)."""
NEW_DEPTH_M = 0.5
"""How far an added surface reaches out of the wall, m (the synthetic corner's)."""
NEW_ALBEDO = 0.8
"""An added surface's albedo, and the wall's when nothing surrounded it."""


def check_surroundings(
    data: Mapping[str, Any] | SurroundingsSpec | None,
) -> SurroundingsSpec | None:
    """The section of `data` (its fields, as the project file holds them) when the
    project file would take it; InputError naming the key otherwise (the pydantic
    model's words, then the core's refusals of a surface, as the file's loader says them).
    """
    if data is None:
        return None
    try:
        spec = SurroundingsSpec.model_validate(
            data.model_dump() if isinstance(data, SurroundingsSpec) else data
        )
    except ValidationError as exc:
        err = exc.errors()[0]
        key = format_loc(("surroundings", *err["loc"]))
        raise InputError(key, str(err["msg"]).removeprefix("Value error, ")) from exc
    try:
        build_surroundings(spec, "surroundings")
    except InputError as exc:
        # The loader's words, "surroundings.surfaces[k] (name): ...", without its source.
        for k, s in enumerate(spec.surfaces):
            where = f"surroundings.surfaces[{k}]"
            where = f"{where} ({s.name})" if s.name else where
            if exc.detail.startswith(f"{where}: "):
                raise InputError(where, exc.detail.removeprefix(f"{where}: ")) from exc
        raise InputError("surroundings", exc.detail) from exc
    return spec


def _data(spec: SurroundingsSpec | None) -> dict[str, Any]:
    if spec is None:
        return {"surfaces": [], "wall_albedo": NEW_ALBEDO}
    return spec.model_dump()


def with_values(spec: SurroundingsSpec | None, **values: object) -> SurroundingsSpec | None:
    """`spec` with some of `wall_albedo`, `patch_m`, `bounces` (None: all) replaced;
    InputError naming the key of a value the project file refuses."""
    for key in values:
        if key not in SECTION_KEYS:
            raise InputError(
                "surroundings", f"expected one of {', '.join(SECTION_KEYS)}, got {key!r}"
            )
    if spec is None:
        raise InputError("surroundings", "expected a surface first (Add a surface)")
    return check_surroundings({**_data(spec), **values})


def _surface(spec: SurroundingsSpec | None, k: object) -> int:
    n = 0 if spec is None else len(spec.surfaces)
    if isinstance(k, bool) or not isinstance(k, int) or not 0 <= k < n:
        raise InputError("surroundings.surfaces", f"expected a surface 0 to {n - 1}, got {k!r}")
    return k


def with_surface_values(
    spec: SurroundingsSpec | None, k: int, **values: object
) -> SurroundingsSpec | None:
    """`spec` with surface k's `albedo`, `corner_m`, `edge_u_m` or `edge_v_m` replaced;
    InputError naming the key of a value the project file refuses."""
    k = _surface(spec, k)
    for key in values:
        if key not in SURFACE_KEYS:
            raise InputError(
                f"surroundings.surfaces[{k}]",
                f"expected one of {', '.join(SURFACE_KEYS)}, got {key!r}",
            )
    data = _data(spec)
    vectors = {
        key: list(v) if isinstance(v, tuple | np.ndarray) else v for key, v in values.items()
    }
    data["surfaces"][k] = {**data["surfaces"][k], **vectors}
    return check_surroundings(data)


def without_surface(spec: SurroundingsSpec | None, k: int) -> SurroundingsSpec | None:
    """`spec` without surface k; None (nothing surrounds the wall) without it alone."""
    k = _surface(spec, k)
    data = _data(spec)
    del data["surfaces"][k]
    return check_surroundings(data) if data["surfaces"] else None


def new_surface(project: Project, names: list[str]) -> SurfaceSpec:
    """A surface to start from: a ceiling along the top of the wall the views look at
    (world -y is up), `NEW_DEPTH_M` deep and as wide as the views' span and 1 m more,
    named `surface <n>` (a name not in `names`)."""
    centres = np.array([v.center_world for v in project.views])
    x0, x1 = float(centres[:, 0].min()) - 0.5, float(centres[:, 0].max()) + 0.5
    top = float(centres[:, 1].min()) - 0.5
    n = len(names) + 1
    while f"surface {n}" in names:
        n += 1
    return SurfaceSpec(
        name=f"surface {n}",
        corner_m=[x0, top, 0.0],
        edge_u_m=[x1 - x0, 0.0, 0.0],
        edge_v_m=[0.0, 0.0, NEW_DEPTH_M],
        albedo=NEW_ALBEDO,
    )


def with_new_surface(spec: SurroundingsSpec | None, project: Project) -> SurroundingsSpec | None:
    """`spec` with `new_surface` added (a section of its own when there was none);
    InputError beyond the file's most surfaces."""
    data = _data(spec)
    added = new_surface(project, [s["name"] for s in data["surfaces"]])
    data["surfaces"].append(added.model_dump())
    return check_surroundings(data)


def check_mesh(project: Project, spec: SurroundingsSpec | None) -> None:
    """InputError (`surroundings.patch_m`, in the core's words) when the bounce's mesh
    would pass the core's limits (`lightcal.core.bounce.MAX_PATCHES` patches,
    `MAX_NODES` wall nodes over the wall the images see and `MARGIN_M` around it, as
    the overlays build it). The project file is refused then too, when its model is
    built; the page refuses such a section as it is typed, before the overlays or the
    solve would fail on it. The counts are those of `lightcal.core.bounce.BounceMap`."""
    if spec is None:
        return
    h = spec.patch_m
    count = 0
    for s in spec.surfaces:
        sides = (float(np.linalg.norm(e)) for e in (s.edge_u_m, s.edge_v_m))
        nu, nv = (max(1, math.ceil(n / h - 1e-9)) for n in sides)
        count += nu * nv
    if count > MAX_PATCHES:
        raise InputError(
            "surroundings.patch_m",
            f"{count} patches of {h:g} m; expected at most {MAX_PATCHES} (a larger patch_m, "
            "or smaller surfaces)",
        )
    lo, hi = _seen_wall(project)
    step = GRID_FRACTION * h
    extent = (hi - lo) + 2.0 * MARGIN_M
    nodes = math.prod(int(e / step) + 3 for e in extent)
    if nodes > MAX_NODES:
        raise InputError(
            "surroundings.patch_m",
            f"the wall's grid would have about {nodes} nodes of {step:g} m; expected at most "
            f"{MAX_NODES} (a larger patch_m)",
        )


def _seen_wall(project: Project) -> tuple[np.ndarray, np.ndarray]:
    """(2,) the lowest and highest world x, y of the wall at the images' corners."""
    cam = project.camera
    w, h = cam.width - 1, cam.height - 1
    corners = np.array([[0, 0], [w, 0], [w, h], [0, h]])
    points = [pixel_footprints(cam, view, corners).centers_world for view in project.views]
    xy = np.concatenate(points)[:, :2]
    xy = xy[np.all(np.isfinite(xy), axis=1)]
    if not len(xy):
        return np.zeros(2), np.zeros(2)
    return xy.min(axis=0), xy.max(axis=0)
