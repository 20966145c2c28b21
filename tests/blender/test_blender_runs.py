"""Self-test: Blender (as chosen by scripts/blender.sh) renders with Cycles on the CPU.

Run inside Blender, headless:

    scripts/blender.sh run -b --factory-startup --python-exit-code 1 \
        --python tests/blender/test_blender_runs.py [-- OUTPUT_DIR]

The output directory is taken from the first argument after ``--``, else from
the environment variable LOOM_TEST_OUTPUT_DIR, else a fresh temporary
directory is made (and removed again if the test passes).

The test builds a 32x32 scene from scratch (a white plane with a Diffuse BSDF,
lit by a sun, seen by a camera looking straight down, black world), renders it
with Cycles on the CPU at 4 samples to a PNG, loads the PNG back with
bpy.data.images.load and checks that every pixel is finite and that the image
is not black (mean RGB > 0.05; an unlit render gives ~0.002 under AgX).

Exit status (with --python-exit-code 1): 0 when the checks pass, non-zero
otherwise.  The script prints its timings and a one-line verdict.
"""

import math
import os
import shutil
import sys
import tempfile
import time

import bpy

RES = 32
SAMPLES = 4


def output_dir():
    """Return (directory, made_here)."""
    argv = sys.argv
    if "--" in argv:
        rest = argv[argv.index("--") + 1:]
        if rest:
            return rest[0], False
    env = os.environ.get("LOOM_TEST_OUTPUT_DIR")
    if env:
        return env, False
    return tempfile.mkdtemp(prefix="loom-blender-test-"), True


def build_scene():
    # Start from an empty scene so the result does not depend on the startup
    # file (the caller should pass --factory-startup as well).
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene

    # Plane: built from data, not with bpy.ops, so no UI context is needed.
    half = 2.0
    mesh = bpy.data.meshes.new("Plane")
    mesh.from_pydata(
        [(-half, -half, 0.0), (half, -half, 0.0), (half, half, 0.0), (-half, half, 0.0)],
        [],
        [(0, 1, 2, 3)],
    )
    mesh.update()
    plane = bpy.data.objects.new("Plane", mesh)
    scene.collection.objects.link(plane)

    mat = bpy.data.materials.new("Diffuse")
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    out = nodes.new("ShaderNodeOutputMaterial")
    mat.node_tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    mesh.materials.append(mat)

    sun_data = bpy.data.lights.new("Sun", type="SUN")
    sun_data.energy = 3.0
    sun = bpy.data.objects.new("Sun", sun_data)
    sun.rotation_euler = (math.radians(30.0), 0.0, math.radians(20.0))
    scene.collection.objects.link(sun)

    cam_data = bpy.data.cameras.new("Camera")
    cam = bpy.data.objects.new("Camera", cam_data)
    cam.location = (0.0, 0.0, 3.0)  # default orientation looks down -Z
    scene.collection.objects.link(cam)
    scene.camera = cam

    # A black world, so that any light in the image comes from the sun on the plane.
    world = bpy.data.worlds.new("World")
    world.use_nodes = False
    world.color = (0.0, 0.0, 0.0)
    scene.world = world

    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = SAMPLES
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    scene.render.resolution_x = RES
    scene.render.resolution_y = RES
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.film_transparent = False
    return scene


def check_image(path):
    img = bpy.data.images.load(path, check_existing=False)
    w, h = img.size
    assert (w, h) == (RES, RES), f"image is {w}x{h}, expected {RES}x{RES}"
    px = list(img.pixels)  # RGBA floats in [0, 1]
    assert len(px) == RES * RES * 4, f"got {len(px)} pixel values"
    bad = [v for v in px if not math.isfinite(v)]
    assert not bad, f"{len(bad)} non-finite pixel values"
    rgb = [v for i, v in enumerate(px) if i % 4 != 3]
    mean = sum(rgb) / len(rgb)
    peak = max(rgb)
    print(f"loom-test: image {w}x{h}, mean RGB {mean:.4f}, max {peak:.4f}")
    assert peak > 0.0 and mean > 0.05, f"image is black (mean {mean:.4f}, max {peak:.4f})"


def main():
    import _cycles

    print(f"loom-test: Blender {bpy.app.version_string}, Cycles with OSL: {_cycles.with_osl}")
    out_dir, made_here = output_dir()
    out_dir = os.path.abspath(out_dir)
    os.makedirs(out_dir, exist_ok=True)
    path = os.path.join(out_dir, "loom_blender_test.png")
    if os.path.exists(path):
        os.remove(path)

    scene = build_scene()
    scene.render.filepath = path
    t0 = time.monotonic()
    bpy.ops.render.render(write_still=True)
    dt = time.monotonic() - t0
    print(f"loom-test: render {RES}x{RES} at {SAMPLES} samples took {dt:.2f} s -> {path}")
    assert os.path.isfile(path), f"render wrote no file at {path}"
    check_image(path)
    if made_here:
        shutil.rmtree(out_dir, ignore_errors=True)
    print("loom-test: PASS")


try:
    main()
except Exception as exc:
    print(f"loom-test: FAIL: {exc}", file=sys.stderr)
    raise
