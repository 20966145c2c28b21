"""Collect Atlases: copy every atlas the .blend's Loom materials read next to it, into
``//loom/<atlas>/``, and point the materials there with paths relative to the .blend, so that
the .blend and its folder can move to another machine (a render farm) and render there with the
add-on installed, in OSL and in node mode alike.

What points at an atlas, and is rewritten: the node-mode images (their file paths, relative),
the node groups' ``loom_atlas`` (absolute: atlas_check also finds a moved atlas through the
images), the OSL Script nodes' atlas property (relative; osl_paths resolves it before every
render) and ``Material.loom.atlas_dir`` (relative). Atlases of linked (library) materials are
left alone. A copy is made in a temporary folder and renamed into place, so an interrupted
collect leaves no half atlas under the final name.
"""

import os
import shutil

import bpy
from bpy.types import Operator

from . import atlas_check, bakery, material, osl_paths

FOLDER = "loom"


class CollectError(RuntimeError):
    pass


def _manifest_key(atlas_dir: str):
    try:
        m = bakery.read_manifest(atlas_dir)
        return (m.get("bake_key") or m.get("spec_sha256")) if isinstance(m, dict) else None
    except bakery.LoomBakeError:
        return None


def atlases_in_use() -> dict:
    """{absolute atlas directory: [materials reading it]} over the file's own Loom materials."""
    found = {}
    for mat in bpy.data.materials:
        if mat.library is not None or not material.is_loom_material(mat):
            continue
        node = atlas_check.loom_node(mat)
        atlas = atlas_check.atlas_of(node)[0] if node is not None else None
        if atlas:
            found.setdefault(os.path.normpath(os.path.abspath(atlas)), []).append(mat)
    return found


def _copy_atlas(src: str, dest: str) -> bool:
    """Copy the atlas ``src`` to ``dest`` (published by a rename); False when ``dest`` already
    holds the same bake."""
    if os.path.isdir(dest) and _manifest_key(dest) is not None and \
            _manifest_key(dest) == _manifest_key(src):
        return False
    tmp = dest + ".collecting"
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        shutil.copytree(src, tmp)
        if os.path.exists(dest):
            shutil.rmtree(dest)  # another bake of this name: the materials read src's now
        os.replace(tmp, dest)
    except OSError as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        raise CollectError(f"copying {src} to {dest} failed: {exc}") from exc
    return True


def _repoint(mat, src: str, dest: str, rel: str) -> None:
    """Make ``mat``'s Loom nodes read ``dest`` instead of ``src``."""
    tree = mat.node_tree
    for img in atlas_check.images_of(tree):
        path = os.path.normpath(bpy.path.abspath(img.filepath))
        if path.startswith(src + os.sep):
            img.filepath = bpy.path.relpath(dest + path[len(src):])
    for group in atlas_check.trees_of(tree):
        if group.get("loom_atlas") and os.path.normpath(str(group["loom_atlas"])) == src:
            group["loom_atlas"] = dest
    for node in tree.nodes:
        if node.bl_idname == "ShaderNodeScript" and osl_paths.ATLAS_PROP in node:
            node[osl_paths.ATLAS_PROP] = rel
    if hasattr(mat, "loom"):
        mat.loom.atlas_dir = rel


def collect_atlases() -> list:
    """Copy every atlas in use to //loom/<atlas>/ and repoint its materials; returns
    [(source, destination, copied, [material names])]. The .blend must have been saved (its
    folder is where the atlases go); save it afterwards to keep the new paths."""
    if not bpy.data.filepath:
        raise CollectError("save the .blend first: the atlases go into a folder beside it")
    base = os.path.join(os.path.dirname(bpy.data.filepath), FOLDER)
    used = atlases_in_use()
    missing = [a for a in used if not os.path.isfile(os.path.join(a, "manifest.json"))]
    if missing:
        raise CollectError(f"atlas not found: {missing[0]} (used by "
                           f"{', '.join(m.name for m in used[missing[0]])}): re-bake first")
    os.makedirs(base, exist_ok=True)
    done = []
    for src, mats in sorted(used.items()):
        dest = os.path.join(base, os.path.basename(src))
        copied = False if src == os.path.normpath(dest) else _copy_atlas(src, dest)
        rel = f"//{FOLDER}/{os.path.basename(src)}"
        for mat in mats:
            _repoint(mat, src, os.path.normpath(dest), rel)
        done.append((src, dest, copied, [m.name for m in mats]))
    osl_paths.refresh()
    return done


class LOOM_OT_collect_atlases(Operator):
    """Copy every atlas this file's Loom materials read into a "loom" folder beside the .blend
    and make their paths relative, so that the .blend and that folder can move to another
    machine (a render farm) together"""

    bl_idname = "loom.collect_atlases"
    bl_label = "Collect Loom Atlases"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        if not bpy.data.filepath:
            cls.poll_message_set("Save the .blend first: the atlases go into a folder beside it")
            return False
        return True

    def execute(self, context):
        try:
            done = collect_atlases()
        except CollectError as exc:
            self.report({"ERROR"}, f"Loom: {exc}")
            return {"CANCELLED"}
        if not done:
            self.report({"INFO"}, "Loom: no Loom material reads an atlas")
            return {"CANCELLED"}
        copied = sum(1 for d in done if d[2])
        self.report({"INFO"}, f"Loom: {len(done)} atlas(es) in //{FOLDER}/ ({copied} copied); "
                              "save the .blend to keep the new paths")
        return {"FINISHED"}


def menu_external_data(self, context):
    self.layout.separator()
    self.layout.operator(LOOM_OT_collect_atlases.bl_idname, icon="PACKAGE")
    self.layout.operator("loom.bake_all", icon="RENDERLAYERS")


classes = (LOOM_OT_collect_atlases,)
