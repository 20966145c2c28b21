"""texel_guard.h in node mode: every atlas texel a node group reads brought back into the
baker's ranges before any shading math, as the OSL shaders do (see the notes below on where
node mode differs, for values no baked atlas holds). Used by the surface and the ray-wave group.
"""

from __future__ import annotations

from .nodes_expr import F, V, clamp, cross, dot, fabs, length, normalize, select, vmax, vmin

# What this module transcribes (see node_mode.TRANSCRIBED_FROM; tests/blender/
# test_transcription.py checks it).
TRANSCRIBED_FROM = {
    "include/loom/texel_guard.h": "c730c1caecf1a08f",
}

#
# Both shaders bring every atlas texel back into the baker's ranges before any shading math; node
# mode does the same for the texels its math reads (height, h, the optical thickness and the IOR
# are read by neither group's math). The guard costs render time (each node is evaluated at every
# shading point), so it is built from as few nodes as keep it safe, and differs from the header
# only for values no baked atlas holds:
# * a NaN becomes the range's low end, not the field's neutral value: one Clamp node per value
#   (Cycles' clamp is min(max(x, lo), hi) with max(a, b) = a > b ? a : b, so a NaN comes out as lo).
#   In Blender 4.3 on the CPU a NaN never reaches node mode anyway: Cycles sets every channel of a
#   float pixel to 0 when one is not finite (scene/image.cpp, "Make sure we don't have buggy
#   values"), and its SVM image textures read a half NaN or Inf as a finite 65536 or more and a
#   stored 0 as 2^-15 (util/half.h's half_to_float rebiases the exponent without special cases;
#   later versions convert exactly where the CPU can, as GPUs do: there a NaN arrives as NaN);
# * a vector whose length overflows a float (components beyond 1e19, only in float maps) gets the
#   fallback frame instead of its direction. "No direction" is a length of at most 1e-3 in both.

_BIG = 3.0e38  # a finite bound below FLT_MAX that a node socket stores exactly


def texel_guard(x, lo: float, hi: float):
    """texel_guard.h: texel_guard(x, lo, hi, fallback) = isnan(x) ? fallback : clamp(x, lo, hi),
    as one Clamp node: a NaN gives lo (see above)."""
    return clamp(x, lo, hi)


def texel_guard_color(c: V, lo: float, hi: float) -> V:
    """texel_guard.h: texel_guard_color(c, lo, hi, fallback): each channel by texel_guard, as
    min(max(c, lo), hi) on the three at once (Vector Math: a NaN channel gives lo, as above)."""
    return vmin(vmax(c, (lo, lo, lo)), (hi, hi, hi))


def texel_guard_unit(v: V) -> V:
    """texel_guard.h: texel_guard_unit(v): v / |v|, or the zero vector when v is not finite or has
    no direction (no longer than 1e-3).

    Each component is clamped to +-3e38 first (a NaN becomes -3e38, an Inf 3e38), so the Mix
    node's unused side stays finite; Vector Math NORMALIZE gives 0 for 0."""
    cl = texel_guard_color(v, -_BIG, _BIG)
    return select(length(cl) > 1e-3, normalize(cl), (0.0, 0.0, 0.0))


def texel_guard_frame(t: V, n: V):
    """texel_guard.h: texel_guard_frame(t, n) -> (t, n).

        nn = texel_guard_unit(n); if (!(nn.z > 0)) nn = (0,0,1)
        tt = texel_guard_unit(t)
        if (!(length(cross(tt, nn)) > 1e-3) || !(length((tt.x, tt.y, 0)) > 1e-3)):
            a = |nn.x| > 0.9 ? (0,1,0) : (1,0,0);  tt = normalize(a - nn dot(a, nn))
    """
    nn = texel_guard_unit(n)
    nn = select(nn.z > 0.0, nn, (0.0, 0.0, 1.0))
    tt = texel_guard_unit(t)
    a = select(fabs(nn.x) > 0.9, (0.0, 1.0, 0.0), (1.0, 0.0, 0.0))
    fb = normalize(a - nn * dot(a, nn))
    keep = (length(cross(tt, nn)) > 1e-3) * (length(tt * (1.0, 1.0, 0.0)) > 1e-3)
    return select(keep, tt, fb), nn


def texel_guard_horizons(v: V) -> V:
    """texel_guard.h: texel_guard_horizon(s) = texel_guard(s, -1, 1, 0) on three sines at once
    (texel_guard_color)."""
    return texel_guard_color(v, -1.0, 1.0)


def texel_guard_geometry(c_frame: V, c_normal: V, c_info: V, gap: F, info_used=(0,)):
    """texel_guard.h: texel_guard_geometry, for what node mode reads: the ply frame (t, n),
    yarn_info (kind 0-2, along 0-1, ply id 0-1: only the channels in ``info_used``, the others
    pass as they are) and the gap coverage (0-1). Returns (t, n, (kind, along, ply_id), gap)."""
    t, n = texel_guard_frame(c_frame, c_normal)
    ranges = ((0.0, 2.0), (0.0, 1.0), (0.0, 1.0))
    info = tuple(texel_guard(c_info[i], *ranges[i]) if i in info_used else c_info[i]
                 for i in range(3))
    return t, n, info, texel_guard(gap, 0.0, 1.0)


def texel_guard_optics(k_rd: V, k_rs: F, k_td: V, k_ts: F, params: V):
    """texel_guard.h: texel_guard_optics, for what node mode reads: albedos 0-1 and the blend 0-1
    of spec_params (the closures' roughnesses come from the closure LUT, not from the texel).
    Returns (k_rd, k_rs, k_td, k_ts, blend)."""
    return (texel_guard_color(k_rd, 0.0, 1.0), texel_guard(k_rs, 0.0, 1.0),
            texel_guard_color(k_td, 0.0, 1.0), texel_guard(k_ts, 0.0, 1.0),
            texel_guard(params.z, 0.0, 1.0))
