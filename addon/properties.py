"""Per-material Loom settings (Material.loom) and the bake state shown in the UI
(WindowManager.loom_bake_*)."""

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, PointerProperty, StringProperty
from bpy.types import PropertyGroup

from . import bakery, material, preferences

# `loom-bake presets`, asked once per loom-bake path. Enum item callbacks run on every redraw,
# so they must not start processes each time; Blender also requires the returned strings to
# stay referenced from Python. Cleared on unregister.
_preset_items_cache: dict = {}


def _preset_items(self, context):
    prefs = preferences.get(context)
    exe = bakery.find_loom_bake(prefs.loom_bake_path if prefs else None)
    key = exe or ""
    items = _preset_items_cache.get(key)
    if items is None:
        names = list(bakery.FALLBACK_PRESETS)
        if exe:
            try:
                names = bakery.list_presets(exe) or names
            except bakery.LoomBakeError:
                pass
        items = [(n, n.replace("_", " ").capitalize(), f"loom-bake preset '{n}'") for n in names]
        _preset_items_cache[key] = items
    return items


def _update_scale(self, context):
    """Apply a scale change to the built material without rebuilding it."""
    mat = self.id_data
    scale = self.repeats
    if self.scale_mode == "PHYSICAL":
        if not self.atlas_dir:
            return
        try:
            manifest = bakery.read_manifest(bpy.path.abspath(self.atlas_dir))
        except bakery.LoomBakeError:
            return
        scale = material.physical_repeats(context.object, manifest, self.size_factor)
    material.set_scale(mat, scale)


class LoomMaterialSettings(PropertyGroup):
    managed: BoolProperty(
        name="Managed by Loom",
        description="Loom may rebuild this material's node tree",
        default=False,
    )
    source: EnumProperty(
        name="Source",
        items=[("PRESET", "Preset", "A built-in loom-bake preset"),
               ("FILE", "Spec File", "A fabric spec (JSON, schema loom.fabric/1) or a WIF "
                "weaving draft (.wif)")],
        default="PRESET",
    )
    preset: EnumProperty(name="Preset", items=_preset_items,
                         description="Built-in fabric (listed by loom-bake presets)")
    spec_path: StringProperty(name="Spec", subtype="FILE_PATH",
                              description="Fabric spec JSON file or WIF weaving draft")
    model: EnumProperty(
        name="Model",
        items=[("SCENE", "By Scene",
                "Bake what this scene needs of the cloth: the tier from the camera (yarn and ply "
                "widths in pixels), transmission, double layer and diffraction only when "
                "something lights it from behind, multi-ply only for plied yarns"),
               ("SPEC", "As Specified", "The tier and components the spec or preset gives")],
        default="SCENE",
    )
    quality: EnumProperty(
        name="Quality",
        items=[(q, q.capitalize(), f"loom-bake --quality {q}") for q in bakery.QUALITIES],
        default="preview",
    )
    mode: EnumProperty(
        name="Mode",
        items=[("AUTO", "Auto", "OSL where this Blender and device can run it, else nodes"),
               ("OSL", "OSL", "OSL Script node (CPU or OptiX; falls back to nodes elsewhere)"),
               ("NODES", "Nodes", "Built-in Cycles nodes; runs everywhere")],
        default="AUTO",
    )
    scale_mode: EnumProperty(
        name="Scale",
        items=[("REPEATS", "Repeats", "Weave repeats per UV unit"),
               ("PHYSICAL", "Physical", "Real yarn size from the mesh's UV-to-world ratio")],
        default="PHYSICAL",
        update=_update_scale,
    )
    repeats: FloatProperty(name="Repeats per UV", default=10.0, min=1e-3, soft_max=5000.0,
                           update=_update_scale)
    size_factor: FloatProperty(name="Size Factor", default=1.0, min=1e-3, soft_max=100.0,
                               description="Magnify the physical weave by this factor",
                               update=_update_scale)
    atlas_dir: StringProperty(name="Atlas", subtype="DIR_PATH",
                              description="The atlas this material reads")
    mode_used: StringProperty(name="Mode Used")
    status: StringProperty(name="Status")
    atlas_problem: StringProperty(
        name="Atlas Problem",
        description="Why the atlas cannot render (missing, unreadable or stale), found when the "
                    "file was loaded; empty when it is sound")
    needs_report: StringProperty(name="Scene Needs",
                                 description="What Check Scene Needs found, one finding a line")


classes = (LoomMaterialSettings,)


def register_props():
    bpy.types.Material.loom = PointerProperty(type=LoomMaterialSettings)
    wm = bpy.types.WindowManager
    wm.loom_bake_running = BoolProperty(options={"SKIP_SAVE"})
    wm.loom_bake_cancel = BoolProperty(options={"SKIP_SAVE"})
    wm.loom_bake_progress = FloatProperty(name="Progress", subtype="FACTOR", min=0.0, max=1.0,
                                          options={"SKIP_SAVE"})
    wm.loom_bake_status = StringProperty(options={"SKIP_SAVE"})


def unregister_props():
    wm = bpy.types.WindowManager
    for name in ("loom_bake_status", "loom_bake_progress", "loom_bake_cancel",
                 "loom_bake_running"):
        if hasattr(wm, name):
            delattr(wm, name)
    del bpy.types.Material.loom
    _preset_items_cache.clear()
