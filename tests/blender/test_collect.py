"""Collect Atlases and packed files (issue 34): a .blend and its folder move to another place
and render there as before; a packed .blend renders without its atlases.

    blender -b --factory-startup --python-exit-code 1 --python tests/blender/test_collect.py \
        -- --atlas SURFACE_ATLAS --raywave RAYWAVE_ATLAS --out DIR

Two node-mode materials read one surface atlas, a third a ray-wave atlas (nested groups), and a
fourth is an OSL Script node's (its atlas property; OSL cannot run here, so it is not rendered).
After Collect Atlases the atlases sit in //loom/<atlas>/ (the shared one copied once), every
path points there (relative), the original atlases are deleted and the folder is moved: a fresh
Blender (this script again, --phase moved) opens the file without fallbacks and renders the same
image. Packed (File > External Data > Pack Resources) and without its loom/ folder, another
fresh Blender (--phase packed) renders the same again; only the OSL material, which reads files,
falls back.
"""

import os
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import loom_testlib as lt  # noqa: E402

import bpy  # noqa: E402


def render(out, name):
    img = lt.render_to_exr(bpy.context.scene, os.path.join(out, name + ".exr"))
    assert img.finite(), name
    return [img.channel_mean(c) for c in range(3)]


def same(a, b, what):
    assert all(abs(x - y) <= 1e-4 * max(abs(y), 1e-3) for x, y in zip(a, b)), f"{what}: {a} != {b}"


def main(args):
    assert args.atlas, "--atlas is required"
    lt.enable_addon()
    from loom import atlas_check, collect, material, osl_paths
    import loom.api

    work = os.path.join(args.out, "work")
    shutil.rmtree(work, ignore_errors=True)
    elsewhere = os.path.join(work, "cache")
    plain = os.path.join(elsewhere, "plain-draft")
    twill = os.path.join(elsewhere, "twill-raywave")
    shutil.copytree(args.atlas, plain)
    shutil.copytree(args.raywave, twill)

    scene = lt.empty_scene()
    for k, (atlas, name) in enumerate([(plain, "A"), (plain, "B"), (twill, "C")]):
        obj = lt.add_plane(name, half=0.25, location=(0.5 * k - 0.5, 0.0, 0.0))
        mat = loom.api.assign(obj, atlas, mode="nodes", scale=4.0, average=0.0,
                              material=bpy.data.materials.new(name))
        obj.data.materials.append(mat)
    osl = bpy.data.materials.new("OSL")
    osl.use_fake_user = True  # (no object: kept by the save)
    osl.use_nodes = True
    material.mark_managed(osl)
    script = osl.node_tree.nodes.new("ShaderNodeScript")
    script.name = material.NODE_NAMES[1]
    osl_paths.remember(script, plain, {"ply_frame": "ply_frame.exr"})
    lt.top_view(scene, 1.6, sun_direction=(0.2, 0.3, -1.0))
    scene.render.resolution_x, scene.render.resolution_y = 48, 16
    scene.cycles.samples = 4
    before = render(args.out, "before")

    try:  # unsaved: refused, nothing changed
        collect.collect_atlases()
        raise AssertionError("collected into an unsaved file's folder")
    except collect.CollectError as exc:
        assert "save the .blend first" in str(exc), exc
    here = os.path.join(work, "here")
    os.makedirs(here)
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(here, "scene.blend"))
    assert bpy.ops.loom.collect_atlases() == {"FINISHED"}
    copied = sorted(os.listdir(os.path.join(here, "loom")))
    assert copied == ["plain-draft", "twill-raywave"], copied
    for mat in (bpy.data.materials[n] for n in "ABC"):
        assert mat.loom.atlas_dir.startswith("//loom/"), mat.loom.atlas_dir
        imgs = list(atlas_check.images_of(mat.node_tree))
        assert imgs and all(i.filepath.startswith("//loom/") for i in imgs), \
            [i.filepath for i in imgs if not i.filepath.startswith("//loom/")][:3]
    assert script[osl_paths.ATLAS_PROP] == "//loom/plain-draft", script[osl_paths.ATLAS_PROP]
    again = collect.collect_atlases()  # a second collect copies nothing
    assert not any(d[2] for d in again), again
    bpy.ops.wm.save_mainfile()

    # Moved with its folder, the originals gone: a fresh Blender opens it without fallbacks and
    # renders the same image; packed there and without the folder, another fresh Blender
    # renders it the same from the packed maps (the OSL material, which reads files, falls back).
    shutil.rmtree(elsewhere)
    there = os.path.join(work, "there")
    os.rename(here, there)
    blend = os.path.join(there, "scene.blend")
    for phase in ("moved", "packed"):
        cmd = [bpy.app.binary_path, "-b", "--factory-startup", "--python-exit-code", "1",
               "--python", os.path.abspath(__file__), "--", "--phase", phase, "--blend", blend,
               "--expect", ",".join(repr(v) for v in before), "--out", args.out,
               "--atlas", args.atlas, "--raywave", args.raywave]
        res = subprocess.run(cmd, capture_output=True, text=True)
        print(res.stdout[-2000:], res.stderr[-2000:])
        assert res.returncode == 0 and "loom-test collect phase" in res.stdout, \
            f"the fresh Blender's {phase} check failed ({res.returncode})"
    print(f"loom-test collect: before {before}, moved and packed the same in fresh Blenders")


def fresh(args):
    """A fresh Blender's part: open the moved file, check, render, compare (and pack)."""
    lt.enable_addon()
    from loom import atlas_check

    before = [float(v) for v in args.expect.split(",")]
    bpy.ops.wm.open_mainfile(filepath=args.blend, load_ui=False)
    problems = atlas_check.check_all()
    there = os.path.dirname(args.blend)
    if args.phase == "moved":
        assert problems == {}, problems
        node = atlas_check.loom_node(bpy.data.materials["OSL"])
        assert atlas_check.atlas_of(node)[0] == os.path.join(there, "loom", "plain-draft")
        same(render(args.out, "moved"), before, "moved with its folder")
        bpy.ops.file.pack_all()
        bpy.ops.wm.save_mainfile()
        shutil.rmtree(os.path.join(there, "loom"))
    else:
        assert sorted(problems) == ["OSL"], problems  # OSL reads files: no packed maps for it
        same(render(args.out, "packed"), before, "packed")
    print(f"loom-test collect phase {args.phase}: the same image")


def entry():
    args = lt.parse_args(lambda p: (p.add_argument("--raywave", required=True),
                                    p.add_argument("--phase", default=None),
                                    p.add_argument("--blend"), p.add_argument("--expect")))
    (fresh if args.phase else main)(args)


lt.run(entry)
