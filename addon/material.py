"""Building a Loom material from an atlas: mode choice (OSL or nodes), the material's node
tree, and the weave scale.

Mode choice. OSL mode runs ``osl/loom_cloth_surface.osl`` in a Script node; it needs a Cycles
built with OSL (``_cycles.with_osl``; Debian's Blender has none) and a device that runs OSL (the
CPU, or a GPU through OptiX). A Script node anywhere else renders plain black without a warning,
so it is never built there: Auto picks OSL only when it can run and says why it picked what it
did; an explicit OSL request that cannot run falls back to nodes, with the reason.
"""

from __future__ import annotations

import os

import bpy
from mathutils import Matrix

from . import manifest as _manifest, node_mode, node_mode_raywave, osl_paths, osl_source
from .bakery import LoomBakeError, read_manifest

OSL_TEXT_NAME = osl_source.SURFACE_SHADER
# The material's Loom node: the group (node mode) or the Script node (OSL mode), of either tier.
NODE_NAMES = ("Loom Surface", "Loom Surface (OSL)")
MODES = ("AUTO", "OSL", "NODES")
MANAGED_PROP = "loom"  # Material.loom (PropertyGroup) once registered; see is_loom_material
# Recorded at build for atlas_check.py: the warp yarn's linear colour (the fallback's) on the
# material, and the atlas's spec hash on the Script node (node groups record their own).
FALLBACK_RGB_PROP = "loom_fallback_rgb"
SPEC_PROP = "loom_spec_sha256"


class AssignResult:
    """What ``build_material`` did: the mode used and a sentence saying why."""

    def __init__(self, material, mode: str, reason: str, scale: float):
        self.material = material
        self.mode = mode
        self.reason = reason
        self.scale = scale

    def __repr__(self):
        return (f"AssignResult({self.material.name!r}, {self.mode}, {self.reason!r}, "
                f"scale={self.scale:g})")


# ----------------------------------------------------------------------------------- OSL checks


def osl_support(scene) -> tuple[bool, str]:
    """(can OSL run for this scene, why (not))."""
    try:
        import _cycles
    except ImportError:
        return False, "Cycles is not available"
    if not getattr(_cycles, "with_osl", False):
        return False, "this Blender's Cycles is built without OSL"
    if scene.render.engine != "CYCLES":
        return False, f"the render engine is {scene.render.engine}, not Cycles"
    if scene.cycles.device == "CPU":
        return True, "Cycles renders on the CPU, which runs OSL"
    try:
        backend = bpy.context.preferences.addons["cycles"].preferences.compute_device_type
    except (KeyError, AttributeError):
        backend = "NONE"
    if backend == "OPTIX":
        return True, "Cycles renders with OptiX, which runs OSL"
    if backend in ("NONE", ""):
        return True, "no GPU backend is configured, so Cycles renders on the CPU, which runs OSL"
    return False, (f"Cycles renders on the GPU with {backend}, which cannot run OSL "
                   f"(CPU and OptiX can)")


def resolve_mode(requested: str, scene) -> tuple[str, str]:
    """('OSL' | 'NODES', reason) for a requested mode AUTO | OSL | NODES."""
    requested = requested.upper()
    if requested not in MODES:
        raise ValueError(f"mode must be one of {', '.join(m.lower() for m in MODES)}")
    if requested == "NODES":
        return "NODES", "node mode requested"
    ok, why = osl_support(scene)
    if ok and osl_source.osl_dir() is None:
        ok, why = False, "the OSL sources are not shipped with this add-on"
    if requested == "OSL":
        return ("OSL", "OSL requested: " + why) if ok else (
            "NODES", f"OSL requested but {why}: using node mode instead")
    return ("OSL", "Auto: " + why) if ok else ("NODES", f"Auto: node mode, because {why}")


# ----------------------------------------------------------------------------------- materials


def is_loom_material(mat) -> bool:
    """A material Loom may rebuild: one it made, or a placeholder flagged by a scene script
    (``mat["loom"] = {"managed": True}``: the storage of the Material.loom property group, so
    it works before the add-on is registered, e.g. in blend/build_demo.py)."""
    if mat is None:
        return False
    group = mat.get(MANAGED_PROP)
    try:
        return bool(group and group.get("managed"))
    except AttributeError:
        return False


def mark_managed(mat) -> None:
    if hasattr(mat, "loom"):
        mat.loom.managed = True
    else:
        mat[MANAGED_PROP] = {"managed": True}


def ensure_material(obj, material=None, name: str | None = None):
    """The material to build: ``material`` if given; else the object's active material if Loom
    manages it; else a new material placed in the active slot (or appended). Non-Loom materials
    are never overwritten."""
    if material is None:
        active = obj.active_material if obj is not None else None
        if is_loom_material(active):
            material = active
        else:
            material = bpy.data.materials.new(name or "Loom Cloth")
            if obj is not None and obj.data is not None and hasattr(obj.data, "materials"):
                if len(obj.material_slots) == 0:
                    obj.data.materials.append(material)
                else:
                    obj.material_slots[obj.active_material_index].material = material
    mark_managed(material)
    return material


def _clear_tree(mat):
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    out.location = (400, 0)
    return nt, out


def check_tier(manifest: dict, atlas_dir: str) -> None:
    """Raise LoomBakeError for an atlas that cannot be shaded here (a tier the add-on does not
    know, a ray-wave atlas without render tables or from an older loom-bake): say so rather than
    render something else under its name. Called before any material or node tree is touched."""
    tier = manifest.get("tier", "surface")
    if tier == "raywave":
        problem = _manifest.raywave_problem(manifest)
        if problem:
            raise LoomBakeError(f"{atlas_dir}: ray-wave atlas: {problem}")
    elif tier != "surface":
        raise LoomBakeError(f"{atlas_dir}: {_manifest.tier_problem(tier)}")


def shader_file(manifest: dict) -> str:
    """The OSL shader of the atlas's tier."""
    if manifest.get("tier", "surface") == "raywave":
        return node_mode_raywave.SHADER
    return osl_source.SURFACE_SHADER


def build_material(mat, atlas_dir: str, mode: str = "AUTO", scale: float = 1.0, scene=None,
                   interpolation: str = "Linear") -> AssignResult:
    """Build ``mat``'s node tree for the atlas. Returns what was done."""
    scene = scene or bpy.context.scene
    atlas_dir = os.path.abspath(atlas_dir)
    manifest = read_manifest(atlas_dir)
    check_tier(manifest, atlas_dir)
    used, reason = resolve_mode(mode, scene)
    if used == "OSL":
        try:
            _build_osl(mat, atlas_dir, manifest, scale)
            scene.cycles.shading_system = True
            reason += "; enabled Open Shading Language in the scene's render settings"
        except OSLBuildError as exc:
            used, reason = "NODES", f"OSL failed ({exc}): using node mode instead"
    if used == "NODES":
        _build_nodes(mat, atlas_dir, manifest, scale, interpolation)
    # Cycles' "Bump Map Correction" changes closures whose normal differs from the shading
    # normal (n_p, N_c): glossy (and SVM translucent) normals are lifted towards the true normal
    # when their mirror direction would point below it, and diffuse lobes get the smoothed
    # shadow-terminator term. loom-bake's closure LUT (fitted GGX) and its closure emulator assume
    # Blender's default, on; set it explicitly so that a user's change cannot break the weights.
    # (Known divergence: with it on, the SVM Translucent BSDF node lifts its normal but OSL's
    # translucent() does not, so node mode's translucent(n_p) differs from OSL mode's.)
    # An atlas may state the convention its LUT was baked for (manifest "cycles").
    cycles_conv = manifest.get("cycles", {}) if isinstance(manifest.get("cycles"), dict) else {}
    mat.cycles.use_bump_map_correction = bool(cycles_conv.get("bump_map_correction", True))
    # What a later load renders if this atlas goes missing or stale (atlas_check.py).
    colours = manifest.get("yarn_colours_linear", {})
    warp = colours.get("warp") if isinstance(colours, dict) else None
    if isinstance(warp, list) and len(warp) >= 3:
        mat[FALLBACK_RGB_PROP] = [float(c) for c in warp[:3]]
    if hasattr(mat, "loom"):
        mat.loom.atlas_dir = atlas_dir
        mat.loom.mode_used = used
        mat.loom.status = reason
        mat.loom.atlas_problem = ""
    return AssignResult(mat, used, reason, scale)


def _build_nodes(mat, atlas_dir, manifest, scale, interpolation):
    raywave = manifest.get("tier", "surface") == "raywave"
    build = node_mode_raywave.build_raywave_group if raywave else node_mode.build_surface_group
    group = build(atlas_dir, manifest, interpolation=interpolation,
                  name=_unique_group_name(atlas_dir, manifest))
    nt, out = _clear_tree(mat)
    gnode = nt.nodes.new("ShaderNodeGroup")
    gnode.node_tree = group
    gnode.name = NODE_NAMES[0]
    gnode.label = group.name
    gnode.width = 260
    gnode.inputs["Scale"].default_value = scale
    nt.links.new(gnode.outputs["BSDF"], out.inputs["Surface"])


def _unique_group_name(atlas_dir: str, manifest: dict) -> str:
    """"Loom Surface (<name>)" ("Loom Ray-wave (<name>)"), unless a group of that name belongs
    to another atlas."""
    if manifest.get("tier", "surface") == "raywave":
        base = node_mode_raywave.group_name(manifest)
    else:
        base = node_mode.group_name(manifest)
    g = bpy.data.node_groups.get(base)
    if g is None or g.get("loom_atlas") in (None, atlas_dir):
        return base
    sha = str(manifest.get("spec_sha256", ""))[:8] or os.path.basename(atlas_dir)
    return f"{base[:-1]}, {sha})"


class OSLBuildError(RuntimeError):
    pass


def _osl_text(shader: str):
    src = osl_source.flattened_shader(shader)
    text = bpy.data.texts.get(shader)
    if text is None:
        text = bpy.data.texts.new(shader)
    if text.as_string() != src:
        text.from_string(src)
    text.use_fake_user = False
    return text


def _build_osl(mat, atlas_dir, manifest, scale):
    try:
        from cycles import osl as cycles_osl  # Cycles' own add-on module
    except ImportError as exc:
        raise OSLBuildError(f"cannot import Cycles' OSL helpers: {exc}") from exc
    try:
        text = _osl_text(shader_file(manifest))
    except OSError as exc:
        raise OSLBuildError(str(exc)) from exc
    nt, out = _clear_tree(mat)
    script = nt.nodes.new("ShaderNodeScript")
    script.name = NODE_NAMES[1]
    script.mode = "INTERNAL"
    script.script = text
    script.location = (100, 0)
    messages = []
    try:
        ok = cycles_osl.update_script_node(script, lambda kind, msg: messages.append(msg))
    except Exception as exc:  # Cycles' helper raises, e.g. where its OSL entry points are absent
        ok = False
        messages.append(f"{type(exc).__name__}: {exc}")
    if not ok or "BSDF" not in script.outputs:
        nt.nodes.remove(script)  # never leave a Script node that cannot run
        raise OSLBuildError("; ".join(messages) or "the shader did not compile")
    if manifest.get("tier", "surface") == "raywave":
        params, values = _manifest.raywave_osl_parameters(manifest)
        # Every ray-wave parameter matters (a texture left empty renders wrongly in silence):
        # a shader without one of them is not the shader this add-on was written for.
        missing = sorted(n for n in (*params, *values) if n not in script.inputs)
        if missing:
            nt.nodes.remove(script)
            raise OSLBuildError(f"{node_mode_raywave.SHADER} lacks the parameters "
                                f"{', '.join(missing)}")
        for name, value in values.items():
            script.inputs[name].default_value = value
    else:
        params = {name: name for name in manifest["textures"]}
        avg_tex, avg_values = _manifest.average_osl_parameters(manifest)
        params.update(avg_tex)
        for name, value in avg_values.items():
            if name in script.inputs:
                script.inputs[name].default_value = value
    files = {param: manifest["textures"][name]["file"] for param, name in params.items()
             if param in script.inputs}
    for name, file in files.items():
        script.inputs[name].default_value = os.path.join(atlas_dir, file)
    osl_paths.remember(script, atlas_dir, files)  # re-resolved before every render
    script[SPEC_PROP] = str(manifest.get("spec_sha256", ""))
    texco = nt.nodes.new("ShaderNodeTexCoord")
    texco.location = (-300, 100)
    tan = nt.nodes.new("ShaderNodeTangent")
    tan.direction_type = "UV_MAP"
    tan.location = (-300, -150)
    if "UV" in script.inputs:
        nt.links.new(texco.outputs["UV"], script.inputs["UV"])
    if "Tangent" in script.inputs:
        nt.links.new(tan.outputs["Tangent"], script.inputs["Tangent"])
    if "Scale" in script.inputs:
        script.inputs["Scale"].default_value = scale
    if "Aspect" in script.inputs:
        script.inputs["Aspect"].default_value = _manifest.repeat_aspect(manifest)
    nt.links.new(script.outputs["BSDF"], out.inputs["Surface"])


def set_scale(mat, scale: float) -> bool:
    """Change the weave scale of a built Loom material in place (no rebuild)."""
    if mat is None or not mat.use_nodes:
        return False
    for node in mat.node_tree.nodes:
        if node.name in NODE_NAMES and "Scale" in node.inputs:
            node.inputs["Scale"].default_value = scale
            return True
    return False


AVERAGE_NODES = ("Loom Average distance", "Loom Average ramp")


def set_average(mat, drive: dict) -> bool:
    """Drive a built Loom material's Average input (the repeat-averaged closures far away) as
    ``drive`` says (scene_needs.average_drive): a Camera Data distance through a Map Range, or
    a constant. The nodes it adds are named AVERAGE_NODES and replaced on the next call."""
    if mat is None or not mat.use_nodes:
        return False
    nt = mat.node_tree
    target = next((n for n in nt.nodes if n.name in NODE_NAMES and "Average" in n.inputs), None)
    if target is None:
        return False
    for name in AVERAGE_NODES:
        old = nt.nodes.get(name)
        if old is not None:
            nt.nodes.remove(old)
    socket = target.inputs["Average"]
    if drive.get("kind") != "distance":
        socket.default_value = float(drive.get("value", 0.0))
        return True
    cam = nt.nodes.new("ShaderNodeCameraData")
    cam.name = cam.label = AVERAGE_NODES[0]
    cam.location = (target.location.x - 500, target.location.y - 300)
    ramp = nt.nodes.new("ShaderNodeMapRange")
    ramp.name = AVERAGE_NODES[1]
    ramp.label = "Average: 0 near, 1 far (repeat 2 px -> 1 px)"
    ramp.location = (target.location.x - 280, target.location.y - 300)
    ramp.clamp = True
    ramp.inputs["From Min"].default_value = float(drive["near"])
    ramp.inputs["From Max"].default_value = float(drive["far"])
    ramp.inputs["To Min"].default_value = 0.0
    ramp.inputs["To Max"].default_value = 1.0
    nt.links.new(cam.outputs["View Distance"], ramp.inputs["Value"])
    nt.links.new(ramp.outputs["Result"], socket)
    return True


# ----------------------------------------------------------------------------------- scale


def uv_meters_per_unit(obj, local: bool = False, mesh=None) -> float | None:
    """World length of one UV unit on ``obj`` (sqrt of world area over UV area, summed over the
    mesh's triangles, modifiers ignored), or None without UVs or area; ``local``: in the
    object's own space instead; ``mesh``: this mesh (e.g. the evaluated one) instead of
    obj.data. Pure Python: Blender builds without numpy exist (Debian's)."""
    if mesh is None:
        mesh = obj.data if obj is not None and obj.type == "MESH" else None
    if mesh is None or mesh.uv_layers.active is None:
        return None
    mesh.calc_loop_triangles()
    m = Matrix.Identity(4) if local else obj.matrix_world
    co = [m @ v.co for v in mesh.vertices]
    uv = mesh.uv_layers.active.data
    loops = mesh.loops
    area3 = area2 = 0.0
    for tri in mesh.loop_triangles:
        l0, l1, l2 = tri.loops
        p0, p1, p2 = (co[loops[i].vertex_index] for i in (l0, l1, l2))
        area3 += 0.5 * (p1 - p0).cross(p2 - p0).length
        a, b, c = uv[l0].uv, uv[l1].uv, uv[l2].uv
        area2 += 0.5 * abs((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x))
    if area2 <= 0.0 or area3 <= 0.0:
        return None
    return (area3 / area2) ** 0.5


def uv_warning(obj) -> str | None:
    """Why the weave cannot show on ``obj`` (Loom maps the weave with the active render UV map
    and takes the warp direction from its tangent), or None."""
    if obj is None or obj.type != "MESH":
        return None
    if not obj.data.uv_layers:
        return f"{obj.name} has no UV map: the weave needs one (e.g. UV > Unwrap)"
    return None


def physical_repeats(obj, manifest: dict, size_factor: float = 1.0) -> float:
    """Repeats per UV unit that give the weave its real size (times ``size_factor``) on obj;
    the repeat's physical size is manifest["repeat"]["size_um"] (warp direction)."""
    meters = uv_meters_per_unit(obj)
    size_um = manifest.get("repeat", {}).get("size_um", [0.0])[0]
    if not meters or not size_um:
        return 1.0
    return meters / (size_um * 1e-6 * max(size_factor, 1e-9))
