"""Shared helpers of Loom's Blender tests (imported by the test scripts, run inside Blender).

Arguments after ``--`` are parsed by each test with ``parse_args``; common ones:
  --loom-bake PATH   loom-bake to use (inside the Blender chroot: a host-exec wrapper, see
                     scripts/blender.sh host-exec-wrapper); default $LOOM_BAKE
  --atlas DIR        an atlas baked beforehand (skips baking where a test allows it)
  --out DIR          where to write renders (default: a temporary directory)
"""

from __future__ import annotations

import atexit
import argparse
import math
import os
import shutil
import sys
import tempfile
import traceback

import bpy

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
EXT_REPO_MODULE = "loom_dev"


def parse_args(extra=None) -> argparse.Namespace:
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser()
    p.add_argument("--loom-bake", default=os.environ.get("LOOM_BAKE"))
    p.add_argument("--atlas", default=None)
    p.add_argument("--out", default=None)
    if extra:
        extra(p)
    args = p.parse_args(argv)
    if args.out is None:
        args.out = tempfile.mkdtemp(prefix="loom-test-")
    os.makedirs(args.out, exist_ok=True)
    return args


def enable_addon():
    """Enable the add-on from this checkout's addon/ directory the way Blender loads
    extensions: a local extension repository (a temporary directory) holding a symlink
    ``loom -> addon/``; the package becomes ``bl_ext.loom_dev.loom``."""
    import addon_utils

    module = f"bl_ext.{EXT_REPO_MODULE}.loom"
    prefs = bpy.context.preferences
    repo = next((r for r in prefs.extensions.repos if r.module == EXT_REPO_MODULE), None)
    if repo is None:
        tmp = tempfile.mkdtemp(prefix="loom-ext-")
        atexit.register(shutil.rmtree, tmp, True)  # the symlink only, not addon/
        os.symlink(os.path.join(REPO, "addon"), os.path.join(tmp, "loom"))
        prefs.extensions.repos.new(name=EXT_REPO_MODULE, module=EXT_REPO_MODULE,
                                   custom_directory=tmp, source="USER")
    errors = []
    mod = addon_utils.enable(module, default_set=True, handle_error=lambda e: errors.append(e))
    if mod is None or errors:
        raise RuntimeError(f"enabling {module} failed: {errors}")
    return mod


def disable_addon():
    import addon_utils

    addon_utils.disable(f"bl_ext.{EXT_REPO_MODULE}.loom", default_set=True)


def run(main):
    """Run a test's main(); print PASS/FAIL; exit 1 on failure (with --python-exit-code 1
    an exception would do too, but an explicit exit also covers a missing flag)."""
    name = "test"
    if "--python" in sys.argv:
        name = os.path.basename(sys.argv[sys.argv.index("--python") + 1])
    try:
        main()
    except Exception as exc:  # report and fail
        traceback.print_exc()
        print(f"loom-test {name}: FAIL: {exc}", flush=True)
        sys.stdout.flush()
        os._exit(1)
    print(f"loom-test {name}: PASS", flush=True)


# ------------------------------------------------------------------------------- scenes


def empty_scene():
    # read_homefile, not read_factory_settings: the latter also resets the preferences, which
    # would drop the extension repository and the enabled add-on.
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.seed = 1
    # Film values must be linear radiance: no view transform, no look, no exposure.
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    world = bpy.data.worlds.new("Black")
    world.use_nodes = False
    world.color = (0.0, 0.0, 0.0)
    scene.world = world
    return scene


def add_plane(name: str, half: float, uv_per_meter: float = 1.0, location=(0, 0, 0)):
    """A square in z = 0, normal +z, UV = world xy * uv_per_meter (u along +x, v along +y)."""
    mesh = bpy.data.meshes.new(name)
    verts = [(-half, -half, 0.0), (half, -half, 0.0), (half, half, 0.0), (-half, half, 0.0)]
    mesh.from_pydata(verts, [], [(0, 1, 2, 3)])
    uv = mesh.uv_layers.new(name="UVMap")
    for loop in mesh.loops:
        x, y, _ = verts[loop.vertex_index]
        uv.data[loop.index].uv = (x * uv_per_meter, y * uv_per_meter)
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    return obj


def look_along(obj, direction):
    """Orient a camera or light so that its local -Z points along ``direction``."""
    from mathutils import Vector

    d = Vector(direction).normalized()
    obj.rotation_mode = "QUATERNION"
    obj.rotation_quaternion = (-d).to_track_quat("Z", "Y")


def top_view(scene, ortho_scale: float, height: float = 2.0, sun_direction=None,
             energy: float = 3.0):
    """An orthographic camera straight down from ``height`` (the scene's camera) and a sun of
    ``energy`` shining along ``sun_direction`` (default straight down); returns both."""
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = ortho_scale
    cam.location = (0.0, 0.0, height)
    scene.collection.objects.link(cam)
    scene.camera = cam
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", type="SUN"))
    sun.data.energy = energy
    if sun_direction is not None:
        look_along(sun, sun_direction)
    scene.collection.objects.link(sun)
    return cam, sun


def diffuse_material(name="Diffuse", color=(1.0, 1.0, 1.0)):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (*color, 1.0)
    d.inputs["Roughness"].default_value = 0.0
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(d.outputs["BSDF"], out.inputs["Surface"])
    return mat


def render_to_exr(scene, path: str) -> "Image":
    """Render the scene to a 32-bit float OpenEXR (linear radiance) and return its pixels."""
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.color_mode = "RGBA"
    scene.render.image_settings.exr_codec = "ZIP"
    scene.render.filepath = path
    scene.render.use_file_extension = False
    bpy.ops.render.render(write_still=True)
    return load_pixels(path)


class Image:
    """Float RGBA pixels (no numpy: Debian's Blender has none)."""

    def __init__(self, w, h, px):
        self.w, self.h, self.px = w, h, px

    def channel_mean(self, c: int) -> float:
        vals = self.px[c::4]
        return math.fsum(vals) / len(vals)

    def channel_stderr(self, c: int) -> float:
        """Standard error of channel_mean (pixels taken as independent samples)."""
        vals = self.px[c::4]
        n = len(vals)
        m = math.fsum(vals) / n
        return math.sqrt(math.fsum((v - m) ** 2 for v in vals) / max(n - 1, 1) / n)

    def rgb_mean(self) -> float:
        return sum(self.channel_mean(c) for c in range(3)) / 3.0

    def finite(self) -> bool:
        return all(math.isfinite(v) for v in self.px)

    def rgb_max(self) -> float:
        return max(v for i, v in enumerate(self.px) if i % 4 != 3)


def load_pixels(path: str) -> Image:
    import array

    img = bpy.data.images.load(path, check_existing=False)
    w, h = img.size
    px = array.array("f", [0.0]) * (w * h * 4)
    img.pixels.foreach_get(px)
    bpy.data.images.remove(img)
    return Image(w, h, px)


def unit(v):
    n = math.sqrt(sum(c * c for c in v))
    return tuple(c / n for c in v)


class FakeLayout:
    """Records what a panel draws (blender -b has no UI to draw into): ("prop", name),
    ("label", text), ("operator", idname) and, for an operator's button, ("button", text)."""

    def __init__(self, log):
        self.log = log
        self.use_property_split = self.use_property_decorate = False
        self.alert = False
        self.scale_y = 1.0

    def _child(self, *args, **kwargs):
        return FakeLayout(self.log)

    row = column = box = split = _child

    def prop(self, data, prop, **kwargs):
        assert prop in data.bl_rna.properties, f"no property {prop}"
        self.log.append(("prop", prop))

    def label(self, text="", icon="NONE"):
        self.log.append(("label", text))

    def operator(self, idname, text="", icon="NONE"):
        mod, name = idname.split(".")
        getattr(getattr(bpy.ops, mod), name).get_rna_type()  # raises if not registered
        self.log.append(("operator", idname))
        self.log.append(("button", text))
        from types import SimpleNamespace

        return SimpleNamespace()


def draw_material_panel(mat, obj) -> list:
    """What the Loom material panel draws for `mat` on `obj` (a FakeLayout log)."""
    from types import SimpleNamespace

    log = []
    ctx = SimpleNamespace(material=mat, object=obj, window_manager=bpy.context.window_manager,
                          scene=bpy.context.scene, preferences=bpy.context.preferences)
    bpy.types.MATERIAL_PT_loom.draw(SimpleNamespace(layout=FakeLayout(log)), ctx)
    return log


# The operations node mode's expression builder makes (nodes_expr.op_node, Builder.call).
OPERATIONS = ("ShaderNodeMath", "ShaderNodeVectorMath", "ShaderNodeCombineXYZ",
              "ShaderNodeSeparateXYZ", "ShaderNodeClamp", "ShaderNodeMix", "ShaderNodeGroup")


def repeated_operations(tree, seen_trees=None) -> list:
    """Nodes of ``tree`` and of the groups it uses that compute what another node of the same
    tree already computes: the same operation on the same links and constants (each one more
    node that Cycles' SVM runs at every shading point). Returns "tree: node = node" strings."""
    seen_trees = set() if seen_trees is None else seen_trees
    if tree.name in seen_trees:
        return []
    seen_trees.add(tree.name)
    links = {}
    for link in tree.links:
        links[(link.to_node.name, link.to_socket.identifier)] = (link.from_node.name,
                                                                  link.from_socket.identifier)
    first, repeats = {}, []
    for n in tree.nodes:
        if n.bl_idname == "ShaderNodeGroup" and n.node_tree is not None:
            repeats += repeated_operations(n.node_tree, seen_trees)
        if n.bl_idname not in OPERATIONS:
            continue
        props = tuple(getattr(n, p, None) for p in ("operation", "data_type", "clamp_type",
                                                     "factor_mode", "clamp_factor"))
        ins = []
        for s in n.inputs:
            if (n.name, s.identifier) in links:
                ins.append(links[(n.name, s.identifier)])
            elif hasattr(s, "default_value"):
                v = s.default_value
                ins.append(tuple(v) if hasattr(v, "__len__") else v)
        key = (n.bl_idname, props, n.node_tree.name if n.bl_idname == "ShaderNodeGroup" else "",
               tuple(ins))
        if key in first:
            repeats.append(f"{tree.name}: {n.name} = {first[key]}")
        else:
            first[key] = n.name
    return repeats
