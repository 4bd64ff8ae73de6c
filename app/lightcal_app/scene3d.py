"""The 3D view: the wall, one frustum per image carrying its picture, the light(s).

World frame (docs/model.md): the wall is z = 0, cameras at z > 0; the browser's "up" is -y
(image up for cameras looking at the wall the usual way). Each camera is a frustum node
`/cameras/<i>` posed by `T_world_camera`; everything in the camera (rig) frame hangs
below it, so a node's local pose there is exactly `T_camera_light`:

- `/cameras/<ref>/light<j>`: the draggable gizmo of light j on the reference image's
  camera, with its bulb and cones (half-intensity and cut-off angles of the RID);
- `/cameras/<i>/light<j>`: the same light drawn on every other camera pose; behind a
  light's flat port its cones are the beam refracted into the water and the port is
  drawn below it (`/cameras/<i>/light<j>/port`, `lightcal_app.port_scene`);
- `/cameras/<i>/port`: the camera's flat port, when the project declares one;
- `/cameras/<i>/truth<j>`: the true light in demo mode (a ghost);
- `/rays`: rays from the light to the wall for the selected pixels (world frame);
- `/surroundings/<k>`: the surfaces the solve's surroundings declare (world frame).

`Scene3D` only draws what it is given; it never changes the app state itself: the
gizmo and pointer callbacks it is built with do that.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import viser

from lightcal.core.flat_port import FlatPort
from lightcal.core.light_port import port_paths
from lightcal.core.rid import RID
from lightcal.core.rotations import quaternion_wxyz_from_matrix
from lightcal.core.scene import Light, Rig, View
from lightcal.core.surroundings import Surroundings
from lightcal.core.wall_mesh import wall_footprints
from lightcal.io.project import Project
from lightcal_app.beam_scene import draw_beam, draw_beam_fill
from lightcal_app.beam_shapes import rid_angles
from lightcal_app.overlays import bounce_key
from lightcal_app.picking import FrustumPlane, frustum_plane, frustum_scale_for_depth
from lightcal_app.port_scene import camera_port_faces, draw_port_slab
from lightcal_app.state import LightGuess

LIGHT_RGB = (255, 170, 0)
TRUTH_RGB = (40, 200, 90)
RAY_RGB = (255, 200, 40)
CAMERA_RGB = (60, 60, 70)
REF_CAMERA_RGB = (230, 120, 0)
FOCUS_CAMERA_RGB = (210, 30, 110)
FRUSTUM_PX, FOCUS_FRUSTUM_PX = 1.5, 4.0
WALL_RGB = (228, 226, 220)
#: The surroundings' surfaces (`surroundings:`), drawn translucent.
SURROUNDINGS_RGB = (214, 190, 150)
MAX_RAYS_PER_IMAGE = 300

GizmoCallback = Callable[[int, np.ndarray, np.ndarray, Any], tuple[np.ndarray, np.ndarray] | None]
"""`on_gizmo(light, position as sent, wxyz as sent, client)`: the pose taken, or None."""


def _rid_key(rid: RID, port: FlatPort | None = None) -> bytes:
    d = rid.data()
    parts = [type(rid).__name__.encode(), np.int64(d.kind).tobytes()]
    parts += [
        np.asarray(a, dtype=np.float64).tobytes() for a in (d.params, d.theta_knots, d.values)
    ]
    if port is not None:  # the beam drawn refracted, and the port
        parts.append(repr(sorted(port.describe().items())).encode())
        parts.append(np.asarray(port.normal_camera).tobytes())
    return b"|".join(parts)


def light_rays(light: Light, view: View, points_world: np.ndarray) -> np.ndarray:
    """(K, 2, 3) line segments of the light's rays to wall points (M, 3), world frame:
    straight from the emitter, or behind its flat port (`Light.port`) bent where they
    leave the port (emitter -> exit point -> wall point, `lightcal.core.light_port`);
    a point the port does not reach gets no ray."""
    src = light.position_world(view)
    if light.port is None:
        seg = np.empty((len(points_world), 2, 3))
        seg[:, 0] = src
        seg[:, 1] = points_world
        return seg
    R = light.rotation_world(view)
    paths = port_paths((points_world - src) @ R, light.port)
    ok = paths.ok
    exits = src + paths.exits_light[ok] @ R.T
    first = np.stack([np.broadcast_to(src, exits.shape), exits], axis=1)
    second = np.stack([exits, points_world[ok]], axis=1)
    return np.concatenate([first, second])


def wall_extent(project: Project, *, margin: float = 0.15) -> tuple[np.ndarray, np.ndarray]:
    """(2,) min and max world x, y of the wall seen by the images (with a margin)."""
    cam = project.camera
    corners_px = np.array(
        [[0, 0], [cam.width - 1, 0], [cam.width - 1, cam.height - 1], [0, cam.height - 1]]
    )
    pts = []
    for view in project.views:
        fp = wall_footprints(cam, view, corners_px, mesh=None, port=project.camera_port)
        c = fp.corners_world.reshape(-1, 3)
        pts.append(c[np.all(np.isfinite(c), axis=1), :2])
        pts.append(view.center_world[None, :2])
    xy = np.concatenate(pts)
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    pad = margin * max(float((hi - lo).max()), 0.1)
    return lo - pad, hi + pad


def _pose(light: Light | LightGuess) -> tuple[np.ndarray, np.ndarray]:
    return light.t_camera_light, light.R_camera_light


class Scene3D:
    """Scene nodes of one project and how to update them.

    Args:
        server: the viser server (server-level scene: every browser sees the same).
        on_gizmo: called with (light index, t_camera_light (3,), R_camera_light (3, 3), client)
            when a browser drags a gizmo.
    """

    def __init__(self, server: viser.ViserServer, *, on_gizmo: GizmoCallback) -> None:
        self.server = server
        self.scene = server.scene
        self.on_gizmo = on_gizmo
        self.frusta: list[Any] = []
        self.pictures: dict[int, np.ndarray] = {}  # what each frustum shows, or would
        self.outlines_only = False  # the frusta without pictures (`set_outlines_only`)
        self.channel_shown = 0  # the colour channel whose pictures show (`set_channel`)
        self.channel_of: list[int] = []  # each image's (`Project.channel_index`)
        self.planes: list[FrustumPlane] = []
        self.gizmos: list[Any] = []
        self.light_frames: dict[tuple[int, int], Any] = {}
        self._cone_keys: list[bytes | None] = []
        self._light_port_nodes: dict[int, list[Any]] = {}
        self._gizmo_pose: list[tuple[np.ndarray, np.ndarray] | None] = []
        self.rays: Any = None
        self.ref_image = 0
        self.cone_length_m = 0.3
        self.light_size_m = 0.02
        self.frustum_scale = 0.1
        self._surroundings_key: str | None = None
        self._surroundings_nodes: list[Any] = []

    # -- building ---------------------------------------------------------------------------

    def build(
        self,
        project: Project,
        *,
        pictures: list[np.ndarray],
        guess: list[LightGuess],
        ref_image: int,
        truth: list[LightGuess] | None,
    ) -> None:
        """(Re)create every node for a project."""
        scene = self.scene
        scene.reset()
        scene.set_up_direction("-y")
        self.project = project
        cam = project.camera
        dist = float(np.median([v.center_world[2] for v in project.views]))
        depth = 0.25 * dist
        self.cone_length_m = 0.8 * depth  # short of the pictures: they stay visible
        self.light_size_m = 0.012 * dist
        lo, hi = wall_extent(project)
        verts = np.array(
            [[lo[0], lo[1], 0], [hi[0], lo[1], 0], [hi[0], hi[1], 0], [lo[0], hi[1], 0]]
        )
        faces = np.array([[0, 1, 2], [0, 2, 3]])
        mesh = project.wall_mesh
        if mesh is not None:  # the wall's own shape (`wall.mesh`)
            verts, faces = mesh.vertices_world, mesh.faces
        scene.add_mesh_simple(
            "/wall",
            verts.astype(np.float32),
            faces.astype(np.uint32),
            color=WALL_RGB,
            side="double",
        )
        center = 0.5 * (lo + hi)
        size = float((hi - lo).max())
        scene.add_grid(
            "/wall_grid",
            width=size,
            height=size,
            plane="xy",
            cell_size=0.1,
            section_size=0.5,
            position=(float(center[0]), float(center[1]), 0.001),
        )
        label = "wall (z = 0)" if mesh is None else "wall (mesh)"
        scene.add_label("/wall_label", label, position=(float(lo[0]), float(lo[1]), 0.0))
        self._surroundings_key = None  # drawn by `set_surroundings` (the reset removed them)
        self._surroundings_nodes = []
        fov = cam.fov_y_rad
        scale = frustum_scale_for_depth(depth, fov_y_rad=fov, aspect=cam.aspect)
        self.frustum_scale = scale
        self.frusta = []
        self.pictures = dict(enumerate(pictures))
        self.outlines_only = False
        self.channel_shown = 0
        self.channel_of = [project.channel_index(i) for i in range(len(project.views))]
        self.planes = []
        for i, view in enumerate(project.views):
            R_wc = view.R_camera_world.T
            h = scene.add_camera_frustum(
                f"/cameras/{i}",
                fov=fov,
                aspect=cam.aspect,
                scale=scale,
                thickness=FRUSTUM_PX,
                thickness_units="screen",
                color=REF_CAMERA_RGB if i == ref_image else CAMERA_RGB,
                image=pictures[i] if self._pictured(i) else None,
                format="jpeg",
                jpeg_quality=80,
                wxyz=quaternion_wxyz_from_matrix(R_wc),
                position=view.center_world,
            )
            self.frusta.append(h)
            self.planes.append(
                frustum_plane(
                    R_wc,
                    view.center_world,
                    fov_y_rad=fov,
                    aspect=cam.aspect,
                    scale=scale,
                    width_px=cam.width,
                    height_px=cam.height,
                )
            )
        port = project.camera_port
        if port is not None:  # the camera's flat port, in front of every frustum
            inner, outer = camera_port_faces(port, fov_y_rad=fov, aspect=cam.aspect)
            for i in range(len(project.views)):
                draw_port_slab(scene, f"/cameras/{i}", inner, outer)
        self.ref_image = ref_image
        self._build_lights(guess)
        if truth:
            self._build_truth(truth)
        self.rays = None
        mid = np.mean([v.center_world for v in project.views], axis=0)
        self.server.initial_camera.position = mid + np.array([0.0, 0.6 * dist, 1.4 * dist])
        self.server.initial_camera.look_at = (float(center[0]), float(center[1]), 0.0)
        self.server.initial_camera.up = (0.0, -1.0, 0.0)

    def set_surroundings(self, surroundings: Surroundings | None) -> None:
        """The surfaces whose bounce light the model adds (`surroundings:`, as the page
        edits them), each a translucent rectangle labelled with its name and albedo;
        redrawn only when they changed."""
        key = None if surroundings is None else bounce_key(surroundings)
        if key == self._surroundings_key:
            return
        for node in self._surroundings_nodes:
            node.remove()
        self._surroundings_nodes = []
        self._surroundings_key = key
        if surroundings is None:
            return
        faces = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32)
        for k, surface in enumerate(surroundings.surfaces):
            corners = surface.corners_world
            mesh = self.scene.add_mesh_simple(
                f"/surroundings/{k}",
                corners.astype(np.float32),
                faces,
                color=SURROUNDINGS_RGB,
                opacity=0.5,
                side="double",
            )
            label = self.scene.add_label(
                f"/surroundings/{k}_label",
                f"{surface.name} (albedo {surface.albedo:.2g})",
                position=corners.mean(axis=0),
            )
            self._surroundings_nodes += [mesh, label]

    def _build_lights(self, guess: list[LightGuess]) -> None:
        scene = self.scene
        n_img = len(self.project.views)
        self.gizmos = []
        self.light_frames = {}
        self._cone_keys = [None] * len(guess)
        self._light_port_nodes = {}
        self._gizmo_pose = [None] * len(guess)
        for j, g in enumerate(guess):
            t, R = _pose(g)
            gizmo = scene.add_transform_controls(
                f"/cameras/{self.ref_image}/light{j}",
                scale=20.0 * self.light_size_m,  # a quarter of the camera-wall distance
                line_width=3.0,
                depth_test=False,
                wxyz=quaternion_wxyz_from_matrix(R),
                position=t,
            )
            gizmo.on_update(self._gizmo_callback(j))
            self.gizmos.append(gizmo)
            self._gizmo_pose[j] = (t.copy(), R.copy())
            for i in range(n_img):
                if i == self.ref_image:
                    continue
                self.light_frames[(i, j)] = scene.add_frame(
                    f"/cameras/{i}/light{j}",
                    show_axes=False,
                    wxyz=quaternion_wxyz_from_matrix(R),
                    position=t,
                )
            for i in range(n_img):
                scene.add_icosphere(
                    f"/cameras/{i}/light{j}/bulb",
                    radius=self.light_size_m,
                    color=LIGHT_RGB,
                )

    def _build_truth(self, truth: list[LightGuess]) -> None:
        for j, g in enumerate(truth):
            for i in range(len(self.project.views)):
                base = f"/cameras/{i}/truth{j}"
                self.scene.add_frame(
                    base,
                    show_axes=False,
                    wxyz=quaternion_wxyz_from_matrix(g.R_camera_light),
                    position=g.t_camera_light,
                )
                self.scene.add_icosphere(
                    f"{base}/bulb", radius=self.light_size_m, color=TRUTH_RGB, opacity=0.55
                )
                axis = np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, self.cone_length_m]]], np.float32)
                self.scene.add_line_segments(
                    f"{base}/axis", axis, TRUTH_RGB, thickness=0.25 * self.light_size_m
                )

    def _gizmo_callback(self, j: int) -> Callable[[Any], None]:
        def cb(event: Any) -> None:
            # Checked by `on_gizmo`; a refused pose is forgotten, so the next redraw
            # puts the gizmo back where the state has it.
            taken = self.on_gizmo(
                j, np.asarray(event.target.position), np.asarray(event.target.wxyz), event.client
            )
            self._gizmo_pose[j] = None if taken is None else (taken[0].copy(), taken[1].copy())

        return cb

    # -- updates ----------------------------------------------------------------------------

    def set_pictures(self, pictures: dict[int, np.ndarray]) -> None:
        """Replace the pictures of some frusta."""
        self.pictures.update(pictures)
        for i in filter(self._pictured, pictures):
            self.frusta[i].image = pictures[i]

    def _pictured(self, i: int) -> bool:
        """Frustum i shows its picture: not outlines only, and of the channel shown."""
        return not self.outlines_only and self.channel_of[i] == self.channel_shown

    def set_channel(self, channel: int) -> None:
        """Pictures on this colour channel's frusta only (`sensor.channels`: a photo's
        channels share a pose, their frusta coincide); clicks land there (`pickable_planes`)."""
        if channel != self.channel_shown:
            self.channel_shown = channel
            for i, h in enumerate(self.frusta):
                h.image = self.pictures.get(i) if self._pictured(i) else None

    def pickable_planes(self) -> list[FrustumPlane | None]:
        """Per image its picture's plane, None for a channel not shown."""
        shown = zip(self.planes, self.channel_of, strict=True)
        return [plane if ch == self.channel_shown else None for plane, ch in shown]

    def set_outlines_only(self, outlines: bool) -> None:
        """Draw the frusta as outlines (True) or with their pictures. viser draws no
        frustum in front of another: a suggested view behind a photo's picture would be
        hidden, so while suggestions are shown the photos are outlines."""
        if outlines == self.outlines_only:
            return
        self.outlines_only = outlines
        for i, h in enumerate(self.frusta):
            h.image = self.pictures.get(i) if self._pictured(i) else None

    def set_focus(self, focus: int | None, ref_image: int) -> None:
        """Frame the highlighted image's frustum (thick, crimson); the others as built."""
        for i, h in enumerate(self.frusta):
            colour = REF_CAMERA_RGB if i == ref_image else CAMERA_RGB
            thickness = FRUSTUM_PX
            if i == focus:
                colour, thickness = FOCUS_CAMERA_RGB, FOCUS_FRUSTUM_PX
            if tuple(h.color) != colour or h.thickness != thickness:
                h.color = colour
                h.thickness = thickness

    def set_lights(self, lights: list[Light | LightGuess]) -> None:
        """Pose every light node (gizmo and copies) and refresh its cones."""
        for j, light in enumerate(lights):
            if j >= len(self.gizmos):
                break
            t, R = _pose(light)
            q = quaternion_wxyz_from_matrix(R)
            seen = self._gizmo_pose[j]
            if seen is None or not (
                np.allclose(seen[0], t, atol=1e-12) and np.allclose(seen[1], R, atol=1e-12)
            ):
                self.gizmos[j].position = t
                self.gizmos[j].wxyz = q
                self._gizmo_pose[j] = (t.copy(), R.copy())
            for i in range(len(self.project.views)):
                frame = self.light_frames.get((i, j))
                if frame is not None:
                    frame.position = t
                    frame.wxyz = q
            if isinstance(light, Light):
                self._set_cones(j, light.rid, light.port)
        if lights and isinstance(lights[0], LightGuess):
            for j, u in enumerate(self.project.lights):
                self._set_cones(j, u.initial.rid, u.initial.port)

    def _set_cones(self, j: int, rid: RID, port: FlatPort | None = None) -> None:
        """Cone outlines (half-intensity: bold, 1 % cut-off: thin) on every camera, and a
        translucent half-intensity cone on the gizmo; behind a port the cones refracted
        into the water (narrower), the port drawn and the water's angles labelled."""
        key = _rid_key(rid, port)
        if j < len(self._cone_keys) and self._cone_keys[j] == key:
            return
        self._cone_keys[j] = key
        angles = rid_angles(rid)
        for node in self._light_port_nodes.pop(j, []):
            node.remove()
        nodes = []
        for i in range(len(self.project.views)):
            base = f"/cameras/{i}/light{j}"
            nodes += draw_beam(self.scene, base, angles, self.cone_length_m, port, rgb=LIGHT_RGB)
        base = f"/cameras/{self.ref_image}/light{j}"
        nodes += draw_beam_fill(self.scene, base, angles, self.cone_length_m, port, rgb=LIGHT_RGB)
        self._light_port_nodes[j] = nodes

    def set_rays(self, rig: Rig | None, wall_points: tuple[np.ndarray, ...], which: str) -> None:
        """Rays from each light to the selected pixels' footprint centres.

        Args:
            rig: the lights (None: no rays).
            wall_points: per image (N, 3) footprint centres, world frame.
            which: "all", "none" or an image name.
        """
        names = self.project.names
        if rig is None:
            which = "none"
        images = (
            range(len(names)) if which == "all" else [i for i, n in enumerate(names) if n == which]
        )
        segs = []
        for i in images:
            pts = wall_points[i]
            if len(pts) == 0:
                continue
            if len(pts) > MAX_RAYS_PER_IMAGE:
                pts = pts[:: math.ceil(len(pts) / MAX_RAYS_PER_IMAGE)]
            view = self.project.views[i]
            assert rig is not None
            for light in rig.lights:
                segs.append(light_rays(light, view, pts))
        if not segs:
            if self.rays is not None:
                self.rays.visible = False
            return
        points = np.concatenate(segs).astype(np.float32)
        self.rays = self.scene.add_line_segments(
            "/rays", points, RAY_RGB, thickness=0.12 * self.light_size_m
        )
