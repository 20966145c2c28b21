"""visibility.h in node mode: the horizon visibility of a direction from the horizon maps'
sines (the surface and the ray-wave group)."""

from __future__ import annotations

import math

from .nodes_expr import F, V, atan2, clamp, fabs, max_, select, wrap

# What this module transcribes (see node_mode.TRANSCRIBED_FROM; tests/blender/
# test_transcription.py checks it).
TRANSCRIBED_FROM = {
    "include/loom/visibility.h": "748a60042d62eda6",
}

def horizon_sine(w: V, h: list, K) -> F:
    """visibility.h: horizon_sine(w, h).

        phi = atan2(w.y, w.x); if (phi < 0) phi += 2 pi
        x = phi / (2 pi) * DIRS;  k = floor(x);  f = x - k;  k1 = (k + 1) % DIRS
        return mix(h[k], h[k1], clamp(f, 0, 1))

    Nodes cannot index an array, so the linear interpolation between bins k and k+1 on the
    circle is written as the identical sum of tents: for x in [0, DIRS),
    mix(h[k], h[k+1], f) = sum_j h[j] max(0, 1 - d_j) with d_j the circular distance from x to
    bin j, d_j = |wrap(x - j + DIRS/2, DIRS, 0) - DIRS/2| (only j = k, k+1 have d_j < 1, with
    weights 1 - f and f)."""
    n = int(K["LOOM_HORIZON_DIRS"])
    phi = atan2(w.y, w.x)
    phi = select(phi < 0.0, phi + 2.0 * math.pi, phi)
    x = phi / (2.0 * math.pi) * n
    terms = []
    for j in range(n):
        d = fabs(wrap(x + (0.5 * n - j), float(n), 0.0) - 0.5 * n)
        terms.append(h[j] * max_(1.0 - d, 0.0))
    return balanced_sum(terms)


def horizon_visibility(w: V, h: list, K) -> F:
    """visibility.h: horizon_visibility(w, h).

        if (w.z <= 0) return 1
        s = horizon_sine(w, h)
        x = clamp((w.z - (s - SOFT)) / (2 SOFT), 0, 1);  return x x (3 - 2 x)
    """
    soft = K["LOOM_HORIZON_SOFTNESS"]
    s = horizon_sine(w, h, K)
    x = clamp((w.z - (s - soft)) / (2.0 * soft), 0.0, 1.0)
    smooth = x * x * (3.0 - 2.0 * x)
    below = 1.0 - (w.z > 0.0)  # w.z <= 0
    return select(below, 1.0, smooth)


def horizon_ambient_visibility(h: list, K) -> F:
    """visibility.h: horizon_ambient_visibility(h).

        sum = 0; for k: s = clamp(h[k], 0, 1); sum += 1 - s s;  return sum / DIRS
    """
    n = int(K["LOOM_HORIZON_DIRS"])
    terms = []
    for k in range(n):
        s = clamp(h[k], 0.0, 1.0)
        terms.append(1.0 - s * s)
    return balanced_sum(terms) / float(n)


def balanced_sum(terms):
    """terms[0] + terms[1] + ... as a balanced tree of Add nodes (short dependency chains keep
    the group's layout compact; the sum is the same)."""
    while len(terms) > 1:
        terms = [terms[i] + terms[i + 1] if i + 1 < len(terms) else terms[i]
                 for i in range(0, len(terms), 2)]
    return terms[0]
