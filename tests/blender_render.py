"""Render an exported Blender snippet's lights on a diffuse wall with Cycles, in `bpy`.

Run by tests/test_export_blender_render.py with an interpreter that has `bpy` (Blender
5 as a Python module), never imported by the test suite itself (its NumPy is Blender's):

    python-with-bpy tests/blender_render.py JOB.json

JOB.json holds `snippet` (the exported .py), `T_camera_world` (4 x 4, a view's pose),
`albedo`, `samples`, `seed` and `out` (an .npy path). The script starts from an empty
scene, adds a camera at the world origin (so the world frame is Blender's camera frame),
runs the snippet (which parents the lights to that camera and gives it the project's
intrinsics), adds a Lambertian wall of the albedo on the plane z = 0 of the view's world
frame (its matrix F T_camera_world, F = diag(1, -1, -1, 1), its normal +z towards the
camera) and renders each light alone with Cycles on the CPU: direct light only, a 1 pixel
box filter (a pixel's value is the mean over its square, as lightcal's footprint), no
denoising, no adaptive sampling, a black world, the Standard view transform. It saves
the sum over the lights of the red channel (H, W) as float64 to `out` and prints one
JSON line with the render time.
"""

import json
import sys
import tempfile
import time
from pathlib import Path

import bpy
import numpy as np
from mathutils import Matrix

F = np.diag([1.0, -1.0, -1.0, 1.0])


def empty_scene(samples: int, seed: int):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    cycles = scene.cycles
    cycles.device = "CPU"
    cycles.samples = samples
    cycles.seed = seed
    cycles.use_denoising = False
    cycles.use_adaptive_sampling = False
    cycles.max_bounces = 0
    cycles.pixel_filter_type = "BOX"
    cycles.filter_width = 1.0
    scene.render.threads_mode = "FIXED"
    scene.render.threads = 2
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.world = None
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_depth = "32"
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.data.clip_start = 1e-3
    camera.data.clip_end = 1e4
    scene.collection.objects.link(camera)
    scene.camera = camera
    return scene


def add_wall(scene, T_camera_world: np.ndarray, albedo: float) -> None:
    half = 50.0
    mesh = bpy.data.meshes.new("wall")
    corners = [(-half, -half, 0.0), (half, -half, 0.0), (half, half, 0.0), (-half, half, 0.0)]
    mesh.from_pydata(corners, [], [(0, 1, 2, 3)])  # counter-clockwise seen from +z: normal +z
    material = bpy.data.materials.new("wall")
    if material.node_tree is None:  # Blender < 5 (Material.use_nodes goes in Blender 6)
        material.use_nodes = True
    tree = material.node_tree
    tree.nodes.clear()
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (albedo, albedo, albedo, 1.0)
    diffuse.inputs["Roughness"].default_value = 0.0
    tree.links.new(diffuse.outputs["BSDF"], output.inputs["Surface"])
    mesh.materials.append(material)
    wall = bpy.data.objects.new("wall", mesh)
    scene.collection.objects.link(wall)
    wall.matrix_world = Matrix((F @ T_camera_world).tolist())


def render(scene, folder: Path) -> np.ndarray:
    path = folder / "render.exr"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(str(path))
    width, height = image.size
    pixels = np.array(image.pixels[:], dtype=np.float64).reshape(height, width, 4)
    bpy.data.images.remove(image)
    return pixels[::-1, :, 0]  # Blender's rows run bottom to top


def main(job_path: str) -> None:
    job = json.loads(Path(job_path).read_text())
    scene = empty_scene(int(job["samples"]), int(job["seed"]))
    namespace = {"__name__": "__main__"}
    snippet = Path(job["snippet"])
    exec(compile(snippet.read_text(), str(snippet), "exec"), namespace)
    lights = [obj for obj in scene.objects if obj.type == "LIGHT"]
    add_wall(scene, np.array(job["T_camera_world"], dtype=np.float64), float(job["albedo"]))
    start = time.perf_counter()
    total = None
    with tempfile.TemporaryDirectory() as folder:
        for light in lights:  # one light at a time: no noise from choosing among lights
            for other in lights:
                other.hide_render = other is not light
            image = render(scene, Path(folder))
            total = image if total is None else total + image
    seconds = time.perf_counter() - start
    np.save(job["out"], np.asarray(total, dtype=np.float64))
    size = [scene.render.resolution_x, scene.render.resolution_y]
    print(json.dumps({"render_s": seconds, "lights": len(lights), "size": size}))


if __name__ == "__main__":
    main(sys.argv[-1])
