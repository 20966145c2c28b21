"""The gaps' diffraction in node mode: loom_cloth_raywave.osl's sampling of the diffraction
tables where light passes between the yarns (diffraction_sampling.h, through node_wave's
transcriptions), as Refraction BSDF nodes, one per sampled lobe and colour channel."""

from __future__ import annotations

from .node_raywave_lobes import microfacet_albedo_uv
from .node_wave import (diffraction_cell_row, diffraction_gap_offset, diffraction_light_direction,
                        diffraction_lobe_closure, diffraction_lobe_weight, diffraction_sample_uv,
                        diffraction_split, diffraction_stratum, diffraction_table_s,
                        diffraction_tile_pick)
from .nodes_expr import dot, fract, normalize, select, sqrt, vec


def build_gap_diffraction(b, table, geo_p, uv, V_, frame, back, gap, dif, albedo_file, K):
    """The diffraction lobes of a gap point and what stays a delta transmission.

    ``table(file, s, tv, what=...)`` reads an atlas table (node_mode_raywave); ``geo_p`` the
    shading position, ``uv`` the repeat coordinates, ``frame`` (T, B, N) the tangent frame,
    ``gap`` the point's gap coverage, ``dif`` the manifest's diffraction section (None: no
    diffraction baked). Returns (the Refraction BSDF outputs, the transparent closure's weight)."""
    T, B, Nw = frame
    gap_delta = vec(gap, gap, gap)
    gap_lobes = []
    if not dif:
        return gap_lobes, gap_delta
    with b.block("Gap diffraction (diffraction_sampling.h; loom_cloth_raywave.osl)"):
        # Four independent uniform numbers. (Not one node's Value and Color: Cycles' white
        # noise computes Color.r with the very hash of Value, kernel/svm/white_noise.h.)
        rnd_nodes = []
        for w in (0.0, 1.0):
            node = b.new("ShaderNodeTexWhiteNoise", noise_dimensions="4D",
                         label=f'noise("hash", P, {w:g} ...)')
            b.link(geo_p, node.inputs["Vector"])
            b.link(w, node.inputs["W"])
            rnd_nodes.append(node)
        rnd = b.vector_socket(rnd_nodes[0].outputs["Color"])
        r3 = b.float_socket(rnd_nodes[1].outputs["Value"])
        nx, ny, size = dif["tiles_x"], dif["tiles_y"], dif["size"]
        ox = diffraction_gap_offset(fract(uv.x), dif["weft_yarns"],
                                    dif["gap_fraction"][0])
        oy = diffraction_gap_offset(fract(uv.y), dif["warp_yarns"],
                                    dif["gap_fraction"][1])
        tx = b.label(diffraction_tile_pick(ox, nx, rnd.x), "tile x")
        ty = b.label(diffraction_tile_pick(oy, ny, rnd.y), "tile y")
        gs, gt = diffraction_sample_uv(0.5, size, tx, ty, nx, ny, size, K)
        p_out, _ = table(dif["file"], gs, gt, what="p_out")
        n_samples = int(K["LOOM_DIFFRACTION_SAMPLES"])
        for k in range(n_samples):
            u_y, sgn_y = diffraction_split(diffraction_stratum(rnd.z, k, 1.0 / n_samples))
            u_x, sgn_x = diffraction_split(diffraction_stratum(r3, k, 0.6180339887))
            gs, gt = diffraction_sample_uv(u_y, 0, tx, ty, nx, ny, size, K)
            t_y, _ = table(dif["file"], gs, gt, what=f"t_y (marginal), lobe {k}")
            for c in range(3):
                row = diffraction_cell_row(t_y[c], size)
                gs, gt = diffraction_sample_uv(u_x, row, tx, ty, nx, ny, size, K)
                t_x, _ = table(dif["file"], gs, gt, what=f"t_x, lobe {k} channel {c}")
                L, ok1 = b.call(diffraction_light_direction,
                                V_, sgn_x * diffraction_table_s(t_x[c], K),
                                sgn_y * diffraction_table_s(t_y[c], K))
                Nd, alpha, ok2 = b.call(diffraction_lobe_closure, V_, L, K=K)
                ok = ok1 * ok2
                ls, lt = microfacet_albedo_uv(dot(Nd, V_), alpha, K)
                E, _ = table(albedo_file, ls, lt, what=f"lobe {k} channel {c}")
                w = gap * b.call(diffraction_lobe_weight, V_, L, p_out[c], E.y, K=K) * ok
                unit = tuple(1.0 if i == c else 0.0 for i in range(3))
                rf = b.new("ShaderNodeBsdfRefraction", distribution="BECKMANN",
                           label=f'microfacet("beckmann", N, N, a, a, eta, 1), lobe {k} '
                                 f'channel {c}')
                b.link(vec(*(w if i == c else 0.0 for i in range(3))), rf.inputs["Color"])
                b.link(sqrt(alpha), rf.inputs["Roughness"])
                b.link(select(back, 1.0 / K["LOOM_RAYWAVE_ETA"], K["LOOM_RAYWAVE_ETA"]),
                       rf.inputs["IOR"])
                b.link(normalize(T * Nd.x + B * Nd.y + Nw * Nd.z), rf.inputs["Normal"])
                gap_lobes.append(rf.outputs["BSDF"])
                gap_delta = gap_delta - vec(*unit) * (gap * p_out[c] * ok
                                                      * (1.0 / n_samples))
    return gap_lobes, gap_delta
