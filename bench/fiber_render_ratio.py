"""Render time of the fiber tier against the ray-wave tier on the same close-up, in one run.

An orthographic close-up of a flat cloth (fibers about --fiber-px pixels wide), black world, one
sun from the camera's side. Rendered alternately --repeats times: a Principled BSDF with sheen,
the ray-wave material alone, and the ray-wave material with the fibers Loom realizes for this
camera (addon/fibers.py); medians and ratios, node mode (the Blender here has no OSL).

    blender -b --factory-startup --python-exit-code 1 --python bench/fiber_render_ratio.py -- \
        --atlas RAYWAVE_ATLAS --loom-bake LOOM_BAKE [--samples 16] [--res 128] [--repeats 3] \
        [--fiber-px 1.0] [--json OUT]
"""

import json
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests",
                                "blender"))
import loom_testlib as lt  # noqa: E402

import bpy  # noqa: E402


def extra_args(p):
    p.add_argument("--samples", type=int, default=16)
    p.add_argument("--res", type=int, default=128)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--fiber-px", type=float, default=1.0)
    p.add_argument("--json", default=None)


def main():
    args = lt.parse_args(extra_args)
    assert args.atlas and args.loom_bake, "--atlas and --loom-bake are required"
    lt.enable_addon()
    import loom.api

    scene = lt.empty_scene()
    scene.cycles.samples = args.samples
    scene.render.resolution_x = scene.render.resolution_y = args.res
    cloth = lt.add_plane("Cloth", 0.01, uv_per_meter=50.0)
    raywave = loom.api.assign(cloth, args.atlas, mode="nodes")
    with open(os.path.join(args.atlas, "manifest.json")) as f:
        fiber_um = json.load(f)["spec"]["warp"]["fiber_diameter_um"]
    sheen = bpy.data.materials.new("Principled sheen")
    sheen.use_nodes = True
    p = sheen.node_tree.nodes["Principled BSDF"]
    p.inputs["Sheen Weight"].default_value = 1.0
    p.inputs["Roughness"].default_value = 0.8
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 3.0
    scene.collection.objects.link(sun)
    lt.look_along(sun, (-0.3, 0.2, -0.93))
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = args.res * fiber_um * 1e-6 / args.fiber_px
    cam.data.clip_start = 0.001
    cam.location = (0.0, 0.0, 0.02)
    scene.collection.objects.link(cam)
    lt.look_along(cam, (0.0, 0.0, -1.0))
    scene.camera = cam
    t0 = time.monotonic()
    res = loom.api.update_fibers(cloth, scene, loom_bake=args.loom_bake,
                                 cache_dir=os.path.join(args.out, "cache"),
                                 max_vertices=20_000_000)
    t_fibers = time.monotonic() - t0
    print(f"loom-bench: {res['reason']} in {t_fibers:.2f} s", flush=True)
    fo = bpy.data.objects[res["object"]]
    out = os.path.join(args.out, "fiber_ratio.exr")

    def render(mat, fibers):
        cloth.data.materials.clear()
        cloth.data.materials.append(mat)
        fo.hide_render = not fibers
        t = time.monotonic()
        lt.render_to_exr(scene, out)
        return time.monotonic() - t

    cases = {"principled_sheen": (sheen, False), "raywave": (raywave, False),
             "raywave_fibers": (raywave, True)}
    times = {k: [] for k in cases}
    for _ in range(args.repeats):
        for k, (mat, fibers) in cases.items():
            times[k].append(render(mat, fibers))
    med = {k: statistics.median(v) for k, v in times.items()}
    for k in cases:
        print(f"loom-bench: {k:18s} median {med[k]:7.2f} s  ratio to Principled "
              f"{med[k] / med['principled_sheen']:6.2f}", flush=True)
    ratio = med["raywave_fibers"] / med["raywave"]
    print(f"loom-bench: fiber tier / ray-wave tier: {ratio:.2f}", flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"samples": args.samples, "res": args.res, "fiber_px": args.fiber_px,
                       "fibers": {k: res[k] for k in ("curves", "vertices", "region_um")},
                       "fibers_seconds": t_fibers, "times": times, "medians": med,
                       "fiber_over_raywave": ratio}, f, indent=1)


lt.run(main)
