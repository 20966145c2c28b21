"""What a node-mode shader that only reads its closures' parameters and emits them would cost:
an atlas's own textures read by N Image Texture nodes straight into M closures (each read feeds
a closure's Color or Normal; reads beyond the closures are summed by one Math node each into the
first closure's Roughness), against a Principled BSDF with sheen and the atlas's Loom material
(node mode, Average 0) in the same scene: that of bench/blender_render_ratio.py (a swatch seen
by an orthographic camera 5 cm across, 96 px, one sun from the front), time per sample from
renders at 8 and 32 samples, medians of --repeats, alternating, one Blender process.

    blender -b --factory-startup --python-exit-code 1 --python bench/node_cost_floor.py -- \\
        --atlas ATLAS [--repeats 5]
"""

import os
import statistics
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests",
                                "blender"))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import loom_testlib as lt  # noqa: E402
from swatch_scene import principled_sheen, swatch_scene  # noqa: E402

import bpy  # noqa: E402

# (name, reads, closures): what the surface group reads and emits today, and two smaller sets.
FLOORS = (("reads12_closures7", 12, 7), ("reads6_closures4", 6, 4), ("reads3_closures3", 3, 3))
CLOSURES = ("ShaderNodeBsdfDiffuse", "ShaderNodeBsdfDiffuse", "ShaderNodeBsdfTranslucent",
            "ShaderNodeBsdfTranslucent", "ShaderNodeBsdfAnisotropic", "ShaderNodeBsdfHair",
            "ShaderNodeBsdfTransparent")


def extra_args(p):
    p.add_argument("--repeats", type=int, default=5)


def floor_material(name, images, n_reads, n_closures):
    """n_reads Image Textures of the atlas's images into n_closures closures, summed."""
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    nt.nodes.clear()
    uv = nt.nodes.new("ShaderNodeTexCoord").outputs["UV"]
    reads = []
    for k in range(n_reads):
        t = nt.nodes.new("ShaderNodeTexImage")
        t.image = images[k % len(images)]
        t.interpolation = "Linear"
        nt.links.new(uv, t.inputs["Vector"])
        reads.append(t)
    shader = first = None
    for i, kind in enumerate(CLOSURES[:n_closures]):
        c = nt.nodes.new(kind)
        nt.links.new(reads[i % n_reads].outputs["Color"], c.inputs["Color"])
        if "Normal" in c.inputs and n_reads > 1:
            nt.links.new(reads[(i + 1) % n_reads].outputs["Color"], c.inputs["Normal"])
        if shader is None:
            shader, first = c.outputs[0], c
            continue
        add = nt.nodes.new("ShaderNodeAddShader")
        nt.links.new(shader, add.inputs[0])
        nt.links.new(c.outputs[0], add.inputs[1])
        shader = add.outputs[0]
    acc = None
    for r in reads[n_closures:]:
        if acc is None:
            acc = r.outputs["Alpha"]
            continue
        add = nt.nodes.new("ShaderNodeMath")
        add.operation = "ADD"
        nt.links.new(acc, add.inputs[0])
        nt.links.new(r.outputs["Alpha"], add.inputs[1])
        acc = add.outputs[0]
    if acc is not None:
        nt.links.new(acc, first.inputs["Roughness"])
    nt.links.new(shader, nt.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    return m


def main():
    args = lt.parse_args(extra_args)
    lt.enable_addon()
    import loom.api

    scene, plane = swatch_scene(96)
    ref = principled_sheen()
    loom_mat = loom.api.assign(plane, args.atlas, mode="nodes", scale=None,
                               material=bpy.data.materials.new("loom"), average=0.0)
    group = next(n for n in loom_mat.node_tree.nodes if n.bl_idname == "ShaderNodeGroup")
    images = [n.image for n in group.node_tree.nodes if n.bl_idname == "ShaderNodeTexImage"]
    mats = {"principled_sheen": ref, "loom": loom_mat}
    for name, reads, closures in FLOORS:
        mats[name] = floor_material(name, images, reads, closures)
    out = os.path.join(bpy.app.tempdir or "/tmp", "loom_cost_floor.exr")

    def render(m, samples):
        plane.data.materials.clear()
        plane.data.materials.append(m)
        scene.cycles.samples = samples
        t0 = time.monotonic()
        lt.render_to_exr(scene, out)
        return time.monotonic() - t0

    per = {k: [] for k in mats}
    for _ in range(args.repeats):
        for k, m in mats.items():
            a, b = render(m, 8), render(m, 32)
            per[k].append((b - a) / 24)
    base = statistics.median(per["principled_sheen"])
    for k, v in per.items():
        ps = statistics.median(v)
        print(f"loom-bench: {k:18s} per sample {ps * 1e3:8.3f} ms  ratio {ps / base:5.2f}",
              flush=True)


lt.run(main)
