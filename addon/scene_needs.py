"""What a scene requires of a Loom cloth: model only what it needs (design: "Model only what a
scene requires").

* The tier from the camera: the width in pixels of a yarn and of a ply on the cloth, at the
  object's distance from the camera and the render resolution. Yarns narrower than
  ``YARN_PX_RAYWAVE`` pixels are a texture, the surface tier; where plies are at least
  ``PLY_PX_RAYWAVE`` pixels wide the ray-wave tier's ply scattering is visible.
* The components from the lights: transmission, the double layer and aperture diffraction only
  matter when something lights the cloth from behind (relative to the camera): a light on the
  far side of the cloth's plane, or a world brighter than ``WORLD_BACKLIGHT``. Single-ply yarns
  need no multi-ply terms.

``scene_needs(obj, scene, ...)`` returns the choice with its reasons, in words, for the UI and
for scripts (``loom.api.scene_needs``); ``spec_for_needs`` turns a canonical spec into the one
that bakes only that (Bake & Assign with Model "By Scene"). Sizes in the spec are micrometres; one weave repeat
spans ``1 / repeats_per_uv`` UV units, and the object's world size per UV unit comes from its
mesh (material.uv_meters_per_unit). The cloth is taken as its mean plane (area-weighted normal
and centre) for the camera distance and for which side a light is on.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import bpy
from mathutils import Vector

from . import material

YARN_PX_RAYWAVE = 4.0
PLY_PX_RAYWAVE = 2.0
WORLD_BACKLIGHT = 0.1


@dataclass
class SceneNeeds:
    tier: str = "surface"
    transmission: bool = False
    double_layer: bool = False
    diffraction: bool = False
    multi_ply: bool = False
    yarn_px: float = 0.0
    ply_px: float = 0.0
    reasons: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        return {"tier": self.tier, "transmission": self.transmission,
                "double_layer": self.double_layer, "diffraction": self.diffraction,
                "multi_ply": self.multi_ply, "yarn_px": self.yarn_px, "ply_px": self.ply_px,
                "reasons": list(self.reasons)}


def _plane(obj):
    """Area-weighted world normal and centre of a mesh object (its mean plane)."""
    mesh = obj.data
    mesh.calc_loop_triangles()
    mw = obj.matrix_world
    co = [mw @ v.co for v in mesh.vertices]
    normal = Vector((0.0, 0.0, 0.0))
    centre = Vector((0.0, 0.0, 0.0))
    area = 0.0
    for tri in mesh.loop_triangles:
        p0, p1, p2 = (co[i] for i in tri.vertices)
        a = (p1 - p0).cross(p2 - p0) * 0.5
        normal += a
        centre += (p0 + p1 + p2) / 3.0 * a.length
        area += a.length
    if area <= 0.0:
        return Vector((0.0, 0.0, 1.0)), mw.translation.copy()
    return normal.normalized(), centre / area


def pixels_per_metre(scene, camera, point) -> float:
    """Pixels that one world unit spans at ``point``, facing the camera, in the final render."""
    r = scene.render
    scale = r.resolution_percentage / 100.0
    res_x, res_y = r.resolution_x * scale * r.pixel_aspect_x, r.resolution_y * scale * r.pixel_aspect_y
    cam = camera.data
    fit = cam.sensor_fit
    if fit == "AUTO":
        width_px, sensor = max(res_x, res_y), cam.sensor_width
    elif fit == "HORIZONTAL":
        width_px, sensor = res_x, cam.sensor_width
    else:
        width_px, sensor = res_y, cam.sensor_height
    if cam.type == "ORTHO":
        return width_px / max(cam.ortho_scale, 1e-9)
    depth = -(camera.matrix_world.inverted() @ point).z
    if depth <= 1e-9:
        return 0.0
    return width_px * cam.lens / (sensor * depth)


# The repeat-averaged closures (average_closures.h) take over where one weave repeat spans
# fewer pixels than AVERAGE_FROM_PX, fully at AVERAGE_FULL_PX and below.
AVERAGE_FROM_PX = 2.0
AVERAGE_FULL_PX = 1.0


def average_drive(obj, scene, scale: float) -> dict:
    """How a Loom material's Average input follows the camera on ``obj`` at ``scale`` repeats
    per UV unit: {"kind": "distance", "near": d, "far": d} (metres: a perspective camera, the
    averaged closures ramp in from where a repeat spans AVERAGE_FROM_PX pixels to where it
    spans AVERAGE_FULL_PX), {"kind": "constant", "value": v} (an orthographic camera: one
    footprint everywhere; or no camera or UV map: 0, every texel), with a "reason"."""
    camera = scene.camera if scene is not None else None
    meters = material.uv_meters_per_unit(obj) if obj is not None else None
    if camera is None or not meters or scale <= 0.0:
        why = "no scene camera" if camera is None else "no UV size"
        return {"kind": "constant", "value": 0.0, "reason": f"{why}: every texel shaded"}
    repeat_m = meters / scale
    _normal, centre = _plane(obj)
    ppm = pixels_per_metre(scene, camera, centre)
    if camera.data.type == "ORTHO":
        px = repeat_m * ppm
        v = min(max((AVERAGE_FROM_PX - px) / (AVERAGE_FROM_PX - AVERAGE_FULL_PX), 0.0), 1.0)
        return {"kind": "constant", "value": v,
                "reason": f"orthographic camera: a repeat spans {px:.2g} px"}
    if ppm <= 0.0:
        return {"kind": "constant", "value": 0.0, "reason": "the cloth is behind the camera"}
    # Perspective: pixels per repeat fall as 1 / distance: k / d.
    k = repeat_m * ppm * (centre - camera.matrix_world.translation).length
    return {"kind": "distance", "near": k / AVERAGE_FROM_PX, "far": k / AVERAGE_FULL_PX,
            "reason": f"a repeat spans {AVERAGE_FROM_PX:g} px at {k / AVERAGE_FROM_PX:.3g} m "
                      f"from the camera"}


def _luminance(c) -> float:
    return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]


def _world_strength(world) -> float:
    if world is None:
        return 0.0
    if world.use_nodes and world.node_tree is not None:
        best = 0.0
        for node in world.node_tree.nodes:
            if node.type == "BACKGROUND":
                col, strength = node.inputs["Color"], node.inputs["Strength"]
                # A linked colour (an environment texture) counts as unit brightness.
                lum = 1.0 if col.is_linked else _luminance(col.default_value)
                best = max(best, lum * (1.0 if strength.is_linked else strength.default_value))
        return best
    return _luminance(world.color)


def spec_for_needs(canonical: dict, needs: SceneNeeds) -> dict:
    """The canonical spec ``canonical`` (``loom-bake check``) with the tier and the components
    ``needs`` asks for: model.tier; components.transmission (both tiers; the ray-wave tier's
    forward lobes are part of its fitted ply scattering and stay), components.double_layer,
    components.multi_ply and wave.diffraction (ray-wave). What the spec had switched off stays
    off: a need only removes work. A spec with per-thread yarn sequences stays on the surface
    tier (``needs`` says so)."""
    import copy

    spec = copy.deepcopy(canonical)
    threads = any(isinstance(spec.get(y), dict) and "sequence" in spec[y] for y in ("warp", "weft"))
    if needs.tier == "raywave" and threads:  # (the ray-wave tier refuses them: issue 33)
        needs.tier = "surface"
        needs.reasons.append("per-thread yarn types (stripes, checks): the ray-wave tier does not "
                             "take them yet, surface tier")
    model = spec.setdefault("model", {})
    model["tier"] = needs.tier
    if needs.tier != "surface" and model.get("closures") == "fitted":
        model.pop("closures")  # fitted closures are the surface tier's; the others map
    comp = spec.setdefault("components", {})
    wave = spec.setdefault("wave", {})
    comp["transmission"] = bool(comp.get("transmission", True)) and needs.transmission
    comp["double_layer"] = bool(comp.get("double_layer", True)) and needs.double_layer
    comp["multi_ply"] = bool(comp.get("multi_ply", True)) and needs.multi_ply
    wave["diffraction"] = bool(wave.get("diffraction", True)) and needs.diffraction
    return spec


def scene_needs(obj, scene, yarn_um: float, ply_um: float, plies: int, repeat_um: float,
                repeats_per_uv: float) -> SceneNeeds:
    """The tier and components ``obj`` needs in ``scene`` (module docstring). ``repeat_um`` is
    the weave repeat's length along u (the spec's), ``repeats_per_uv`` the material's Scale."""
    out = SceneNeeds()
    if scene == bpy.context.scene:
        bpy.context.evaluated_depsgraph_get()  # world matrices up to date after edits
    per_uv = material.uv_meters_per_unit(obj)
    cam = scene.camera
    if cam is None:
        out.reasons.append("no scene camera: surface tier")
        return out
    if per_uv is None:
        out.reasons.append(f"{obj.name} has no UV map: its yarn size is unknown, surface tier")
        return out
    n, centre = _plane(obj)
    metres_per_um = per_uv / max(repeats_per_uv, 1e-12) / max(repeat_um, 1e-12)
    ppm = pixels_per_metre(scene, cam, centre)
    out.yarn_px = yarn_um * metres_per_um * ppm
    out.ply_px = ply_um * metres_per_um * ppm
    dist = (cam.matrix_world.translation - centre).length
    where = f"at {dist:.3g} m, {scene.render.resolution_x}x{scene.render.resolution_y}"
    if out.yarn_px < YARN_PX_RAYWAVE or out.ply_px < PLY_PX_RAYWAVE:
        out.tier = "surface"
        out.reasons.append(f"yarns {out.yarn_px:.2g} px, plies {out.ply_px:.2g} px wide {where}: "
                           f"surface tier (ray-wave from {YARN_PX_RAYWAVE:g} px yarns and "
                           f"{PLY_PX_RAYWAVE:g} px plies)")
    else:
        out.tier = "raywave"
        out.reasons.append(f"yarns {out.yarn_px:.2g} px, plies {out.ply_px:.2g} px wide {where}: "
                           f"plies visible, ray-wave tier")

    # Lights behind the cloth: on the other side of its plane from the camera.
    cam_side = n.dot(cam.matrix_world.translation - centre)
    behind = []
    for light in scene.objects:
        if light.type != "LIGHT" or light.hide_render or light.data.energy <= 0:
            continue
        if light.data.type == "SUN":
            to_light = light.matrix_world.to_3x3() @ Vector((0.0, 0.0, 1.0))
        else:
            to_light = light.matrix_world.translation - centre
        if to_light.length > 0 and cam_side * n.dot(to_light) < 0:
            behind.append(f"light \"{light.name}\"")
    world = _world_strength(scene.world)
    if world >= WORLD_BACKLIGHT:
        behind.append(f"the world (brightness {world:.2g})")
    if behind:
        out.transmission = out.double_layer = True
        out.diffraction = out.tier == "raywave"
        out.reasons.append(f"lit from behind by {', '.join(behind)}: transmission and double "
                           f"layer" + (", diffraction" if out.diffraction else ""))
    else:
        out.reasons.append("nothing lights the cloth from behind: no transmission, double layer "
                           "or diffraction")
    out.multi_ply = out.tier == "raywave" and plies > 1
    if out.tier == "raywave":
        out.reasons.append(f"{plies}-ply yarns: " + ("multi-ply terms" if plies > 1
                                                      else "no multi-ply terms"))
    return out
