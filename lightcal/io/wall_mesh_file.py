"""The wall's mesh file (project `wall.mesh`): read and write a `WallMesh`.

Any format trimesh loads (PLY, OBJ, STL, OFF, GLB, ...), in the project's world frame
and metres (docs/model.md, "Non-planar targets"). A file of several bodies (a scene) is
read as their union. Written as binary PLY.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lightcal.core.wall_mesh import WallMesh
from lightcal.errors import InputError
from lightcal.io.atomic import atomic_write_bytes


def read_wall_mesh(path: str | Path) -> WallMesh:
    """The triangles of a mesh file as a `WallMesh`.

    Raises:
        InputError: naming the file: missing, unreadable, no triangles, non-finite or
            out-of-range vertices.
    """
    import trimesh

    p = Path(path)
    if not p.is_file():
        raise InputError(p, "wall mesh: file not found (expected a triangle mesh trimesh reads)")
    try:
        loaded = trimesh.load(str(p), force="mesh", process=False)
    except Exception as exc:  # trimesh raises many kinds on a corrupt or unknown file
        raise InputError(
            p, f"wall mesh: not a triangle mesh trimesh can read ({type(exc).__name__}: {exc})"
        ) from exc
    faces = np.asarray(getattr(loaded, "faces", np.zeros((0, 3))))
    vertices = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))), dtype=np.float64)
    if faces.size == 0 or faces.ndim != 2 or faces.shape[1] != 3:
        raise InputError(p, "wall mesh: the file holds no triangles (expected a triangle mesh)")
    try:
        return WallMesh(vertices, faces.astype(np.int64))
    except ValueError as exc:
        raise InputError(p, f"wall mesh: {exc}") from exc


def write_wall_mesh(path: str | Path, mesh: WallMesh) -> None:
    """Write `mesh` as binary little-endian PLY, vertices in double precision (trimesh's
    own PLY export rounds them to float32: 50 nm at 1.5 m), atomically."""
    v = mesh.vertices_world
    f = mesh.faces
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment lightcal wall mesh, world frame, m\n"
        f"element vertex {len(v)}\nproperty double x\nproperty double y\nproperty double z\n"
        f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    rows = np.empty(len(f), dtype=[("n", "u1"), ("v", "<i4", (3,))])
    rows["n"] = 3
    rows["v"] = f
    data = header.encode("ascii") + v.astype("<f8").tobytes() + rows.tobytes()
    atomic_write_bytes(path, data)
