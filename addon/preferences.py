"""Add-on preferences: where loom-bake is and where atlases are cached."""

import bpy
from bpy.props import StringProperty
from bpy.types import AddonPreferences

from . import bakery


class LoomPreferences(AddonPreferences):
    bl_idname = __package__

    loom_bake_path: StringProperty(
        name="loom-bake",
        description="Path of the loom-bake executable; empty: $LOOM_BAKE, then the one this "
                    "package carries, then loom-bake on PATH",
        subtype="FILE_PATH",
        default="",
    )
    cache_dir: StringProperty(
        name="Atlas Cache",
        description="Directory where baked atlases are kept, one sub-directory per spec and "
                    "quality",
        subtype="DIR_PATH",
        default=bakery.default_cache_dir(),
    )

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "loom_bake_path")
        exe = bakery.find_loom_bake(self.loom_bake_path or None)
        row = layout.row()
        if exe:
            row.label(text=f"Using {exe}", icon="CHECKMARK")
        else:
            row.alert = True
            row.label(text="loom-bake not found (set the path, $LOOM_BAKE, or PATH)", icon="ERROR")
        layout.prop(self, "cache_dir")


def get(context=None):
    """The preferences, or None when the add-on is not registered (e.g. imported by a test)."""
    context = context or bpy.context
    addon = context.preferences.addons.get(__package__)
    return addon.preferences if addon is not None else None


def find_loom_bake(loom_bake: str | None = None) -> str | None:
    """loom-bake from the argument, the add-on preference, $LOOM_BAKE or PATH."""
    if loom_bake:
        return bakery.find_loom_bake(loom_bake)
    p = get()
    return bakery.find_loom_bake(p.loom_bake_path if p is not None else None)


classes = (LoomPreferences,)
