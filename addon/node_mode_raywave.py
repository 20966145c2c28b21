"""Node mode for the ray-wave tier: ``osl/loom_cloth_raywave.osl`` as a node group of Cycles'
built-in nodes.

The same transcription rules as the surface tier (``node_mode.py``, whose docstring explains the
atlas images, the tangent frame and the closure weights in Color inputs): the groups below are
built from the line-by-line transcriptions of the headers in ``node_raywave_lobes.py``
(``raywave_lobes.h``, ``asg.h``, ``double_layer_factors.h``) and ``node_wave.py``
(``diffraction_*.h``, ``speckle_noise.h``); what the atlas holds is read by ``manifest.py``.
What is particular to this tier:

* Lobe tables (ply_high_*, ply_refl_*), their tints (ply_tint_*), the double-layer factors
  (layer_factors_*) and the microfacet albedo LUT are Image Textures with EXTEND; the node images
  the tints (one texel per node, like the lobes) and the factors are read 'Linear' (a bilinear
  look-up between node texels *is* Eq. S.7). Image coordinates are the headers' (s from the left,
  tv from the bottom), which is how Blender maps an image's vector input.
* Warp and weft: OSL picks the yarn's files with an ``if``; nodes cannot choose an image, so each
  yarn's texels are read and the values are selected (yarn_info.r > 1.5: weft). Yarns that share
  their tables (manifest ``same_as``) share the look-ups.
* Gap diffraction (``diffraction_sampling.h``): the OSL shader hashes the shading position with
  ``noise("hash", P, w)``; nodes take the four random numbers from two White Noise Textures (4D,
  Position, W = 0 and 1: the first's Color, the second's Value). The numbers differ (both are
  uniform hashes of the sample's position), the distributions sampled do not. One Refraction
  BSDF per lobe and colour channel.
* Closures: each lobe has a Glossy BSDF (Beckmann, anisotropic), a Refraction BSDF (Beckmann)
  and a Translucent BSDF, whose Colors are the weights raywave_lobe_weights gives them, each
  with its share of the lobe from raywave_lobe_closures (Cycles allocates no closure of zero
  weight);
  the diffuse forward part (Eq. S.22, s k_f T) and the forward energy residual share one more
  Translucent BSDF (why not one for all: build_lobe_group), and the backward energy residual and
  the light the layers return backwards (k_b T, double_layer_factors.h) a Diffuse BSDF
  (Roughness 0: Cycles' Lambertian diffuse closure); T, the point's forward light, sums each
  lobe group's ``forward`` output and the forward residual.
  - Glossy BSDF (Beckmann) has no alpha inputs: Cycles (kernel/svm/closure.h, 4.2 to 5.x) sets
    alpha = saturate(Roughness)^2, and for 0 < Anisotropy <= 0.99 alpha_x = alpha (1 - Anisotropy)
    along Tangent, alpha_y = alpha / (1 - Anisotropy). So alpha_x = a_x <= alpha_y = a_y needs
    Roughness = (a_x a_y)^(1/4), Anisotropy = 1 - sqrt(a_x / a_y) (a >= LOOM_RAYWAVE_MIN_ALPHA
    keeps Anisotropy <= 0.969, inside Cycles' clamp; an isotropic lobe gives 0, which Cycles
    treats as isotropic, the same closure).
  - Refraction BSDF (Beckmann): alpha = Roughness^2, and the SVM node inverts its IOR on back
    faces where OSL's microfacet() does not; the OSL shader passes LOOM_RAYWAVE_ETA on both faces,
    so node mode passes 1 / LOOM_RAYWAVE_ETA on back faces.
"""

from __future__ import annotations

import os

import bpy

from . import manifest as _manifest, node_mode, node_texel_guard, node_visibility
from .manifest import AVERAGE_TEXTURE
from .node_average import REQUIRED_CONSTANTS as AVERAGE_CONSTANTS, build_average_closures
from .node_raywave_lobes import (asg_frame, asg_integral_from_lut, asg_integral_lut_uv,
                                 asg_node_coord, asg_node_uv, asg_tint_uv, double_layer_uv,
                                 microfacet_albedo_uv, raywave_energy_budget,
                                 raywave_layer_diffuse_weight, raywave_layer_translucent_weight,
                                 raywave_lobe_closures, raywave_lobe_energy, raywave_lobe_forward,
                                 raywave_lobe_weights, raywave_ply_space,
                                 raywave_residual_diffuse_weight,
                                 raywave_residual_translucent_weight, raywave_residual_uv)
from .node_gap_diffraction import build_gap_diffraction
from .node_wave import diffraction_gap_sampled, noise_lobe_uv, noise_pick
from .nodes_builder import Builder, sync_sockets
from .nodes_expr import cos, cross, dot, max_, normalize, select, sin, sqrt, vec

GROUP_PREFIX = "Loom Ray-wave"
SHADER = "loom_cloth_raywave.osl"
MAPS = _manifest.RAYWAVE_MAPS

REQUIRED_CONSTANTS = ("LOOM_RAYWAVE_PARTS", "LOOM_RAYWAVE_MIN_ALPHA", "LOOM_RAYWAVE_ETA",
                      "LOOM_RAYWAVE_MIN_ALBEDO", "LOOM_RAYWAVE_MIN_COS",
                      "LOOM_RAYWAVE_SIDE_BAND", "LOOM_RAYWAVE_REFRACTION_BAND",
                      "LOOM_MICROFACET_ALBEDO_SIZE", "LOOM_ASG_INTEGRAL_LUT_SIZE", "LOOM_ASG_MU_MAX",
                      "LOOM_HORIZON_DIRS", "LOOM_HORIZON_SOFTNESS", "LOOM_DIFFRACTION_S_MAX",
                      "LOOM_DIFFRACTION_ICDF_SIZE", "LOOM_DIFFRACTION_KERNEL_RAD",
                      "LOOM_DIFFRACTION_MIN_COS", "LOOM_DIFFRACTION_MIN_GAP",
                      "LOOM_DIFFRACTION_SAMPLES",
                      "LOOM_NOISE_SEGMENTS_PER_REPEAT", "LOOM_NOISE_HASH_MOD", "LOOM_NOISE_LEVELS",
                      "LOOM_DOUBLE_LAYER_BLOCKS")

# What this module transcribes (see node_mode.TRANSCRIBED_FROM; tests/blender/test_transcription.py
# checks it). The headers: node_raywave_lobes.py, node_wave.py, node_texel_guard.py,
# node_visibility.py.
TRANSCRIBED_FROM = {
    "loom_cloth_raywave.osl": "b70a6e638c7f102e",
}


def constants() -> dict[str, float]:
    return node_mode.constants(REQUIRED_CONSTANTS)


def group_name(manifest: dict) -> str:
    return f"{GROUP_PREFIX} ({manifest.get('spec', {}).get('name', 'atlas')})"


# ======================================================================= the groups

# The lobe group's inputs (name, socket type), in the order of loom_lobes' per-lobe arguments.
LOBE_INPUTS = (
    ("p0", "NodeSocketVector"), ("mu1", "NodeSocketFloat"), ("p1", "NodeSocketVector"),
    ("tint", "NodeSocketColor"), ("V", "NodeSocketVector"), ("xp", "NodeSocketVector"),
    ("yp", "NodeSocketVector"), ("t", "NodeSocketVector"), ("T", "NodeSocketVector"),
    ("B", "NodeSocketVector"), ("N", "NodeSocketVector"), ("back", "NodeSocketFloat"),
    *((n, "NodeSocketVector") for n in node_visibility.HORIZON_SOCKETS),
    ("open", "NodeSocketFloat"),
    ("vis_v", "NodeSocketFloat"), ("k_f", "NodeSocketColor"),
    ("s", "NodeSocketFloat"), ("theta_i", "NodeSocketFloat"), ("noise_instance", "NodeSocketFloat"),
    ("noise_shift", "NodeSocketFloat"), ("used", "NodeSocketColor"))


def _new_group(name: str, inputs, outputs, description: str):
    group = bpy.data.node_groups.get(name)
    if group is None or group.bl_idname != "ShaderNodeTree":
        group = bpy.data.node_groups.new(name, "ShaderNodeTree")
    group.nodes.clear()
    sync_sockets(group, "INPUT", list(inputs))
    sync_sockets(group, "OUTPUT", list(outputs))
    group.description = description
    return group


def build_lobe_group(name: str, albedo_image, integral_image, K, noise_image=None, refl=False,
                     noise_instances=1, functions: dict | None = None):
    """One lobe of loom_lobes (loom_cloth_raywave.osl) as a group: raywave_lobe_closures, the
    microfacet albedo look-ups, the light-side visibility, the lobe's integral from the ASG
    integral LUT, raywave_lobe_weights and the lobe's Glossy, Refraction and Translucent BSDFs (a
    closure whose share is 0 has weight 0). Built once per atlas (it holds the atlas's albedo and
    integral images) and used for every lobe: a group of a few
    hundred nodes instead of one of thousands, which Blender builds and edits much faster.

    Each lobe ends in its own closures, although the translucent ones could share one closure
    (OSL sums them in one translucent() term): a value that several closures read stays on
    Cycles' SVM stack (255 floats) until the last of them is compiled, so one Translucent BSDF
    fed by every lobe kept every lobe's intermediate values alive and overflowed the stack at
    final quality (6 lobes: "out of SVM stack space", the material renders black).

    With ``noise_image`` (the atlas's noise tile for f_refl lobes if ``refl``, else f_high's),
    each lobe's weights are scaled by the noise averaged over the lobe (speckle_noise.h,
    noise_lobe_uv): two look-ups, one per blur level, blended.

    Its second output, ``forward``, is the lobe's part of the point's forward light T
    (raywave_lobe_forward), which the layers' closures sum (double_layer_factors.h). The lobe
    takes its share of the yarn's energy budget after ``used``, what the lobes before it send
    out (raywave_energy_budget, on raywave_lobe_energy with the noise); its third output,
    ``energy``, is what it sends out, which the next lobe's ``used`` adds."""
    group = _new_group(name, LOBE_INPUTS, (("BSDF", "NodeSocketShader"),
                                           ("forward", "NodeSocketColor"),
                                           ("energy", "NodeSocketColor")),
                       "Loom ray-wave: one fitted lobe as Cycles closures (raywave_lobes.h)")
    b = Builder(group, functions)
    eta = K["LOOM_RAYWAVE_ETA"]
    with b.block("Lobe inputs (loom_lobes)"):
        gin = b.new("NodeGroupInput")
        i = {n: (b.vector_socket if kind != "NodeSocketFloat" else b.float_socket)(
            gin.outputs[n]) for n, kind in LOBE_INPUTS}
        hor = [i[n] for n in node_visibility.HORIZON_SOCKETS]
        V_, back = i["V"], i["back"]
    with b.block("raywave_lobes.h: raywave_lobe_closures"):
        z, Nr, Tr, axr, ayr, Nt, at, b_refl, b_refr = b.call(
            raywave_lobe_closures, V_, i["xp"], i["yp"], i["t"], i["p0"], i["mu1"], i["p1"], K=K)
    with b.block("microfacet_albedo_uv, the albedo LUT (reflection, refraction), "
                 "raywave_lobe_visibility(z)"):
        albedos = []
        for cos_nv, alpha, what in ((dot(Nr, V_), sqrt(axr * ayr), "reflection"),
                                    (dot(Nt, V_), at, "refraction")):
            ls, lt = microfacet_albedo_uv(cos_nv, alpha, K)
            node = b.new("ShaderNodeTexImage", interpolation="Linear", extension="EXTEND",
                         label=f"microfacet_albedo ({what})")
            node.image = albedo_image
            b.link(vec(ls, lt, 0.0), node.inputs["Vector"])
            albedos.append(b.vector_socket(node.outputs["Color"]))
        albedo_r = b.label(albedos[0].x, "albedo_r")
        albedo_t = b.label(albedos[1].y, "albedo_t")
        z_vis = vec(z.x, z.y, max_(z.z, 1e-6))
        vis_z = b.label(select(back, 1.0, b.call(node_visibility.horizon_visibility, z_vis, hor, K=K)),
                        "vis_z")
    with b.block("asg.h: the lobe's integral from the LUT (asg_integral_from_lut)"):
        hs, ht = asg_integral_lut_uv(i["mu1"], i["p1"].x, K)
        node = b.new("ShaderNodeTexImage", interpolation="Linear", extension="EXTEND",
                     label="asg_integral_lut")
        node.image = integral_image
        b.link(vec(hs, ht, 0.0), node.inputs["Vector"])
        h_lut = b.vector_socket(node.outputs["Color"]).x
        integral = b.label(asg_integral_from_lut(h_lut, i["mu1"], i["p1"].x, i["p1"].y, K),
                           "integral")
    with b.block("raywave_lobes.h: raywave_lobe_weights"):
        w_refl, w_refr, w_transl = raywave_lobe_weights(
            integral, albedo_r, albedo_t, i["tint"], i["open"], i["vis_v"], vis_z, i["k_f"],
            i["s"], b_refl, b_refr, K)
        forward = raywave_lobe_forward(integral, i["tint"], b_refl)
        energy = raywave_lobe_energy(integral, i["tint"], i["open"], i["vis_v"], vis_z,
                                     i["k_f"], i["s"], b_refl)
    if noise_image is not None:
        with b.block("speckle_noise.h: noise_lobe_uv, the noise at two blur levels (Eq. S.39)"):
            _, _, lz = asg_frame(i["p0"].x, i["p0"].y, i["p0"].z)
            wi = vec(0.0, cos(i["theta_i"]), sin(i["theta_i"]))
            nu, nv0, nv1, nt = b.call(noise_lobe_uv, lz, wi, refl, i["mu1"], i["p1"].x,
                                      i["noise_instance"], i["noise_shift"], noise_instances,
                                      K=K)
            looked = []
            for v_ in (nv0, nv1):
                node = b.new("ShaderNodeTexImage", interpolation="Linear", extension="EXTEND",
                             label="noise_refl" if refl else "noise_high")
                node.image = noise_image
                b.link(vec(nu, v_, 0.0), node.inputs["Vector"])
                looked.append(b.vector_socket(node.outputs["Color"]))
            nz = b.label(looked[0] * (1.0 - nt) + looked[1] * nt, "noise")
            w_refl = w_refl * nz
            w_refr = w_refr * nz
            w_transl = w_transl * nz
            energy = energy * nz
    with b.block("raywave_lobes.h: raywave_energy_budget after the lobes before"):
        budget = b.label(raywave_energy_budget(energy, i["used"], i["open"]), "budget")
        w_refl = w_refl * budget
        w_refr = w_refr * budget
        w_transl = w_transl * budget
        energy = energy * budget
    with b.block("closures"):
        T, B, Nw = i["T"], i["B"], i["N"]
        nr = normalize(T * Nr.x + B * Nr.y + Nw * Nr.z)
        tw = normalize(T * Tr.x + B * Tr.y + Nw * Tr.z)
        gl = b.new("ShaderNodeBsdfGlossy", distribution="BECKMANN",
                   label='microfacet("beckmann", Nr, Tr, axr, ayr, 1, 0)')
        b.link(w_refl, gl.inputs["Color"])
        b.link(sqrt(sqrt(axr * ayr)), gl.inputs["Roughness"])
        b.link(1.0 - sqrt(axr / ayr), gl.inputs["Anisotropy"])
        b.link(0.0, gl.inputs["Rotation"])
        b.link(nr, gl.inputs["Normal"])
        b.link(tw, gl.inputs["Tangent"])
        nrt = normalize(T * Nt.x + B * Nt.y + Nw * Nt.z)
        rf = b.new("ShaderNodeBsdfRefraction", distribution="BECKMANN",
                   label='microfacet("beckmann", Nt, Nt, at, at, eta, 1)')
        b.link(w_refr, rf.inputs["Color"])
        b.link(sqrt(at), rf.inputs["Roughness"])
        b.link(select(back, 1.0 / eta, eta), rf.inputs["IOR"])
        b.link(nrt, rf.inputs["Normal"])
        tr = b.new("ShaderNodeBsdfTranslucent", label="translucent(N)")
        b.link(w_transl, tr.inputs["Color"])
        b.link(Nw, tr.inputs["Normal"])
        gout = b.new("NodeGroupOutput")
        b.connect(b.add_shaders((gl.outputs["BSDF"], rf.outputs["BSDF"], tr.outputs["BSDF"])),
                  gout.inputs["BSDF"])
        b.link(forward, gout.inputs["forward"])
        b.link(energy, gout.inputs["energy"])
    b.layout()
    return group


def _lobe_nodes(b, table, tex_params, g, lobe_groups, node_coords, weft, point, K):
    """One lobe group node per fitted lobe of f_refl and f_high (loom_lobes), fed its texels
    and the point's quantities (``point``: the lobe group's other inputs), each within what
    the lobes before it left of the budget: (the lobe nodes, the energy they send out)."""
    fi, fj = node_coords
    rows, cols = g["m"] // 2 + 1, g["n"] // 2 + 1
    lobe_outputs = []
    used = (0.0, 0.0, 0.0)  # what the lobes so far send out (raywave_energy_budget)

    def lobe_texels(part_name, l, lobes):
        """p0, mu1, p1, tint of lobe l for the yarn at this point: each yarn's texels, selected
        by `weft`; a table or tint that both yarns share is read once."""
        nodes_of, tint_of, per_yarn = {}, {"": (1.0, 1.0, 1.0)}, {}  # f_refl has no tint
        for y in ("warp", "weft"):
            f = tex_params[f"{part_name}_{y}"]
            tf = tex_params[f"tint_{y}"] if part_name == "high" else ""
            if f not in nodes_of:
                s0, t0 = asg_node_uv(fi, fj, 0, l, lobes, rows, cols, K)
                s1, t1 = asg_node_uv(fi, fj, 1, l, lobes, rows, cols, K)
                p0, mu1 = table(f, s0, t0, what=f"lobe {l} part 0")
                p1, _ = table(f, s1, t1, what=f"lobe {l} part 1")
                nodes_of[f] = (p0, mu1, p1)
            if tf not in tint_of:
                ts, tt = asg_tint_uv(fi, fj, l, lobes, rows, cols)
                tint_of[tf], _ = table(tf, ts, tt, what=f"lobe {l}")
            per_yarn[y] = (*nodes_of[f], tint_of[tf])
        return tuple(a if a is e else select(weft, e, a)
                     for a, e in zip(per_yarn["warp"], per_yarn["weft"]))

    for part_name, lobes in (("refl", g["refl_lobes"]), ("high", g["high_lobes"])):
        for l in range(lobes):
            with b.block(f"loom_lobes: {part_name} lobe {l} (asg_node_uv, asg_tint_uv)"):
                p0, mu1, p1, tintc = lobe_texels(part_name, l, lobes)
                node = b.new("ShaderNodeGroup", label=f"{part_name} lobe {l}")
                node.node_tree = lobe_groups[part_name]
                node.hide = False
                args = {**point, "p0": p0, "mu1": mu1, "p1": p1, "tint": tintc, "used": used}
                for n, _kind in LOBE_INPUTS:
                    b.link(args[n], node.inputs[n])
                lobe_outputs.append(node)
                used = used + b.vector_socket(node.outputs["energy"])
    return lobe_outputs, used


def _residual_and_layers(b, table, tex_params, g, slice_, weft, lobe_outputs, open_, vis_v,
                         factors, used):
    """The energy residual's and the double layer's weights (raywave_lobes.h,
    double_layer_factors.h), within what the lobes left of the point's budget: (the diffuse
    closure's weight, the translucent closure's weight)."""
    theta_i, h = slice_
    k_b, k_f = factors
    M, N_ = g["m"], g["n"]
    with b.block("Energy residual (raywave_lobes.h: raywave_residual_uv, weights)"):
        res = {}
        for side in (0, 1):
            rs, rt = raywave_residual_uv(theta_i, h, g["theta_min"], g["theta_max"], M, N_, side)
            per_yarn = {}
            for y in ("warp", "weft"):
                f = tex_params[f"residual_{y}"]
                if f not in per_yarn:
                    per_yarn[f], _ = table(f, rs, rt, what=f"side {side}")
            e_w = per_yarn[tex_params["residual_warp"]]
            e_e = per_yarn[tex_params["residual_weft"]]
            res[side] = e_w if e_w is e_e else select(weft, e_e, e_w)
        # The point's forward light T (double_layer_factors.h): the lobes' parts, then e_f.
        t_fwd = res[1]
        for node in lobe_outputs:
            t_fwd = t_fwd + b.vector_socket(node.outputs["forward"])
        t_fwd = b.label(t_fwd, "T (forward light)")
        w_diffuse = b.label(raywave_residual_diffuse_weight(res[0], open_, vis_v)
                            + raywave_layer_diffuse_weight(t_fwd, open_, vis_v, k_b),
                            "residual and layers' diffuse weight")
        w_transl = b.label(raywave_residual_translucent_weight(res[1], open_, k_f, g["blend"])
                           + raywave_layer_translucent_weight(t_fwd, open_, k_f, g["blend"]),
                           "residual and layers' translucent weight")
        # After the lobes, within what they left of the budget (raywave_energy_budget).
        rest = b.label(raywave_energy_budget(w_diffuse + w_transl, used, open_),
                       "budget of the residual and the layers")
        w_diffuse = w_diffuse * rest
        w_transl = w_transl * rest
    return w_diffuse, w_transl


def _raywave_closures(b, Nw, w_transl, w_diffuse, gap, gap_delta, gap_lobes, lobe_outputs, K):
    """The point's closures (loom_cloth_raywave.osl): (the yarns' closures, the gaps')."""
    with b.block("Closures (loom_cloth_raywave.osl)"):
        tr = b.new("ShaderNodeBsdfTranslucent",
                   label="translucent(N) * (residual and layers' translucent weight)")
        b.link(w_transl, tr.inputs["Color"])
        b.link(Nw, tr.inputs["Normal"])
        dif_node = b.new("ShaderNodeBsdfDiffuse",
                         label="diffuse(N) * (residual and layers' diffuse weight)")
        dif_node.inputs["Roughness"].default_value = 0.0
        b.link(w_diffuse, dif_node.inputs["Color"])
        b.link(Nw, dif_node.inputs["Normal"])
        transp = b.new("ShaderNodeBsdfTransparent",
                       label="transparent() * (1 - open), less the sampled diffraction")
        b.link(gap_delta, transp.inputs["Color"])
        # The lobes first: Cycles' SVM compiler emits the closures of an Add Shader chain in
        # order, and a value stays on its stack (255 floats) until its last user is compiled.
        # The layers' closures read every lobe's `forward`; compiled after the lobes, they keep
        # only those few values alive, not every lobe's look-ups (see build_lobe_group).
        # The gaps' closures behind a Mix Shader whose factor is 1 in a gap and 0 elsewhere:
        # Cycles' SVM compiler jumps over a mix input of weight 0 and over the nodes only it
        # needs (SVMCompiler::generate_multi_closure), so yarn points skip the diffraction
        # sampling (the OSL shader's `if (diffraction_gap_sampled(gap) ...)`: Blender reads a
        # stored coverage of 0 as a tiny positive value, so `gap > 0` would run it everywhere);
        # where it runs the factor is 1 and the weights are unchanged.
        gap_closures = b.add_shaders((*gap_lobes, transp.outputs["BSDF"]))
        if gap_lobes:
            mix = b.new("ShaderNodeMixShader",
                        label="diffraction_gap_sampled: the gaps' closures, else none")
            b.link(diffraction_gap_sampled(gap, K), mix.inputs["Fac"])
            b.connect(gap_closures, mix.inputs[2])
            gap_closures = mix.outputs["Shader"]
        yarns = b.add_shaders((*(n.outputs["BSDF"] for n in lobe_outputs),
                               tr.outputs["BSDF"], dif_node.outputs["BSDF"]))
    return yarns, gap_closures


def _lobe_groups(name, atlas_dir, image, rw, nz, K, functions):
    """The lobe groups of this atlas, {"refl": ..., "high": ...}: one for both parts, or one
    each where f_refl and f_high read different noise tiles (speckle_noise.h)."""
    albedo_img = image(rw["shading"]["microfacet_albedo"])
    integral_img = image(rw["shading"]["asg_integral"])
    if nz:
        lobe_groups = {part: build_lobe_group(f"{name} lobe {part}", albedo_img, integral_img, K,
                                              image(nz[part]), part == "refl", nz["instances"],
                                              functions)
                       for part in ("refl", "high")}
    else:
        one = build_lobe_group(f"{name} lobe", albedo_img, integral_img, K,
                               functions=functions)
        lobe_groups = {"refl": one, "high": one}
    for lg in lobe_groups.values():
        lg["loom_atlas"] = os.path.abspath(atlas_dir)
    return lobe_groups


def build_raywave_group(atlas_dir: str, manifest: dict, interpolation: str = "Linear",
                        name: str | None = None):
    """Build (or rebuild in place) the ray-wave node group for this atlas and return it.

    Interface and ``interpolation`` (of the periodic surface maps) as
    node_mode.build_surface_group; the tables are always read as described in the module
    docstring. The lobes are instances of a second group, ``<name> lobe`` (build_lobe_group)."""
    problem = _manifest.raywave_problem(manifest)
    if problem:
        raise ValueError(f"{atlas_dir}: {problem}")
    K = constants()
    g = _manifest.raywave_grid(manifest)
    rw = manifest["raywave"]
    tex_params, _ = _manifest.raywave_osl_parameters(manifest)
    M, N_ = g["m"], g["n"]

    name = name or group_name(manifest)
    label = f"Loom {manifest.get('spec', {}).get('name', 'atlas')}"
    images: dict[str, object] = {}

    def image(tex_name):
        if tex_name not in images:
            images[tex_name] = node_mode.load_atlas_image(atlas_dir, manifest, tex_name, label)
        return images[tex_name]

    functions: dict = {}  # the function groups (Builder.call) of this build
    nz = _manifest.raywave_noise(manifest)
    lobe_groups = _lobe_groups(name, atlas_dir, image, rw, nz, K, functions)
    group = _new_group(name, (("Scale", "NodeSocketFloat"), ("Average", "NodeSocketFloat")),
                       (("BSDF", "NodeSocketShader"),),
                       f"Loom ray-wave cloth from atlas {os.path.abspath(atlas_dir)}")
    node_mode.describe_inputs(group)
    group["loom_atlas"] = os.path.abspath(atlas_dir)
    group["loom_spec_sha256"] = str(manifest.get("spec_sha256", ""))
    group["loom_tier"] = "raywave"

    b = Builder(group, functions)

    def table(tex_name, s, tv, interp="Linear", what=""):
        node = b.new("ShaderNodeTexImage", interpolation=interp, extension="EXTEND",
                     label=f"{tex_name} {what}".strip())
        node.image = image(tex_name)
        b.link(vec(s, tv, 0.0), node.inputs["Vector"])
        return b.vector_socket(node.outputs["Color"]), b.float_socket(node.outputs["Alpha"])

    # ---------------------------------------------------------------- inputs, maps, frame
    with b.block("Inputs: UV * Scale, view, frame (loom_cloth_raywave.osl)"):
        gin = b.new("NodeGroupInput")
        texco = b.new("ShaderNodeTexCoord")
        geo = b.new("ShaderNodeNewGeometry")
        tan = b.new("ShaderNodeTangent", direction_type="UV_MAP")
        scale_ = b.float_socket(gin.outputs["Scale"])
        uvraw = b.vector_socket(texco.outputs["UV"])
        uv = b.label(vec(uvraw.x * scale_, uvraw.y * scale_ * _manifest.repeat_aspect(manifest),
                         0.0), "uv = UV * (Scale, Scale * Aspect)")

    with b.block("Atlas maps (manifest.json: textures, channels RGBA)"):
        tex = {}
        for m in MAPS:
            node = b.new("ShaderNodeTexImage", interpolation=interpolation,
                         extension="REPEAT", label=m)
            node.image = image(m)
            b.link(uv, node.inputs["Vector"])
            tex[m] = (b.vector_socket(node.outputs["Color"]), b.float_socket(node.outputs["Alpha"]))
    c_frame, _ = tex["ply_frame"]
    c_normal, _ = tex["ply_normal"]
    c_info, a_info = tex["yarn_info"]
    c_h0, a_h0 = tex["horizon_0"]
    c_h1, a_h1 = tex["horizon_1"]

    with b.block("Frame: T, B from the front normal, V, ply space (loom_cloth_raywave.osl, "
                 "raywave_ply_space)"):
        back = b.float_socket(geo.outputs["Backfacing"])
        Nw = b.vector_socket(geo.outputs["Normal"])
        Nf = b.label(Nw * (1.0 - 2.0 * back), "Nf (front normal)")
        Tg = b.vector_socket(tan.outputs["Tangent"])
        T = b.label(normalize(Tg - Nf * dot(Nf, Tg)), "T")
        B = b.label(cross(Nf, T), "B")
        Vw = b.vector_socket(geo.outputs["Incoming"])
        V_ = b.label(vec(dot(Vw, T), dot(Vw, B), dot(Vw, Nw)), "V (tangent frame)")
        # Texels outside the baker's ranges back into them first (node_mode: texel_guard.h).
        t, np_, c_info, a_info = node_texel_guard.texel_guard_geometry(
            c_frame, c_normal, c_info, a_info, info_used=(0, 1, 2) if nz else (0,))
        b.label(t, "t")
        b.label(np_, "n_p")
        hor = node_visibility.horizon_vectors(c_h0, a_h0, c_h1, a_h1)
        xp, yp, theta_i, h = b.call(raywave_ply_space, V_, t, np_)
        b.label(theta_i, "theta_i")
        b.label(h, "h")
        open_ = b.label(1.0 - a_info, "open")  # a_info guarded to 0-1 above
        vis_v = b.label(select(back, 1.0, b.call(node_visibility.horizon_visibility, V_, hor, K=K)),
                        "vis_v")
        weft = b.label(c_info[0] > 1.5, "weft (yarn_info.r > 1.5)")
        if nz:
            noise_inst, noise_shift = noise_pick(c_info[2], c_info[1], nz["instances"], K)
            noise_inst = b.label(noise_inst, "noise instance (noise_pick)")
        else:
            noise_inst, noise_shift = 0.0, 0.0

    # ---------------------------------------------------------------- double layer
    with b.block("double_layer_factors.h: k_b, k_f at xi = V"):
        files = rw["shading"]["factors"]
        fac = []
        for block in range(int(K["LOOM_DOUBLE_LAYER_BLOCKS"])):
            ds, dt = double_layer_uv(V_, block, g["layer_theta_count"], g["layer_phi_count"], K)
            cf, _ = table(files["front"], ds, dt, what=f"block {block}")
            cb, _ = table(files["back"], ds, dt, what=f"block {block}")
            fac.append(select(back, cb, cf))
        k_b, k_f = (b.label(f, n) for f, n in zip(fac, ("k_b", "k_f")))

    with b.block("raywave_lobes.h: asg_node_coord"):
        fi = b.label(asg_node_coord(theta_i, g["theta_min"], g["theta_max"], M), "fi")
        fj = b.label(asg_node_coord(h, g["h_min"], g["h_max"], N_), "fj")

    # ---------------------------------------------------------------- lobes
    lobe_outputs, used = _lobe_nodes(b, table, tex_params, g, lobe_groups, (fi, fj), weft, {
        "V": V_, "xp": xp, "yp": yp, "t": t, "T": T, "B": B, "N": Nw, "back": back,
        **dict(zip(node_visibility.HORIZON_SOCKETS, hor)), "open": open_, "vis_v": vis_v,
        "k_f": k_f, "s": g["blend"], "theta_i": theta_i, "noise_instance": noise_inst,
        "noise_shift": noise_shift}, K)

    # ---------------------------------------------------------------- energy residual
    w_diffuse, w_transl = _residual_and_layers(b, table, tex_params, g, (theta_i, h), weft,
                                               lobe_outputs, open_, vis_v, (k_b, k_f), used)

    # ---------------------------------------------------------------- gap diffraction
    gap = 1.0 - open_
    gap_lobes, gap_delta = build_gap_diffraction(
        b, table, b.vector_socket(geo.outputs["Position"]), uv, V_, (T, B, Nw), back, gap,
        _manifest.raywave_diffraction(manifest), rw["shading"]["microfacet_albedo"], K)

    # ---------------------------------------------------------------- closures
    yarns, gap_closures = _raywave_closures(b, Nw, w_transl, w_diffuse, gap, gap_delta,
                                            gap_lobes, lobe_outputs, K)

    far = build_average_closures(b, image(AVERAGE_TEXTURE), V_, back, T, Nw, Vw, a_info,
                                 _manifest.average_gap_mean(manifest),
                                 node_mode.constants(AVERAGE_CONSTANTS))
    with b.block("Average: the texels' yarn closures (0) or the repeat-averaged ones (1)"):
        gout = b.new("NodeGroupOutput")
        b.connect(b.add_shaders((node_mode.mix_average(b, gin.outputs["Average"], yarns, far),
                                 gap_closures)),
                  gout.inputs["BSDF"])

    b.layout()
    return group
