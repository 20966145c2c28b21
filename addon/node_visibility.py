"""visibility.h in node mode: the horizon visibility of a direction from the horizon maps'
sines (the surface and the ray-wave group)."""

from __future__ import annotations

import math

from .node_texel_guard import texel_guard_horizons
from .nodes_expr import F, V, atan2, clamp, dot, select, vabs, vec, vmax, vmin

# What this module transcribes (see node_mode.TRANSCRIBED_FROM; tests/blender/
# test_transcription.py checks it).
TRANSCRIBED_FROM = {
    "include/loom/visibility.h": "227539d6258fc762",
}

# The 8 horizon sines travel as three vectors, bins HORIZON_BINS[k] in horizon vector k: the
# colour channels of horizon_0 and horizon_1 and the two maps' alphas (third component 0).
# Vector Math nodes work on three values at once, so the sums over the 8 bins below take a third
# of the nodes a sum of scalars takes (each node is evaluated at every shading point: the
# scalar form of the visibility was half of the surface group's render time).
HORIZON_BINS = ((0, 1, 2), (4, 5, 6), (3, 7, 3))
HORIZON_SOCKETS = ("hor_a", "hor_b", "hor_c")


def horizon_vectors(c_h0: V, a_h0: F, c_h1: V, a_h1: F) -> list:
    """The horizon maps' texels as the three vectors of HORIZON_BINS, each sine guarded as
    texel_guard.h's texel_guard_horizon does (node_texel_guard.texel_guard_horizons)."""
    return [texel_guard_horizons(c_h0), texel_guard_horizons(c_h1),
            texel_guard_horizons(vec(a_h0, a_h1, 0.0))]


def horizon_sine(w: V, hv: list, K) -> F:
    """visibility.h: horizon_sine(w, h).

        phi = atan2(w.y, w.x); if (phi < 0) phi += 2 pi
        x = phi / (2 pi) * DIRS;  k = floor(x);  f = x - k;  k1 = (k + 1) % DIRS
        return mix(h[k], h[k1], clamp(f, 0, 1))

    Nodes cannot index an array, so the linear interpolation between bins k and k+1 on the
    circle is written as the identical sum of tents: for x in [0, DIRS],
    mix(h[k], h[k+1], f) = sum_j h[j] max(0, 1 - d_j) with d_j = min(|x - j|, DIRS - |x - j|)
    the circular distance from x to bin j (only j = k, k+1 have d_j < 1, with weights 1 - f and
    f), three bins a Vector Math node (``hv``: horizon_vectors)."""
    n = int(K["LOOM_HORIZON_DIRS"])
    if n != 8:
        raise ValueError("node mode packs 8 horizon directions (LOOM_HORIZON_DIRS)")
    phi = atan2(w.y, w.x)
    phi = select(phi < 0.0, phi + 2.0 * math.pi, phi)
    x = phi / (2.0 * math.pi) * n
    xv = vec(x, x, x)
    terms = []
    for h, bins in zip(hv, HORIZON_BINS):
        dist = vabs(xv - tuple(float(j) for j in bins))
        dist = vmin(dist, (float(n),) * 3 - dist)
        terms.append(dot(vmax((1.0, 1.0, 1.0) - dist, (0.0, 0.0, 0.0)), h))
    return balanced_sum(terms)


def horizon_ramp(w: V, s: F, K) -> F:
    """visibility.h: horizon_ramp(w, s).

        if (w.z <= 0) return 1
        x = clamp((w.z - (s - SOFT)) / (2 SOFT), 0, 1);  return x x (3 - 2 x)
    """
    soft = K["LOOM_HORIZON_SOFTNESS"]
    x = clamp((w.z - (s - soft)) / (2.0 * soft), 0.0, 1.0)
    smooth = x * x * (3.0 - 2.0 * x)
    below = 1.0 - (w.z > 0.0)  # w.z <= 0
    return select(below, 1.0, smooth)


def horizon_visibility(w: V, hv: list, K) -> F:
    """visibility.h: horizon_visibility(w, h).

        if (w.z <= 0) return 1
        return horizon_ramp(w, horizon_sine(w, h))

    (horizon_ramp's own test of w.z is the same, so it is made once.)"""
    return horizon_ramp(w, horizon_sine(w, hv, K), K)


def horizon_ambient_visibility(hv: list, K) -> F:
    """visibility.h: horizon_ambient_visibility(h).

        sum = 0; for k: s = clamp(h[k], 0, 1); sum += 1 - s s;  return sum / DIRS

    as (DIRS - sum_k s_k^2) / DIRS, each vector's squares a dot product (the unused third
    component of the alphas' vector is 0 and adds nothing)."""
    n = int(K["LOOM_HORIZON_DIRS"])
    squares = []
    for h in hv:
        s = vmin(vmax(h, (0.0, 0.0, 0.0)), (1.0, 1.0, 1.0))
        squares.append(dot(s, s))
    return (float(n) - balanced_sum(squares)) / float(n)


def balanced_sum(terms):
    """terms[0] + terms[1] + ... as a balanced tree of Add nodes (short dependency chains keep
    the group's layout compact; the sum is the same)."""
    while len(terms) > 1:
        terms = [terms[i] + terms[i + 1] if i + 1 < len(terms) else terms[i]
                 for i in range(0, len(terms), 2)]
    return terms[0]
