"""raywave_lobes.h, asg.h and double_layer_factors.h in node mode: the ray-wave model at a
shading point (ply space, the lobes' node look-ups and closures, the energy budget, the residual
and double-layer weights), transcribed line by line through ``nodes_expr`` (node_mode_raywave.py
builds the groups from them). Each function names the header function it mirrors; ``K`` is the
headers' constants (node_mode_raywave.constants)."""

from __future__ import annotations

import math

from .nodes_expr import (acos, asin, atan2, clamp, cos, cross, dot, fabs, length, log, max_, min_,
                         normalize, select, sin, sqrt, vec)

# What this module transcribes (see node_mode.TRANSCRIBED_FROM; tests/blender/test_transcription.py
# checks it).
TRANSCRIBED_FROM = {
    "include/loom/raywave_lobes.h": "ca74348eaa1d3868",
    "include/loom/double_layer_factors.h": "f779eff78c2ea96c",
    "include/loom/asg.h": "8e66624946a2b7e5",
}


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
