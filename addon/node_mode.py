"""Node mode: the Loom surface shader as a node group of Cycles' built-in nodes.

This is ``osl/loom_cloth_surface.osl`` rebuilt with Math / Vector Math / Image Texture nodes
and built-in BSDF nodes, for Blenders without OSL (Debian's, GPUs other than OptiX). The
functions below transcribe the shared headers line by line through ``nodes_expr`` (see its
docstring); each one names the header function it mirrors, and the group's frames carry the
same names. Constants come from the headers themselves (``osl_source.header_constants``).

What node mode adds to the header math is only Blender's side of the plumbing:

* Atlas maps are the ``.exr`` twins of the ``.tx`` files (same texels), read by Image Texture
  nodes as Non-Color data with alpha ``CHANNEL_PACKED`` (any other alpha mode premultiplies or
  drops the A channel, which holds data), linear interpolation, REPEAT for the periodic maps and
  EXTEND for the closure LUT. Row 0 of the files is the top, which is also how Blender maps v, so
  UV in [0,1) reads a repeat as is.
* The tangent frame: T from a Tangent node (UV map), orthogonalised against the normal; N the
  shading normal (Geometry > Normal, which Cycles turns towards the viewer on back faces); B built
  from the *front* normal Nf = N * (back ? -1 : 1), so that seeing the cloth from below mirrors z
  only, as the model does (surface_bsdf.h); atlas vectors are used as stored, so a back face
  shows the mirror image of the front, exactly like the OSL shader.
* The glossy closure ``microfacet("ggx", N_c, t, ax, ay, ...)`` becomes a Glossy BSDF node (GGX).
  That node has no alpha inputs: Cycles (kernel/svm/closure.h, CLOSURE_BSDF_MICROFACET_GGX_ID,
  4.2 to 5.x) sets alpha = saturate(Roughness)^2 and, for 0 < Anisotropy <= 0.99,
  alpha_x = alpha (1 - Anisotropy) along Tangent and alpha_y = alpha / (1 - Anisotropy); for
  -0.99 <= Anisotropy < 0, alpha_x = alpha / (1 + Anisotropy), alpha_y = alpha (1 + Anisotropy).
  So Roughness = (ax ay)^(1/4) and Anisotropy = 1 - sqrt(ax / ay) (or sqrt(ay / ax) - 1 when
  ax > ay); the fitted alphas lie in [1e-3, 1], so |Anisotropy| <= 0.969, inside Cycles' clamp.
* ``hair_transmission(N, r1, r2, T, 0)`` is a Hair BSDF node (component Transmission) with
  RoughnessU = r1, RoughnessV = r2, Offset 0 (SVM negates it) and the Tangent linked (unlinked,
  Cycles would take dPdv); its normal is the shading normal, as OSL's N.
* Closure weights go into each BSDF node's Color input (Cycles multiplies the closure by it, and
  does not clamp it: the fitted weights may exceed 1); the closures are summed with Add Shader
  nodes, like the OSL ``+``.
"""

from __future__ import annotations

import math
import os
from types import SimpleNamespace

import bpy

from . import osl_source
from .manifest import AVERAGE_TEXTURE, average_gap_mean
from .manifest import SURFACE_LUT as LUT, SURFACE_MAPS as MAPS, repeat_aspect
from .node_average import REQUIRED_CONSTANTS as AVERAGE_CONSTANTS, build_average_closures
from .node_bsdf import ggx_glossy
from .node_fitted import FITTED_TEXTURE, REQUIRED_CONSTANTS as FITTED_CONSTANTS
from .node_fitted import HORIZON_STRIP, fitted_yarn_weights, strip_visibility
from .node_texel_guard import texel_guard_geometry, texel_guard_optics
from .node_visibility import horizon_ambient_visibility, horizon_vectors, horizon_visibility
from .nodes_builder import Builder, sync_sockets
from .nodes_expr import (F, V, atan2, clamp, cross, dot, floor, length, madd, math_op, max_, min_,
                         mix, normalize, select, vec)

GROUP_PREFIX = "Loom Surface"

# The headers' #defines that node mode uses; their values are read from the headers themselves
# (osl_source.header_constants), so they live in one place.
REQUIRED_CONSTANTS = ("LOOM_HORIZON_DIRS", "LOOM_HORIZON_SOFTNESS", "LOOM_CLOSURE_LUT_SIZE",
                      "LOOM_LUT_PANELS",
                      "LOOM_LUT_SLICES", "LOOM_LUT_TZ_MAX")


# What this module transcribes, as code fingerprints (osl_source.code_fingerprint: comments and
# whitespace ignored) at the time of the transcription. tests/blender/test_transcription.py
# fails when a source's code changes: read the diff, update the transcription below, run
# tests/blender/test_parity.py, then record the new fingerprints here.
TRANSCRIBED_FROM = {
    "include/loom/closure_mapping.h": "fc6c97297790ce3c",
    "loom_cloth_surface.osl": "56783062a1a2a335",
}


def constants(required=REQUIRED_CONSTANTS) -> dict[str, float]:
    return osl_source.required_constants(required)


# ======================================================================= closure_mapping.h


def surface_glossy_normal(t: V) -> V:
    """closure_mapping.h: surface_glossy_normal(t).

        n = (0,0,1) - t t.z;  l = length(n);  return l < 1e-6 ? (0,0,1) : n / l
    """
    n = vec(0.0, 0.0, 1.0) - t * t.z
    ln = length(n)
    return select(ln < 1e-6, (0.0, 0.0, 1.0), n / ln)


def fold_unit(a):
    """closure_mapping.h: fold_unit(a) = |a wrapped into [-1, 1]|: Blender's pingpong(a, 1),
    one Math node (|fract((a - 1) / 2) 2 - 1|, as the header writes it)."""
    return math_op("PINGPONG", a, 1.0)


def surface_lut_coords(V_: V, t_in: V, K):
    """closure_mapping.h: surface_lut_coords(V, t, x, y, z).

        t = t_in; if (t.z < 0) t = -t
        x = fold_unit((atan2(V.y, V.x) - atan2(t.y, t.x)) (1 / pi))
        y = clamp(V.z, 0, 1)
        z = clamp(t.z / LUT_TZ_MAX, 0, 1) (LUT_SLICES - 1)
    """
    t = select(t_in.z < 0.0, -t_in, t_in)
    x = fold_unit((atan2(V_.y, V_.x) - atan2(t.y, t.x)) * (1.0 / math.pi))
    y = clamp(V_.z, 0.0, 1.0)
    z = clamp(t.z / K["LOOM_LUT_TZ_MAX"], 0.0, 1.0) * (K["LOOM_LUT_SLICES"] - 1.0)
    return x, y, z


def surface_lut_slices(z, K):
    """closure_mapping.h: surface_lut_slices(z, s0, s1, f).

        s0 = floor(clamp(z, 0, SLICES - 1)); s1 = min(s0 + 1, SLICES - 1); f = clamp(z - s0, 0, 1)
    """
    last = K["LOOM_LUT_SLICES"] - 1.0
    s0 = floor(clamp(z, 0.0, last))
    s1 = min_(s0 + 1.0, last)
    f = clamp(z - s0, 0.0, 1.0)
    return s0, s1, f


def surface_lut_uvs(kind, xs: dict, y, slices: dict, K) -> dict:
    """closure_mapping.h: surface_lut_uv(kind, x, y, slice, panel, lut_u, lut_v) for each panel
    (``xs``: panel -> x) and slice (``slices``: name -> slice), as (lut_u, lut_v, 0) vectors.

        n = CLOSURE_LUT_SIZE; rows = n SLICES; row0 = slice n; if (kind > 1.5) row0 += rows
        lut_u = (panel n + 0.5 + clamp(x, 0, 1) (n - 1)) / (LUT_PANELS n)
        lut_v = (row0 + 0.5 + clamp(y, 0, 1) (n - 1)) / (2 rows)

    Regrouped so that the four look-ups share what they can, in as few nodes as that allows:
    (lut_u, lut_v) = (clamp(x), clamp(y)) ((n - 1) / (LUT_PANELS n), (n - 1) / (2 rows))
    + (panel n + 0.5, 0) / (LUT_PANELS n) + (0, slice n + kind_rows + 0.5) / (2 rows)."""
    n = K["LOOM_CLOSURE_LUT_SIZE"]
    rows = n * K["LOOM_LUT_SLICES"]
    su, sv = 1.0 / (K["LOOM_LUT_PANELS"] * n), 1.0 / (2.0 * rows)
    # row0 + 0.5 over 2 rows: slice n sv + (kind > 1.5) rows sv + 0.5 sv
    row_base = madd(kind > 1.5, rows * sv, 0.5 * sv)
    cy = clamp(y, 0.0, 1.0)
    xy = {panel: madd(vec(clamp(x, 0.0, 1.0), cy, 0.0), ((n - 1.0) * su, (n - 1.0) * sv, 0.0),
                      ((panel * n + 0.5) * su, 0.0, 0.0))
          for panel, x in xs.items()}
    uvs = {}
    for which, slice_ in slices.items():
        row = vec(0.0, madd(slice_, n * sv, row_base), 0.0)
        for panel in xs:
            uvs[panel, which] = xy[panel] + row
    return uvs


def surface_lut_transmission_x(x, back):
    """closure_mapping.h: surface_lut_transmission_x(x, back).

        return back ? 1 - x : x
    """
    return select(back, 1.0 - x, x)


def surface_transmission_tangent(t: V, back) -> V:
    """closure_mapping.h: surface_transmission_tangent(t, back).

        return back ? (t.x, t.y, -t.z) : t
    """
    return vec(t.x, t.y, t.z * (1.0 - 2.0 * back))


def surface_glossy_light_visibility(V_: V, Nc: V, h: list, K, vis_amb) -> F:
    """closure_mapping.h: surface_glossy_light_visibility(V, Nc, hor).

        Ls = 2 dot(V, Nc) Nc - V
        return Ls.z <= 0 ? horizon_ambient_visibility(hor) : horizon_visibility(Ls, hor)
    (``vis_amb`` is the ambient visibility already built for the diffuse weights.)
    """
    Ls = Nc * (2.0 * dot(V_, Nc)) - V_
    return select(1.0 - (Ls.z > 0.0), vis_amb, horizon_visibility(Ls, h, K))


def surface_closure_weights(c, w, k_rs, k_rd, k_ts, k_td, vis_v, vis_amb, vis_gl, lut_g,
                            lut_h, lut_l):
    """closure_mapping.h: surface_closure_weights(c, w, k_rs, k_rd, k_ts, k_td, vis_v, vis_amb,
    vis_gl, lut_g, lut_h, lut_l) -> (w_gap, w_diffuse_np, w_diffuse_ns, w_translucent_np,
    w_translucent_ns, w_glossy, w_hair).

        open = 1 - clamp(c, 0, 1);  w_gap = 1 - open
        w_diffuse_np = k_rd (open w vis_v vis_amb)
        w_diffuse_ns = k_rd (open (1 - w) vis_v vis_amb)
        w_translucent_np = k_td (open w)
        w_glossy = open k_rs vis_v vis_gl max(lut_g, 0)
        w_hair = open k_ts max(lut_h, 0)
        w_translucent_ns = k_td (open (1 - w)) + color(open k_ts max(lut_l, 0))
    """
    open_ = 1.0 - clamp(c, 0.0, 1.0)
    w_gap = 1.0 - open_
    w_diffuse_np = k_rd * (open_ * w * vis_v * vis_amb)
    w_diffuse_ns = k_rd * (open_ * (1.0 - w) * vis_v * vis_amb)
    w_translucent_np = k_td * (open_ * w)
    w_glossy = open_ * k_rs * vis_v * vis_gl * max_(lut_g, 0.0)
    w_hair = open_ * k_ts * max_(lut_h, 0.0)
    tl = open_ * k_ts * max_(lut_l, 0.0)
    w_translucent_ns = k_td * (open_ * (1.0 - w)) + vec(tl, tl, tl)
    return (w_gap, w_diffuse_np, w_diffuse_ns, w_translucent_np, w_translucent_ns, w_glossy,
            w_hair)


# ======================================================================= group inputs


def describe_inputs(group) -> None:
    """Defaults, ranges and tooltips of the inputs both tiers' groups share."""
    s_in = group.interface.items_tree["Scale"]
    s_in.default_value = 1.0
    s_in.min_value = 0.0
    s_in.description = "weave repeats per UV unit"
    a_in = group.interface.items_tree["Average"]
    a_in.default_value = 0.0
    a_in.min_value = 0.0
    a_in.max_value = 1.0
    a_in.description = ("1: the weave repeat's averaged closures (cloth far away, a few "
                        "look-ups); 0: every texel's closures; Bake & Assign drives it by the "
                        "camera distance")


def mix_average(b, average_socket, yarns, far):
    """Mix Shader of the texels' yarn closures and the averaged ones by the Average input:
    Cycles' SVM jumps over the input of weight 0 and the nodes only it needs."""
    mix = b.new("ShaderNodeMixShader", label="Average: texels (0) or averaged (1)")
    b.connect(average_socket, mix.inputs["Fac"])
    b.connect(yarns, mix.inputs[1])
    b.connect(far, mix.inputs[2])
    return mix.outputs["Shader"]


# ======================================================================= images


def load_atlas_image(atlas_dir: str, manifest: dict, name: str, label: str):
    """The atlas map ``name`` as a Blender image set up for data (see the module docstring)."""
    tex = manifest["textures"][name]
    path = os.path.join(atlas_dir, tex.get("node_file", name + ".exr"))
    if not os.path.isfile(path):
        raise FileNotFoundError(f"atlas map {name}: {path} is missing")
    known = any(i.filepath == path for i in bpy.data.images)
    img = bpy.data.images.load(path, check_existing=True)
    if known:
        img.reload()  # the atlas may have been re-baked in place since it was loaded
    img.name = f"{label} {name}"
    img.colorspace_settings.name = "Non-Color"
    img.alpha_mode = "CHANNEL_PACKED"
    return img


# ======================================================================= the group


def group_name(manifest: dict) -> str:
    return f"{GROUP_PREFIX} ({manifest.get('spec', {}).get('name', 'atlas')})"


def _surface_lut(b, atlas_dir, manifest, label, V_, t, c_info, back, K):
    """The closure LUT's two panels at this view, each mixed between the two slices around the
    tangent's elevation: (refl (g, ax, ay), trans (h, r1, r2), trans l)."""
    with b.block("closure_mapping.h: surface_lut_coords, surface_lut_slices, surface_lut_uv"):
        lx, ly, lz = surface_lut_coords(V_, t, K)
        s0, s1, sf = surface_lut_slices(lz, K)
        # the reflection panel at this view; the transmission panel on a back face for the
        # physical slab's tangent (surface_lut_transmission_x)
        lxt = surface_lut_transmission_x(lx, back)
        by_panel = surface_lut_uvs(c_info[0], {0.0: lx, 1.0: lxt}, ly, {"s0": s0, "s1": s1}, K)
        uvs = {}
        for what, panel in (("reflection", 0.0), ("transmission", 1.0)):
            for which in ("s0", "s1"):
                uvs[what, which] = b.label(by_panel[panel, which],
                                           f"LUT uv ({what}), slice {which}")

    with b.block("Closure LUT (g, ax, ay | h, r1, r2, l), slices mixed (loom_cloth_surface.osl)"):
        def lut_lookup(what):  # two slices, mixed by sf
            looks = []
            for which in ("s0", "s1"):
                node = b.new("ShaderNodeTexImage", interpolation="Linear", extension="EXTEND",
                             label=f"{LUT} ({what}, {which})")
                node.image = load_atlas_image(atlas_dir, manifest, LUT, label)
                b.link(uvs[what, which], node.inputs["Vector"])
                looks.append((b.vector_socket(node.outputs["Color"]),
                              b.float_socket(node.outputs["Alpha"])))
            return mix(looks[0][0], looks[1][0], sf), mix(looks[0][1], looks[1][1], sf)

        refl, _ = lut_lookup("reflection")
        trans, trans_a = lut_lookup("transmission")
        b.label(refl, "refl (g, ax, ay)")
        b.label(trans, "trans (h, r1, r2)")
        b.label(trans_a, "trans l")
    return refl, trans, trans_a


def _surface_closures(b, frame, np_, Nc, t, back, refl, trans, weights):
    """The closures of closure_mapping.h's table with their weights, normals and tangents in
    world space (frame: T, B, N): (the transparent closure, the sum of the yarns' closures)."""
    T, B, N = frame
    w_gap, w_dnp, w_dns, w_tnp, w_tns, w_glossy, w_hair = weights
    with b.block("Closure normals and tangents in world space "
                 "(loom_cloth_surface.osl)"):
        np_w = b.label(normalize(T * np_.x + B * np_.y + N * np_.z), "n_p world")
        nc_w = b.label(normalize(T * Nc.x + B * Nc.y + N * Nc.z), "N_c world")
        t_w = b.label(normalize(T * t.x + B * t.y + N * t.z), "t world")
        tt = surface_transmission_tangent(t, back)
        tt_w = b.label(normalize(T * tt.x + B * tt.y + N * tt.z), "transmission tangent world")

    # ---------------------------------------------------------------- closures
    with b.block("Closures (closure_mapping.h table)"):
        transp = b.new("ShaderNodeBsdfTransparent", label="transparent() * w_gap")
        b.link(vec(w_gap, w_gap, w_gap), transp.inputs["Color"])
        d_np = b.new("ShaderNodeBsdfDiffuse", label="diffuse(n_p) * w_diffuse_np")
        b.link(w_dnp, d_np.inputs["Color"])
        b.link(0.0, d_np.inputs["Roughness"])  # Lambert (Oren-Nayar off)
        b.link(np_w, d_np.inputs["Normal"])
        d_ns = b.new("ShaderNodeBsdfDiffuse", label="diffuse(N) * w_diffuse_ns")
        b.link(w_dns, d_ns.inputs["Color"])
        b.link(0.0, d_ns.inputs["Roughness"])
        t_np = b.new("ShaderNodeBsdfTranslucent", label="translucent(n_p) * w_translucent_np")
        b.link(w_tnp, t_np.inputs["Color"])
        b.link(np_w, t_np.inputs["Normal"])
        t_ns = b.new("ShaderNodeBsdfTranslucent", label="translucent(N) * w_translucent_ns")
        b.link(w_tns, t_ns.inputs["Color"])
        gl = ggx_glossy(b, 'microfacet("ggx", N_c, t, ax, ay) * w_glossy',
                        vec(w_glossy, w_glossy, w_glossy), refl.y, refl.z, nc_w, t_w)
        hair = b.new("ShaderNodeBsdfHair", component="Transmission",
                     label="hair_transmission(N, r1, r2, t, 0) * w_hair")
        b.link(vec(w_hair, w_hair, w_hair), hair.inputs["Color"])
        b.link(0.0, hair.inputs["Offset"])
        b.link(trans.y, hair.inputs["RoughnessU"])
        b.link(trans.z, hair.inputs["RoughnessV"])
        b.link(tt_w, hair.inputs["Tangent"])
        yarns = b.add_shaders(n.outputs["BSDF"] for n in (d_np, d_ns, t_np, t_ns, gl, hair))
    return transp, yarns


def build_surface_group(atlas_dir: str, manifest: dict, interpolation: str = "Linear",
                        name: str | None = None):
    """Build (or rebuild in place) the node group for this atlas and return it.

    Group interface: input ``Scale`` (weave repeats per UV unit), output ``BSDF``. The group
    reads UV and the UV-map tangent of the active render UV map itself.
    ``interpolation`` is the Image Texture interpolation of the periodic maps ('Linear' for
    rendering; 'Closest' reads whole texels, which the parity tests use so that a render's mean
    is exactly comparable with ``loom-bake eval bsdf --average`` over texels). The closure LUT
    is always 'Linear' (the table is sampled bilinearly in every evaluator).
    """
    K = constants()
    n_lut = int(K["LOOM_CLOSURE_LUT_SIZE"])
    cols = int(K["LOOM_LUT_PANELS"]) * n_lut
    rows = 2 * n_lut * int(K["LOOM_LUT_SLICES"])
    lut_size = list(manifest["textures"][LUT]["size"])
    if lut_size != [cols, rows]:
        raise ValueError(f"closure LUT is {lut_size[0]}x{lut_size[1]}; the shaders expect "
                         f"{cols}x{rows} (LOOM_CLOSURE_LUT_SIZE, LOOM_LUT_PANELS, "
                         f"LOOM_LUT_SLICES): re-bake the atlas with this version of loom-bake")
    if int(K["LOOM_HORIZON_DIRS"]) != 8:
        raise ValueError("the atlas stores 8 horizon directions (horizon_0, horizon_1)")

    fitted = FITTED_TEXTURE in manifest["textures"]
    name = name or group_name(manifest)
    group = bpy.data.node_groups.get(name)
    if group is None or group.bl_idname != "ShaderNodeTree":
        group = bpy.data.node_groups.new(name, "ShaderNodeTree")
    group.nodes.clear()
    sync_sockets(group, "INPUT", [("Scale", "NodeSocketFloat"), ("Average", "NodeSocketFloat")])
    sync_sockets(group, "OUTPUT", [("BSDF", "NodeSocketShader")])
    describe_inputs(group)
    group["loom_atlas"] = os.path.abspath(atlas_dir)
    group["loom_spec_sha256"] = str(manifest.get("spec_sha256", ""))
    group.description = f"Loom surface cloth from atlas {os.path.abspath(atlas_dir)}"

    b = Builder(group)
    label = f"Loom {manifest.get('spec', {}).get('name', 'atlas')}"

    # ---------------------------------------------------------------- inputs (OSL: shader params)
    with b.block("Inputs: UV * Scale, view, frame (loom_cloth_surface.osl)"):
        gin = b.new("NodeGroupInput")
        texco = b.new("ShaderNodeTexCoord")
        geo = b.new("ShaderNodeNewGeometry")
        tan = b.new("ShaderNodeTangent", direction_type="UV_MAP")  # active render UV map
        scale_ = b.float_socket(gin.outputs["Scale"])
        # OSL: su = UV[0] Scale, sv = UV[1] Scale Aspect; Aspect = Lx / Ly of the repeat keeps a
        # non-square repeat (warp and weft densities differ) at its physical proportions.
        uvraw = b.vector_socket(texco.outputs["UV"])
        uv = b.label(vec(uvraw.x * scale_, uvraw.y * scale_ * repeat_aspect(manifest), 0.0),
                     "uv = UV * (Scale, Scale * Aspect)")

    # ---------------------------------------------------------------- atlas look-ups
    with b.block("Atlas maps (manifest.json: textures, channels RGBA)"):
        tex = {}
        for m in MAPS:
            # With fitted closures: the fits hold what spec_params gives the mapping, and V(V)
            # is read from the horizon strip (fitted_closures.h).
            if fitted and m in ("spec_params", "horizon_0", "horizon_1"):
                continue
            node = b.new("ShaderNodeTexImage", interpolation=interpolation,
                         extension="REPEAT", label=m)
            node.image = load_atlas_image(atlas_dir, manifest, m, label)
            b.link(uv, node.inputs["Vector"])
            tex[m] = (b.vector_socket(node.outputs["Color"]), b.float_socket(node.outputs["Alpha"]))

    c_frame, _height = tex["ply_frame"]
    c_normal, _h = tex["ply_normal"]
    c_info, a_info = tex["yarn_info"]  # kind, along, ply_id | gap coverage c
    c_refl, a_refl = tex["albedo_reflect"]  # k_rd | k_rs
    c_trans, a_trans = tex["albedo_transmit"]  # k_td | k_ts
    # roughness, optical thickness, diffuse blend | ior; not read with fitted closures (the fits
    # hold what the mapping takes from it): only the blend would be, as the OSL shader's constant
    c_par, _ior = tex["spec_params"] if not fitted else (SimpleNamespace(z=0.5), 1.5)

    # ---------------------------------------------------------------- frame
    with b.block("Frame: T, B from the front normal, V, atlas vectors "
                 "(loom_cloth_surface.osl)"):
        back = b.float_socket(geo.outputs["Backfacing"])
        N = b.vector_socket(geo.outputs["Normal"])  # Cycles: towards the viewer on back faces
        zs = 1.0 - 2.0 * back  # OSL: zs = back ? -1 : 1
        Nf = b.label(N * zs, "Nf (front normal)")
        Tg = b.vector_socket(tan.outputs["Tangent"])
        T = b.label(normalize(Tg - Nf * dot(Nf, Tg)), "T")
        B = b.label(cross(Nf, T), "B")
        Vw = b.vector_socket(geo.outputs["Incoming"])  # OSL: Vw = -I
        V_ = b.label(vec(dot(Vw, T), dot(Vw, B), dot(Vw, N)), "V (tangent frame)")

    with b.block("texel_guard.h: texel_guard_geometry, texel_guard_optics, texel_guard_horizon"):
        t, np_, c_info, a_info = texel_guard_geometry(c_frame, c_normal, c_info, a_info)
        b.label(t, "t")
        b.label(np_, "n_p")
        c_refl, a_refl, c_trans, a_trans, blend = texel_guard_optics(
            c_refl, a_refl, c_trans, a_trans, c_par)
        if not fitted:
            hor = horizon_vectors(*tex["horizon_0"], *tex["horizon_1"])

    with b.block("closure_mapping.h: surface_glossy_normal"):
        Nc = b.label(surface_glossy_normal(t), "N_c")

    if fitted:  # fitted_closures.h: per-texel factors in place of the mapping's weights
        width = int(manifest["textures"]["ply_frame"]["size"][0])
        KF = constants(FITTED_CONSTANTS)
        vis_v = strip_visibility(b, load_atlas_image(atlas_dir, manifest, HORIZON_STRIP, label),
                                 uv, V_, back, interpolation, width, KF)
        refl, trans, _trans_a = _surface_lut(b, atlas_dir, manifest, label, V_, t, c_info,
                                             back, K)
        w_gap = a_info
        w_dnp, w_dns, w_tnp, w_tns, w_glossy, w_hair = fitted_yarn_weights(
            b, load_atlas_image(atlas_dir, manifest, FITTED_TEXTURE, label), uv, back,
            interpolation, width, (c_refl, a_refl, c_trans, a_trans), refl.x, trans.x, vis_v, KF)
    else:
        with b.block("visibility.h, closure_mapping.h: vis_v, vis_amb, vis_gl (1 on back faces)"):
            vis_amb_f = horizon_ambient_visibility(hor, K)
            vis_v = b.label(select(back, 1.0, horizon_visibility(V_, hor, K)), "vis_v")
            vis_amb = b.label(select(back, 1.0, vis_amb_f), "vis_amb")
            vis_gl = b.label(select(back, 1.0, surface_glossy_light_visibility(V_, Nc, hor, K,
                                                                               vis_amb_f)),
                             "vis_gl")

        refl, trans, trans_a = _surface_lut(b, atlas_dir, manifest, label, V_, t, c_info, back,
                                            K)

        with b.block("closure_mapping.h: surface_closure_weights"):
            (w_gap, w_dnp, w_dns, w_tnp, w_tns, w_glossy, w_hair) = surface_closure_weights(
                a_info, blend, a_refl, c_refl, a_trans, c_trans, vis_v, vis_amb, vis_gl,
                refl.x, trans.x, trans_a)
    for e, txt in ((w_gap, "w_gap"), (w_dnp, "w_diffuse_np"), (w_dns, "w_diffuse_ns"),
                   (w_tnp, "w_translucent_np"), (w_tns, "w_translucent_ns"),
                   (w_glossy, "w_glossy"), (w_hair, "w_hair")):
        b.label(e, txt)

    transp, yarns = _surface_closures(b, (T, B, N), np_, Nc, t, back, refl, trans,
                                      (w_gap, w_dnp, w_dns, w_tnp, w_tns, w_glossy, w_hair))

    far = build_average_closures(b, load_atlas_image(atlas_dir, manifest, AVERAGE_TEXTURE, label),
                                 V_, back, T, N, Vw, a_info, average_gap_mean(manifest),
                                 constants(AVERAGE_CONSTANTS))
    with b.block("Average: the texels' yarn closures (0) or the repeat-averaged ones (1)"):
        gout = b.new("NodeGroupOutput")
        b.connect(b.add_shaders((transp.outputs["BSDF"],
                                 mix_average(b, gin.outputs["Average"], yarns, far))),
                  gout.inputs["BSDF"])

    b.layout()
    return group
