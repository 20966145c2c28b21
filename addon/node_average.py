"""average_closures.h in node mode: the repeat-averaged closures (level of detail by footprint)
that both tiers' groups use where a pixel covers whole weave repeats, transcribed line by line
through ``nodes_expr``, and the block that reads them and builds their four BSDF nodes.

A group mixes its per-texel yarn closures with these by its ``Average`` input (a Mix Shader:
Cycles' SVM jumps over the input of weight 0 and the nodes only it needs, so at Average 1 no
per-texel look-up but yarn_info runs, and at 0 none of these)."""

from __future__ import annotations

import math

from .manifest import AVERAGE_TEXTURE
from .node_bsdf import ggx_glossy
from .nodes_expr import F, V, atan2, clamp, length, madd, max_, select, sqrt, vec

# What this module transcribes (see node_mode.TRANSCRIBED_FROM; tests/blender/
# test_transcription.py checks it).
TRANSCRIBED_FROM = {
    "include/loom/average_closures.h": "35ad9e82ce09a41d",
    "include/loom/average_closures_osl.h": "f7035e7779242cec",
}
REQUIRED_CONSTANTS = ("LOOM_AVERAGE_THETA", "LOOM_AVERAGE_PHI", "LOOM_AVERAGE_PANELS",
                      "LOOM_AVERAGE_ETA")


def average_closures_uv(V_: V, back, panel: float, K):
    """average_closures.h: average_closures_uv(V, back, panel, s, tv).

        phi = atan2(V.y, V.x); if (phi < 0) phi += 2 pi
        s = (0.5 + phi np / (2 pi)) / (np + 1)
        c = clamp(V.z / max(|V|, 1e-8), 0, 1); row0 = (back PANELS + panel) nt
        tv = (row0 + 0.5 + c (nt - 1)) / (2 PANELS nt)
    """
    n_p, n_t = K["LOOM_AVERAGE_PHI"], K["LOOM_AVERAGE_THETA"]
    panels = K["LOOM_AVERAGE_PANELS"]
    phi = atan2(V_.y, V_.x)
    phi = select(phi < 0.0, phi + 2.0 * math.pi, phi)
    s = (0.5 + phi * (n_p / (2.0 * math.pi))) * (1.0 / (n_p + 1.0))
    c = clamp(V_.z / max_(length(V_), 1e-8), 0.0, 1.0)
    # regrouped, so that the four panels share all but one node: with k = 1 / (2 PANELS nt),
    # tv = (c (nt - 1) k + back PANELS nt k) + (panel nt + 0.5) k
    k = 1.0 / (2.0 * panels * n_t)
    tv = madd(c, (n_t - 1.0) * k, back * (panels * n_t * k)) + (panel * n_t + 0.5) * k
    return s, tv


def average_closures_yarn_scale(gap, gap_mean: float):
    """average_closures.h: average_closures_yarn_scale(gap, gap_mean) =
    (1 - gap) / max(1 - gap_mean, 1e-3)."""
    return (1.0 - gap) * (1.0 / max(1.0 - gap_mean, 1e-3))


def build_average_closures(b, image, V_: V, back: F, T: V, N: V, Vw: V, gap: F, gap_mean: float,
                           K):
    """The repeat-averaged closures (average_closures.h's table) at view V_ (the frame T, B, N,
    N towards the viewer), scaled by this point's yarn coverage: returns their summed shader.
    ``image``: the atlas's average_closures (.exr twin), read Linear with EXTEND (texel centres
    sit on the fitted views; the wrap column makes the azimuth periodic)."""
    looks = []
    with b.block("average_closures.h: average_closures_uv, the four panels"):
        for panel, what in enumerate(("d, a_x", "l, a_y", "g, a_t", "r")):
            s, tv = average_closures_uv(V_, back, float(panel), K)
            node = b.new("ShaderNodeTexImage", interpolation="Linear", extension="EXTEND",
                         label=f"{AVERAGE_TEXTURE} ({what})")
            node.image = image
            # Image nodes count v from the bottom, as tv.
            b.link(vec(s, tv, 0.0), node.inputs["Vector"])
            looks.append((b.vector_socket(node.outputs["Color"]),
                          b.float_socket(node.outputs["Alpha"])))
    (d, ax), (l_, ay), (g, at), (r, _) = looks
    eta = K["LOOM_AVERAGE_ETA"]
    with b.block("average_closures.h: average_closures_yarn_scale; the closures"):
        k = b.label(average_closures_yarn_scale(gap, gap_mean), "yarn scale")
        dif = b.new("ShaderNodeBsdfDiffuse", label="diffuse(N) * d")
        dif.inputs["Roughness"].default_value = 0.0
        b.link(d * k, dif.inputs["Color"])
        b.link(N, dif.inputs["Normal"])
        tr = b.new("ShaderNodeBsdfTranslucent", label="translucent(N) * l")
        b.link(l_ * k, tr.inputs["Color"])
        b.link(N, tr.inputs["Normal"])
        gl = ggx_glossy(b, 'microfacet("ggx", N, T, a_x, a_y) * g', g * k, ax, ay, N, T)
        # microfacet("ggx", V, V, a_t, a_t, ETA, 1): alpha = Roughness^2; the SVM node inverts
        # its IOR on back faces, so it gets 1 / ETA there.
        rf = b.new("ShaderNodeBsdfRefraction", distribution="GGX",
                   label='microfacet("ggx", V, V, a_t, a_t, ETA, 1) * r')
        b.link(r * k, rf.inputs["Color"])
        b.link(sqrt(at), rf.inputs["Roughness"])
        b.link(select(back, 1.0 / eta, eta), rf.inputs["IOR"])
        b.link(Vw, rf.inputs["Normal"])
        return b.add_shaders((dif.outputs["BSDF"], tr.outputs["BSDF"], gl.outputs["BSDF"],
                              rf.outputs["BSDF"]))
