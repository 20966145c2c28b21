"""Loom: physically based woven cloth for Blender's Cycles.

A material panel bakes a fabric spec with the ``loom-bake`` command into an *atlas* (textures
plus manifest.json) and builds a material from it, either as an OSL Script node (where OSL can
run) or as a node group of Cycles' built-in nodes ("node mode"). Scripts and CI use ``loom.api``.
"""

import sys

import bpy

from . import (api, atlas_check, collect, fibers, operators, osl_paths, preferences, properties,
               ui)

_classes = (*preferences.classes, *properties.classes, *operators.classes, *collect.classes,
            *ui.classes)
_register_classes, _unregister_classes = bpy.utils.register_classes_factory(_classes)

# Scripts and CI write `import loom.api`; installed as an extension this package is
# `bl_ext.<repository>.loom`, so the short names are aliased while the add-on is enabled (and
# only if nothing else owns them).
_ALIASES = {"loom": sys.modules[__name__], "loom.api": api}


def register():
    _register_classes()
    properties.register_props()
    osl_paths.register()
    atlas_check.register()
    fibers.register()
    bpy.types.TOPBAR_MT_file_import.append(operators.menu_import)
    bpy.types.TOPBAR_MT_file_external_data.append(collect.menu_external_data)
    for name, module in _ALIASES.items():
        if __name__ != "loom":
            sys.modules.setdefault(name, module)


def unregister():
    for name, module in _ALIASES.items():
        if __name__ != "loom" and sys.modules.get(name) is module:
            del sys.modules[name]
    bpy.types.TOPBAR_MT_file_external_data.remove(collect.menu_external_data)
    bpy.types.TOPBAR_MT_file_import.remove(operators.menu_import)
    fibers.unregister()
    atlas_check.unregister()
    osl_paths.unregister()
    properties.unregister_props()
    _unregister_classes()
    api._last.clear()
