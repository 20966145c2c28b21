"""Atlas paths of OSL Script nodes, made absolute at render time.

An OSL shader reads its textures by file name (string inputs), which Blender does not relocate
the way it does image datablocks. Each Loom Script node therefore keeps its atlas directory in a
custom property, relative to the .blend once it has been saved (``//atlas``), and the texture
inputs are rewritten to absolute paths right before every render and after a file is loaded:
moving a .blend together with its atlas folder keeps working.
"""

import os

import bpy
from bpy.app.handlers import persistent

ATLAS_PROP = "loom_atlas"  # the atlas directory, "//"-relative once the .blend is saved
FILES_PROP = "loom_files"  # shader input name -> file name inside the atlas


def remember(script, atlas_dir: str, files: dict) -> None:
    """Record where ``script``'s textures live (called when the node is built)."""
    script[ATLAS_PROP] = bpy.path.relpath(atlas_dir) if bpy.data.filepath else atlas_dir
    script[FILES_PROP] = dict(files)


def resolve(stored: str, blend_path: str) -> str:
    """The absolute atlas directory for a stored path ('//'-relative to ``blend_path``'s folder,
    or absolute)."""
    if stored.startswith("//"):
        base = os.path.dirname(blend_path) if blend_path else os.getcwd()
        return os.path.normpath(os.path.join(base, stored[2:]))
    return os.path.abspath(stored)


def _loom_scripts():
    for mat in bpy.data.materials:
        if mat.node_tree is None:
            continue
        for node in mat.node_tree.nodes:
            if node.bl_idname == "ShaderNodeScript" and ATLAS_PROP in node:
                yield node


def refresh(*_args) -> int:
    """Rewrite every Loom Script node's texture inputs as absolute paths; returns how many."""
    n = 0
    for node in _loom_scripts():
        atlas = resolve(str(node[ATLAS_PROP]), bpy.data.filepath)
        for name, file in node[FILES_PROP].items():
            if name in node.inputs:
                node.inputs[name].default_value = os.path.join(atlas, str(file))
        n += 1
    return n


def make_relative(*_args) -> None:
    """After a save, store atlas paths relative to the .blend (so it can move with its atlas)."""
    if not bpy.data.filepath:
        return
    for node in _loom_scripts():
        stored = str(node[ATLAS_PROP])
        if not stored.startswith("//"):
            try:
                node[ATLAS_PROP] = bpy.path.relpath(stored)
            except ValueError:  # another drive (Windows): keep it absolute
                pass


_refresh = persistent(refresh)
_make_relative = persistent(make_relative)
_HANDLERS = (("render_pre", _refresh), ("load_post", _refresh), ("save_post", _make_relative))


def register() -> None:
    for name, fn in _HANDLERS:
        lst = getattr(bpy.app.handlers, name)
        if fn not in lst:
            lst.append(fn)


def unregister() -> None:
    for name, fn in _HANDLERS:
        lst = getattr(bpy.app.handlers, name)
        if fn in lst:
            lst.remove(fn)
