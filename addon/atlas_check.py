"""What a Loom material finds when its .blend opens: is its atlas still there, and still the one
it was built from?

An atlas lives outside the .blend (a folder of textures and manifest.json). When a file is
loaded, each material Loom built is checked:
  * missing: the atlas folder, its manifest.json or one of the texture files it lists is gone;
  * unreadable: the manifest is not JSON, or of another schema than this add-on reads;
  * stale: the atlas was re-baked from another spec since the material was built (its
    spec_sha256 differs from the one the material's node group or Script node recorded), so its
    textures no longer match the constants the node tree was built with.
Such a material renders a plain fallback, a Principled BSDF with sheen in the fabric's colour,
instead of magenta missing textures or a wrong BSDF: the fallback node is added and feeds every
Material Output in place of what fed it, and nothing of the tree is removed (the Loom node and
whatever the user put between it and the output stay, unlinked from the output). The
reason is in the material's Loom panel (``mat.loom.atlas_problem``) with a Re-bake button
(Bake & Assign: it rebuilds the material's nodes), and printed. When a later load finds the
atlas sound again, each output gets back exactly what fed it and the fallback goes.
"""

import json
import os

import bpy
from bpy.app.handlers import persistent

from . import material, osl_paths

FALLBACK_NODE = "Loom Fallback"
ATLAS_SCHEMA_PREFIX = "loom.atlas/"


def loom_node(mat):
    """The node of ``mat`` that Loom built (group or Script), or None."""
    if mat is None or mat.node_tree is None:
        return None
    for name in material.NODE_NAMES:
        node = mat.node_tree.nodes.get(name)
        if node is not None:
            return node
    return None


def atlas_of(node):
    """(atlas directory, recorded spec hash) of a Loom node; either may be None."""
    if node.bl_idname == "ShaderNodeScript":
        stored = node.get(osl_paths.ATLAS_PROP)
        atlas = osl_paths.resolve(str(stored), bpy.data.filepath) if stored else None
        return atlas, node.get(material.SPEC_PROP)
    group = getattr(node, "node_tree", None)
    if group is None:
        return None, None
    atlas = group.get("loom_atlas")
    atlas = str(atlas) if atlas else None
    if atlas is None or not os.path.isdir(atlas):
        # The .blend and its atlas may have moved together: the images (paths relative to the
        # .blend once saved) say where the atlas is now.
        for img in images_of(group):
            path = bpy.path.abspath(img.filepath)
            folder = os.path.dirname(path)
            if os.path.isfile(os.path.join(folder, "manifest.json")):
                atlas = folder
                break
    return atlas, group.get(material.SPEC_PROP)


def trees_of(tree, seen=None):
    """The node tree and every group tree under it, each once."""
    seen = set() if seen is None else seen
    if tree is None or tree.name in seen:
        return
    seen.add(tree.name)
    yield tree
    for n in tree.nodes:
        if n.bl_idname == "ShaderNodeGroup":
            yield from trees_of(n.node_tree, seen)


def images_of(tree):
    """Every image a node tree reads, its groups' included."""
    for t in trees_of(tree):
        for n in t.nodes:
            if n.bl_idname == "ShaderNodeTexImage" and n.image is not None:
                yield n.image


def atlas_problem(atlas_dir, spec_sha256) -> str | None:
    """Why a material built from ``atlas_dir`` (spec hash ``spec_sha256``, if recorded) cannot
    render it now, or None."""
    if not atlas_dir:
        return "missing: the material does not say which atlas it was built from"
    if not os.path.isdir(atlas_dir):
        return f"missing: {atlas_dir} does not exist"
    path = os.path.join(atlas_dir, "manifest.json")
    try:
        with open(path, encoding="utf-8") as f:
            manifest = json.load(f)
    except OSError:
        return f"missing: {path} cannot be read"
    except ValueError as exc:
        return f"unreadable: {path} is not valid JSON ({exc})"
    if not isinstance(manifest, dict):
        return f"unreadable: {path} is not a JSON object"
    schema = str(manifest.get("schema", ""))
    if not schema.startswith(ATLAS_SCHEMA_PREFIX):
        return f"unreadable: {path} has schema {schema!r}, not a Loom atlas"
    textures = manifest.get("textures")
    if not isinstance(textures, dict):
        return f"unreadable: {path} lists no textures"
    gone = []
    for name, tex in textures.items():
        if not isinstance(tex, dict):
            return f"unreadable: {path}: texture {name!r} is not an object"
        for key in ("file", "node_file"):
            file = tex.get(key)
            if isinstance(file, str) and not os.path.isfile(os.path.join(atlas_dir, file)):
                gone.append(file)
    if gone:
        more = f" and {len(gone) - 3} more" if len(gone) > 3 else ""
        return f"missing: {', '.join(sorted(gone)[:3])}{more} in {atlas_dir}"
    have = str(manifest.get("spec_sha256", ""))
    if spec_sha256 and have != str(spec_sha256):
        return (f"stale: {atlas_dir} was re-baked from another spec since this material was "
                f"built (spec {have[:12]}, the material's {str(spec_sha256)[:12]})")
    return None


def material_problem(mat) -> str | None:
    node = loom_node(mat)
    if node is None:
        return None  # not built yet, or built by hand: nothing to check
    if node.bl_idname != "ShaderNodeScript":
        imgs = list(images_of(getattr(node, "node_tree", None)))
        if imgs and all(i.packed_file is not None for i in imgs):
            return None  # packed (File > External Data > Pack Resources): the maps are in the file
    return atlas_problem(*atlas_of(node))


PREV_PROP = "loom_replaced"  # on the fallback node: what it replaced, to put back


def _outputs(mat):
    return [n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"]


def apply_fallback(mat, reason: str) -> None:
    """Render a plain fallback in place of ``mat``'s Loom material, keeping every node: each
    Material Output's Surface is fed by the fallback instead of what fed it (recorded on the
    fallback node, so that restore() puts exactly that back)."""
    nt = mat.node_tree
    fb = nt.nodes.get(FALLBACK_NODE)
    if fb is None:
        fb = nt.nodes.new("ShaderNodeBsdfPrincipled")
        fb.name = fb.label = FALLBACK_NODE
        node = loom_node(mat)
        if node is not None:
            fb.location = (node.location.x, node.location.y - 400)
        rgb = list(mat.get(material.FALLBACK_RGB_PROP, (0.5, 0.5, 0.5)))[:3]
        fb.inputs["Base Color"].default_value = (*rgb, 1.0)
        fb.inputs["Roughness"].default_value = 0.8
        fb.inputs["Sheen Weight"].default_value = 1.0
        fb.inputs["Sheen Roughness"].default_value = 0.5
        replaced = []
        outs = _outputs(mat)
        if not outs:
            outs = [nt.nodes.new("ShaderNodeOutputMaterial")]
        for out in outs:
            links = out.inputs["Surface"].links
            if links:
                lk = links[0]
                replaced.append([out.name, lk.from_node.name, lk.from_socket.identifier])
            elif out.is_active_output or len(outs) == 1:
                replaced.append([out.name, "", ""])  # nothing fed it: unlinked again later
        fb[PREV_PROP] = replaced
        for out_name, _, _ in replaced:
            nt.links.new(fb.outputs["BSDF"], nt.nodes[out_name].inputs["Surface"])
    if hasattr(mat, "loom"):
        mat.loom.atlas_problem = reason


def restore(mat) -> bool:
    """Undo apply_fallback once the atlas is sound again: every output gets back what fed it and
    the fallback node goes. True if something changed; a fallback whose replaced nodes are gone
    (the user edited the tree) is left in place, with a message."""
    nt = mat.node_tree
    fb = nt.nodes.get(FALLBACK_NODE) if nt is not None else None
    if fb is None:
        if hasattr(mat, "loom") and mat.loom.atlas_problem:
            mat.loom.atlas_problem = ""
            return True
        return False
    replaced = [list(r) for r in fb.get(PREV_PROP, [])]
    for out_name, node_name, socket in replaced:
        out = nt.nodes.get(out_name)
        src = nt.nodes.get(node_name) if node_name else None
        if out is None or (node_name and (src is None or not any(
                o.identifier == socket for o in src.outputs))):
            if hasattr(mat, "loom"):
                mat.loom.atlas_problem = (f"sound again, but {node_name or out_name} is gone: "
                                          "connect the material by hand or Re-bake")
            return False
    for out_name, node_name, socket in replaced:
        out = nt.nodes[out_name]
        for lk in list(out.inputs["Surface"].links):
            nt.links.remove(lk)
        if node_name:
            src = nt.nodes[node_name]
            nt.links.new(next(o for o in src.outputs if o.identifier == socket),
                         out.inputs["Surface"])
    nt.nodes.remove(fb)
    if hasattr(mat, "loom"):
        mat.loom.atlas_problem = ""
    return True


def check_all(*_args) -> dict:
    """Check every material Loom built; fall back or restore. Returns {material: problem}.
    Materials linked from a library are not Loom's to change here and are skipped; one
    material's failure is printed and does not stop the others."""
    found = {}
    for mat in bpy.data.materials:
        if mat.library is not None or getattr(mat, "override_library", None) is not None:
            continue
        if not material.is_loom_material(mat) or mat.node_tree is None:
            continue
        try:
            problem = material_problem(mat)
            if problem:
                apply_fallback(mat, problem)
                found[mat.name] = problem
                print(f"loom: {mat.name}: atlas {problem}; rendering a plain fallback until it "
                      f"is re-baked (Material > Loom Cloth > Re-bake)")
            elif restore(mat):
                print(f"loom: {mat.name}: atlas found again; the Loom material is back")
        except Exception as exc:  # one material must not stop the checks of the others
            print(f"loom: {mat.name}: checking its atlas failed: {type(exc).__name__}: {exc}")
    return found


_check_all = persistent(check_all)


def register() -> None:
    if _check_all not in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.append(_check_all)


def unregister() -> None:
    if _check_all in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(_check_all)
