"""Render time of Loom materials as a ratio to a Principled BSDF with sheen, same scene, samples
and resolution, measured in one run (absolute seconds are noise on a shared machine).

The ratio is of the time per sample: each material renders at --samples and again at
--timing-samples (default 4x), and its time per sample is the difference of the two times over
the difference of the sample counts. What a render costs once (scene and shader sync, image
loads, the BVH) cancels: at the small sizes a benchmark can afford it was most of the
Principled render (0.05-0.18 s at 64 px and 16 samples) and made the whole-render ratio swing 2x
between runs. The whole-render times and ratio (at --samples) are reported beside it, and each
material's fixed cost (whole time minus --samples times the time per sample).

--scene swatch (the default): a swatch seen by an orthographic camera, black world, one sun:
from the camera's side (--light front, the default) or from behind the cloth towards the
camera, a little off its axis (--light back: what the transmission, double-layer and
diffraction closures cost). --scene drape: a curtain in folds seen in perspective, a small
light behind it, a dim world (bench/swatch_scene.py; --light and --ortho-scale are the
swatch's: refused here). Each
material is rendered --repeats times, alternating, and the medians are reported with their
ratios to the Principled medians. Node mode (the Blender here has no OSL).

    blender -b --factory-startup --python-exit-code 1 --python bench/blender_render_ratio.py -- \
        --material NAME=ATLAS [--material NAME=ATLAS ...] [--samples 16] [--res 128] \
        [--timing-samples 64] [--repeats 3] [--scene swatch|drape] [--light front|back] \
        [--reference NAME [--noise-floor]] [--images DIR] [--json OUT]

--reference NAME adds each image's relative RMSE against NAME's image (RGB, last repeat):
sqrt(sum (a - b)^2 / sum b^2). Every material renders with the same seed (common random
numbers: what differs is mostly the material); --noise-floor renders NAME once more with
another seed and reports that pair's RMSE, what Monte Carlo noise alone does at these
samples. --images keeps every material's last render as DIR/NAME.exr.
"""

import json
import math
import os
import shutil
import statistics
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests",
                                "blender"))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import loom_testlib as lt  # noqa: E402
from swatch_scene import drape_scene, principled_sheen, swatch_scene  # noqa: E402

import bpy  # noqa: E402


ORTHO_SCALE = 0.05  # the swatch camera's default


def extra_args(p):
    p.add_argument("--material", action="append", default=[], dest="atlases",
                   help="NAME=DIR, repeatable")
    p.add_argument("--samples", type=int, default=16)
    p.add_argument("--timing-samples", type=int, default=None,
                   help="second sample count, for the time per sample (default 4 x --samples)")
    p.add_argument("--res", type=int, default=128)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--scene", choices=("swatch", "drape"), default="swatch")
    p.add_argument("--light", choices=("front", "back"), default=None,
                   help="the swatch's sun: front (default) or back")
    p.add_argument("--reference", default=None, help="material the images are compared with")
    p.add_argument("--noise-floor", action="store_true")
    p.add_argument("--images", default=None, help="directory for each material's render")
    p.add_argument("--json", default=None)
    p.add_argument("--average", default="auto",
                   help="the Loom materials' Average: auto (driven by the camera, "
                        "scene_needs.average_drive) or a number in [0, 1] (1: the "
                        "repeat-averaged closures)")
    p.add_argument("--ortho-scale", type=float, default=ORTHO_SCALE,
                   help="metres the camera sees across (0.05: weave resolved; 1 and more: "
                        "many repeats a pixel)")


def node_counts(tree):
    """(nodes, image reads) of a material's node tree with every group expanded, as Cycles'
    SVM compiler inlines them (frames, reroutes and group inputs/outputs not counted)."""
    nodes = reads = 0
    for n in tree.nodes:
        if n.bl_idname == "ShaderNodeGroup" and n.node_tree is not None:
            a, b = node_counts(n.node_tree)
            nodes, reads = nodes + a, reads + b
        elif n.bl_idname not in ("NodeFrame", "NodeReroute", "NodeGroupInput", "NodeGroupOutput"):
            nodes += 1
            reads += n.bl_idname == "ShaderNodeTexImage"
    return nodes, reads


def relative_rmse(a, b):
    """sqrt(sum (a - b)^2 / sum b^2) over the RGB of two images of one size."""
    num = den = 0.0
    for i in range(0, len(b.px), 4):
        for c in range(3):
            d = a.px[i + c] - b.px[i + c]
            num += d * d
            den += b.px[i + c] * b.px[i + c]
    return math.sqrt(num / den) if den > 0 else 0.0


def main():
    args = lt.parse_args(extra_args)
    lt.enable_addon()
    import loom.api

    if args.samples < 1:
        raise SystemExit(f"--samples: {args.samples} (allowed: >= 1)")
    if args.timing_samples is None:
        args.timing_samples = 4 * args.samples
    if args.timing_samples <= args.samples:
        raise SystemExit(f"--timing-samples: {args.timing_samples} (allowed: more than --samples, "
                         f"{args.samples})")
    if args.scene == "drape":
        if args.light is not None or args.ortho_scale != ORTHO_SCALE:
            raise SystemExit("--light, --ortho-scale: the swatch scene's (--scene swatch); the "
                             "drape has its own camera and light")
        scene, plane = drape_scene(args.res)
    else:
        scene, plane = swatch_scene(args.res, args.ortho_scale, args.light or "front")
    scene.cycles.samples = args.samples

    materials = {"principled_sheen": principled_sheen()}
    for item in args.atlases:
        name, atlas = item.split("=", 1)
        t0 = time.monotonic()
        materials[name] = loom.api.assign(
            plane, atlas, mode="nodes", scale=None, material=bpy.data.materials.new(name),
            average=None if args.average == "auto" else float(args.average))
        print(f"loom-bench: {name}: material built in {time.monotonic() - t0:.2f} s", flush=True)
    if args.noise_floor and args.reference is None:
        raise SystemExit("--noise-floor: needs --reference NAME (the material rendered again)")
    if args.reference is not None and args.reference not in materials:
        raise SystemExit(f"--reference: {args.reference!r} is not one of the --material names "
                         f"({', '.join(materials)})")
    times = {n: [] for n in materials}  # whole render at --samples
    per_sample = {n: [] for n in materials}
    images = {}
    out = os.path.join(bpy.app.tempdir or "/tmp", "loom_render_ratio.exr")
    if args.images:
        os.makedirs(args.images, exist_ok=True)

    def render(mat, samples=args.samples):
        plane.data.materials.clear()
        plane.data.materials.append(mat)
        scene.cycles.samples = samples
        t0 = time.monotonic()
        img = lt.render_to_exr(scene, out)
        return time.monotonic() - t0, img

    for _ in range(args.repeats):
        for name, mat in materials.items():
            dt, images[name] = render(mat)
            times[name].append(dt)
            if args.images:
                shutil.copyfile(out, os.path.join(args.images, name + ".exr"))
            dt_more, _ = render(mat, args.timing_samples)
            per_sample[name].append((dt_more - dt) / (args.timing_samples - args.samples))
    floor = None
    if args.reference is not None and args.noise_floor:
        scene.cycles.seed = scene.cycles.seed + 1
        _, again = render(materials[args.reference])
        floor = relative_rmse(again, images[args.reference])
        print(f"loom-bench: {args.reference} against itself with another seed: relative RMSE "
              f"{floor:.4f}", flush=True)
    base = statistics.median(times["principled_sheen"])
    for name, ps in per_sample.items():
        if not statistics.median(ps) > 0:
            raise SystemExit(f"{name}: renders took no longer at {args.timing_samples} samples "
                             f"than at {args.samples} (per-sample times {ps}): raise "
                             "--timing-samples or --res")
    base_ps = statistics.median(per_sample["principled_sheen"])
    rows = []
    for name, ts in times.items():
        med = statistics.median(ts)
        ps = statistics.median(per_sample[name])
        n_nodes, n_reads = node_counts(materials[name].node_tree)
        row = {"material": name, "ratio": ps / base_ps, "per_sample_s": ps,
               "nodes": n_nodes, "image_reads": n_reads,
               "per_sample": per_sample[name], "median_s": med, "whole_ratio": med / base,
               "fixed_s": med - args.samples * ps, "times": ts}
        line = (f"loom-bench: {name:28s} per sample {ps * 1e3:8.3f} ms  ratio {ps / base_ps:6.2f}"
                f"  (whole render {med:6.2f} s, ratio {med / base:6.2f}; fixed "
                f"{row['fixed_s']:5.2f} s; {n_nodes} nodes, {n_reads} image reads)")
        if args.reference is not None:
            row["relative_rmse"] = relative_rmse(images[name], images[args.reference])
            line += f"  rel. RMSE vs {args.reference} {row['relative_rmse']:.4f}"
        rows.append(row)
        print(line, flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"samples": args.samples, "timing_samples": args.timing_samples,
                       "res": args.res, "scene": args.scene, "light": args.light,
                       "reference": args.reference, "noise_floor": floor, "rows": rows}, f,
                      indent=1)


lt.run(main)
