"""The ray-wave supplement's sample scenes: a swatch of each sample fabric, front-lit and
back-lit, rendered in each of the variants its figures compare.

    blender -b --factory-startup --python blend/sample_scenes.py -- --atlases ATLASES.json \
        --out DIR [--samples N] [--res W H] [--save-blend] [--mode nodes|auto]

ATLASES.json maps each fabric to its variants' atlases (scripts/render_samples.sh bakes them):
    {"white_silk_organza": {"diffraction": DIR, "delta": DIR, "perlin": DIR,
                            "perlin_nonoise": DIR, "nonoise": DIR}, ...}
The variants (the supplement's figures 12-37):
  * back-lit: "delta" (delta transmission through the gaps, the non-wave variant) and
    "diffraction" (Gaussian-beam aperture diffraction);
  * front-lit: Perlin off / on x wave noise off / on: "nonoise", "perlin_nonoise",
    "diffraction" (the full model: Perlin off, noise on) and "perlin".
Each image is DIR/<fabric>_<light>_<variant>.png; with --save-blend the two scenes of each
fabric are saved as DIR/<fabric>_<light>.blend (materials built from the full model's atlas).

The scenes (choices; the supplement describes its photographs, not its set-up): a 3 cm square
swatch at its real weave size seen from 2.5 cm by a 50 mm camera (yarns 2 to 8 pixels at
384 px: the ray-wave tier's range).
  * front-lit: a sun 40 degrees above the cloth from the camera's side, a dim grey world;
  * back-lit: a small bright sphere (0.5 mm, 5 cm behind the cloth) on the camera's axis, seen
    through the cloth, black world: what comes through the gaps and the yarns, and the
    diffraction cross around the light.
"""

import argparse
import json
import math
import os
import sys
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from loom_blend import loom_api, run  # noqa: E402

FRONT_VARIANTS = ("nonoise", "perlin_nonoise", "diffraction", "perlin")
BACK_VARIANTS = ("delta", "diffraction")


def parse():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(description="Render the ray-wave sample scenes")
    p.add_argument("--atlases", required=True, help="JSON: fabric -> variant -> atlas dir")
    p.add_argument("--out", required=True)
    p.add_argument("--samples", type=int, default=32)
    p.add_argument("--res", type=int, nargs=2, metavar=("W", "H"), default=(256, 256))
    p.add_argument("--save-blend", action="store_true")
    p.add_argument("--mode", default="nodes", choices=["nodes", "auto"],
                   help="material mode (auto: OSL where this Blender has it)")
    p.add_argument("--check", action="store_true",
                   help="fail unless every front-lit image has light in it")
    return p.parse_args(argv)


def look_along(obj, direction):
    from mathutils import Vector

    obj.rotation_euler = Vector(direction).to_track_quat("-Z", "Y").to_euler()


def swatch(half=0.015):
    """A square in z = 0, normal +z, UV = world xy in metres."""
    mesh = bpy.data.meshes.new("Swatch")
    verts = [(-half, -half, 0.0), (half, -half, 0.0), (half, half, 0.0), (-half, half, 0.0)]
    mesh.from_pydata(verts, [], [(0, 1, 2, 3)])
    uv = mesh.uv_layers.new(name="UVMap")
    for loop in mesh.loops:
        x, y, _ = verts[loop.vertex_index]
        uv.data[loop.index].uv = (x, y)
    mesh.update()
    obj = bpy.data.objects.new("Swatch", mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def build_scene(light: str, args):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = args.samples
    scene.cycles.use_denoising = False  # (what the model renders; Debian's Blender has no OIDN)
    scene.render.resolution_x, scene.render.resolution_y = args.res
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.view_settings.view_transform = "Standard"
    world = bpy.data.worlds.new("World")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Strength"].default_value = 1.0
    grey = 0.02 if light == "front" else 0.0
    bg.inputs["Color"].default_value = (grey, grey, grey, 1.0)
    scene.world = world
    obj = swatch()
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))  # 50 mm lens
    cam.data.clip_start = 0.001
    scene.collection.objects.link(cam)
    scene.camera = cam
    if light == "front":
        cam.location = (0.0, -0.004, 0.025)
        look_along(cam, (0.0, 0.004, -0.025))
        sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", type="SUN"))
        sun.data.energy = 4.0
        sun.data.angle = math.radians(1.0)
        el, az = math.radians(40.0), math.radians(-110.0)
        look_along(sun, (-math.cos(el) * math.cos(az), -math.cos(el) * math.sin(az),
                         -math.sin(el)))
        scene.collection.objects.link(sun)
    else:
        cam.location = (0.0, 0.0, 0.025)
        look_along(cam, (0.0, 0.0, -1.0))
        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.0005, location=(0.0, 0.0, -0.05))
        lamp = bpy.context.active_object
        lamp.name = "Light behind"
        mat = bpy.data.materials.new("Emitter")
        mat.use_nodes = True
        nodes = mat.node_tree.nodes
        nodes.clear()
        em = nodes.new("ShaderNodeEmission")
        em.inputs["Strength"].default_value = 1.0e3
        out = nodes.new("ShaderNodeOutputMaterial")
        mat.node_tree.links.new(em.outputs["Emission"], out.inputs["Surface"])
        lamp.data.materials.append(mat)
    return scene, obj


def main():
    args = parse()
    api = loom_api()
    with open(args.atlases, encoding="utf-8") as f:
        atlases = json.load(f)
    os.makedirs(args.out, exist_ok=True)
    report = []
    for fabric, variants in atlases.items():
        for light, names in (("front", FRONT_VARIANTS), ("back", BACK_VARIANTS)):
            scene, obj = build_scene(light, args)
            for variant in names:
                if variant not in variants:
                    continue
                api.assign(obj, variants[variant], mode=args.mode, scale=None, scene=scene)
                path = os.path.join(os.path.abspath(args.out), f"{fabric}_{light}_{variant}.png")
                scene.render.filepath = path
                scene.render.use_file_extension = False
                t0 = time.monotonic()
                bpy.ops.render.render(write_still=True)
                dt = time.monotonic() - t0
                info = api.last_assign()
                img = bpy.data.images.load(path)
                px = img.pixels[:]
                mean = math.fsum(v for i, v in enumerate(px) if i % 4 != 3) / (len(px) * 0.75)
                bpy.data.images.remove(img)
                report.append({"fabric": fabric, "light": light, "variant": variant,
                               "png": path, "seconds": dt, "mode": info["mode"], "mean": mean})
                if args.check and light == "front" and not mean > 1e-3:
                    raise SystemExit(f"sample_scenes: {path} is black (mean {mean})")
                print(f"loom-samples: {fabric} {light}-lit {variant}: {dt:.1f} s, "
                      f"{info['mode'].lower()} mode, mean {mean:.4f} -> {path}", flush=True)
            if args.save_blend and "diffraction" in variants:
                api.assign(obj, variants["diffraction"], mode=args.mode, scale=None, scene=scene)
                blend = os.path.join(os.path.abspath(args.out), f"{fabric}_{light}.blend")
                bpy.ops.wm.save_as_mainfile(filepath=blend, check_existing=False)
                print(f"loom-samples: saved {blend}", flush=True)
    with open(os.path.join(args.out, "samples.json"), "w", encoding="utf-8") as f:
        json.dump(report, f, indent=1)


run(main)
