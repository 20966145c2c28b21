"""diffraction_table.h, diffraction_sampling.h and speckle_noise.h in node mode: the gaps'
diffraction as the shaders sample it and the speckle noise per lobe, transcribed line by line
through ``nodes_expr`` (node_mode_raywave.py builds the groups from them). Each function names
the header function it mirrors; ``K`` is the headers' constants."""

from __future__ import annotations

import math

from .node_raywave_lobes import asg_lobe_refraction_frame, asg_refraction_alpha
from .nodes_expr import (asin, atan2, clamp, fabs, floor, fract, length, max_, min_, normalize,
                         select, sqrt, vec)

# What this module transcribes (see node_mode.TRANSCRIBED_FROM; tests/blender/test_transcription.py
# checks it).
TRANSCRIBED_FROM = {
    "include/loom/diffraction_table.h": "452b37e1478a3fd5",
    "include/loom/diffraction_sampling.h": "4d46b702270699dc",
    "include/loom/speckle_noise.h": "db12339f3a287d00",
}


# ======================================================================= diffraction_table.h,
#                                                                         diffraction_sampling.h


def diffraction_obliquity(xi_i, xi_o):
    """diffraction_table.h: diffraction_obliquity(xi_i, xi_o) = (|xi_i.z| + |xi_o.z|)^2 / 4."""
    a = fabs(xi_i.z) + fabs(xi_o.z)
    return 0.25 * a * a


def diffraction_table_s(t, K):
    """diffraction_table.h: diffraction_table_s(t) = S_MAX t^2."""
    return K["LOOM_DIFFRACTION_S_MAX"] * t * t


def diffraction_gap_sampled(gap, K):
    """diffraction_sampling.h: diffraction_gap_sampled(gap) = gap > LOOM_DIFFRACTION_MIN_GAP."""
    return gap > K["LOOM_DIFFRACTION_MIN_GAP"]


def diffraction_gap_offset(coord, yarns, gap_fraction):
    """diffraction_sampling.h: diffraction_gap_offset(coord, yarns, gap_fraction).

        x = coord yarns;  c = x - floor(x + 0.5);  min(|c| 2 / max(gap_fraction, 1e-6), 1)"""
    x = coord * float(yarns)
    c = x - floor(x + 0.5)
    return min_(fabs(c) * (2.0 / max(gap_fraction, 1e-6)), 1.0)


def diffraction_tile_coord(o, n):
    """diffraction_sampling.h: diffraction_tile_coord(o, n) = (n - 1) (1 - sqrt(1 - clamp(o, 0, 1)))
    (NaN: 0, which Blender's Clamp node already gives)."""
    return float(n - 1) * (1.0 - sqrt(1.0 - clamp(o, 0.0, 1.0)))


def diffraction_tile_pick(o, n, r):
    """diffraction_sampling.h: diffraction_tile_pick(o, n, r).

        n < 2: 0;  f = diffraction_tile_coord(o, n);  i = floor(f);  i >= n - 1: n - 1
        r < f - i: i + 1;  else i"""
    if n < 2:
        return 0.0
    f = diffraction_tile_coord(o, n)
    i = floor(f)
    return select(i > n - 1.5, float(n - 1), select(r < f - i, i + 1.0, i))


def diffraction_stratum(r, k, step):
    """diffraction_sampling.h: diffraction_stratum(r, k, step) = x - floor(x), x = r + k step."""
    x = r + k * step
    return fract(x)


def diffraction_split(r):
    """diffraction_sampling.h: diffraction_split(r, sgn) -> (u, sgn).

        sgn = r < 0.5 ? -1 : 1;  u = clamp(|2 r - 1|, 0, 1)"""
    return clamp(fabs(2.0 * r - 1.0), 0.0, 1.0), select(r < 0.5, -1.0, 1.0)


def diffraction_sample_uv(u, row, tx, ty, tiles_x, tiles_y, size, K):
    """diffraction_sampling.h: diffraction_sample_uv(u, row, tx, ty, tiles_x, tiles_y, size) ->
    (s, tv).

        k = clamp(u, 0, 1) (ICDF - 1) + 0.5;  s = (tx ICDF + k) / (tiles_x ICDF)
        tv = (ty (size + 1) + row + 0.5) / (tiles_y (size + 1))"""
    icdf = K["LOOM_DIFFRACTION_ICDF_SIZE"]
    k = clamp(u, 0.0, 1.0) * (icdf - 1.0) + 0.5
    s = (tx * icdf + k) * (1.0 / (tiles_x * icdf))
    tv = (ty * (size + 1.0) + row + 0.5) * (1.0 / (tiles_y * (size + 1.0)))
    return s, tv


def diffraction_cell_row(t_y, size):
    """diffraction_sampling.h: diffraction_cell_row(t_y, size) =
    1 + max(0, min(floor(clamp(t_y, 0, 1) (size - 1)), size - 2)) (NaN: row 1, as the Clamp
    node gives)."""
    j = floor(clamp(t_y, 0.0, 1.0) * (size - 1.0))
    return 1.0 + max_(0.0, min_(j, size - 2.0))


def diffraction_light_direction(V_, s_x, s_y):
    """diffraction_sampling.h: diffraction_light_direction(V, s_x, s_y, L) -> (L, ok).

        lx = s_x - V.x;  ly = s_y - V.y;  r2 = lx^2 + ly^2
        ok = r2 < 1;  L = ok ? (lx, ly, -sqrt(1 - r2)) : (0, 0, -1)"""
    lx = s_x - V_.x
    ly = s_y - V_.y
    r2 = lx * lx + ly * ly
    ok = r2 < 1.0
    L = select(ok, vec(lx, ly, -sqrt(max_(1.0 - r2, 0.0))), (0.0, 0.0, -1.0))
    return L, ok


def diffraction_lobe_weight(V_, L, p_out, albedo, K):
    """diffraction_sampling.h: diffraction_lobe_weight(V, L, p_out, albedo) =
    p_out obliquity(L, V) / max(|L.z|, MIN_COS) / (max(albedo, MIN_ALBEDO) SAMPLES)."""
    w = p_out * diffraction_obliquity(L, V_) / max_(fabs(L.z), K["LOOM_DIFFRACTION_MIN_COS"])
    return w / (max_(albedo, K["LOOM_RAYWAVE_MIN_ALBEDO"]) * K["LOOM_DIFFRACTION_SAMPLES"])


def diffraction_lobe_closure(V_, L, K):
    """diffraction_sampling.h: diffraction_lobe_closure(V, L, N, alpha) -> (N, alpha, ok).

        mu = 0.5 / KERNEL_RAD^2;  ok = asg_lobe_refraction_frame(V, L, N, mag)
        alpha = asg_refraction_alpha(mu, mu, mag, N, L)"""
    mu = 0.5 / (K["LOOM_DIFFRACTION_KERNEL_RAD"] ** 2)
    N, mag, ok = asg_lobe_refraction_frame(V_, L, K)
    return N, asg_refraction_alpha(mu, mu, mag, N, L, K), ok


# ======================================================================= speckle_noise.h


def _mod(x, y):
    """OSL's mod(x, y) = x - y floor(x / y) (y a positive constant)."""
    return x - floor(x * (1.0 / y)) * y


def noise_hash_round(x, a, c, K):
    """speckle_noise.h: noise_hash_round(x, a, c) = mod(a mod(x, p) + c, p), p = HASH_MOD."""
    p = K["LOOM_NOISE_HASH_MOD"]
    return _mod(_mod(x, p) * a + c, p)


def noise_hash(ply_id, segment, K):
    """speckle_noise.h: noise_hash(ply_id, segment) (exact integers in float, as in OSL).

        a = floor(clamp(id, 0, 1) 4095);  b = mod(floor(segment), 4096)
        h = round(a 16 + mod(b, 16), 251, 17);  h = round(h + floor(b / 16) 97, 223, 41)
        h = round(h, 199, 7);  h = round(h, 241, 113);  h / HASH_MOD"""
    a = floor(clamp(ply_id, 0.0, 1.0) * 4095.0)
    b = _mod(floor(segment), 4096.0)
    h = noise_hash_round(a * 16.0 + _mod(b, 16.0), 251.0, 17.0, K)
    h = noise_hash_round(h + floor(b * (1.0 / 16.0)) * 97.0, 223.0, 41.0, K)
    h = noise_hash_round(h, 199.0, 7.0, K)
    h = noise_hash_round(h, 241.0, 113.0, K)
    return h * (1.0 / K["LOOM_NOISE_HASH_MOD"])


def noise_pick(ply_id, along, instances, K):
    """speckle_noise.h: noise_pick(ply_id, along, instances, instance, phi_shift) ->
    (instance, phi_shift).

        h = noise_hash(id, floor(clamp(along, 0, 1) SEGMENTS));  x = h max(n, 1)
        instance = min(floor(x), max(n, 1) - 1);  phi_shift = x - instance"""
    n = max(int(instances), 1)
    h = noise_hash(ply_id, floor(clamp(along, 0.0, 1.0) * K["LOOM_NOISE_SEGMENTS_PER_REPEAT"]), K)
    x = h * float(n)
    inst = min_(floor(x), float(n - 1))
    return inst, x - inst


def noise_memory_effect_direction(wi, wo):
    """speckle_noise.h: noise_memory_effect_direction(wi, wo) (Eq. S.40).

        s = normalize(wi) + normalize(wo);  l = |s|;  l <= 1e-6: normalize(wo)
        H = s / l;  2 (n.H) H - n,  n = (0, 1, 0)"""
    s = normalize(wi) + normalize(wo)
    l = length(s)
    H = s / l
    mirrored = H * (2.0 * H.y) - vec(0.0, 1.0, 0.0)
    return select(l > 1e-6, mirrored, normalize(wo))


def noise_tile_uv(w, phi_shift, instance, instances):
    """speckle_noise.h: noise_tile_uv(w, phi_shift, instance, instances, u, v) -> (u, v), with
    noise_angles (theta = asin(clamp(n.z, -1, 1)), phi = atan2(n.y, n.x), n = normalize(w)).

        u = mod((phi + pi) / (2 pi) + phi_shift, 1);  t = clamp((theta + pi/2) / pi, 0, 1)
        v = (instance + t) / max(instances, 1)"""
    n = normalize(w)
    theta = asin(clamp(n.z, -1.0, 1.0))
    phi = atan2(n.y, n.x)
    x = (phi + math.pi) * (1.0 / (2.0 * math.pi)) + phi_shift
    u = fract(x)
    t = clamp((theta + 0.5 * math.pi) * (1.0 / math.pi), 0.0, 1.0)
    return u, (instance + t) * (1.0 / max(int(instances), 1))


def noise_level_blur(l):
    """speckle_noise.h: noise_level_blur(l): 0, 0.015, 0.05, 0.15 rad."""
    return (0.0, 0.015, 0.05, 0.15)[min(max(l, 0), 3)]


def noise_level_coord(sigma, K):
    """speckle_noise.h: noise_level_coord(sigma): linear in sigma between the levels' blurs,
    clamped to [0, LEVELS - 1] (sigma >= the last blur: LEVELS - 1)."""
    levels = int(K["LOOM_NOISE_LEVELS"])
    c = 0.0
    for l in range(levels - 1):
        a, b_ = noise_level_blur(l), noise_level_blur(l + 1)
        inside = (1.0 - (sigma < a)) * (sigma < b_)
        c = c + select(inside, l + (sigma - a) * (1.0 / (b_ - a)), 0.0)
    return select(sigma < noise_level_blur(levels - 1), c, float(levels - 1))


def noise_lobe_sigma(mu1, mu2):
    """speckle_noise.h: noise_lobe_sigma(mu1, mu2) = 1 / sqrt(2 sqrt(m1 m2)),
    m = clamp(mu, 1e-6, 1e12)."""
    m = sqrt(clamp(mu1, 1e-6, 1e12) * clamp(mu2, 1e-6, 1e12))
    return 1.0 / sqrt(2.0 * m)


def noise_lobe_uv(z, wi, refl, mu1, mu2, instance, phi_shift, instances, K):
    """speckle_noise.h: noise_lobe_uv(z, wi, refl, mu1, mu2, instance, phi_shift, instances,
    u, v0, v1, t) -> (u, v0, v1, t).

        w = refl ? noise_memory_effect_direction(wi, z) : z;  (u, v) = noise_tile_uv(w, ...)
        c = noise_level_coord(noise_lobe_sigma(mu1, mu2));  l = min(floor(c), LEVELS - 2)
        t = c - l;  v0 = (l + v) / LEVELS;  v1 = (l + 1 + v) / LEVELS"""
    levels = int(K["LOOM_NOISE_LEVELS"])
    w = noise_memory_effect_direction(wi, z) if refl else z
    u, v = noise_tile_uv(w, phi_shift, instance, instances)
    c = noise_level_coord(noise_lobe_sigma(mu1, mu2), K)
    l = min_(floor(c), float(levels - 2))
    v = clamp(v, 0.0, 1.0)
    return u, (l + v) * (1.0 / levels), (l + 1.0 + v) * (1.0 / levels), c - l
