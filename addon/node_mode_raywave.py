"""Node mode for the ray-wave tier: ``osl/loom_cloth_raywave.osl`` as a node group of Cycles'
built-in nodes.

The same transcription rules as the surface tier (``node_mode.py``, whose docstring explains the
atlas images, the tangent frame and the closure weights in Color inputs): the functions below
transcribe ``raywave_lobes.h``, ``double_layer_factors.h`` and ``asg.h`` line by line through
``nodes_expr``; each names the header function it mirrors. What is particular to this tier:

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

import math
import os

import bpy

from . import node_mode, node_texel_guard, node_visibility
from .nodes_expr import (Builder, acos, asin, atan2, clamp, cos, cross, dot, fabs,
                         floor, length, log, max_, min_, normalize, select, sin, sqrt,
                         sync_sockets, vec)

GROUP_PREFIX = "Loom Ray-wave"
SHADER = "loom_cloth_raywave.osl"
MAPS = ("ply_frame", "ply_normal", "yarn_info", "horizon_0", "horizon_1")
# The lobe tables' layout this module reads: the manifest's raywave.yarns.<yarn>.node_layout, as
# loom-bake writes it (baker/include/loom/ply_tables.h: kAsgNodeLayout).
NODE_LAYOUT = "lobe-major/node-scales"
# The double-layer factors this module reads: the manifest's raywave.shading.factors_layout
# (baker/include/loom/raywave_bsdf.h: kLayerFactorsLayout; double_layer_factors.h).
FACTORS_LAYOUT = "k_b,k_f"

REQUIRED_CONSTANTS = ("LOOM_RAYWAVE_PARTS", "LOOM_RAYWAVE_MIN_ALPHA", "LOOM_RAYWAVE_ETA",
                      "LOOM_RAYWAVE_MIN_ALBEDO", "LOOM_RAYWAVE_MIN_COS",
                      "LOOM_RAYWAVE_SIDE_BAND", "LOOM_RAYWAVE_REFRACTION_BAND",
                      "LOOM_MICROFACET_ALBEDO_SIZE", "LOOM_ASG_INTEGRAL_LUT_SIZE", "LOOM_ASG_MU_MAX",
                      "LOOM_HORIZON_DIRS", "LOOM_HORIZON_SOFTNESS", "LOOM_DIFFRACTION_S_MAX",
                      "LOOM_DIFFRACTION_ICDF_SIZE", "LOOM_DIFFRACTION_KERNEL_RAD",
                      "LOOM_DIFFRACTION_MIN_COS", "LOOM_DIFFRACTION_SAMPLES",
                      "LOOM_NOISE_SEGMENTS_PER_REPEAT", "LOOM_NOISE_HASH_MOD", "LOOM_NOISE_LEVELS",
                      "LOOM_DOUBLE_LAYER_BLOCKS")

# What this module transcribes (see node_mode.TRANSCRIBED_FROM; tests/blender/test_transcription.py
# checks both). texel_guard.h and visibility.h: node_texel_guard.py, node_visibility.py.
TRANSCRIBED_FROM = {
    "include/loom/raywave_lobes.h": "ca74348eaa1d3868",
    "include/loom/double_layer_factors.h": "f779eff78c2ea96c",
    "include/loom/asg.h": "8e66624946a2b7e5",
    "include/loom/diffraction_table.h": "452b37e1478a3fd5",
    "include/loom/diffraction_sampling.h": "4552302033af31ad",
    "include/loom/speckle_noise.h": "db12339f3a287d00",
    "loom_cloth_raywave.osl": "407aed919a31d683",
}


def constants() -> dict[str, float]:
    return node_mode.constants(REQUIRED_CONSTANTS)


# ======================================================================= asg.h


def asg_frame(theta_z, phi_z, phi_xy):
    """asg.h: asg_frame(theta_z, phi_z, phi_xy, x, y, z) (Eq. S.2).

        z = (ct cp, ct sp, st); x0 = (-sp, cp, 0); y0 = (-st cp, -st sp, ct)
        x = ca x0 - sa y0;  y = sa x0 + ca y0
    """
    st, ct, sp, cp = sin(theta_z), cos(theta_z), sin(phi_z), cos(phi_z)
    z = vec(ct * cp, ct * sp, st)
    x0 = vec(-sp, cp, 0.0)
    y0 = vec(-st * cp, -st * sp, ct)
    sa, ca = sin(phi_xy), cos(phi_xy)
    return x0 * ca - y0 * sa, x0 * sa + y0 * ca, z


def asg_integral_lut_coord(mu, K):
    """asg.h: asg_integral_lut_coord(mu) = log(1 + clamp(mu, 0, MU_MAX)) / log(1 + MU_MAX)."""
    top = K["LOOM_ASG_MU_MAX"]
    return log(1.0 + clamp(mu, 0.0, top)) * (1.0 / math.log(1.0 + top))


def asg_integral_lut_uv(mu1, mu2, K):
    """asg.h: asg_integral_lut_uv(mu1, mu2) -> (s, tv) = ((0.5 + coord(mu) (n - 1)) / n),
    n = LOOM_ASG_INTEGRAL_LUT_SIZE."""
    n = K["LOOM_ASG_INTEGRAL_LUT_SIZE"]
    return ((0.5 + asg_integral_lut_coord(mu1, K) * (n - 1.0)) * (1.0 / n),
            (0.5 + asg_integral_lut_coord(mu2, K) * (n - 1.0)) * (1.0 / n))


def asg_integral_from_lut(h, mu1, mu2, c, K):
    """asg.h: asg_integral_from_lut(h, mu1, mu2, c) = c > 0 ? c pi h / sqrt((1 + m1) (1 + m2))
    : 0, m = clamp(mu, 0, MU_MAX)."""
    top = K["LOOM_ASG_MU_MAX"]
    m1 = clamp(mu1, 0.0, top)
    m2 = clamp(mu2, 0.0, top)
    return select(c > 0.0, c * math.pi * h / sqrt((1.0 + m1) * (1.0 + m2)), 0.0)


# ======================================================================= raywave_lobes.h


def raywave_any_normal(n):
    """raywave_lobes.h: raywave_any_normal(n).

        a = |n.z| > 0.9 ? (1,0,0) : (0,0,1);  return normalize(a - n (a.n))
    """
    a = select(fabs(n.z) > 0.9, (1.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    return normalize(a - n * dot(a, n))


def raywave_ply_space(V_, t, np_):
    """raywave_lobes.h: raywave_ply_space(V, t, np, xp, yp, theta_i, h) -> (xp, yp, theta_i, h).

        n_perp = normalize(np - t (np.t)); if (|n_perp| < 0.5) n_perp = raywave_any_normal(t)
        v_perp = V - t (V.t); lv = |v_perp|; yp = lv > 1e-6 ? v_perp / lv : n_perp
        xp = yp x t; theta_i = asin(clamp(V.t, -1, 1)); h = clamp(n_perp.xp, -1, 1)
    """
    n_perp = normalize(np_ - t * dot(np_, t))
    n_perp = select(length(n_perp) < 0.5, raywave_any_normal(t), n_perp)
    v_perp = V_ - t * dot(V_, t)
    lv = length(v_perp)
    yp = select(lv > 1e-6, v_perp / lv, n_perp)
    xp = cross(yp, t)
    theta_i = asin(clamp(dot(V_, t), -1.0, 1.0))
    h = clamp(dot(n_perp, xp), -1.0, 1.0)
    return xp, yp, theta_i, h


def raywave_from_ply(a, xp, yp, t):
    """raywave_lobes.h: raywave_from_ply(a, xp, yp, t) = a.x xp + a.y yp + a.z t."""
    return xp * a.x + yp * a.y + t * a.z


def asg_node_coord(x, lo, hi, n):
    """raywave_lobes.h: asg_node_coord(x, lo, hi, n) = 0.5 (clamp(x, lo, hi) - lo) / (hi - lo)
    (n - 1) (the header's NaN guard is max(u, 0) for finite inputs)."""
    u = (clamp(x, lo, hi) - lo) / (hi - lo) * (n - 1)
    return 0.5 * max_(u, 0.0)


def asg_node_uv(fi, fj, part, lobe, lobes, rows, cols, K):
    """raywave_lobes.h: asg_node_uv -> (s, tv).

        i = clamp(fi, 0, rows - 1); j = clamp(fj, 0, cols - 1)
        s = (asg_node_column(part, lobe, 0) + j + 0.5) / (PARTS lobes cols); tv = (i + 0.5) / rows
    asg_node_column(part, lobe, j) = (part lobes + lobe) cols + j.
    """
    i = clamp(fi, 0.0, rows - 1.0)
    j = clamp(fj, 0.0, cols - 1.0)
    col0 = (part * lobes + lobe) * cols
    s = (j + (col0 + 0.5)) / (K["LOOM_RAYWAVE_PARTS"] * lobes * cols)
    return s, (i + 0.5) / rows


def asg_tint_uv(fi, fj, lobe, lobes, rows, cols):
    """raywave_lobes.h: asg_tint_uv -> (s, tv).

        i = clamp(fi, 0, rows - 1); j = clamp(fj, 0, cols - 1)
        s = (lobe cols + j + 0.5) / (lobes cols); tv = (i + 0.5) / rows
    """
    i = clamp(fi, 0.0, rows - 1.0)
    j = clamp(fj, 0.0, cols - 1.0)
    return (j + (lobe * cols + 0.5)) / (lobes * cols), (i + 0.5) / rows


def asg_lobe_reflection(V_, z, x, y, mu1, mu2, K):
    """raywave_lobes.h: asg_lobe_reflection(V, z, x, y, mu1, mu2) -> (N, T, ax, ay).

        N = normalize(V + z) (or (0,0,1) if |N| < 0.5); vn = V.N
        g_a = P_N(2 vn a + 2 (N.a) V); e1 = normalize(P_N x) (or raywave_any_normal(N)); e2 = N x e1
        m = clamp(mu, 0, 1e6) (the header's NaN guard, for finite inputs)
        M = [[a11, a12], [a12, a22]] in (e1, e2); psi = atan2(2 a12, a11 - a22) / 2
        T = cos psi e1 + sin psi e2;  a = clamp(1 / sqrt(max(mean +- dev, 1e-12)), MIN_ALPHA, 1)
    """
    N = normalize(V_ + z)
    N = select(length(N) < 0.5, (0.0, 0.0, 1.0), N)
    vn = dot(V_, N)
    gx = x * (2.0 * vn) + V_ * (2.0 * dot(N, x))
    gy = y * (2.0 * vn) + V_ * (2.0 * dot(N, y))
    gx = gx - N * dot(gx, N)
    gy = gy - N * dot(gy, N)
    e1 = normalize(x - N * dot(x, N))
    e1 = select(length(e1) < 0.5, raywave_any_normal(N), e1)
    e2 = cross(N, e1)
    m1 = clamp(mu1, 0.0, 1e6)
    m2 = clamp(mu2, 0.0, 1e6)
    x1, x2, y1, y2 = dot(gx, e1), dot(gx, e2), dot(gy, e1), dot(gy, e2)
    a11 = m1 * x1 * x1 + m2 * y1 * y1
    a12 = m1 * x1 * x2 + m2 * y1 * y2
    a22 = m1 * x2 * x2 + m2 * y2 * y2
    mean = 0.5 * (a11 + a22)
    d = a11 - a22
    dev = sqrt(0.25 * d * d + a12 * a12)
    psi = 0.5 * atan2(2.0 * a12, d)
    T = e1 * cos(psi) + e2 * sin(psi)
    lo = K["LOOM_RAYWAVE_MIN_ALPHA"]
    ax = clamp(1.0 / sqrt(max_(mean + dev, 1e-12)), lo, 1.0)
    ay = clamp(1.0 / sqrt(max_(mean - dev, 1e-12)), lo, 1.0)
    return N, T, ax, ay


def asg_lobe_refraction_frame(V_, z, K):
    """raywave_lobes.h: asg_lobe_refraction_frame(V, z, N, magnification) -> (N, mag, ok).

        hv = -(ETA z + V); m = |hv|; m < 1e-6: N = (0,0,1), mag = 1, 0
        N = hv / m; mag = ETA / m
        ok = N.V >= MIN_COS && N.z > 0 && R.z >= min(0.9 V.z, 0.01),  R = 2 (N.V) N - V
    """
    eta = K["LOOM_RAYWAVE_ETA"]
    hv = -(z * eta + V_)
    m = length(hv)
    tiny = m < 1e-6
    N = select(tiny, (0.0, 0.0, 1.0), hv / m)
    mag = select(tiny, 1.0, eta / m)
    nv = dot(N, V_)
    R = N * (2.0 * nv) - V_
    ok = ((1.0 - tiny) * (1.0 - (nv < K["LOOM_RAYWAVE_MIN_COS"])) * (N.z > 0.0)
          * (1.0 - (R.z < min_(0.9 * V_.z, 0.01))))
    return N, mag, ok


def asg_refraction_alpha(mu1, mu2, mag, N, z, K):
    """raywave_lobes.h: asg_refraction_alpha(mu1, mu2, mag, N, z) =
    clamp(mag sqrt(|N.z|) / sqrt(sqrt(m1 m2)), MIN_ALPHA, 1), m = mu >= 1e-6 ? mu : 1e-6."""
    mu = sqrt(max_(mu1, 1e-6) * max_(mu2, 1e-6))
    return clamp(mag * sqrt(fabs(dot(N, z))) / sqrt(mu), K["LOOM_RAYWAVE_MIN_ALPHA"], 1.0)


def microfacet_albedo_uv(cos_nv, alpha, K):
    """raywave_lobes.h: microfacet_albedo_uv -> (s, tv) = ((0.5 + clamp(cos, 0, 1) (n - 1)) / n,
    (0.5 + sqrt(clamp(alpha, 0, 1)) (n - 1)) / n), n = LOOM_MICROFACET_ALBEDO_SIZE."""
    n = K["LOOM_MICROFACET_ALBEDO_SIZE"]
    s = (0.5 + clamp(cos_nv, 0.0, 1.0) * (n - 1.0)) / n
    tv = (0.5 + sqrt(clamp(alpha, 0.0, 1.0)) * (n - 1.0)) / n
    return s, tv


def asg_microfacet_weight(integral, albedo, K):
    """raywave_lobes.h: asg_microfacet_weight = !(albedo >= 0) || !(integral > 0) ? 0 :
    integral / max(albedo, MIN_ALBEDO)."""
    ok = (integral > 0.0) * (1.0 - (albedo < 0.0))
    return select(ok, integral / max_(albedo, K["LOOM_RAYWAVE_MIN_ALBEDO"]), 0.0)


def raywave_smooth_unit(x):
    """raywave_lobes.h: raywave_smooth_unit(x) = c^2 (3 - 2 c), c = clamp(x, 0, 1) (NaN: 0, as
    Blender's Clamp node gives)."""
    c = clamp(x, 0.0, 1.0)
    return c * c * (3.0 - 2.0 * c)


def raywave_reflection_share(zz, band):
    """raywave_lobes.h: raywave_reflection_share(zz, band) =
    raywave_smooth_unit(0.5 (zz + band) / band)."""
    return raywave_smooth_unit((zz + band) * (0.5 / band))


def asg_lobe_refraction_share(V_, N, ok, band, K):
    """raywave_lobes.h: asg_lobe_refraction_share(V, N, ok, band).

        !ok: 0;  nv = N.V;  R = 2 nv N - V
        smooth((nv - MIN_COS) / band) smooth(N.z / band) smooth((R.z - min(0.9 V.z, 0.01)) / band)
    """
    nv = dot(N, V_)
    R = N * (2.0 * nv) - V_
    a = raywave_smooth_unit((nv - K["LOOM_RAYWAVE_MIN_COS"]) * (1.0 / band))
    b = raywave_smooth_unit(N.z * (1.0 / band))
    c = raywave_smooth_unit((R.z - min_(0.9 * V_.z, 0.01)) * (1.0 / band))
    return ok * a * b * c


def raywave_lobe_closures(V_, xp, yp, t, p0, mu1, p1, K):
    """raywave_lobes.h: raywave_lobe_closures(V, xp, yp, t, p0, mu1, p1, z, Nr, Tr, axr, ayr, Nt,
    at, b_refl, b_refr).

        (x, y, z) = asg_frame(p0) in the tangent frame (raywave_from_ply)
        b_refl = raywave_reflection_share(z.z, SIDE_BAND)
        (Nr, Tr, axr, ayr) = asg_lobe_reflection (where b_refl > 0)
        (Nt, mag, ok) = asg_lobe_refraction_frame (where b_refl < 1)
        b_refr = asg_lobe_refraction_share(V, Nt, ok, REFRACTION_BAND); at = asg_refraction_alpha
    Both frames are computed everywhere: where the header keeps a frame's defaults its closure's
    share is 0, so its weight is 0 and Cycles allocates no closure. (The header's b_refr is 0
    where b_refl = 1; here it need not be, but every weight it enters is multiplied by
    1 - b_refl.)
    Returns (z, Nr, Tr, axr, ayr, Nt, at, b_refl, b_refr)."""
    lx, ly, lz = asg_frame(p0.x, p0.y, p0.z)
    z = raywave_from_ply(lz, xp, yp, t)
    x = raywave_from_ply(lx, xp, yp, t)
    y = raywave_from_ply(ly, xp, yp, t)
    Nr, Tr, axr, ayr = asg_lobe_reflection(V_, z, x, y, mu1, p1.x, K)
    Nt, mag, ok = asg_lobe_refraction_frame(V_, z, K)
    at = asg_refraction_alpha(mu1, p1.x, mag, Nt, z, K)
    b_refl = raywave_reflection_share(z.z, K["LOOM_RAYWAVE_SIDE_BAND"])
    b_refr = asg_lobe_refraction_share(V_, Nt, ok, K["LOOM_RAYWAVE_REFRACTION_BAND"], K)
    return z, Nr, Tr, axr, ayr, Nt, at, b_refl, b_refr


def raywave_lobe_weights(integral, albedo_r, albedo_t, tint, open_, vis_v, vis_z, k_f, s,
                         b_refl, b_refr, K):
    """raywave_lobes.h: raywave_lobe_weights(integral, albedo_r, albedo_t, tint, open, vis_v,
    vis_z, k_f, s, b_refl, b_refr, w_refl, w_refr, w_transl), with
    raywave_lobe_weight(kind, ...):

        kind 0: asg_microfacet_weight(integral, albedo) open vis_v vis_z tint
        kind 2: asg_microfacet_weight(integral, albedo) open (1 - s) tint k_f
        kind 1: integral open (1 - s) tint k_f
        w_refl = b_refl kind 0 (albedo_r);  w_refr = (1 - b_refl) b_refr kind 2 (albedo_t)
        w_transl = (1 - b_refl) (1 - b_refr) kind 1
    Returns (w_refl, w_refr, w_transl)."""
    mw_r = asg_microfacet_weight(integral, albedo_r, K)
    mw_t = asg_microfacet_weight(integral, albedo_t, K)
    w_refl = tint * (b_refl * (mw_r * open_ * vis_v * vis_z))
    fwd = tint * k_f
    far = 1.0 - b_refl
    w_refr = fwd * ((far * b_refr) * (mw_t * (open_ * (1.0 - s))))
    w_transl = fwd * ((far * (1.0 - b_refr)) * (integral * (open_ * (1.0 - s))))
    return w_refl, w_refr, w_transl


def raywave_lobe_forward(integral, tint, b_refl):
    """raywave_lobes.h: raywave_lobe_forward(integral, tint, b_refl) = integral (1 - b_refl) tint."""
    return tint * (integral * (1.0 - b_refl))


def raywave_lobe_energy(integral, tint, open_, vis_v, vis_z, k_f, s, b_refl):
    """raywave_lobes.h: raywave_lobe_energy(integral, tint, open, vis_v, vis_z, k_f, s, b_refl)
    = integral open tint (b_refl vis_v vis_z + (1 - b_refl) (1 - s) k_f)."""
    up = b_refl * vis_v * vis_z
    return tint * (k_f * ((1.0 - b_refl) * (1.0 - s)) + vec(up, up, up)) * (integral * open_)


def raywave_energy_budget(x, used, open_):
    """raywave_lobes.h: raywave_energy_budget(x, used, open): per channel c,
    min(1, max(open - used[c], 0) / x[c]) where x[c] > 0, else 1. (Math MINIMUM is fminf: a
    NaN or Inf quotient on the side select does not take gives 1, not NaN.)"""
    k = []
    for c in ("x", "y", "z"):
        xc, uc = getattr(x, c), getattr(used, c)
        k.append(select(xc > 0.0, min_(1.0, max_(open_ - uc, 0.0) / xc), 1.0))
    return vec(*k)


# ======================================================================= diffraction_table.h,
#                                                                         diffraction_sampling.h


def diffraction_obliquity(xi_i, xi_o):
    """diffraction_table.h: diffraction_obliquity(xi_i, xi_o) = (|xi_i.z| + |xi_o.z|)^2 / 4."""
    a = fabs(xi_i.z) + fabs(xi_o.z)
    return 0.25 * a * a


def diffraction_table_s(t, K):
    """diffraction_table.h: diffraction_table_s(t) = S_MAX t^2."""
    return K["LOOM_DIFFRACTION_S_MAX"] * t * t


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
    return x - floor(x)


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
    u = x - floor(x)
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


# ======================================================================= double_layer_factors.h


def raywave_residual_uv(theta_i, h, theta_lo, theta_hi, m, n, side):
    """raywave_lobes.h: raywave_residual_uv(theta_i, h, theta_lo, theta_hi, m, n, side) -> (s, tv).

        fi = 2 asg_node_coord(theta_i, lo, hi, m);  fj = 2 asg_node_coord(h, -1, 1, n)
        s = (side n + fj + 0.5) / (2 n);  tv = (fi + 0.5) / m"""
    fi = 2.0 * asg_node_coord(theta_i, theta_lo, theta_hi, m)
    fj = 2.0 * asg_node_coord(h, -1.0, 1.0, n)
    return (fj + (side * n + 0.5)) * (1.0 / (2.0 * n)), (fi + 0.5) * (1.0 / m)


def raywave_residual_diffuse_weight(e_b, open_, vis_v):
    """raywave_lobes.h: raywave_residual_diffuse_weight = open vis_v e_b."""
    return e_b * (open_ * vis_v)


def raywave_residual_translucent_weight(e_f, open_, k_f, s_blend):
    """raywave_lobes.h: raywave_residual_translucent_weight = open (1 - s) k_f e_f."""
    return k_f * e_f * (open_ * (1.0 - s_blend))


def raywave_layer_diffuse_weight(t_fwd, open_, vis_v, k_b):
    """raywave_lobes.h: raywave_layer_diffuse_weight = open vis_v k_b t_fwd."""
    return k_b * t_fwd * (open_ * vis_v)


def raywave_layer_translucent_weight(t_fwd, open_, k_f, s_blend):
    """raywave_lobes.h: raywave_layer_translucent_weight = open s k_f t_fwd."""
    return k_f * t_fwd * (open_ * s_blend)


def double_layer_uv(xi, block, theta_count, phi_count, K):
    """double_layer_factors.h: double_layer_uv(xi, block, theta_count, phi_count) -> (s, tv),
    with K the headers' constants (LOOM_DOUBLE_LAYER_BLOCKS).

        theta = acos(clamp(xi.z, 0, 1)) 180 / pi;  row = clamp(theta Tc / 90 - 0.5, 0, Tc - 1)
        phi = |xi.x| + |xi.y| > 1e-9 ? atan2(xi.y, xi.x) 180 / pi : 0;  phi < 0: phi += 360
        col = clamp(phi Pc / 360 + 0.5, 0.5, Pc + 0.5);  w = Pc + 2
        s = (block w + col + 0.5) / (LOOM_DOUBLE_LAYER_BLOCKS w);  tv = (row + 0.5) / Tc
    """
    theta = acos(clamp(xi.z, 0.0, 1.0)) * (180.0 / math.pi)
    row = clamp(theta * (theta_count / 90.0) - 0.5, 0.0, theta_count - 1.0)
    phi = select(fabs(xi.x) + fabs(xi.y) > 1e-9, atan2(xi.y, xi.x) * (180.0 / math.pi), 0.0)
    phi = select(phi < 0.0, phi + 360.0, phi)
    col = clamp(phi * (phi_count / 360.0) + 0.5, 0.5, phi_count + 0.5)
    w = phi_count + 2.0
    return ((col + (block * w + 0.5)) / (K["LOOM_DOUBLE_LAYER_BLOCKS"] * w),
            (row + 0.5) / theta_count)


# ======================================================================= atlas checks


def _grid(manifest: dict) -> dict:
    """The lobe grids of a ray-wave atlas, which the OSL shader takes once for all tables: raise
    ValueError naming what differs when the yarns' or the components' grids are not one."""
    rw = manifest["raywave"]
    grids = []
    for y in ("warp", "weft"):
        for part in ("high", "refl"):
            g = rw["yarns"][y][part]
            grids.append(((g["theta_i"]["count"], g["theta_i"]["min"], g["theta_i"]["max"]),
                          (g["h"]["count"], g["h"]["min"], g["h"]["max"])))
    if any(g != grids[0] for g in grids):
        raise ValueError("the yarns' lobe tables use different (theta_i, h) grids; the ray-wave "
                         "shaders take one grid (not yet supported: bake both yarns at one "
                         "quality)")
    (m, th_lo, th_hi), (n, h_lo, h_hi) = grids[0]
    if (float(h_lo), float(h_hi)) != (-1.0, 1.0):
        raise ValueError(f"the lobe tables' h range is [{h_lo}, {h_hi}]; the ray-wave shaders "
                         f"take h in [-1, 1]")
    lobes = {part: {rw["yarns"][y][part]["lobes"] for y in ("warp", "weft")}
             for part in ("high", "refl")}
    if any(len(v) != 1 for v in lobes.values()):
        raise ValueError("the yarns' lobe tables have different lobe counts; the ray-wave shaders "
                         "take one count per component")
    dl = rw["double_layer"]
    return {"m": int(m), "n": int(n), "theta_min": float(th_lo), "theta_max": float(th_hi),
            "h_min": float(h_lo), "h_max": float(h_hi),
            "high_lobes": int(next(iter(lobes["high"]))),
            "refl_lobes": int(next(iter(lobes["refl"]))),
            "layer_theta_count": int(dl["theta_count"]), "layer_phi_count": int(dl["phi_count"]),
            "blend": float(dl.get("blend", 0.5))}


def _diffraction(manifest: dict) -> dict | None:
    """The gap diffraction the shaders sample (diffraction_sampling.h), or None for delta
    transmission (no gap table: the non-wave variant, or yarns that touch). Raises KeyError when
    a gap table comes without its sampling table (an older loom-bake)."""
    dif = manifest["raywave"].get("diffraction", {})
    files = dif.get("files", {})
    if dif.get("mode") != "tables" or "gap" not in files:
        return None
    n = int(dif["gap_offsets"])
    return {"file": files["gap_sampling"], "tiles_x": n, "tiles_y": n,
            "size": int(dif["tile_size"]), "gap_fraction": [float(g) for g in dif["gap_fraction"]],
            "weft_yarns": int(manifest["repeat"]["weft_yarns"]),
            "warp_yarns": int(manifest["repeat"]["warp_yarns"])}


def _noise(manifest: dict) -> dict | None:
    """The speckle noise tiles (speckle_noise.h), or None (wave.noise off). Raises KeyError when
    the tiles come without their blur levels (an older loom-bake)."""
    nz = manifest["raywave"].get("noise", {})
    files = nz.get("files", {})
    if "refl" not in files:
        return None
    return {"refl": files["refl"], "high": files["high"], "instances": int(nz["instances"]),
            "theta_count": int(nz["theta_count"]), "levels": int(nz["levels"])}


def atlas_problem(manifest: dict) -> str | None:
    """None if node mode (and the OSL shader) can read this ray-wave atlas, else why not."""
    try:
        rw = manifest["raywave"]
        textures = manifest["textures"]
        for y in ("warp", "weft"):
            if rw["yarns"][y].get("node_layout") != NODE_LAYOUT:
                return (f"its lobe tables are not in the {NODE_LAYOUT!r} layout this add-on reads "
                        f"(they are {rw['yarns'][y].get('node_layout')!r}): re-bake the atlas with "
                        f"this version of loom-bake")
        got = rw["shading"].get("factors_layout")
        if got != FACTORS_LAYOUT:
            return (f"raywave.shading.factors_layout is "
                    f"{'missing' if got is None else repr(got)}, not the {FACTORS_LAYOUT!r} this "
                    f"add-on reads (double-layer factors of an older loom-bake): re-bake the "
                    f"atlas with this version of loom-bake")
        _grid(manifest)
        needed = set(MAPS) | {rw["shading"]["microfacet_albedo"], rw["shading"]["asg_integral"],
                              *rw["shading"]["factors"].values()}
        for y in ("warp", "weft"):
            files = rw["yarns"][y]["files"]
            needed |= {files["high"], files["refl"], files["tint"], files["residual"]}
        dif = _diffraction(manifest)
        if dif:
            needed.add(dif["file"])
        nz = _noise(manifest)
        if nz:
            needed |= {nz["refl"], nz["high"]}
    except (KeyError, TypeError) as exc:
        return (f"not a ray-wave atlas with render tables (manifest lacks {exc}): re-bake it "
                f"with this version of loom-bake")
    except ValueError as exc:
        return str(exc)
    missing = sorted(m for m in needed if m not in textures)
    if missing:
        return f"maps missing: {', '.join(missing)}"
    K = constants()
    n = int(K["LOOM_MICROFACET_ALBEDO_SIZE"])
    got = list(textures[rw["shading"]["microfacet_albedo"]].get("size", []))
    if got != [n, n]:
        return f"microfacet albedo LUT is {got}, the shaders expect {[n, n]}"
    n = int(K["LOOM_ASG_INTEGRAL_LUT_SIZE"])
    got = list(textures[rw["shading"]["asg_integral"]].get("size", []))
    if got != [n, n]:
        return f"ASG integral LUT is {got}, the shaders expect {[n, n]}: re-bake the atlas"
    # The tables' sizes against the grids (raywave_lobes.h: asg_node_uv, asg_tint_uv).
    g = _grid(manifest)
    rows, cols = g["m"] // 2 + 1, g["n"] // 2 + 1
    parts = int(K["LOOM_RAYWAVE_PARTS"])
    for y in ("warp", "weft"):
        files = rw["yarns"][y]["files"]
        want = {files["high"]: [parts * g["high_lobes"] * cols, rows],
                files["refl"]: [parts * g["refl_lobes"] * cols, rows],
                files["tint"]: [g["high_lobes"] * cols, rows],
                files["residual"]: [2 * g["n"], g["m"]]}
        for name, size in want.items():
            got = list(textures[name].get("size", []))
            if got != size:
                return f"{name} is {got}, the grids say {size}: re-bake the atlas"
    # The double-layer factors (double_layer_factors.h: double_layer_uv).
    want = [int(K["LOOM_DOUBLE_LAYER_BLOCKS"]) * (g["layer_phi_count"] + 2),
            g["layer_theta_count"]]
    for name in rw["shading"]["factors"].values():
        got = list(textures[name].get("size", []))
        if got != want:
            return f"{name} is {got}, the double-layer grids say {want}: re-bake the atlas"
    dif = _diffraction(manifest)
    if dif:
        want = [int(K["LOOM_DIFFRACTION_ICDF_SIZE"]) * dif["tiles_x"],
                (dif["size"] + 1) * dif["tiles_y"]]
        got = list(textures[dif["file"]].get("size", []))
        if got != want:
            return f"{dif['file']} is {got}, the diffraction tables say {want}: re-bake the atlas"
    nz = _noise(manifest)
    if nz:
        if nz["levels"] != int(K["LOOM_NOISE_LEVELS"]):
            return (f"its noise tiles have {nz['levels']} blur levels, the shaders read "
                    f"{int(K['LOOM_NOISE_LEVELS'])}: re-bake the atlas")
        want = [2 * nz["theta_count"], nz["theta_count"] * nz["instances"] * nz["levels"]]
        for name in (nz["refl"], nz["high"]):
            got = list(textures[name].get("size", []))
            if got != want:
                return f"{name} is {got}, the noise settings say {want}: re-bake the atlas"
    return None


def osl_parameters(manifest: dict) -> tuple[dict, dict]:
    """(texture parameters -> atlas texture names, other parameters -> values) of
    loom_cloth_raywave.osl for this atlas."""
    rw = manifest["raywave"]
    g = _grid(manifest)
    tex = {m: m for m in MAPS}
    for y in ("warp", "weft"):
        files = rw["yarns"][y]["files"]
        tex[f"high_{y}"] = files["high"]
        tex[f"refl_{y}"] = files["refl"]
        tex[f"tint_{y}"] = files["tint"]
        tex[f"residual_{y}"] = files["residual"]
    tex["factors_front"] = rw["shading"]["factors"]["front"]
    tex["factors_back"] = rw["shading"]["factors"]["back"]
    tex["microfacet_albedo"] = rw["shading"]["microfacet_albedo"]
    tex["asg_integral_lut"] = rw["shading"]["asg_integral"]
    values = {"high_lobes": g["high_lobes"], "refl_lobes": g["refl_lobes"],
              "theta_count": g["m"], "h_count": g["n"], "theta_min": g["theta_min"],
              "theta_max": g["theta_max"], "layer_theta_count": g["layer_theta_count"],
              "layer_phi_count": g["layer_phi_count"], "double_layer_blend": g["blend"]}
    nz = _noise(manifest)
    if nz:  # (without: the shader's defaults, empty names, give no noise)
        tex["noise_refl"], tex["noise_high"] = nz["refl"], nz["high"]
        values["noise_instances"] = nz["instances"]
    dif = _diffraction(manifest)
    if dif:  # (without: the shader's defaults, diffraction_tiles_x = 0, give delta transmission)
        tex["diffraction_gap_sampling"] = dif["file"]
        values.update({"diffraction_tiles_x": dif["tiles_x"], "diffraction_tiles_y": dif["tiles_y"],
                       "diffraction_size": dif["size"], "weft_yarns": dif["weft_yarns"],
                       "warp_yarns": dif["warp_yarns"], "gap_fraction_x": dif["gap_fraction"][0],
                       "gap_fraction_y": dif["gap_fraction"][1]})
    return tex, values


def group_name(manifest: dict) -> str:
    return f"{GROUP_PREFIX} ({manifest.get('spec', {}).get('name', 'atlas')})"


# ======================================================================= the groups

# The lobe group's inputs (name, socket type), in the order of loom_lobes' per-lobe arguments.
LOBE_INPUTS = (
    ("p0", "NodeSocketVector"), ("mu1", "NodeSocketFloat"), ("p1", "NodeSocketVector"),
    ("tint", "NodeSocketColor"), ("V", "NodeSocketVector"), ("xp", "NodeSocketVector"),
    ("yp", "NodeSocketVector"), ("t", "NodeSocketVector"), ("T", "NodeSocketVector"),
    ("B", "NodeSocketVector"), ("N", "NodeSocketVector"), ("back", "NodeSocketFloat"),
    *((f"hor{k}", "NodeSocketFloat") for k in range(8)), ("open", "NodeSocketFloat"),
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
        hor = [i[f"hor{k}"] for k in range(8)]
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


def build_raywave_group(atlas_dir: str, manifest: dict, interpolation: str = "Linear",
                        name: str | None = None):
    """Build (or rebuild in place) the ray-wave node group for this atlas and return it.

    Interface and ``interpolation`` (of the periodic surface maps) as
    node_mode.build_surface_group; the tables are always read as described in the module
    docstring. The lobes are instances of a second group, ``<name> lobe`` (build_lobe_group)."""
    problem = atlas_problem(manifest)
    if problem:
        raise ValueError(f"{atlas_dir}: {problem}")
    K = constants()
    g = _grid(manifest)
    rw = manifest["raywave"]
    tex_params, _ = osl_parameters(manifest)
    M, N_ = g["m"], g["n"]
    rows, cols = M // 2 + 1, N_ // 2 + 1

    name = name or group_name(manifest)
    label = f"Loom {manifest.get('spec', {}).get('name', 'atlas')}"
    images: dict[str, object] = {}

    def image(tex_name):
        if tex_name not in images:
            images[tex_name] = node_mode.load_atlas_image(atlas_dir, manifest, tex_name, label)
        return images[tex_name]

    albedo_img = image(rw["shading"]["microfacet_albedo"])
    integral_img = image(rw["shading"]["asg_integral"])
    functions: dict = {}  # the function groups (Builder.call) of this build
    nz = _noise(manifest)
    if nz:  # f_refl and f_high lobes read different noise tiles (speckle_noise.h)
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
    group = _new_group(name, (("Scale", "NodeSocketFloat"),), (("BSDF", "NodeSocketShader"),),
                       f"Loom ray-wave cloth from atlas {os.path.abspath(atlas_dir)}")
    s_in = group.interface.items_tree["Scale"]
    s_in.default_value = 1.0
    s_in.min_value = 0.0
    s_in.description = "weave repeats per UV unit"
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
        uv = b.label(vec(uvraw.x * scale_, uvraw.y * scale_ * node_mode.repeat_aspect(manifest),
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
        hor = [node_texel_guard.texel_guard_horizon(s) for s in (c_h0.x, c_h0.y, c_h0.z, a_h0,
                                                          c_h1.x, c_h1.y, c_h1.z, a_h1)]
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
                args = {"p0": p0, "mu1": mu1, "p1": p1, "tint": tintc, "V": V_, "xp": xp,
                        "yp": yp, "t": t, "T": T, "B": B, "N": Nw, "back": back,
                        **{f"hor{k}": hor[k] for k in range(8)}, "open": open_,
                        "vis_v": vis_v, "k_f": k_f, "s": g["blend"],
                        "theta_i": theta_i, "noise_instance": noise_inst,
                        "noise_shift": noise_shift, "used": used}
                for n, _kind in LOBE_INPUTS:
                    b.link(args[n], node.inputs[n])
                lobe_outputs.append(node)
                used = used + b.vector_socket(node.outputs["energy"])

    # ---------------------------------------------------------------- energy residual
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

    # ---------------------------------------------------------------- gap diffraction
    gap = 1.0 - open_
    gap_delta = vec(gap, gap, gap)
    gap_lobes = []
    dif = _diffraction(manifest)
    if dif:
        with b.block("Gap diffraction (diffraction_sampling.h; loom_cloth_raywave.osl)"):
            # Four independent uniform numbers. (Not one node's Value and Color: Cycles' white
            # noise computes Color.r with the very hash of Value, kernel/svm/white_noise.h.)
            geo_p = b.vector_socket(geo.outputs["Position"])
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
            ox = diffraction_gap_offset(uv.x - floor(uv.x), dif["weft_yarns"],
                                        dif["gap_fraction"][0])
            oy = diffraction_gap_offset(uv.y - floor(uv.y), dif["warp_yarns"],
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
                    E, _ = table(rw["shading"]["microfacet_albedo"], ls, lt,
                                 what=f"lobe {k} channel {c}")
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

    # ---------------------------------------------------------------- closures
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
        # sampling (the OSL shader's `if (gap > 0.0 ...)`); where it runs the factor is 1 and
        # the weights are unchanged.
        gap_closures = b.add_shaders((*gap_lobes, transp.outputs["BSDF"]))
        if gap_lobes:
            mix = b.new("ShaderNodeMixShader", label="gap > 0: the gaps' closures, else none")
            b.link(gap > 0.0, mix.inputs["Fac"])
            b.connect(gap_closures, mix.inputs[2])
            gap_closures = mix.outputs["Shader"]
        total = b.add_shaders((*(n.outputs["BSDF"] for n in lobe_outputs), gap_closures,
                               tr.outputs["BSDF"], dif_node.outputs["BSDF"]))
        gout = b.new("NodeGroupOutput")
        b.connect(total, gout.inputs["BSDF"])

    b.layout()
    return group
