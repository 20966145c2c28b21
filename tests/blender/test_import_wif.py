"""File > Import > Weaving Draft: the operator, its menu entry and drop handler, headless.

    blender -b --factory-startup --python-exit-code 1 --python tests/blender/test_import_wif.py \
        -- --loom-bake LOOM_BAKE [--out DIR]

A good draft becomes a new cloth plane with a Loom material baked from it (the draft's yarn
types in its atlas), the user's own object and material untouched; a bad draft is refused with
the section and line named and changes nothing (no object, no material); unregistering removes
the menu entry and the file handler.
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import loom_testlib as lt  # noqa: E402

import bpy  # noqa: E402


def main():
    args = lt.parse_args()
    assert args.loom_bake, "give --loom-bake"
    os.environ["LOOM_BAKE"] = args.loom_bake
    lt.enable_addon()
    from loom import bakery, operators, preferences

    preferences.get().cache_dir = os.path.join(args.out, "cache")
    lt.empty_scene()
    menu = bpy.types.TOPBAR_MT_file_import
    assert operators.menu_import in getattr(menu.draw, "_draw_funcs", []), "no File > Import entry"
    assert hasattr(bpy.types, "LOOM_FH_wif"), "no file handler for dropped .wif files"

    # The user's own object and material, selected and active: left as they are.
    mine = lt.add_plane("Mine", half=0.5)
    own = lt.diffuse_material("Own", (0.2, 0.4, 0.6))
    mine.data.materials.append(own)
    bpy.context.view_layer.objects.active = mine
    mine.select_set(True)
    own_nodes = sorted(n.bl_idname for n in own.node_tree.nodes)

    # A bad draft: refused, nothing made.
    bad = os.path.join(args.out, "bad.wif")
    with open(bad, "w", encoding="utf-8") as f:
        f.write("[WIF]\n[WEAVING]\nShafts=2\nTreadles=2\n[WARP]\nThreads=2\n[WEFT]\nThreads=2\n"
                "[THREADING]\n1=1\n2=5\n[TIEUP]\n1=1\n2=2\n[TREADLING]\n1=1\n2=2\n")
    objects, materials = len(bpy.data.objects), len(bpy.data.materials)
    try:
        result = bpy.ops.loom.import_wif(filepath=bad)
    except RuntimeError as exc:  # an operator's ERROR report raises in background mode
        result, message = {"CANCELLED"}, str(exc)
    else:
        message = ""
    assert result == {"CANCELLED"}, result
    assert "line 11 [THREADING]" in message, message
    assert (len(bpy.data.objects), len(bpy.data.materials)) == (objects, materials), \
        "a refused draft left something behind"

    # The gingham: a 10 cm plane at the cursor with its material baked from the draft.
    here = os.path.dirname(os.path.abspath(__file__))
    draft = os.path.abspath(os.path.join(here, "..", "..", "presets", "drafts", "gingham.wif"))
    bpy.context.scene.cursor.location = (0.3, 0.0, 0.0)
    result = bpy.ops.loom.import_wif(filepath=draft, size=0.1)
    assert result == {"FINISHED"}, result
    obj = bpy.context.view_layer.objects.active
    assert obj is not None and obj.name == "gingham", obj
    assert abs(obj.dimensions.x - 0.1) < 1e-6 and abs(obj.location.x - 0.3) < 1e-6
    mat = obj.active_material
    assert mat is not None and mat.loom.managed and mat.loom.spec_path == draft, mat
    atlas = mat.loom.atlas_dir or next(
        n.node_tree["loom_atlas"] for n in mat.node_tree.nodes
        if n.type == "GROUP" and n.node_tree and "loom_atlas" in n.node_tree)
    manifest = bakery.read_manifest(bpy.path.abspath(atlas))
    spec = manifest["spec"]
    assert spec["warp"]["sequence"] == [["color_1", 4], ["color_2", 4]], spec["warp"]
    assert set(spec["yarn_types"]) == {"color_1", "color_2"}, spec.get("yarn_types")
    print(f"loom-test: imported {draft} as {obj.name} with {mat.name} from {atlas}")
    assert mine.active_material == own and not own.loom.managed, "the user's material changed"
    assert sorted(n.bl_idname for n in own.node_tree.nodes) == own_nodes
    assert not mine.select_get(), "the import left the user's object selected"

    lt.disable_addon()
    assert operators.menu_import not in getattr(menu.draw, "_draw_funcs", []), \
        "the menu entry outlived unregister"
    assert not hasattr(bpy.types, "LOOM_FH_wif"), "the file handler outlived unregister"


lt.run(main)
