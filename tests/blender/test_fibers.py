"""Fiber tier in Blender (addon/fibers.py): a close-up camera gets real fibers on the cloth
(curves exist, lie on the surface, and change the render), a far camera gets none, a region over
the vertex budget is refused without touching the scene, moving the camera moves the region,
and the cloth's own material is left as it was; with Fibers Follow Camera a render updates them.

    blender -b --factory-startup --python-exit-code 1 --python tests/blender/test_fibers.py \
        -- --loom-bake LOOM_BAKE --atlas ATLAS --out DIR

ATLAS: a baked surface atlas (the plain weave fixture). With --raywave RAYWAVE_ATLAS, the fibers
of a ray-wave cloth take their absorption from its atlas.
"""

import math
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import loom_testlib as lt  # noqa: E402

import bpy  # noqa: E402


def tree_of(mat):
    nt = mat.node_tree
    return ({n.name for n in nt.nodes},
            {(lk.from_node.name, lk.from_socket.identifier, lk.to_node.name,
              lk.to_socket.identifier) for lk in nt.links})


def evaluated_points(obj):
    dg = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(dg)
    pts = [p.position.copy() for p in ev.data.points]
    return pts


def render(scene, out, name):
    t0 = time.perf_counter()
    img = lt.render_to_exr(scene, os.path.join(out, name + ".exr"))
    return img, time.perf_counter() - t0


def main():
    args = lt.parse_args(lambda p: p.add_argument("--raywave", default=None))
    assert args.atlas and args.loom_bake, "--atlas and --loom-bake are required"
    lt.enable_addon()
    import loom.api

    scene = lt.empty_scene()
    scene.render.resolution_x = scene.render.resolution_y = 64
    scene.cycles.samples = 8
    cloth = lt.add_plane("Cloth", 0.01, uv_per_meter=50.0)  # 2 cm square, UV [-0.5, 0.5]
    mat = loom.api.assign(cloth, args.atlas, mode="nodes")
    before = tree_of(mat)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 3.0
    scene.collection.objects.link(sun)
    lt.look_along(sun, (0.3, 0.2, -1.0))
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = 0.0015  # 1.5 mm over 64 px: 23 um a pixel, a fiber 0.6 px
    cam.data.clip_start = 0.001
    cam.location = (0.0, 0.0, 0.02)
    scene.collection.objects.link(cam)
    lt.look_along(cam, (0.0, 0.0, -1.0))
    scene.camera = cam

    # Close-up: fibers.
    res = loom.api.update_fibers(cloth, scene, loom_bake=args.loom_bake,
                                 cache_dir=os.path.join(args.out, "cache"))
    print("loom test: close-up:", res["reason"])
    assert res["object"], res
    fo = bpy.data.objects[res["object"]]
    assert res["curves"] > 100, res
    assert 0 < res["vertices"] <= 4_000_000, res
    assert res["bytes"] >= res["vertices"] * 12, res  # reported: at least the points loaded
    assert res["finest_px"] >= 0.5, res
    pts = evaluated_points(fo)
    assert len(pts) > 1000, f"only {len(pts)} points left on the surface"
    # On the cloth: within the plane (2 cm) and within a yarn's height of it.
    assert all(abs(p.z) < 1e-3 and abs(p.x) <= 0.0101 and abs(p.y) <= 0.0101 for p in pts), \
        "fiber points off the cloth"
    # And where the camera looks: the region is the view's footprint (plus a yarn or two).
    xs = sorted(p.x for p in pts)
    assert xs[len(xs) // 2] ** 2 < (0.0015) ** 2, f"fibers not centred under the camera: {xs[len(xs) // 2]}"
    assert tree_of(mat) == before, "the cloth's material changed"

    with_fibers, t_fib = render(scene, args.out, "fibers")
    fo.hide_render = True
    without, t_surf = render(scene, args.out, "surface")
    fo.hide_render = False
    assert with_fibers.finite()
    diff = math.fsum(abs(a - b) for a, b in zip(with_fibers.px, without.px)) / len(without.px)
    mean = without.rgb_mean()
    print(f"loom test: fibers change the image by {diff:.4g} (mean {mean:.4g}); render "
          f"{t_fib:.2f} s with fibers, {t_surf:.2f} s without")
    assert diff > 0.02 * mean, "the fibers do not show in the render"

    # Moving the camera moves the region.
    region0 = res["region_um"]
    cam.location = (0.004, 0.0, 0.02)
    res2 = loom.api.update_fibers(cloth, scene, loom_bake=args.loom_bake,
                                  cache_dir=os.path.join(args.out, "cache"))
    assert res2["object"] == res["object"], res2
    assert res2["region_um"][0] > region0[0] + 1000, (region0, res2["region_um"])
    assert len([o for o in bpy.data.objects if o.type == "CURVES"]) == 1, "fibers duplicated"

    # At the cloth's corner the region runs past the mesh: points off the UV map are dropped,
    # none is left at the surface's origin.
    cam.location = (0.0095, 0.0095, 0.02)
    res_c = loom.api.update_fibers(cloth, scene, loom_bake=args.loom_bake,
                                   cache_dir=os.path.join(args.out, "cache"))
    assert res_c["region_um"][2] > 10000 + 300, res_c["region_um"]  # past the edge (u > 0.5)
    pts = evaluated_points(bpy.data.objects[res_c["object"]])
    assert pts and all(p.x > 0.006 and p.y > 0.006 for p in pts), \
        f"points off the UV map kept: min x {min(p.x for p in pts):.4g}"

    # On the evaluated surface: a modifier moves the cloth 2.5 mm along x; the fibers come with
    # it, and the region is where the moved cloth is under the camera.
    disp = cloth.modifiers.new("Shift", "DISPLACE")
    disp.direction = "X"
    disp.strength = 0.005  # no texture: every vertex moves strength x (1 - mid level) = 2.5 mm
    cam.location = (0.0, 0.0, 0.02)
    res_d = loom.api.update_fibers(cloth, scene, loom_bake=args.loom_bake,
                                   cache_dir=os.path.join(args.out, "cache"))
    xs = sorted(p.x for p in evaluated_points(bpy.data.objects[res_d["object"]]))
    assert abs(xs[len(xs) // 2]) < 0.001, f"fibers not under the camera on the moved cloth: {xs[len(xs) // 2]}"
    cloth.modifiers.remove(disp)

    # Following the camera: a render updates the region for the camera of that frame.
    scene.loom_fibers_follow_camera = True
    os.environ["LOOM_BAKE"] = args.loom_bake
    cam.location = (-0.004, 0.0, 0.02)
    render(scene, args.out, "follow")
    fo = bpy.data.objects[res2["object"]]
    xs = sorted(p.x for p in evaluated_points(fo))
    assert xs[len(xs) // 2] < -0.003, f"fibers did not follow the camera: {xs[len(xs) // 2]}"
    scene.loom_fibers_follow_camera = False

    # Over the budget: refused with the count, the scene as it was.
    n_before = len(bpy.data.objects[res2["object"]].data.points)
    try:
        loom.api.update_fibers(cloth, scene, loom_bake=args.loom_bake,
                               cache_dir=os.path.join(args.out, "cache-small"), max_vertices=1000)
        raise AssertionError("a region over the vertex budget was accepted")
    except loom.api.LoomError as exc:
        assert "max-vertices" in str(exc), exc
    assert len(bpy.data.objects[res2["object"]].data.points) == n_before

    # Far: the camera resolves no fiber, and the old ones go.
    cam.data.ortho_scale = 0.05
    res3 = loom.api.update_fibers(cloth, scene, loom_bake=args.loom_bake,
                                  cache_dir=os.path.join(args.out, "cache"))
    print("loom test: far:", res3["reason"])
    assert res3["object"] is None and res3["curves"] == 0, res3
    assert not any(o.type == "CURVES" for o in bpy.data.objects), "far camera kept fibers"
    assert tree_of(mat) == before, "the cloth's material changed"

    if args.raywave:  # a ray-wave cloth: the hair absorbs as the atlas's yarns do
        import json
        rw = loom.api.assign(cloth, args.raywave, mode="nodes")
        cam.data.ortho_scale = 0.0015
        res4 = loom.api.update_fibers(cloth, scene, loom_bake=args.loom_bake,
                                      cache_dir=os.path.join(args.out, "cache"))
        assert res4["object"], res4
        with open(os.path.join(args.raywave, "manifest.json")) as f:
            m = json.load(f)
        fo = bpy.data.objects[res4["object"]]
        hair = next(n for n in fo.data.materials[0].node_tree.nodes
                    if n.bl_idname == "ShaderNodeBsdfHairPrincipled")
        assert hair.parametrization == "ABSORPTION", hair.parametrization
        want = [s * 0.5e-3 * m["spec"]["warp"]["fiber_diameter_um"]
                for s in m["raywave"]["yarns"]["warp"]["absorption"]["sigma_rgb_per_mm"]]
        got = list(hair.inputs["Absorption Coefficient"].default_value)
        assert all(abs(a - b) <= 1e-5 * max(1.0, abs(b)) for a, b in zip(got, want)), (got, want)
        print(f"loom test: ray-wave fibers absorb {got} per fiber radius ({rw.name})")
    print("loom test: fibers ok")


lt.run(main)
