// The ray-wave model at a shading point (ray-wave supplement sections 1 and 3): from the surface
// maps and the view direction to the ply space of the simulation, the atlas coordinates of the
// fitted ASG lobes (S.6, S.7, S.11) and of the double-layer factors (S.20-S.22, made per point:
// double_layer_factors.h), and each lobe's Cycles closure.
//
// Ply space is the simulation's (baker/include/loom/ply_scattering.h): the ply runs along +z, the
// beam comes from omega_i = (0, cos theta_i, sin theta_i), h is its offset along +x in ply radii.
// At render time the beam is the camera ray (reciprocity: the lobes are built around the direction
// towards the camera and describe the light directions), so for a view V, ply tangent t and ply
// normal n_p (all in the cloth's tangent frame):
//   z_p = t,  y_p = normalize(V - (V.t) t),  x_p = y_p x z_p,  theta_i = asin(V.t),
//   h = n_perp . x_p,  n_perp = normalize(n_p - (n_p.t) t)
// h is the impact parameter of the ray that meets the ply's (round) cross-section where its
// normal is n_perp. The ply scattering density f (fraction of the beam's power per steradian
// towards L) is what Cycles' closure eval (BSDF times cosine) must return for light from L: a sun
// of irradiance E then gives radiance f E, and a ply whose f integrates to 1 reflects all light.
//
// Lobe tables in the atlas (ply_tables.h): the corner nodes of the block fit, one row per theta_i
// node, lobe-major columns ((part L + lobe) (N' + 1) + j) so that a bilinear texture look-up at
// fractional node coordinates is exactly Eq. S.7 (texel centres sit on the nodes; the look-up stays
// between the first and the last centre of its lobe's columns, so no wrap mode is needed). The
// amplitude scale at the yarn's absorption (Eq. S.10, S.11, one value per colour channel) is a
// separate, colour-dependent image (`ply_tint_<yarn>`) in the same lobe-major layout with one
// texel per node, read bilinearly like the nodes (Loom keeps the scale-downs at the nodes, not per
// block: asg_fit.h).
//
// Closures (choices, measured by the closure emulator: loom-bake eval mapping --by-kind):
//   * a lobe whose centre z lies on the viewer's side of the cloth: an anisotropic Beckmann
//     reflection microfacet("beckmann", N, T, a_x, a_y, 1, 0) with N = normalize(V + z), the half
//     vector that reflects V into z, so the closure peaks at the lobe centre; T and the two
//     roughnesses from the first-order match of the lobe's shape (asg_lobe_reflection). Beckmann,
//     not GGX: its D is a Gaussian in the half vector's slope,
//     exp(-tan^2 theta_h / a^2), the shape of the ASG's exp(-mu theta^2), where GGX's
//     (1 + tan^2 / a^2)^-2 carries half its energy in long tails (measured); weight = the lobe's integral (asg_integral) over the closure's
//     directional albedo E(cos(N, V), sqrt(a_x a_y)) (the atlas's microfacet_albedo LUT, F = 1,
//     isotropic), so the closure carries the lobe's energy.
//   * a lobe whose centre is on the far side: transmission. Cycles' refraction closures are
//     isotropic and steered by an index of refraction: microfacet("beckmann", N, N, a, a, eta, 1)
//     with the fixed eta = LOOM_RAYWAVE_ETA sends V to z when N = -(eta z + V) / m,
//     m = |eta z + V| (Cycles' refraction half vector solved for N). That N faces the viewer only
//     while the lobe is within acos(1 / eta) of straight through; there the closure is used, with
//     the isotropic roughness of asg_refraction_alpha (the anisotropy is lost) and
//     weight = integral / E_t(cos(N, V), a) (channel 1 of the LUT). Beyond that cone,
//     or where N would fall below the surface or be raised by Cycles (its mirror direction of V
//     below the surface), translucent(n_s) with the lobe's integral as weight (energy kept,
//     direction lost).
//   * no hard switch between these kinds (raywave_lobe_closures): a lobe whose centre is
//     within LOOM_RAYWAVE_SIDE_BAND (in z.z, the sine of its elevation) of the cloth's plane
//     gives both its reflection closure and its far-side closure, weighted by the smooth share
//     b = raywave_reflection_share(z.z) and 1 - b; and the far side's refraction closure fades
//     into translucent() over LOOM_RAYWAVE_REFRACTION_BAND of each of the cosines that bound it
//     (asg_lobe_refraction_share). A switch moved the lobe's energy from one closure to another
//     at once: the mixture stepped where the model is continuous (on twill, 0.6 % of f in
//     reflection and up to 170 % in transmission), as the view turned the lobe across a border.
//     In the band a reflection closure may be aimed below the plane (Cycles raises its normal);
//     its light-side visibility is the horizon's at the lobe's azimuth on the plane
//     (raywave_lobe_visibility), which joins the visibility above it continuously.
//   * weights divide by the closure's albedo, floored at LOOM_RAYWAVE_MIN_ALBEDO so that a
//     closure at grazing angles (E near 0) cannot be scaled into fireflies.
//   * each lobe's closures, then the residual's and the layers', times raywave_energy_budget:
//     1 unless the closures before and these would send out more than the open fraction.
//   * the energy residual (baker/include/loom/asg_residual.h: what the fitted lobes miss of the
//     simulated energy, backward and forward in the ply's cross-section) at the yarn's absorption
//     (`ply_residual_<yarn>`, read bilinearly between slices): backward energy E_b as
//     diffuse(n_s) with weight open vis_v E_b, forward energy E_f as translucent(n_s) with
//     weight open (1 - s) k_f E_f (double_layer_factors.h). The model is the same (a Lambertian lobe of albedo E on each
//     side, f cos = E |cos| / pi), so this part maps without error. Choice: no horizon term for
//     the light direction (the residual is light spread by many fibres; vis_v still applies).
#ifndef LOOM_RAYWAVE_LOBES_H
#define LOOM_RAYWAVE_LOBES_H
#include "osl_compat.h"
#include "asg.h"
#include "visibility.h"

/// Texels per lobe node: (theta_z, phi_z, phi_xy, mu1) and (mu2, c, 0, 0).
#define LOOM_RAYWAVE_PARTS 2
#define LOOM_RAYWAVE_MIN_ALPHA 0.001
/// The refraction closures' index of refraction (header comment).
#define LOOM_RAYWAVE_ETA 6.0
/// Floor of the albedo a lobe's integral is divided by (asg_microfacet_weight).
#define LOOM_RAYWAVE_MIN_ALBEDO 0.05
/// Smallest cos(N, V) of a refraction closure before the lobe falls back to translucent().
#define LOOM_RAYWAVE_MIN_COS 0.05
/// Half-width, in z.z of a lobe's centre, of the band about the cloth's plane across which the
/// lobe's closure turns from reflection into transmission (raywave_reflection_share).
#define LOOM_RAYWAVE_SIDE_BAND 0.1
/// Width, in each cosine that bounds the refraction closure (asg_lobe_refraction_frame), of the
/// band over which it fades into translucent() (asg_lobe_refraction_share).
#define LOOM_RAYWAVE_REFRACTION_BAND 0.05
/// The microfacet albedo LUT (Beckmann; channel 0 reflection, 1 refraction at LOOM_RAYWAVE_ETA):
/// LOOM_MICROFACET_ALBEDO_SIZE^2 texels over (cos(N, V), sqrt(alpha)) in [0, 1]^2.
#define LOOM_MICROFACET_ALBEDO_SIZE 32

/// The unit vector normal to unit n closest to one of two fixed axes (for degenerate inputs).
LOOM_FN vector raywave_any_normal(vector n) {
  vector a = vector(0.0, 0.0, 1.0);
  if (fabs(n[2]) > 0.9)
    a = vector(1.0, 0.0, 0.0);
  return normalize(a - n * dot(a, n));
}

/// Ply space of a shading point (see the header comment). V, t, n_p unit, tangent frame. When V
/// runs along the ply, y_p falls back to n_perp (the beam then meets the ply's top).
LOOM_FN void raywave_ply_space(vector V, vector t, vector np, LOOM_OUT(vector) xp,
                               LOOM_OUT(vector) yp, LOOM_OUT(float) theta_i, LOOM_OUT(float) h) {
  vector n_perp = normalize(np - t * dot(np, t));
  if (length(n_perp) < 0.5)
    n_perp = raywave_any_normal(t);  // n_p along t (a degenerate map texel)
  vector v_perp = V - t * dot(V, t);
  float lv = length(v_perp);
  if (lv > 1e-6)
    yp = v_perp / lv;
  else
    yp = n_perp;
  xp = cross(yp, t);
  theta_i = asin(clamp(dot(V, t), -1.0, 1.0));
  h = clamp(dot(n_perp, xp), -1.0, 1.0);
}

/// A ply-space direction a in the tangent frame.
LOOM_FN vector raywave_from_ply(vector a, vector xp, vector yp, vector t) {
  return a[0] * xp + a[1] * yp + a[2] * t;
}

/// Fractional node coordinate (S.6) of x on the uniform grid [lo, hi] of n (odd) samples: the
/// nodes are every second sample, so the result lies in [0, (n - 1) / 2].
LOOM_FN float asg_node_coord(float x, float lo, float hi, int n) {
  float u = (clamp(x, lo, hi) - lo) / (hi - lo) * (n - 1);
  if (!(u >= 0.0))
    u = 0.0;
  return 0.5 * u;
}

/// Column of (part, lobe, h node j) in a node image of `cols` = N' + 1 node columns.
LOOM_FN int asg_node_column(int part, int lobe, int j, int cols, int lobes) {
  return (part * lobes + lobe) * cols + j;
}

/// Image coordinates (s from the left, tv from the bottom, in [0, 1]) of the bilinear look-up
/// that returns part `part` of lobe `lobe` at fractional node coordinates (fi, fj): Eq. S.7.
LOOM_FN void asg_node_uv(float fi, float fj, int part, int lobe, int lobes, int rows, int cols,
                         LOOM_OUT(float) s, LOOM_OUT(float) tv) {
  float i = clamp(fi, 0.0, rows - 1.0);
  float j = clamp(fj, 0.0, cols - 1.0);
  s = (asg_node_column(part, lobe, 0, cols, lobes) + j + 0.5) / (LOOM_RAYWAVE_PARTS * lobes * cols);
  tv = (i + 0.5) / rows;
}

/// Image coordinates of the bilinear look-up that returns lobe `lobe`'s amplitude scale (Eq. S.11
/// at the yarn's absorption) at fractional node coordinates (fi, fj) in a ply_tint image of
/// lobes cols columns (column lobe cols + j) and rows rows: the scales sit on the nodes, as the
/// lobes do, and interpolate with S.7's weights, so they are continuous across block borders.
LOOM_FN void asg_tint_uv(float fi, float fj, int lobe, int lobes, int rows, int cols,
                         LOOM_OUT(float) s, LOOM_OUT(float) tv) {
  float i = clamp(fi, 0.0, rows - 1.0);
  float j = clamp(fj, 0.0, cols - 1.0);
  s = (lobe * cols + j + 0.5) / (lobes * cols);
  tv = (i + 0.5) / rows;
}

/// The reflection closure of a lobe (centre z, axes x, y, bandwidths mu1, mu2; tangent frame) seen
/// from V: N = normalize(V + z) and the anisotropic roughness that matches the lobe to first
/// order. A half-vector turn e (normal to N) turns the reflected direction by
/// dL = 2 (V.N) e + 2 (V.e) N, so the lobe's exponent mu1 (dL.x)^2 + mu2 (dL.y)^2 is the quadratic
/// form e^T M e, M = mu1 g_x g_x^T + mu2 g_y g_y^T with g_a = P_N(2 (V.N) a + 2 (N.a) V) (P_N the
/// projection normal to N). Beckmann's exponent is (e.T)^2 / a_x^2 + (e.B)^2 / a_y^2, so T is M's
/// first eigenvector and a = 1 / sqrt(eigenvalue), clamped to [LOOM_RAYWAVE_MIN_ALPHA, 1]. At
/// normal incidence this is a = 1 / (2 sqrt(mu)) along the lobe's own axes.
LOOM_FN void asg_lobe_reflection(vector V, vector z, vector x, vector y, float mu1, float mu2,
                                 LOOM_OUT(vector) N, LOOM_OUT(vector) T, LOOM_OUT(float) ax,
                                 LOOM_OUT(float) ay) {
  N = normalize(V + z);
  if (length(N) < 0.5)
    N = vector(0.0, 0.0, 1.0);
  float vn = dot(V, N);
  vector gx = 2.0 * vn * x + 2.0 * dot(N, x) * V;
  vector gy = 2.0 * vn * y + 2.0 * dot(N, y) * V;
  gx = gx - N * dot(gx, N);
  gy = gy - N * dot(gy, N);
  vector e1 = normalize(x - N * dot(x, N));
  if (length(e1) < 0.5)
    e1 = raywave_any_normal(N);
  vector e2 = cross(N, e1);
  float m1 = 0.0, m2 = 0.0;  // (NaN bandwidths give the broadest closure)
  if (mu1 >= 0.0)
    m1 = min(mu1, 1e6);
  if (mu2 >= 0.0)
    m2 = min(mu2, 1e6);
  float x1 = dot(gx, e1), x2 = dot(gx, e2), y1 = dot(gy, e1), y2 = dot(gy, e2);
  float a11 = m1 * x1 * x1 + m2 * y1 * y1;
  float a12 = m1 * x1 * x2 + m2 * y1 * y2;
  float a22 = m1 * x2 * x2 + m2 * y2 * y2;
  float mean = 0.5 * (a11 + a22);
  float dev = sqrt(0.25 * (a11 - a22) * (a11 - a22) + a12 * a12);
  float psi = 0.5 * atan2(2.0 * a12, a11 - a22);
  T = cos(psi) * e1 + sin(psi) * e2;
  ax = clamp(1.0 / sqrt(max(mean + dev, 1e-12)), LOOM_RAYWAVE_MIN_ALPHA, 1.0);
  ay = clamp(1.0 / sqrt(max(mean - dev, 1e-12)), LOOM_RAYWAVE_MIN_ALPHA, 1.0);
}

/// Refraction closure of a forward lobe with centre z seen from V: its normal N and the
/// magnification eta / m of outgoing turns into half-vector turns. Returns 0 when the lobe is
/// outside the cone the closure can reach (then use translucent()).
LOOM_FN int asg_lobe_refraction_frame(vector V, vector z, LOOM_OUT(vector) N,
                                      LOOM_OUT(float) magnification) {
  vector hv = -(LOOM_RAYWAVE_ETA * z + V);
  float m = length(hv);
  N = vector(0.0, 0.0, 1.0);
  magnification = 1.0;
  if (m < 1e-6)
    return 0;
  N = hv / m;
  magnification = LOOM_RAYWAVE_ETA / m;
  if (!(dot(N, V) >= LOOM_RAYWAVE_MIN_COS && N[2] > 0.0))
    return 0;
  // Cycles raises a microfacet normal whose mirror direction of V dips below the surface
  // (ensure_valid_specular_reflection, also for refraction closures): keep such lobes out of
  // the refraction closure, whose aim would move.
  vector R = 2.0 * dot(N, V) * N - V;
  if (!(R[2] >= min(0.9 * V[2], 0.01)))
    return 0;
  return 1;
}

/// 0 below 0, 1 above 1, smooth (C1) in between; NaN gives 0.
LOOM_FN float raywave_smooth_unit(float x) {
  if (!(x > 0.0))
    return 0.0;
  if (!(x < 1.0))
    return 1.0;
  return x * x * (3.0 - 2.0 * x);
}

/// The share of a lobe with centre elevation sine zz (z.z, tangent frame) that its reflection
/// closure carries, the rest going to the far side's closures: 0 below -band, 1 above band.
LOOM_FN float raywave_reflection_share(float zz, float band) {
  return raywave_smooth_unit(0.5 * (zz + band) / band);
}

/// The share of a far-side lobe that its refraction closure (normal N, from
/// asg_lobe_refraction_frame, which returned `ok`) carries, the rest going to translucent(): the
/// product of smooth ramps over `band` of the three margins that asg_lobe_refraction_frame tests
/// (cos(N, V) above LOOM_RAYWAVE_MIN_COS, N above the plane, its mirror direction of V above
/// Cycles' threshold), so 0 exactly where the frame is refused.
LOOM_FN float asg_lobe_refraction_share(vector V, vector N, int ok, float band) {
  if (!ok)
    return 0.0;
  float nv = dot(N, V);
  vector R = 2.0 * nv * N - V;
  float a = raywave_smooth_unit((nv - LOOM_RAYWAVE_MIN_COS) / band);
  float b = raywave_smooth_unit(N[2] / band);
  float c = raywave_smooth_unit((R[2] - min(0.9 * V[2], 0.01)) / band);
  return a * b * c;
}

/// Beckmann roughness of the refraction closure (normal N) of a lobe centred at z: the half
/// vector turns by eta / m times the outgoing turn projected normal to N, which scales areas by
/// |N.z|; the isotropic closure keeps the lobe's solid angle: a = (eta / m) sqrt(|N.z|) /
/// (mu1 mu2)^(1/4).
LOOM_FN float asg_refraction_alpha(float mu1, float mu2, float magnification, vector N, vector z) {
  float m1 = 1e-6, m2 = 1e-6;
  if (mu1 >= 1e-6)
    m1 = mu1;
  if (mu2 >= 1e-6)
    m2 = mu2;
  float mu = sqrt(m1 * m2);
  return clamp(magnification * sqrt(fabs(dot(N, z))) / sqrt(mu), LOOM_RAYWAVE_MIN_ALPHA, 1.0);
}

/// Image coordinates in the microfacet albedo LUT of cos(N, V) and alpha.
LOOM_FN void microfacet_albedo_uv(float cos_nv, float alpha, LOOM_OUT(float) s, LOOM_OUT(float) tv) {
  float n = LOOM_MICROFACET_ALBEDO_SIZE;
  s = (0.5 + clamp(cos_nv, 0.0, 1.0) * (n - 1.0)) / n;
  tv = (0.5 + sqrt(clamp(alpha, 0.0, 1.0)) * (n - 1.0)) / n;
}

/// Weight of a lobe's microfacet closure: its integral over the closure's albedo E.
LOOM_FN float asg_microfacet_weight(float integral, float albedo) {
  if (!(albedo >= 0.0) || !(integral > 0.0))
    return 0.0;
  return integral / max(albedo, LOOM_RAYWAVE_MIN_ALBEDO);
}

/// The closures of one lobe from its two node texels (p0 = theta_z, phi_z, phi_xy with mu1 in its
/// alpha; p1 = mu2, c), seen from V in the ply space (xp, yp, t), with no switch between kinds
/// (header comment): the Beckmann reflection closure (Nr, Tr, axr, ayr) with share b_refl, the
/// Beckmann refraction closure (Nt, at = its isotropic roughness) with share
/// (1 - b_refl) b_refr, and translucent(n_s) with share (1 - b_refl) (1 - b_refr). z is the lobe centre in the tangent frame (for its visibility). A
/// closure whose share is 0 has the defaults (N = n_s, T = x, roughness 1).
LOOM_FN void raywave_lobe_closures(vector V, vector xp, vector yp, vector t, color p0, float mu1,
                                   color p1, LOOM_OUT(vector) z, LOOM_OUT(vector) Nr,
                                   LOOM_OUT(vector) Tr, LOOM_OUT(float) axr,
                                   LOOM_OUT(float) ayr, LOOM_OUT(vector) Nt, LOOM_OUT(float) at,
                                   LOOM_OUT(float) b_refl, LOOM_OUT(float) b_refr) {
  vector lx, ly, lz;
  asg_frame(p0[0], p0[1], p0[2], lx, ly, lz);
  z = raywave_from_ply(lz, xp, yp, t);
  vector x = raywave_from_ply(lx, xp, yp, t);
  vector y = raywave_from_ply(ly, xp, yp, t);
  Nr = vector(0.0, 0.0, 1.0);
  Tr = vector(1.0, 0.0, 0.0);
  axr = 1.0;
  ayr = 1.0;
  Nt = vector(0.0, 0.0, 1.0);
  at = 1.0;
  b_refl = raywave_reflection_share(z[2], LOOM_RAYWAVE_SIDE_BAND);
  b_refr = 0.0;
  if (b_refl > 0.0)
    asg_lobe_reflection(V, z, x, y, mu1, p1[0], Nr, Tr, axr, ayr);
  if (b_refl < 1.0) {
    float mag;
    vector Nf;
    int ok = asg_lobe_refraction_frame(V, z, Nf, mag);
    b_refr = asg_lobe_refraction_share(V, Nf, ok, LOOM_RAYWAVE_REFRACTION_BAND);
    if (b_refr > 0.0) {
      Nt = Nf;
      at = asg_refraction_alpha(mu1, p1[0], mag, Nf, z);
    }
  }
}

/// Light-side visibility of a lobe's reflection closure: the horizon's at the lobe centre z, or,
/// for a centre on or below the plane (in the band of raywave_reflection_share), at z's azimuth
/// on the plane, where the visibility above it ends.
LOOM_FN float raywave_lobe_visibility(vector z, float hor[LOOM_HORIZON_DIRS]) {
  return horizon_visibility(vector(z[0], z[1], max(z[2], 1e-6)), hor);
}

/// Colour weight of a lobe's closure: its integral (asg_integral(mu1, mu2, c)) over the closure's
/// albedo E (ignored for translucent), times the per-channel tint (Eq. S.11), the open fraction,
/// for reflection the view- and light-side visibilities, for forward lobes (1 - s) k_f, the
/// directional part of Eq. S.22 with the per-point factor of double_layer_factors.h.
LOOM_FN color raywave_lobe_weight(int kind, float integral, float albedo, color tint, float open,
                                  float vis_v, float vis_z, color k_f, float s) {
  if (kind == 0)
    return asg_microfacet_weight(integral, albedo) * open * vis_v * vis_z * tint;
  float w = integral;
  if (kind == 2)
    w = asg_microfacet_weight(integral, albedo);
  return w * open * (1.0 - s) * tint * k_f;
}

/// Colour weights of a lobe's three closures (raywave_lobe_closures): raywave_lobe_weight of each
/// kind times its share; albedo_r and albedo_t are the reflection and the refraction closure's
/// albedos E (channels 0 and 1 of the LUT at their own cos(N, V) and roughness).
LOOM_FN void raywave_lobe_weights(float integral, float albedo_r, float albedo_t, color tint,
                                  float open, float vis_v, float vis_z, color k_f, float s,
                                  float b_refl, float b_refr, LOOM_OUT(color) w_refl,
                                  LOOM_OUT(color) w_refr, LOOM_OUT(color) w_transl) {
  w_refl = b_refl * raywave_lobe_weight(0, integral, albedo_r, tint, open, vis_v, vis_z, k_f, s);
  color w_fwd = raywave_lobe_weight(1, integral, albedo_t, tint, open, vis_v, vis_z, k_f, s);
  w_refr = ((1.0 - b_refl) * b_refr) *
           raywave_lobe_weight(2, integral, albedo_t, tint, open, vis_v, vis_z, k_f, s);
  w_transl = ((1.0 - b_refl) * (1.0 - b_refr)) * w_fwd;
}

/// A lobe's part of the point's forward light T (double_layer_factors.h), before the layers'
/// factors: the energy its far-side closures carry, integral (1 - b_refl) tint (the speckle
/// noise left out: T feeds the layers' diffuse light, an incoherent sum).
LOOM_FN color raywave_lobe_forward(float integral, color tint, float b_refl) {
  return (integral * (1.0 - b_refl)) * tint;
}

/// A lobe's energy as its closures carry it (raywave_lobe_weights without the albedos the
/// microfacet weights divide by, which the closures' albedos cancel), before the speckle noise:
/// integral tint open (b_refl vis_v vis_z + (1 - b_refl) (1 - s) k_f).
LOOM_FN color raywave_lobe_energy(float integral, color tint, float open, float vis_v,
                                  float vis_z, color k_f, float s, float b_refl) {
  return (integral * open) * tint *
         (color(b_refl * vis_v * vis_z) + ((1.0 - b_refl) * (1.0 - s)) * k_f);
}

/// The factor, per channel, that lets energy x (a lobe's with the speckle noise, or the yarn's
/// other closures') follow energy `used` (what the closures before it send out) without the
/// yarn sending out more than its open fraction: 1 where used + x <= open, else
/// max(open - used, 0) / x; written min(1, max(open - used, 0) / x) for x > 0 and 1 otherwise
/// (x <= 0 or NaN), so that node mode, whose select evaluates both sides, never meets an
/// Inf or NaN on the side it does not take (a tiny x). Loom's choice where S.39 is silent: its noise
/// has mean 1 over directions, not over one point's lobes, so on its own it lifted a point of a
/// white yarn to 1.07-1.10 of the light it receives, and the fitted lobes interpolated between
/// slices reached 1.003 with the noise off. The closures take the budget in order (f_refl's
/// lobes, f_high's, then the residual's and the layers' diffuse and translucent closures
/// together), so what the noise adds is taken from the yarn's diffuse light first and the
/// speckle keeps its contrast; a lobe is cut only where the lobes before it already fill the
/// budget. A yarn within the budget is untouched. Computed in order, one lobe at a time, so
/// that node mode needs no pass over all the lobes before their closures (Cycles' SVM stack).
LOOM_FN color raywave_energy_budget(color x, color used, float open) {
  color k = color(1.0);
  for (int c = 0; c < 3; c += 1) {
    if (x[c] > 0.0)
      k[c] = min(1.0, max(open - used[c], 0.0) / x[c]);
  }
  return k;
}

/// Look-up coordinates of the energy residual (`ply_residual_<yarn>`, header comment) of the slice
/// at (theta_i, h) on the (m x n) slice grid: texel (side n + j, i) holds slice (i, j) of side 0
/// (backward) or 1 (forward). The coordinate stays between the first and the last texel centre of
/// its side, so the bilinear look-up interpolates between slices and never across sides.
LOOM_FN void raywave_residual_uv(float theta_i, float h, float theta_lo, float theta_hi, int m,
                                 int n, int side, LOOM_OUT(float) s, LOOM_OUT(float) tv) {
  float fi = 2.0 * asg_node_coord(theta_i, theta_lo, theta_hi, m);
  float fj = 2.0 * asg_node_coord(h, -1.0, 1.0, n);
  s = (side * n + fj + 0.5) / (2.0 * n);
  tv = (fi + 0.5) / m;
}

/// Weight of the diffuse closure carrying the backward residual e_b (header comment).
LOOM_FN color raywave_residual_diffuse_weight(color e_b, float open, float vis_v) {
  return open * vis_v * e_b;
}

/// Weight of the translucent closure carrying the forward residual e_f (header comment): the
/// directional share (1 - s) k_f of Eq. S.22, as the forward lobes.
LOOM_FN color raywave_residual_translucent_weight(color e_f, float open, color k_f, float s) {
  return open * (1.0 - s) * k_f * e_f;
}

/// Weight of the diffuse closure carrying the light the layers below return, k_b T
/// (double_layer_factors.h; t_fwd = T, the lobes' raywave_lobe_forward plus e_f).
LOOM_FN color raywave_layer_diffuse_weight(color t_fwd, float open, float vis_v, color k_b) {
  return open * vis_v * k_b * t_fwd;
}

/// Weight of the translucent closure carrying the diffuse BTDF of Eq. S.22, s k_f T
/// (double_layer_factors.h).
LOOM_FN color raywave_layer_translucent_weight(color t_fwd, float open, color k_f, float s) {
  return open * s * k_f * t_fwd;
}

#endif
