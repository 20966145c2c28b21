"""fitted_closures.h in node mode: the surface tier's per-texel fitted closures (issue 31): the
weights of closure_mapping.h's seven closures as the albedo maps times per-texel factors read
from the atlas's fitted_closures texture (two tiles a side), the closure LUT's specular weights
at the view and the view-side visibility V(V), in place of the mapping's per-sample weights."""

from __future__ import annotations

import math

from .manifest import FITTED_TEXTURE, HORIZON_STRIP
from .node_texel_guard import texel_guard, texel_guard_horizons
from .node_visibility import horizon_ramp
from .nodes_expr import F, V, atan2, clamp, floor, fract, max_, min_, mix, select, vec

# What this module transcribes (see node_mode.TRANSCRIBED_FROM; tests/blender/
# test_transcription.py checks it).
TRANSCRIBED_FROM = {
    "include/loom/fitted_closures.h": "c5145bdf468e993a",
}

REQUIRED_CONSTANTS = ("LOOM_FITTED_PANELS", "LOOM_FITTED_TILES", "LOOM_FITTED_MAX_WEIGHT",
                      "LOOM_HORIZON_DIRS", "LOOM_HORIZON_SOFTNESS")


def fitted_closures_s(su: F, panel: int, back: F, width: int, K) -> F:
    """fitted_closures.h: fitted_closures_s(su, panel, back, width).

        tile = panel + PANELS back
        return (tile (width + 2) + 1 + su width) / (TILES (width + 2))
    """
    tw = float(width + 2)
    n = float(K["LOOM_FITTED_TILES"])
    return (su * (float(width) / (n * tw)) + (panel * tw + 1.0) / (n * tw)
            + back * (K["LOOM_FITTED_PANELS"] * tw / (n * tw)))


def fitted_weight_guard(x: F, K) -> F:
    """fitted_closures.h: fitted_weight_guard(x) = texel_guard(x, 0, MAX_WEIGHT, 0) (one Clamp
    node: a NaN gives the low end, 0, which is the fallback here too)."""
    return texel_guard(x, 0.0, K["LOOM_FITTED_MAX_WEIGHT"])


def fitted_closure_weights(k_rd: V, k_rs: F, k_td: V, k_ts: F, fd, fs, lut_g: F, lut_h: F,
                           vis_v: F):
    """fitted_closures.h: fitted_closure_weights(...) -> (w_diffuse_np, w_diffuse_ns,
    w_translucent_np, w_translucent_ns, w_glossy, w_hair); fd = (a_np, a_ns, b_np, b_ns),
    fs = (m_g, m_h, l).

        w_diffuse_np = k_rd (a_np vis_v);  w_diffuse_ns = k_rd (a_ns vis_v)
        w_translucent_np = k_td b_np;  w_translucent_ns = k_td b_ns + k_ts l
        w_glossy = k_rs m_g max(lut_g, 0) vis_v;  w_hair = k_ts m_h max(lut_h, 0)
    """
    a_np, a_ns, b_np, b_ns = fd
    m_g, m_h, l_ = fs
    w_dnp = k_rd * (a_np * vis_v)
    w_dns = k_rd * (a_ns * vis_v)
    w_tnp = k_td * b_np
    kl = k_ts * l_
    w_tns = k_td * b_ns + vec(kl, kl, kl)
    return (w_dnp, w_dns, w_tnp, w_tns, k_rs * m_g * max_(lut_g, 0.0) * vis_v,
            k_ts * m_h * max_(lut_h, 0.0))


def fitted_yarn_weights(b, image, uv: V, back: F, interpolation: str, width: int, optics,
                        lut_g: F, lut_h: F, vis_v: F, K):
    """The fitted texture's two panels at this point and side, guarded, and the closures'
    weights (w_dnp, w_dns, w_tnp, w_tns, w_glossy, w_hair). ``optics``: the guarded (k_rd, k_rs,
    k_td, k_ts); lut_g, lut_h: the closure LUT's weights at this view."""
    with b.block("fitted_closures.h: fitted_closures_s, the two panels, fitted_weight_guard"):
        su = fract(uv.x)  # the repeat's u in [0, 1); v wraps by the image's REPEAT
        reads = []
        for panel in range(int(K["LOOM_FITTED_PANELS"])):
            node = b.new("ShaderNodeTexImage", interpolation=interpolation, extension="REPEAT",
                         label=f"{FITTED_TEXTURE} panel {panel}")
            node.image = image
            b.link(vec(fitted_closures_s(su, panel, back, width, K), uv.y, 0.0),
                   node.inputs["Vector"])
            reads.append((b.vector_socket(node.outputs["Color"]),
                          b.float_socket(node.outputs["Alpha"])))
        (c0, a0), (c1, _a1) = reads
        fd = [fitted_weight_guard(x, K) for x in (c0.x, c0.y, c0.z, a0)]
        fs = [fitted_weight_guard(x, K) for x in (c1.x, c1.y, c1.z)]
    with b.block("fitted_closures.h: fitted_closure_weights"):
        k_rd, k_rs, k_td, k_ts = optics
        return fitted_closure_weights(k_rd, k_rs, k_td, k_ts, fd, fs, lut_g, lut_h, vis_v)


def horizon_strip_coords(w: V, su: F, width: int, K):
    """fitted_closures.h: horizon_strip_coords(w, su, width, s, f) -> (s, f).

        phi = atan2(w.y, w.x); if (phi < 0) phi += 2 pi
        x = phi / (2 pi) DIRS;  k = min(floor(x), DIRS - 1);  f = clamp(x - k, 0, 1)
        s = (k (width + 2) + 1 + su width) / (DIRS (width + 2))
    """
    n = float(K["LOOM_HORIZON_DIRS"])
    phi = atan2(w.y, w.x)
    phi = select(phi < 0.0, phi + 2.0 * math.pi, phi)
    x = phi * (n / (2.0 * math.pi))
    k = min_(floor(x), n - 1.0)
    f = clamp(x - k, 0.0, 1.0)
    tw = float(width + 2)
    return k * (1.0 / n) + su * (float(width) / (n * tw)) + 1.0 / (n * tw), f


def strip_visibility(b, image, uv: V, V_: V, back: F, interpolation: str, width: int, K) -> F:
    """V(V) from the horizon strip, 1 on a back face (loom_cloth_surface.osl, fitted closures):
    fitted_closures.h's horizon_strip_visibility(V, h_k, h_k+1, f) = horizon_ramp(V, mix(h_k,
    h_k+1, f)) with the two sines read at V's azimuth, each guarded as texel_guard_horizon (the
    three channels in one node)."""
    with b.block("fitted_closures.h, visibility.h: V(V) from the horizon strip"):
        su = fract(uv.x)
        s, f = horizon_strip_coords(V_, su, width, K)
        node = b.new("ShaderNodeTexImage", interpolation=interpolation, extension="REPEAT",
                     label=HORIZON_STRIP)
        node.image = image
        b.link(vec(s, uv.y, 0.0), node.inputs["Vector"])
        h = texel_guard_horizons(b.vector_socket(node.outputs["Color"]))
        return b.label(select(back, 1.0, horizon_ramp(V_, mix(h.x, h.y, f), K)), "vis_v")
