"""Render Loom's demo scene with an atlas.

    blender -b blend/demo_surface.blend --python blend/render_demo.py -- \
        --atlas ATLAS_DIR --out OUT.png [--samples N] [--res W H] [--mode auto|osl|nodes]
        [--size-factor F]

Enables the Loom add-on (the installed extension if there is one, else this checkout's addon/
through a temporary local extension repository), builds every material Loom manages (the demo's
"Loom Cloth" placeholder) from the atlas through loom.api.assign in the requested mode (Auto by
default: OSL where it runs, else node mode, saying which and why), renders a still and prints
the path of the PNG.
"""

import argparse
import os
import sys
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from loom_blend import loom_api, run  # noqa: E402



def parse():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(description="Render the Loom demo scene with an atlas")
    p.add_argument("--atlas", required=True, help="atlas directory (loom-bake bake ... -o DIR)")
    p.add_argument("--out", required=True, help="PNG to write")
    p.add_argument("--samples", type=int, default=None)
    p.add_argument("--res", type=int, nargs=2, metavar=("W", "H"), default=None)
    p.add_argument("--mode", default="auto", choices=["auto", "osl", "nodes"])
    p.add_argument("--size-factor", type=float, default=None,
                   help="weave magnification (default: the scene's loom_size_factor)")
    return p.parse_args(argv)


def main():
    args = parse()
    api = loom_api()
    from loom import material as loom_material

    scene = bpy.context.scene
    size_factor = args.size_factor or float(scene.get("loom_size_factor", 1.0))
    done = set()
    for obj in scene.objects:
        mat = obj.active_material
        if obj.type != "MESH" or mat is None or mat.name in done:
            continue
        if not loom_material.is_loom_material(mat):
            continue
        api.assign(obj, args.atlas, mode=args.mode, scale=None, size_factor=size_factor,
                   material=mat, scene=scene)
        done.add(mat.name)
    if not done:
        raise SystemExit("render_demo: no Loom material in the scene")
    if args.samples:
        scene.cycles.samples = args.samples
    if args.res:
        scene.render.resolution_x, scene.render.resolution_y = args.res
    scene.render.image_settings.file_format = "PNG"
    out = os.path.abspath(args.out)
    scene.render.filepath = out
    scene.render.use_file_extension = False
    t0 = time.monotonic()
    bpy.ops.render.render(write_still=True)
    dt = time.monotonic() - t0
    info = api.last_assign()
    print(f"loom-demo: rendered {scene.render.resolution_x}x{scene.render.resolution_y} at "
          f"{scene.cycles.samples} samples in {dt:.1f} s, "
          f"{'OSL' if info['mode'] == 'OSL' else 'node'} mode "
          f"({info['reason']})")
    print(out)


run(main)
