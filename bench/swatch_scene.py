"""The benchmark scenes of bench/blender_render_ratio.py and bench/node_cost_floor.py: a swatch
(a plane 4 m across, UV 1 per metre) seen by an orthographic camera, black world, one sun from
the camera's side (front) or from behind the cloth towards the camera, a little off its axis
(back); a draped cloth (a hanging curtain in folds) seen in perspective with a small light
behind it and a dim world; and the Principled BSDF with sheen that Loom's render times are
measured against."""

import math

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


def drape_scene(res: int, width: float = 0.2, folds: int = 4, depth: float = 0.012,
                grid: int = 64):
    """A new empty scene holding a curtain `width` metres wide and high hanging in the xz plane,
    `folds` sine folds `depth` metres deep along y, faces towards -y (a `grid` x `grid` mesh,
    smooth, UV = arc length along x and height, in metres); a perspective camera 0.35 m in front,
    a little above and to the side; a 5 cm square area light 0.2 m behind the cloth shining
    through it towards the camera; a dim grey world: (scene, cloth)."""
    scene = lt.empty_scene()
    scene.render.resolution_x = scene.render.resolution_y = res
    scene.render.resolution_percentage = 100
    scene.world.color = (0.02, 0.02, 0.02)
    k = 2.0 * math.pi * folds / width

    def y_of(x):
        return depth * math.sin(k * x)

    xs = [-width / 2 + width * i / grid for i in range(grid + 1)]
    arc = [0.0]  # arc length along the folds, for u
    for a, b in zip(xs, xs[1:]):
        arc.append(arc[-1] + math.hypot(b - a, y_of(b) - y_of(a)))
    verts, uvs = [], []
    for j in range(grid + 1):
        z = width * j / grid
        for i, x in enumerate(xs):
            verts.append((x, y_of(x), z))
            uvs.append((arc[i], z))
    n = grid + 1
    faces = [(j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i)
             for j in range(grid) for i in range(grid)]
    mesh = bpy.data.meshes.new("Drape")
    mesh.from_pydata(verts, [], faces)
    uv = mesh.uv_layers.new(name="UVMap")
    for loop in mesh.loops:
        uv.data[loop.index].uv = uvs[loop.vertex_index]
    for poly in mesh.polygons:
        poly.use_smooth = True
    mesh.update()
    cloth = bpy.data.objects.new("Drape", mesh)
    scene.collection.objects.link(cloth)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Perspective"))
    cam.data.lens = 50.0
    cam.location = (0.08, -0.35, 0.16)
    lt.look_along(cam, (-0.08, 0.35, -0.06))
    scene.collection.objects.link(cam)
    scene.camera = cam
    light = bpy.data.objects.new("Back light", bpy.data.lights.new("Back light", type="AREA"))
    light.data.size = 0.05
    light.data.energy = 10.0
    light.location = (-0.04, 0.2, 0.13)
    lt.look_along(light, (0.04, -0.2, -0.03))
    scene.collection.objects.link(light)
    return scene, cloth


def principled_sheen():
    mat = bpy.data.materials.new("Principled sheen")
    mat.use_nodes = True
    p = mat.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    p.inputs["Roughness"].default_value = 0.8
    p.inputs["Sheen Weight"].default_value = 1.0
    p.inputs["Sheen Roughness"].default_value = 0.5
    return mat
