"""Auto choice of tier and components (addon/scene_needs.py): a close camera picks the ray-wave
tier and a far one the surface tier (perspective and orthographic); diffraction, transmission and
the double layer only when a light (sun, point) or a bright world lights the cloth from behind.

    blender -b --factory-startup --python-exit-code 1 --python tests/blender/test_scene_needs.py \
        [-- --atlas DIR]   (a plain-weave surface atlas: also checks the panel's operator)
"""

import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import loom_testlib as lt  # noqa: E402

import bpy  # noqa: E402

# A plain weave of the README's default fabric: 300 um yarns of two 170 um plies, 28 yarns/cm,
# so one repeat (two yarns) is 714.3 um; the 2 m plane's UV unit spans 2 m, so 2800 repeats per
# UV unit give the yarns their physical size.
YARN, PLY, PLIES, REPEAT = 300.0, 170.0, 2, 2e4 / 28
REPEATS_PER_UV = 2.0 / (REPEAT * 1e-6)


def scene():
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    cloth = bpy.context.active_object
    cam_data = bpy.data.cameras.new("cam")
    cam_data.lens = 50
    cam = bpy.data.objects.new("cam", cam_data)
    bpy.context.scene.collection.objects.link(cam)
    sc = bpy.context.scene
    sc.camera = cam
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 1920, 1080, 100
    world = sc.world or bpy.data.worlds.new("w")
    sc.world = world
    world.use_nodes = True
    bg = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
    bg.inputs["Strength"].default_value = 0.0
    return sc, cloth, cam, bg


def needs(cloth):
    import loom.api

    return loom.api.scene_needs(cloth, YARN, PLY, PLIES, REPEAT, REPEATS_PER_UV)


def add_light(kind, location, rotation=(0.0, 0.0, 0.0)):
    data = bpy.data.lights.new(kind.lower(), kind)
    data.energy = 3.0
    obj = bpy.data.objects.new(kind.lower(), data)
    obj.location, obj.rotation_euler = location, rotation
    bpy.context.scene.collection.objects.link(obj)
    return obj


def main():
    args = lt.parse_args()
    lt.enable_addon()
    sc, cloth, cam, bg = scene()

    # Camera straight above the cloth, looking down (-z).
    cam.location = (0.0, 0.0, 0.05)
    n = needs(cloth)
    # 300 um at 5 cm through a 50 mm lens on a 36 mm sensor, 1920 px wide: 16 px.
    assert abs(n["yarn_px"] - 0.3e-3 * 1920 * 50 / (36 * 0.05)) < 0.05, n
    assert n["tier"] == "raywave" and n["multi_ply"], n
    assert not n["diffraction"] and not n["transmission"], n
    assert any("nothing lights the cloth from behind" in r for r in n["reasons"]), n

    cam.location = (0.0, 0.0, 20.0)
    n = needs(cloth)
    assert n["tier"] == "surface" and not n["multi_ply"] and n["yarn_px"] < 0.1, n

    cam.data.type = "ORTHO"
    cam.data.ortho_scale = 0.02  # 2 cm across 1920 px: a 0.3 mm yarn is 29 px
    n = needs(cloth)
    assert n["tier"] == "raywave" and abs(n["yarn_px"] - 0.3e-3 * 1920 / 0.02) < 0.05, n
    cam.data.ortho_scale = 4.0
    assert needs(cloth)["tier"] == "surface"
    # The repeat-averaged closures (scene_needs.average_drive): a repeat spans 0.34 px at 4 m
    # across 1920 px (all averaged), 69 px at 2 cm (none).
    from loom import scene_needs
    d = scene_needs.average_drive(cloth, sc, REPEATS_PER_UV)
    assert d["kind"] == "constant" and d["value"] == 1.0, d
    cam.data.ortho_scale = 0.02
    d = scene_needs.average_drive(cloth, sc, REPEATS_PER_UV)
    assert d["kind"] == "constant" and d["value"] == 0.0, d
    cam.data.type = "PERSP"
    cam.location = (0.0, 0.0, 0.05)
    # Perspective, 50 mm on 36 mm over 1920 px: a 714.3 um repeat spans 2 px at
    # REPEAT 1920 50 / (36 2) = 0.952 m and 1 px at twice that.
    d = scene_needs.average_drive(cloth, sc, REPEATS_PER_UV)
    near = REPEAT * 1e-6 * 1920 * 50 / (36 * 2)
    assert d["kind"] == "distance" and abs(d["near"] - near) < 1e-3 * near, (d, near)
    assert abs(d["far"] - 2 * near) < 2e-3 * near, d

    # A sun shining down (its -z) lights the camera's side; turned over, it lights the back.
    sun = add_light("SUN", (0.0, 0.0, 3.0))
    assert not needs(cloth)["diffraction"]
    sun.rotation_euler = (math.pi, 0.0, 0.0)
    n = needs(cloth)
    assert n["diffraction"] and n["transmission"] and n["double_layer"], n
    assert any("sun" in r for r in n["reasons"]), n
    bpy.data.objects.remove(sun)

    point = add_light("POINT", (0.3, 0.0, -1.0))
    assert needs(cloth)["diffraction"]
    point.location = (0.3, 0.0, 1.0)
    assert not needs(cloth)["diffraction"]
    point.hide_render = True
    point.location = (0.3, 0.0, -1.0)
    assert not needs(cloth)["diffraction"], "a light hidden from renders lights nothing"

    bg.inputs["Strength"].default_value = 1.0
    bg.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    n = needs(cloth)
    assert n["transmission"] and n["diffraction"] and any("world" in r for r in n["reasons"]), n

    # The surface tier never asks for diffraction, even lit from behind.
    cam.location = (0.0, 0.0, 20.0)
    n = needs(cloth)
    assert n["tier"] == "surface" and n["transmission"] and not n["diffraction"], n

    # The spec a need derives: a surface spec's fitted closures (its default) do not follow it
    # to the ray-wave tier, which refuses them; its mapped ones may; back on the surface tier
    # the choice stays.
    from loom import scene_needs

    for closures, tier, want in (("fitted", "raywave", None), ("mapped", "raywave", "mapped"),
                                 ("mapped", "surface", "mapped"), ("fitted", "surface", "fitted")):
        canon = {"model": {"tier": "surface", "closures": closures}, "components": {},
                 "wave": {}, "warp": {}, "weft": {}}
        derived = scene_needs.spec_for_needs(canon, scene_needs.SceneNeeds(tier=tier))
        assert derived["model"].get("closures") == want, (closures, tier, derived["model"])

    # The panel's operator: from the material's atlas (the plain weave of the fixture, physical
    # scale) to the report shown in the panel.
    if args.atlas:
        cam.location = (0.0, 0.0, 0.05)
        with bpy.context.temp_override(object=cloth):
            assert bpy.ops.loom.material_new() == {"FINISHED"}
        mat = cloth.active_material
        mat.loom.atlas_dir = args.atlas
        mat.loom.scale_mode = "PHYSICAL"
        with bpy.context.temp_override(object=cloth, material=mat):
            assert bpy.ops.loom.scene_needs() == {"FINISHED"}
        lines = mat.loom.needs_report.splitlines()
        assert lines[0] == "Needs: raywave tier", lines
        assert any("lit from behind by the world" in ln for ln in lines), lines
        # Assigning drives the material's Average by the camera distance.
        import loom.api
        mat = loom.api.assign(cloth, args.atlas, mode="nodes", scale=REPEATS_PER_UV)
        group = next(n for n in mat.node_tree.nodes if n.type == "GROUP")
        links = group.inputs["Average"].links
        assert links and links[0].from_node.bl_idname == "ShaderNodeMapRange", links
        ramp = links[0].from_node
        assert abs(ramp.inputs["From Min"].default_value - near) < 1e-3 * near
        assert ramp.inputs["Value"].links[0].from_socket.name == "View Distance"
    print("scene needs: OK")


lt.run(main)
