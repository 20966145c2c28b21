"""The benchmark scene of bench/blender_render_ratio.py and bench/node_cost_floor.py: a swatch
(a plane 4 m across, UV 1 per metre) seen by an orthographic camera, black world, one sun from
the camera's side (front) or from behind the cloth towards the camera, a little off its axis
(back); and the Principled BSDF with sheen that Loom's render times are measured against."""

import bpy

import loom_testlib as lt


def swatch_scene(res: int, ortho_scale: float = 0.05, light: str = "front"):
    """A new empty scene holding the swatch, the camera and the sun: (scene, plane)."""
    scene = lt.empty_scene()
    scene.cycles.use_denoising = False
    scene.render.resolution_x = scene.render.resolution_y = res
    scene.render.resolution_percentage = 100
    plane = lt.add_plane("Swatch", half=2.0, uv_per_meter=1.0)
    cam_data = bpy.data.cameras.new("Ortho")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = ortho_scale
    cam = bpy.data.objects.new("Camera", cam_data)
    cam.location = (0.0, -0.3, 0.95)
    lt.look_along(cam, (0.0, 0.3, -0.95))
    scene.collection.objects.link(cam)
    scene.camera = cam
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", type="SUN"))
    sun.data.energy = 3.0
    lt.look_along(sun, (-0.3, 0.2, -0.93) if light == "front" else (0.08, -0.25, 0.965))
    scene.collection.objects.link(sun)
    return scene, plane


def principled_sheen():
    mat = bpy.data.materials.new("Principled sheen")
    mat.use_nodes = True
    p = mat.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    p.inputs["Roughness"].default_value = 0.8
    p.inputs["Sheen Weight"].default_value = 1.0
    p.inputs["Sheen Roughness"].default_value = 0.5
    return mat
