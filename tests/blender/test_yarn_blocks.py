"""A gingham woven from a WIF draft renders each block in its colours (node mode, surface tier).

    blender -b --factory-startup --python-exit-code 1 --python tests/blender/test_yarn_blocks.py \
        -- --loom-bake LOOM_BAKE [--out DIR] [--res 64] [--samples 16]

presets/drafts/gingham.wif: a plain weave, 4 white and 4 red threads in turn in warp and weft.
Its atlas holds one colour repeat (8 x 8 threads). Seen straight down with one repeat across
the frame: the warp threads run along u and lie in v (warp thread i at v in [i/8, (i+1)/8),
the atlas's convention), the weft threads the other way, so the quadrants are white x white,
red x red, and two of white and red. Their colours are measured against what the draft's
colours make of them (see the checks).
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import loom_testlib as lt  # noqa: E402

import bpy  # noqa: E402


def extra(p):
    p.add_argument("--res", type=int, default=64)
    p.add_argument("--samples", type=int, default=16)


def block_mean(img, x0, x1, y0, y1):
    """Mean RGB over pixels [x0, x1) x [y0, y1) (rows from the bottom)."""
    s, n = [0.0, 0.0, 0.0], 0
    for y in range(y0, y1):
        for x in range(x0, x1):
            i = 4 * (y * img.w + x)
            for c in range(3):
                s[c] += img.px[i + c]
            n += 1
    return [v / n for v in s]


def main():
    args = lt.parse_args(extra)
    lt.enable_addon()
    import loom.api

    here = os.path.dirname(os.path.abspath(__file__))
    draft = os.path.join(here, "..", "..", "presets", "drafts", "gingham.wif")
    atlas = loom.api.bake(os.path.abspath(draft), "draft", loom_bake=args.loom_bake,
                          cache_dir=os.path.join(args.out, "cache"))

    scene = lt.empty_scene()
    scene.world.color = (0.2, 0.2, 0.2)
    scene.cycles.samples = args.samples
    scene.render.resolution_x = scene.render.resolution_y = args.res
    scene.render.resolution_percentage = 100
    plane = lt.add_plane("Gingham", half=1.0)  # UV = world xy, [-1, 1]
    loom.api.assign(plane, atlas, mode="nodes", scale=0.5)  # one repeat across, from u = -0.5
    mode = loom.api.last_assign()["mode"]
    assert mode == "NODES", mode

    cam_data = bpy.data.cameras.new("Camera")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 2.0  # the plane fills the frame
    cam = bpy.data.objects.new("Camera", cam_data)
    cam.location = (0.0, 0.0, 3.0)
    lt.look_along(cam, (0.0, 0.0, -1.0))  # image right = +x (u), image up = +y (v)
    scene.collection.objects.link(cam)
    scene.camera = cam
    sun_data = bpy.data.lights.new("Sun", type="SUN")
    sun_data.energy = 3.0
    sun = bpy.data.objects.new("Sun", sun_data)
    lt.look_along(sun, tuple(-c for c in lt.unit((0.2, 0.1, 1.0))))
    scene.collection.objects.link(sun)

    img = lt.render_to_exr(scene, os.path.join(args.out, "gingham.exr"))
    assert img.finite(), "non-finite pixels"
    # Quadrants of the frame, inner 60 % of each: u = x / 2, v = y / 2 (world x, y in [-1, 1]),
    # wrapped, so x < 0 is u in [0.5, 1) (weft threads 4-7, red), y > 0 is v in [0, 0.5) (warp
    # threads 0-3, white).
    h = args.res // 2
    a, b = int(0.2 * h), int(0.8 * h)
    blocks = {
        "white x white": block_mean(img, h + a, h + b, h + a, h + b),  # right, top
        "red x red": block_mean(img, a, b, a, b),                      # left, bottom
        "white warp x red weft": block_mean(img, a, b, h + a, h + b),  # left, top
        "red warp x white weft": block_mean(img, h + a, h + b, a, b),  # right, bottom
    }
    for k, v in blocks.items():
        print(f"loom-test: {k}: rgb ({v[0]:.4f}, {v[1]:.4f}, {v[2]:.4f})")
    white, red = blocks["white x white"], blocks["red x red"]
    # What the draft's colours make of the blocks: the yarns' white specular light is the same
    # in every block, so red minus white is the diffuse light's change, along the draft's red
    # minus white in linear light (sRGB decoded here); the plain weave shows as much warp as
    # weft, so a mixed block is the mean of the two pure ones.
    c_white = [srgb_to_linear(v / 255) for v in (245, 245, 240)]
    c_red = [srgb_to_linear(v / 255) for v in (200, 16, 46)]
    want = [r - w for r, w in zip(c_red, c_white)]
    got = [r - w for r, w in zip(red, white)]
    cos = sum(a * b for a, b in zip(want, got)) / (norm(want) * norm(got))
    print(f"loom-test: red - white block along the draft's red - white: cos {cos:.4f}")
    assert cos > 0.995, f"the red block differs from the white one in another colour: {cos:.4f}"
    assert norm(got) > 0.1 * sum(white), "the red and white blocks look alike"
    assert 0.9 < white[0] / white[1] < 1.1, f"the white block is not neutral: {white}"
    for k in ("white warp x red weft", "red warp x white weft"):
        for c in range(3):
            mid = 0.5 * (white[c] + red[c])
            assert abs(blocks[k][c] - mid) < 0.05 * mid, f"{k}: {blocks[k]} is not half-way"


def srgb_to_linear(v):
    return v / 12.92 if v <= 0.04045 else ((v + 0.055) / 1.055) ** 2.4


def norm(v):
    return sum(c * c for c in v) ** 0.5

lt.run(main)
