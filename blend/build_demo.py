"""Build blend/demo_surface.blend from nothing: Loom's surface-model demo scene.

    blender -b --factory-startup --python blend/build_demo.py [-- --out blend/demo_surface.blend]

The scene: a cloth draped over a sphere (an analytic drape, no cloth simulation, so the file is
deterministic and quick to build), a flat swatch on the floor, a floor, a key light in front, a
back light behind the cloth (to show translucency and the gaps between yarns), a camera, and
Cycles on the CPU with modest samples. No atlas is baked here: both cloth objects carry a
placeholder material "Loom Cloth" (a plain diffuse, flagged for Loom through mat["loom"]), which
blend/render_demo.py replaces at render time through loom.api.assign.

UVs are in metres on both cloth objects, so one material serves both at the same weave scale;
the scene's custom property "loom_size_factor" says how much the demo magnifies the weave (at
true size a 0.7 mm repeat is far below a pixel of this camera).
"""

import argparse
import math
import os
import sys

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))

SPHERE_R = 0.45
CLOTH_SIZE = 2.2  # metres, flat
GRID = 48  # quads per side before subdivision (the .blend stays small)
SIZE_FACTOR = 30.0  # weave magnification used by render_demo.py


def args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser()
    p.add_argument("--out", default=os.path.join(HERE, "demo_surface.blend"))
    return p.parse_args(argv)


def placeholder_material():
    mat = bpy.data.materials.new("Loom Cloth")
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes.get("Principled BSDF")
    bsdf.inputs["Base Color"].default_value = (0.38, 0.02, 0.02, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.8
    mat.diffuse_color = (0.38, 0.02, 0.02, 1.0)
    # The storage of the add-on's Material.loom property group: marks the material as one Loom
    # may rebuild, readable before the add-on is registered.
    mat["loom"] = {"managed": True}
    return mat


def drape_point(x, y):
    """Where the flat cloth point (x, y) lands when draped over the sphere. Along each radius the
    cloth keeps its length: it hugs the sphere's cap up to polar angle PHI0, then hangs, its
    slope bending from the sphere's tangent towards vertical, and what reaches the floor lies
    flat on it. Folds (radial waves growing with the hanging length) make it look like cloth."""
    lift = 0.004  # clearance over the sphere and the floor
    r = math.hypot(x, y)
    theta = math.atan2(y, x)
    phi0 = math.radians(55.0)
    rs = SPHERE_R + lift
    s0 = rs * phi0
    if r <= s0:
        phi = r / rs
        rr, z = rs * math.sin(phi), SPHERE_R + rs * math.cos(phi)
        return rr * math.cos(theta), rr * math.sin(theta), z
    rr, z = rs * math.sin(phi0), SPHERE_R + rs * math.cos(phi0)
    s, step, done = r - s0, 0.005, 0.0
    while done < s:
        ds = min(step, s - done)
        if z <= lift:  # on the floor: the rest lies flat
            rr += s - done
            break
        beta = phi0 + (math.pi / 2 - phi0) * (1.0 - math.exp(-(done + 0.5 * ds) / 0.3))
        rr += ds * math.cos(beta)
        z = max(lift, z - ds * math.sin(beta))
        done += ds
    # Never inside the sphere (its radius at this height, plus the clearance).
    dz = z - SPHERE_R
    if abs(dz) < rs:
        rr = max(rr, math.sqrt(rs * rs - dz * dz))
    hang = min(1.0, (r - s0) / 0.3)
    wave = 0.5 + 0.5 * math.sin(9.0 * theta + 0.8 * math.sin(2.0 * theta))
    rr += 0.07 * hang * wave  # folds bulge outwards only
    return rr * math.cos(theta), rr * math.sin(theta), z


def cloth_object(mat):
    n = GRID
    verts, faces, uvs = [], [], []
    for j in range(n + 1):
        for i in range(n + 1):
            x = (i / n - 0.5) * CLOTH_SIZE
            y = (j / n - 0.5) * CLOTH_SIZE
            verts.append(drape_point(x, y))
            uvs.append((x, y))
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            faces.append((a, a + 1, a + n + 2, a + n + 1))
    mesh = bpy.data.meshes.new("Cloth")
    mesh.from_pydata(verts, [], faces)
    uv = mesh.uv_layers.new(name="UVMap")
    for poly in mesh.polygons:
        for li in poly.loop_indices:
            uv.data[li].uv = uvs[mesh.loops[li].vertex_index]
    for poly in mesh.polygons:
        poly.use_smooth = True
    mesh.materials.append(mat)
    obj = bpy.data.objects.new("Cloth", mesh)
    sub = obj.modifiers.new("Subdivision", "SUBSURF")
    sub.levels = 1
    sub.render_levels = 2
    return obj


def swatch_object(mat, size=0.5):
    h = size / 2
    mesh = bpy.data.meshes.new("Swatch")
    verts = [(-h, -h, 0.0), (h, -h, 0.0), (h, h, 0.0), (-h, h, 0.0)]
    mesh.from_pydata(verts, [], [(0, 1, 2, 3)])
    uv = mesh.uv_layers.new(name="UVMap")
    for li, loop in enumerate(mesh.loops):
        x, y, _ = verts[loop.vertex_index]
        uv.data[li].uv = (x, y)  # metres, like the cloth
    mesh.materials.append(mat)
    obj = bpy.data.objects.new("Swatch", mesh)
    obj.location = (0.95, -1.05, 0.002)
    obj.rotation_euler = (0.0, 0.0, math.radians(20.0))
    return obj


def simple_material(name, color, roughness=0.6):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes.get("Principled BSDF")
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    return mat


def build(out):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.name = "Loom Demo"
    coll = scene.collection

    cloth_mat = placeholder_material()
    cloth = cloth_object(cloth_mat)
    coll.objects.link(cloth)
    coll.objects.link(swatch_object(cloth_mat))

    sphere_mesh = bpy.data.meshes.new("Sphere")
    import bmesh

    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=32, v_segments=16, radius=SPHERE_R)
    bm.to_mesh(sphere_mesh)
    bm.free()
    sphere_mesh.materials.append(simple_material("Sphere", (0.6, 0.6, 0.6)))
    sphere = bpy.data.objects.new("Sphere", sphere_mesh)
    sphere.location = (0.0, 0.0, SPHERE_R)
    coll.objects.link(sphere)

    floor_mesh = bpy.data.meshes.new("Floor")
    f = 6.0
    floor_mesh.from_pydata([(-f, -f, 0), (f, -f, 0), (f, f, 0), (-f, f, 0)], [], [(0, 1, 2, 3)])
    floor_mesh.materials.append(simple_material("Floor", (0.42, 0.40, 0.37), 0.9))
    coll.objects.link(bpy.data.objects.new("Floor", floor_mesh))

    def light(name, kind, energy, loc, target, size=1.0, color=(1, 1, 1)):
        from mathutils import Vector

        data = bpy.data.lights.new(name, type=kind)
        data.energy = energy
        data.color = color
        if kind == "AREA":
            data.size = size
        obj = bpy.data.objects.new(name, data)
        obj.location = loc
        d = Vector(target) - Vector(loc)
        obj.rotation_mode = "QUATERNION"
        obj.rotation_quaternion = d.to_track_quat("-Z", "Y")
        coll.objects.link(obj)
        return obj

    light("Key", "AREA", 300.0, (2.2, -2.6, 2.6), (0.0, 0.0, 0.6), size=1.2)
    light("Back", "AREA", 260.0, (-1.2, 2.4, 1.4), (0.0, 0.0, 0.5), size=0.8,
          color=(1.0, 0.93, 0.85))
    light("Fill", "AREA", 40.0, (-2.8, -1.5, 1.8), (0.0, 0.0, 0.5), size=2.0)

    cam_data = bpy.data.cameras.new("Camera")
    cam_data.lens = 42.0
    cam = bpy.data.objects.new("Camera", cam_data)
    cam.location = (2.3, -3.4, 1.75)
    from mathutils import Vector

    cam.rotation_mode = "QUATERNION"
    cam.rotation_quaternion = (Vector((0.15, -0.2, 0.45)) - cam.location).to_track_quat("-Z", "Y")
    coll.objects.link(cam)
    scene.camera = cam

    world = bpy.data.worlds.new("World")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.05, 0.055, 0.065, 1)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0
    scene.world = world

    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 32
    scene.cycles.use_adaptive_sampling = True
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = 4
    scene.cycles.seed = 0
    scene.render.resolution_x = 480
    scene.render.resolution_y = 360
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "AgX"
    scene.render.image_settings.file_format = "PNG"
    scene["loom_size_factor"] = SIZE_FACTOR

    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    bpy.context.preferences.filepaths.save_version = 0  # no demo_surface.blend1 backups
    bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(out), compress=True,
                                relative_remap=True)
    print(f"loom-demo: wrote {out} ({os.path.getsize(out)} bytes)")


build(args().out)
