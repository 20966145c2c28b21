"""The fiber tier in Blender: real fibers where the camera resolves them.

For a mesh with a Loom material, ``update_fibers`` finds the part of the cloth the camera sees
with fibers at least ``RESOLVED_PX`` pixels wide, asks ``loom-bake fibers`` for the fibers of
that region of the fabric (the procedural fibers of Luan et al. 2017, the same Eq. 1-4 as the
ray-wave tier), and shows them as a hair-curves object over the cloth:

* the curves are stored in fabric micrometres (x along the warp, y along the weft, z the cloth
  normal); a Geometry Nodes modifier maps each point onto the mesh through its UV map (Sample UV
  Surface: the point's UV is x, y over the weave's micrometres per UV unit) and lifts it along
  the surface normal by z, so the fibers follow the weave the material shows, the object's UV
  layout and any deformation of the mesh;
* they render with a Principled Hair BSDF (Chiang); its absorption comes from the ray-wave
  atlas's per-yarn absorption (sigma per RGB channel, per mm of fiber, scaled to Cycles' unit of
  one fiber radius), or from the yarn colour (direct colouring) with a surface atlas, which has
  no absorption data;
* nothing of the cloth's own material is touched; the fibers object is replaced on each update
  and removed when the camera resolves no fibers.

Counts are bounded: a region needing more than ``max_vertices`` vertices is refused by loom-bake
with the count it would need, and nothing in the scene changes.
"""

from __future__ import annotations

import hashlib
import json
import os
from array import array

import bpy

from . import bakery, preferences
from . import material as _material
from .bakery import LoomBakeError
from .scene_needs import pixels_per_metre

RESOLVED_PX = 0.5          # a fiber this many pixels wide or more is drawn as a curve
DEFAULT_MAX_VERTICES = 4_000_000
OBJECT_SUFFIX = " Loom Fibers"
MODIFIER = "Loom Fibers"
OWNER_PROP = "loom_fibers_of"


def loom_material(obj):
    """(material, manifest, repeats per UV unit) of obj's first Loom material with an atlas."""
    for slot in getattr(obj, "material_slots", []):
        mat = slot.material
        if mat is None or not getattr(mat, "loom", None) or not mat.loom.atlas_dir:
            continue
        try:
            manifest = bakery.read_manifest(bpy.path.abspath(mat.loom.atlas_dir))
        except LoomBakeError:
            continue
        scale = None
        if mat.use_nodes:
            for node in mat.node_tree.nodes:
                if node.name in _material.NODE_NAMES and "Scale" in node.inputs:
                    scale = float(node.inputs["Scale"].default_value)
                    break
        if scale is None:
            scale = float(mat.loom.repeats)
        return mat, manifest, scale
    return None, None, None


def _clip(poly, inside, cut):
    """One Sutherland-Hodgman pass over (point, barycentric weights) pairs: keep where
    inside(point), cut(p, q) the parameter where segment p-q crosses the boundary."""
    out = []
    for j in range(len(poly)):
        (p, wp), (q, wq) = poly[j - 1], poly[j]
        ip, iq = inside(p), inside(q)
        if ip != iq:
            t = cut(p, q)
            out.append((tuple(a + t * (b - a) for a, b in zip(p, q)),
                        tuple(a + t * (b - a) for a, b in zip(wp, wq))))
        if iq:
            out.append((q, wq))
    return out


def _view_planes(scene, camera, margin=0.02):
    """Camera-space planes (n, d), inside where n . p >= d: beyond the near clip and within the
    planes through the frame's edges (the frame grown by margin)."""
    from mathutils import Vector

    cam = camera.data
    frame = [Vector(c) for c in cam.view_frame(scene=scene)]
    centre = sum(frame, Vector()) / 4.0
    frame = [centre + (c - centre) * (1.0 + margin) for c in frame]
    planes = [(Vector((0.0, 0.0, -1.0)), max(cam.clip_start, 1e-9))]
    for i in range(4):
        c0, c1 = frame[i], frame[(i + 1) % 4]
        if cam.type == "ORTHO":
            e = c1 - c0
            n = Vector((-e.y, e.x, 0.0))
            d = n.dot(c0)
            if n.dot(centre) < d:
                n, d = -n, -d
        else:
            n, d = c0.cross(c1), 0.0
            if n.dot(centre) < 0.0:
                n = -n
        planes.append((tuple(n), d))
    planes[0] = (tuple(planes[0][0]), planes[0][1])
    return planes


def _dot(n, p):
    return n[0] * p[0] + n[1] * p[1] + n[2] * p[2]


def _visible_part(planes, eye):
    """The part of a triangle (camera-space corners ``eye``) inside the view, as barycentric
    weights of its corners: clipped in camera space, so exact for any camera."""
    poly = [(tuple(e), tuple(1.0 if k == i else 0.0 for k in range(3))) for i, e in enumerate(eye)]
    for n, d in planes:
        poly = _clip(poly, lambda p, n=n, d=d: _dot(n, p) >= d,
                     lambda p, q, n=n, d=d: (d - _dot(n, p)) / (_dot(n, q) - _dot(n, p)))
        if not poly:
            return []
    return [w for _, w in poly]


def resolved_region(obj, mesh, scene, camera, um_per_uv: float, fiber_um: float,
                    budget=150_000):
    """UV bounding box (u0, v0, u1, v1) of the parts of the mesh inside the camera's view whose
    fibers are at least RESOLVED_PX wide, or None; and the widest fiber footprint seen, in
    pixels. Each triangle in view is sampled on a barycentric grid (finer for meshes of few
    triangles, ``budget`` samples in all) besides the corners of its visible part; the box grows
    by one grid step so that it holds the resolved part whole. ``mesh``: obj's evaluated mesh
    (modifiers, shape keys, simulation), the surface the fibers are placed on."""
    world_per_uv = _material.uv_meters_per_unit(obj, mesh=mesh)
    if not world_per_uv:
        return None, 0.0
    m_per_um = world_per_uv / um_per_uv  # world metres per fabric micrometre
    uv = mesh.uv_layers.active.data
    mw = obj.matrix_world
    to_cam = camera.matrix_world.inverted()
    planes = _view_planes(scene, camera)
    tris = [([mw @ mesh.vertices[mesh.loops[i].vertex_index].co for i in tri.loops],
             [uv[i].uv.copy() for i in tri.loops]) for tri in mesh.loop_triangles]
    steps = max(1, min(32, int((budget / max(len(tris), 1)) ** 0.5)))
    grid = [(i / steps, j / steps) for i in range(steps + 1) for j in range(steps + 1 - i)]
    box, finest = None, 0.0
    for pw, uvs in tris:
        eye = [to_cam @ p for p in pw]
        corners = _visible_part(planes, eye)
        if not corners:
            continue  # behind the camera or outside the frame
        samples = corners + [(1.0 - i - j, i, j) for i, j in grid
                             if all(_dot(n, eye[0] * (1.0 - i - j) + eye[1] * i + eye[2] * j) >= d
                                    for n, d in planes)]
        grow_u = max(abs(uvs[1].x - uvs[0].x), abs(uvs[2].x - uvs[0].x)) / steps
        grow_v = max(abs(uvs[1].y - uvs[0].y), abs(uvs[2].y - uvs[0].y)) / steps
        for w in samples:
            p = pw[0] * w[0] + pw[1] * w[1] + pw[2] * w[2]
            px = pixels_per_metre(scene, camera, p) * fiber_um * m_per_um
            finest = max(finest, px)
            if px < RESOLVED_PX:
                continue
            u = uvs[0].x * w[0] + uvs[1].x * w[1] + uvs[2].x * w[2]
            v = uvs[0].y * w[0] + uvs[1].y * w[1] + uvs[2].y * w[2]
            tb = (u - grow_u, v - grow_v, u + grow_u, v + grow_v)
            box = tb if box is None else (min(box[0], tb[0]), min(box[1], tb[1]),
                                          max(box[2], tb[2]), max(box[3], tb[3]))
    return box, finest


def fibers_object(obj):
    for o in bpy.data.objects:
        if o.get(OWNER_PROP) == obj.name and o.type == "CURVES":
            return o
    return None


def remove_fibers(obj) -> bool:
    """Remove obj's fibers object (and its data and node group); True if there was one."""
    fo = fibers_object(obj)
    if fo is None:
        return False
    data = fo.data
    mod = fo.modifiers.get(MODIFIER)
    group = mod.node_group if mod is not None else None
    bpy.data.objects.remove(fo)
    _remove_unused(data, group)
    return True


def ev_uv_name(obj) -> str:
    """The UV map the fibers are placed through: the mesh's active one."""
    return obj.data.uv_layers.active.name


def _remove_unused(curves, group) -> None:
    """Remove a replaced Curves data-block (with its hair materials) and node group once nothing
    uses them."""
    if curves is not None and curves.users == 0:
        mats = [m for m in curves.materials if m is not None]
        bpy.data.hair_curves.remove(curves)
        for m in mats:
            if m.users == 0:
                bpy.data.materials.remove(m)
    if group is not None and group.users == 0:
        bpy.data.node_groups.remove(group)


def _read(path: str, typecode: str) -> array:
    a = array(typecode)
    with open(path, "rb") as f:
        a.frombytes(f.read())
    return a


def _hair_material(name: str, manifest: dict, yarn: str):
    """Principled Hair BSDF (Chiang) for one yarn system (a new material; the caller removes
    the one it replaces)."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    hair = nt.nodes.new("ShaderNodeBsdfHairPrincipled")
    if hasattr(hair, "model"):
        hair.model = "CHIANG"
    spec = manifest.get("spec", {}).get(yarn, {})
    if "IOR" in hair.inputs and "ior" in spec:
        hair.inputs["IOR"].default_value = float(spec["ior"])
    absorption = (manifest.get("raywave", {}).get("yarns", {}).get(yarn, {})
                  .get("absorption", {}).get("sigma_rgb_per_mm"))
    radius_mm = 0.5e-3 * float(spec.get("fiber_diameter_um", 15.0))
    if absorption:
        hair.parametrization = "ABSORPTION"
        hair.inputs["Absorption Coefficient"].default_value = [float(s) * radius_mm
                                                               for s in absorption]
        mat["loom_absorption"] = "ray-wave atlas sigma_rgb_per_mm x fiber radius"
    else:
        hair.parametrization = "COLOR"
        colours = manifest.get("yarn_colours_linear", {})
        rgb = colours.get(yarn) or colours.get("warp") or [0.5, 0.5, 0.5]
        hair.inputs["Color"].default_value = (*[float(c) for c in rgb[:3]], 1.0)
        mat["loom_absorption"] = "yarn colour (direct colouring; a surface atlas has none)"
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(hair.outputs[0], out.inputs["Surface"])
    return mat


def _surface_group(name: str, surface, uv_name: str, uv_per_um: float, height_per_um: float):
    """Geometry Nodes: fabric-micrometre curve points onto the surface through its UV map (a new
    group; the caller removes the one it replaces)."""
    ng = bpy.data.node_groups.new(name, "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    n, link = ng.nodes, ng.links.new
    gi, go = n.new("NodeGroupInput"), n.new("NodeGroupOutput")
    info = n.new("GeometryNodeObjectInfo")
    info.transform_space = "RELATIVE"
    info.inputs["Object"].default_value = surface
    uvattr = n.new("GeometryNodeInputNamedAttribute")
    uvattr.data_type = "FLOAT_VECTOR"
    uvattr.inputs["Name"].default_value = uv_name
    pos = n.new("GeometryNodeInputPosition")
    sep = n.new("ShaderNodeSeparateXYZ")
    link(pos.outputs[0], sep.inputs[0])
    mul = []
    for i, f in ((0, uv_per_um), (1, uv_per_um), (2, height_per_um)):
        m = n.new("ShaderNodeMath")
        m.operation = "MULTIPLY"
        link(sep.outputs[i], m.inputs[0])
        m.inputs[1].default_value = f
        mul.append(m)
    uvc = n.new("ShaderNodeCombineXYZ")
    link(mul[0].outputs[0], uvc.inputs[0])
    link(mul[1].outputs[0], uvc.inputs[1])
    samples = []
    for value in (n.new("GeometryNodeInputPosition"), n.new("GeometryNodeInputNormal")):
        s = n.new("GeometryNodeSampleUVSurface")
        s.data_type = "FLOAT_VECTOR"
        link(info.outputs["Geometry"], s.inputs[0])
        link(value.outputs[0], s.inputs[1])
        link(uvattr.outputs["Attribute"], s.inputs[2])
        link(uvc.outputs[0], s.inputs[3])
        samples.append(s)
    nrm = n.new("ShaderNodeVectorMath")
    nrm.operation = "NORMALIZE"
    link(samples[1].outputs[0], nrm.inputs[0])
    lift = n.new("ShaderNodeVectorMath")
    lift.operation = "SCALE"
    link(nrm.outputs[0], lift.inputs[0])
    link(mul[2].outputs[0], lift.inputs["Scale"])
    add = n.new("ShaderNodeVectorMath")
    add.operation = "ADD"
    link(samples[0].outputs[0], add.inputs[0])
    link(lift.outputs[0], add.inputs[1])
    # Points off the UV map (outside every face) are dropped, the rest placed.
    invalid = n.new("FunctionNodeBooleanMath")
    invalid.operation = "NOT"
    link(samples[0].outputs[1], invalid.inputs[0])
    # (Deleted first: every field here reads the points' fabric-micrometre positions.)
    drop = n.new("GeometryNodeDeleteGeometry")
    drop.domain = "POINT"
    link(gi.outputs[0], drop.inputs["Geometry"])
    link(invalid.outputs[0], drop.inputs["Selection"])
    setp = n.new("GeometryNodeSetPosition")
    link(drop.outputs[0], setp.inputs["Geometry"])
    link(add.outputs[0], setp.inputs["Position"])
    link(setp.outputs[0], go.inputs[0])
    return ng


def update_fibers(obj, scene=None, camera=None, loom_bake: str | None = None,
                  cache_dir: str | None = None, max_vertices: int = DEFAULT_MAX_VERTICES,
                  timeout: float = 600.0) -> dict:
    """Realize the fibers the camera resolves on ``obj`` (see the module doc) and return what was
    done: ``curves``, ``vertices``, ``hair_curves``, ``region_um``, ``finest_px`` (the widest
    fiber footprint seen), ``object`` (the fibers object's name, or None), ``bytes`` (what was
    loaded) and ``reason``.

    Raises LoomBakeError (nothing in the scene changed) when obj has no Loom material or UV map,
    or loom-bake refuses the region (its message, e.g. over ``max_vertices``)."""
    scene = scene or bpy.context.scene
    camera = camera or scene.camera
    if obj is None or obj.type != "MESH":
        raise LoomBakeError("fibers: the object must be a mesh with a Loom material")
    if camera is None:
        raise LoomBakeError("fibers: the scene has no camera")
    bpy.context.view_layer.update()  # current object and camera matrices
    mat, manifest, repeats = loom_material(obj)
    if mat is None:
        raise LoomBakeError(f"fibers: {obj.name} has no Loom material with a readable atlas")
    if obj.data.uv_layers.active is None:
        raise LoomBakeError(f"fibers: {obj.name} has no UV map")
    size_um = float(manifest.get("repeat", {}).get("size_um", [0.0])[0])
    if size_um <= 0.0 or repeats <= 0.0:
        raise LoomBakeError("fibers: the atlas's repeat size or the material's scale is not set")
    um_per_uv = repeats * size_um
    spec = manifest.get("spec", {})
    fiber_um = min(float(spec.get(y, {}).get("fiber_diameter_um", 15.0)) for y in ("warp", "weft"))
    dg = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(dg)
    ev_mesh = ev.to_mesh()
    try:
        if ev_mesh.uv_layers.active is None:
            raise LoomBakeError(f"fibers: {obj.name}'s evaluated mesh has no UV map")
        box, finest = resolved_region(obj, ev_mesh, scene, camera, um_per_uv, fiber_um)
        # Object-space metres per fabric micrometre on the evaluated surface (the modifier works
        # in the fibers object's space, the surface's: RELATIVE object info, parented with
        # identity).
        local_per_uv = _material.uv_meters_per_unit(obj, local=True, mesh=ev_mesh)
    finally:
        ev.to_mesh_clear()
    result = {"curves": 0, "vertices": 0, "hair_curves": 0, "region_um": None,
              "finest_px": finest, "object": None, "bytes": 0}
    if box is None:
        removed = remove_fibers(obj)
        result["reason"] = (f"no fibers: the camera resolves none (the widest is {finest:.3g} px, "
                            f"below {RESOLVED_PX} px)" + ("; removed the old ones" if removed else ""))
        return result
    region = [box[0] * um_per_uv, box[1] * um_per_uv, box[2] * um_per_uv, box[3] * um_per_uv]
    exe = bakery.require_loom_bake(loom_bake)
    cache = cache_dir or bakery.default_cache_dir()
    os.makedirs(cache, exist_ok=True)
    spec_json = json.dumps(spec, sort_keys=True)
    st = os.stat(exe)  # another loom-bake may realize other fibers: not the same cache entry
    key = hashlib.sha256((spec_json + json.dumps([round(r, 3) for r in region]) +
                          f"{st.st_size}:{st.st_mtime_ns}").encode())
    out_dir = os.path.join(cache, "fibers-" + key.hexdigest()[:16])
    spec_path = os.path.join(cache, "fibers-spec-" + hashlib.sha256(spec_json.encode())
                             .hexdigest()[:16] + ".json")
    with open(spec_path, "w") as f:
        f.write(spec_json)
    if not os.path.isfile(os.path.join(out_dir, "manifest.json")):
        bakery.run_loom_bake(exe, ["fibers", "--spec", spec_path, "--region",
                                   ",".join(f"{r:.6f}" for r in region), "--out", out_dir,
                                   "--max-vertices", str(int(max_vertices))], timeout=timeout)
    with open(os.path.join(out_dir, "manifest.json")) as f:
        fm = json.load(f)
    points = _read(os.path.join(out_dir, "points.f32"), "f")
    first = _read(os.path.join(out_dir, "first.u32"), "I")
    radius = _read(os.path.join(out_dir, "radius.f32"), "f")
    warp = _read(os.path.join(out_dir, "warp.u8"), "B")
    n = len(first) - 1
    if n <= 0:
        remove_fibers(obj)
        result["reason"] = "no fibers in the region"
        return result

    if not local_per_uv:
        raise LoomBakeError(f"fibers: {obj.name}'s UV map has no area")
    m_per_um = local_per_uv / um_per_uv
    # Build everything new first; only then swap it in and remove what it replaces, so that a
    # failure on the way leaves the scene as it was.
    new = {"curves": None, "materials": [], "group": None}
    try:
        curves = new["curves"] = bpy.data.hair_curves.new(obj.name + OBJECT_SUFFIX)
        curves.add_curves([first[i + 1] - first[i] for i in range(n)])
        curves.position_data.foreach_set("vector", points)
        rad = curves.attributes.get("radius") or curves.attributes.new("radius", "FLOAT", "POINT")
        per_point = array("f")
        for i in range(n):
            per_point.extend([radius[i] * m_per_um] * (first[i + 1] - first[i]))
        rad.data.foreach_set("value", per_point)
        mi = curves.attributes.new("material_index", "INT", "CURVE")
        mi.data.foreach_set("value", [0 if w else 1 for w in warp])
        for yarn in ("warp", "weft"):
            hm = _hair_material(f"{mat.name} Fibers ({yarn})", manifest, yarn)
            new["materials"].append(hm)
            curves.materials.append(hm)
        new["group"] = _surface_group(obj.name + OBJECT_SUFFIX, obj, ev_uv_name(obj),
                                      1.0 / um_per_uv, m_per_um)
    except Exception:
        if new["curves"] is not None:
            bpy.data.hair_curves.remove(new["curves"])
        for hm in new["materials"]:
            bpy.data.materials.remove(hm)
        if new["group"] is not None:
            bpy.data.node_groups.remove(new["group"])
        raise

    fo = fibers_object(obj)
    old_curves, old_group = None, None
    if fo is None:
        fo = bpy.data.objects.new(obj.name + OBJECT_SUFFIX, new["curves"])
        for coll in obj.users_collection:
            coll.objects.link(fo)
        fo[OWNER_PROP] = obj.name
    else:
        old_curves = fo.data
        fo.data = new["curves"]
    fo["loom_fibers_cache"] = cache
    fo["loom_fibers_max_vertices"] = int(max_vertices)
    fo.parent = obj
    fo.matrix_parent_inverse.identity()
    fo.matrix_basis.identity()
    mod = fo.modifiers.get(MODIFIER) or fo.modifiers.new(MODIFIER, "NODES")
    old_group = mod.node_group
    mod.node_group = new["group"]
    _remove_unused(old_curves, old_group)
    loaded = sum(os.path.getsize(os.path.join(out_dir, f)) for f in os.listdir(out_dir))
    result.update(curves=n, vertices=len(points) // 3, hair_curves=int(fm.get("hair_curves", 0)),
                  region_um=region, object=fo.name, bytes=loaded,
                  reason=f"{n} fibers ({len(points) // 3} vertices, {loaded / 2**20:.1f} MiB) where "
                         f"the camera resolves them (up to {finest:.3g} px wide)")
    return result


# ------------------------------------------------------------------ following the camera


def update_all(scene, loom_bake: str | None = None) -> list[dict]:
    """Update the fibers of every object in ``scene`` that has them (for the camera as it is
    now), with the cache and budget each was made with. Errors are reported, not raised: a
    render must not fail because a region could not be realized (its old fibers stay)."""
    results = []
    owners = [o.get(OWNER_PROP) for o in scene.objects if o.type == "CURVES" and o.get(OWNER_PROP)]
    for name in owners:
        obj = bpy.data.objects.get(name)
        fo = fibers_object(obj) if obj is not None else None
        if fo is None:
            continue
        try:
            results.append(update_fibers(obj, scene, loom_bake=loom_bake,
                                         cache_dir=fo.get("loom_fibers_cache"),
                                         max_vertices=int(fo.get("loom_fibers_max_vertices",
                                                                 DEFAULT_MAX_VERTICES))))
        except (LoomBakeError, OSError) as exc:
            print(f"loom: fibers of {name} not updated: {exc}")
    return results


def _render_pre(scene, *_args):
    """render_pre handler: with Scene.loom_fibers_follow_camera, fibers follow the camera of
    each frame rendered."""
    if not getattr(scene, "loom_fibers_follow_camera", False):
        return
    if not bpy.app.background and not scene.render.use_lock_interface:
        # Interactive renders run beside the interface: changing data then is unsafe.
        print("loom: Fibers Follow Camera needs Render > Lock Interface for interactive renders; "
              "fibers not updated")
        return
    for r in update_all(scene, preferences.find_loom_bake()):
        print(f"loom: {r['reason']}")


_render_pre_handler = bpy.app.handlers.persistent(_render_pre)


def register() -> None:
    bpy.types.Scene.loom_fibers_follow_camera = bpy.props.BoolProperty(
        name="Fibers Follow Camera",
        description="Before each render, realize again the fibers of every cloth that has them "
                    "for the camera of that frame",
        default=False)
    if _render_pre_handler not in bpy.app.handlers.render_pre:
        bpy.app.handlers.render_pre.append(_render_pre_handler)


def unregister() -> None:
    if _render_pre_handler in bpy.app.handlers.render_pre:
        bpy.app.handlers.render_pre.remove(_render_pre_handler)
    if hasattr(bpy.types.Scene, "loom_fibers_follow_camera"):
        del bpy.types.Scene.loom_fibers_follow_camera
