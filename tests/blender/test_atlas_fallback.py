"""A .blend whose atlas went missing or stale opens, renders a plain fallback and says why,
keeps every node of the material, and comes back by itself once the atlas is sound again
(addon/atlas_check.py).

    blender -b --factory-startup --python-exit-code 1 --python tests/blender/test_atlas_fallback.py \
        -- --atlas ATLAS --out DIR

ATLAS: a baked surface atlas (copied; the copy is moved and edited, never ATLAS itself).
"""

import json
import math
import os
import shutil
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import loom_testlib as lt  # noqa: E402

import bpy  # noqa: E402


def tree_of(mat):
    """Node names and links of a material's tree (what must survive)."""
    nt = mat.node_tree
    names = {n.name for n in nt.nodes}
    links = {(lk.from_node.name, lk.from_socket.identifier, lk.to_node.name,
              lk.to_socket.identifier) for lk in nt.links}
    return names, links


def output_source(mat):
    out = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    links = out.inputs["Surface"].links
    return links[0].from_node.name if links else None


def render(out_dir, name):
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = 24
    scene.cycles.samples = 4
    return lt.render_to_exr(scene, os.path.join(out_dir, name + ".exr"))


def reopen(path):
    bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
    return bpy.data.materials["Cloth"]


def check_panel(mat, problem):
    """The material panel says why (the problem, verbatim) and offers the Re-bake button when
    the atlas has a problem; a sound atlas gets neither."""
    log = lt.draw_material_panel(mat, bpy.data.objects["Swatch"])
    offered = ("button", "Re-bake") in log
    if problem:
        assert ("label", f"Atlas {problem}") in log, (problem, log)
        assert offered and ("operator", "loom.bake_assign") in log, log
        assert any(k == "label" and "fallback" in t for k, t in log), log
    else:
        assert not offered and not any(k == "label" and t.startswith("Atlas ") and "fallback"
                                       in t for k, t in log), log


def check_fallback_render(out_dir, name, mat):
    """A fallback render: finite, not Blender's magenta for missing images, and in the fabric's
    colour (the fallback BSDF's base colour is the one the material recorded at build time)."""
    img = render(out_dir, name)
    means = [img.channel_mean(c) for c in range(3)]
    print(f"loom-test: {name} fallback render mean {means}")
    assert all(math.isfinite(m) for m in means) and means[1] > 1e-3, means
    assert means[1] > 0.5 * min(means[0], means[2]), means
    rgb = list(mat["loom_fallback_rgb"])
    fb = mat.node_tree.nodes["Loom Fallback"].inputs["Base Color"].default_value
    assert all(abs(fb[c] - rgb[c]) < 1e-6 for c in range(3)), (list(fb), rgb)
    return means


def main():
    args = lt.parse_args()
    assert args.atlas, "--atlas is required"
    lt.enable_addon()
    import loom.api

    atlas = os.path.join(args.out, "atlas")
    shutil.rmtree(atlas, ignore_errors=True)
    shutil.copytree(args.atlas, atlas)

    scene = lt.empty_scene()
    plane = lt.add_plane("Swatch", half=1.0, uv_per_meter=1.0)
    lt.top_view(scene, 1.0)
    mat = loom.api.assign(plane, atlas, mode="nodes", scale=4.0,
                          material=bpy.data.materials.new("Cloth"))
    plane.data.materials.append(mat)
    # Nodes of the user's own, which must survive everything below: a value, and a mix shader
    # between the Loom node and the output (whose links must come back as they were).
    nt = mat.node_tree
    assert output_source(mat) == "Loom Surface", output_source(mat)
    mine = nt.nodes.new("ShaderNodeValue")
    mine.name = "My Value"
    mine.outputs[0].default_value = 0.25
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.name = "My Mix"
    mix.inputs["Fac"].default_value = 0.0  # all of the Loom shader
    out = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    nt.links.new(nt.nodes["Loom Surface"].outputs["BSDF"], mix.inputs[1])
    nt.links.new(mix.outputs["Shader"], out.inputs["Surface"])
    names0, links0 = tree_of(mat)
    user_node = output_source(mat)
    assert user_node == "My Mix", user_node
    assert not mat.loom.atlas_problem
    check_panel(mat, "")
    sound = render(args.out, "sound")
    blend = os.path.join(args.out, "fallback.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)

    # 1. The atlas is gone: the file opens, the fallback renders, the reason is given.
    moved = atlas + ".moved"
    shutil.rmtree(moved, ignore_errors=True)
    os.rename(atlas, moved)
    mat = reopen(blend)
    problem = mat.loom.atlas_problem
    print(f"loom-test: missing atlas: {problem}")
    assert problem.startswith("missing:") and atlas in problem, problem
    assert output_source(mat) == "Loom Fallback", output_source(mat)
    names, _ = tree_of(mat)
    assert names0 <= names and names - names0 == {"Loom Fallback"}, (names0, names)
    assert mat.node_tree.nodes["My Value"].outputs[0].default_value == 0.25
    check_panel(mat, problem)
    # The fallback has the fabric's colour (plain's default yarn), not a fixed grey, and is not
    # Blender's magenta for missing images (green not far below red and blue).
    fallback = check_fallback_render(args.out, "missing", mat)
    bpy.ops.wm.save_mainfile()  # saved with the fallback in place

    # 2. The atlas is back: the next load links the Loom node again, as built.
    os.rename(moved, atlas)
    mat = reopen(blend)
    assert not mat.loom.atlas_problem, mat.loom.atlas_problem
    assert output_source(mat) == user_node, output_source(mat)
    names, links = tree_of(mat)
    assert names == names0 and links == links0, (names ^ names0, links ^ links0)
    again = render(args.out, "restored")
    for c in range(3):
        assert abs(again.channel_mean(c) - sound.channel_mean(c)) <= 1e-6 + 1e-4 * abs(
            sound.channel_mean(c)), (c, again.channel_mean(c), sound.channel_mean(c))
    bpy.ops.wm.save_mainfile()

    # 3. Re-baked from another spec in place (stale): fallback, and it says so.
    path = os.path.join(atlas, "manifest.json")
    with open(path, encoding="utf-8") as f:
        manifest = json.load(f)
    manifest["spec_sha256"] = "0" * 64
    with open(path, "w", encoding="utf-8") as f:
        json.dump(manifest, f)
    mat = reopen(blend)
    print(f"loom-test: stale atlas: {mat.loom.atlas_problem}")
    assert mat.loom.atlas_problem.startswith("stale:"), mat.loom.atlas_problem
    assert output_source(mat) == "Loom Fallback"
    check_panel(mat, mat.loom.atlas_problem)
    # The same fallback as for a missing atlas (same scene, samples and seed).
    stale = check_fallback_render(args.out, "stale", mat)
    for c in range(3):
        assert abs(stale[c] - fallback[c]) <= 1e-4 * abs(fallback[c]) + 1e-6, (stale, fallback)

    # 4. A texture file gone, and a manifest that is not JSON.
    manifest["spec_sha256"] = mat.node_tree.nodes["Loom Surface"].node_tree["loom_spec_sha256"]
    victim = next(iter(manifest["textures"].values()))["node_file"]
    with open(path, "w", encoding="utf-8") as f:
        json.dump(manifest, f)
    os.remove(os.path.join(atlas, victim))
    mat = reopen(blend)
    assert mat.loom.atlas_problem.startswith("missing:") and victim in mat.loom.atlas_problem, \
        mat.loom.atlas_problem
    check_panel(mat, mat.loom.atlas_problem)
    with open(path, "w", encoding="utf-8") as f:
        f.write("{ not json")
    mat = reopen(blend)
    assert mat.loom.atlas_problem.startswith("unreadable:"), mat.loom.atlas_problem
    assert output_source(mat) == "Loom Fallback"
    check_panel(mat, mat.loom.atlas_problem)
    check_fallback_render(args.out, "unreadable", mat)
    names, _ = tree_of(mat)
    assert names0 <= names and len(names) == len(names0) + 1, (names0, names)
    assert mat.node_tree.nodes["My Value"].outputs[0].default_value == 0.25


lt.run(main)
