"""A small Loom render is finite, not black, and shows the weave.

    blender -b --factory-startup --python-exit-code 1 --python tests/blender/test_render.py \
        -- (--atlas ATLAS | --loom-bake LOOM_BAKE) [--out DIR] [--res 64] [--samples 16]

The material is assigned in Auto mode (OSL where it runs, else nodes) through loom.api; a swatch
seen at an angle under a sun and a dim grey world, eight weave repeats across the frame.
"""

import math
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import loom_testlib as lt  # noqa: E402

import bpy  # noqa: E402


def extra(p):
    p.add_argument("--res", type=int, default=64)
    p.add_argument("--samples", type=int, default=16)


def main():
    args = lt.parse_args(extra)
    lt.enable_addon()
    import loom.api

    atlas = args.atlas
    if atlas is None:
        assert args.loom_bake, "give --atlas or --loom-bake"
        atlas = loom.api.bake("plain", "draft", loom_bake=args.loom_bake,
                              cache_dir=os.path.join(args.out, "cache"))

    scene = lt.empty_scene()
    scene.world.color = (0.05, 0.05, 0.05)
    scene.cycles.samples = args.samples
    scene.render.resolution_x = scene.render.resolution_y = args.res
    scene.render.resolution_percentage = 100
    plane = lt.add_plane("Swatch", half=1.0)
    loom.api.assign(plane, atlas, mode="auto", scale=4.0)  # UV [-1, 1]: 8 repeats across

    cam_data = bpy.data.cameras.new("Camera")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 1.2
    cam = bpy.data.objects.new("Camera", cam_data)
    wo = lt.unit((0.0, -0.5, 1.0))
    cam.location = tuple(3.0 * c for c in wo)
    lt.look_along(cam, tuple(-c for c in wo))
    scene.collection.objects.link(cam)
    scene.camera = cam
    sun_data = bpy.data.lights.new("Sun", type="SUN")
    sun_data.energy = 3.0
    sun = bpy.data.objects.new("Sun", sun_data)
    lt.look_along(sun, tuple(-c for c in lt.unit((0.4, 0.3, 1.0))))
    scene.collection.objects.link(sun)

    t0 = time.monotonic()
    img = lt.render_to_exr(scene, os.path.join(args.out, "render.exr"))
    dt = time.monotonic() - t0
    assert (img.w, img.h) == (args.res, args.res), (img.w, img.h)
    assert img.finite(), "non-finite pixels"
    mean, peak = img.rgb_mean(), img.rgb_max()
    lum = [img.px[i] + img.px[i + 1] + img.px[i + 2] for i in range(0, len(img.px), 4)]
    mu = sum(lum) / len(lum)
    sd = math.sqrt(sum((v - mu) ** 2 for v in lum) / len(lum))
    mode = loom.api.last_assign()["mode"]
    print(f"loom-test: {args.res}x{args.res} at {args.samples} spp in {dt:.1f} s ({mode}): "
          f"mean {mean:.4f}, max {peak:.4f}, luminance contrast {sd / max(mu, 1e-9):.3f}")
    assert mean > 0.01 and peak > 0.05, "image is black"
    assert sd / mu > 0.02, "no visible weave (uniform image)"
    # Also as the PNG a user would get.
    scene.render.image_settings.file_format = "PNG"
    scene.render.filepath = os.path.join(args.out, "render.png")
    bpy.ops.render.render(write_still=True)


lt.run(main)
