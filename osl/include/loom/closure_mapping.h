// From the surface BSDF (surface_bsdf.h) to a mixture of Cycles' built-in closures.
//
// Cycles has no custom closures, so each term of Zhu et al. 2023 becomes built-in closures with
// weights computed per shading point from the atlas and the view direction V (towards the
// camera, tangent frame, mirrored to the upper side like the model); the specular terms' closures
// are fitted to the model at bake time (closure_fit.h) and read from the closure LUT:
//
//   term (supplement)            closure                                   weight
//   gap (delta transmission)     transparent()                             c
//   Eq. 3, ply-normal part       diffuse(n_p)                              (1-c) w k_rd V(V) V_amb
//   Eq. 3, flat part             diffuse(n_s)                              (1-c) (1-w) k_rd V(V) V_amb
//   Eq. 6, ply-normal part       translucent(n_p)                          (1-c) w k_td
//   Eq. 6, flat part             translucent(n_s)                          (1-c) (1-w) k_td
//   Eq. 1, SGGX fiber specular   microfacet("ggx", N_c, t, ax, ay, 1, 0)   (1-c) k_rs V(V) V(L*) g
//   Eq. 4, fiber transmission    hair_transmission(n_s, r1, r2, t, 0)      (1-c) k_ts h
//                                + translucent(n_s)                        + (1-c) k_ts l
// with (g, ax, ay) and (h, r1, r2, l) the LUT's fitted parameters per unit k_rs and k_ts: per yarn
// kind, ply tangent elevation and view, they minimise the relative L1 distance to the model's
// lobe over the sphere and carry exactly its directional albedo (closure_fit.h).
//
// On a back face (the cloth seen from below) the view frame's z points to the viewer, n_p and t
// are used as stored (the back mirrors the front), the transmission parameters are read for the
// physical slab's tangent (surface_lut_transmission_x), the hair closure gets that tangent, and
// the visibilities are 1.
// V(V) is the view-side visibility; the model's light-side visibility V(i) cannot vary inside a
// closure, so it is replaced by its mean over the lobe: the cosine-weighted sky visibility V_amb
// (horizon_ambient_visibility) for the diffuse lobes, the visibility of the glossy lobe's centre
// L* = reflect(V, N_c) for the specular one.
//
// Why these closures:
//   * Eq. 3/6 times <i . n_s> are Lambertian lobes about n_p and n_s (the light-side cosine of
//     Eq. 3 cancels), which diffuse()/translucent() reproduce exactly.
//   * The SGGX fiber D with S = a^2 t t^T + (I - t t^T) is *identical* to an anisotropic GGX D with
//     normal N_c = normalize(n_s - (n_s . t) t), tangent t, alpha_t = a and alpha_b = 1 on the
//     hemisphere about N_c (expand both: 1 / (pi a ((h.t)^2/a^2 + 1 - (h.t)^2)^2)). What differs is
//     the attenuation (SpongeCake G^r of Eq. 2 against Cycles' height-correlated Smith G) and the
//     cosines, which the fitted alphas and weight absorb.
//   * The fiber transmission lobe lies on the cone i . t = -V . t below the cloth; Cycles'
//     transmissive microfacet closures are isotropic, while its hair transmission closure is a
//     lobe on exactly that cone (Cauchy in the azimuth about t): directional, as Eq. 4 is. What
//     its shape cannot carry goes to a diffuse transmission. The remaining error is measured
//     (loom-bake eval mapping).
#ifndef LOOM_CLOSURE_MAPPING_H
#define LOOM_CLOSURE_MAPPING_H
#include "osl_compat.h"
#include "visibility.h"

/// Closure LUT: per yarn kind, LOOM_LUT_SLICES slices of the tangent's elevation t_z in
/// [0, LOOM_LUT_TZ_MAX], each LOOM_CLOSURE_LUT_SIZE^2 over (azimuth of V about t, cos theta_V),
/// in two panels side by side: reflection (g, ax, ay, 0) and transmission (h, r1, r2, l).
/// The configuration (n_s, t, V) has three degrees of freedom up to rotation; t -> -t leaves the
/// lobes and the fitted closures unchanged (so t_z >= 0) and so does mirroring across the plane
/// of t and n_s (so the azimuth folds to [0, pi]).
#define LOOM_CLOSURE_LUT_SIZE 12
#define LOOM_LUT_PANELS 2
#define LOOM_LUT_SLICES 8
#define LOOM_LUT_TZ_MAX 0.95

/// Normal of the glossy closure: the fiber-normal circle's point closest to n_s = +z.
LOOM_FN vector surface_glossy_normal(vector t) {
  vector n = vector(0.0, 0.0, 1.0) - t * t[2];
  float l = length(n);
  if (l < 1e-6)
    return vector(0.0, 0.0, 1.0);
  return n / l;
}

/// |a| after a is wrapped into [-1, 1] (period 2): Blender's pingpong(a, 1), one Math node.
LOOM_FN float fold_unit(float a) {
  float f = (a - 1.0) * 0.5;
  return fabs((f - floor(f)) * 2.0 - 1.0);
}

/// LUT coordinates for view V and ply tangent t (tangent frame, V_z >= 0): x = folded azimuth of
/// V about t's projection, over [0, pi], as [0, 1]: the azimuths' difference, wrapped (atan2 of
/// a vertical t or V is 0); y = cos theta_V; z = slice coordinate of |t_z| in
/// [0, LOOM_LUT_SLICES - 1].
LOOM_FN void surface_lut_coords(vector V, vector t_in, LOOM_OUT(float) x, LOOM_OUT(float) y,
                                LOOM_OUT(float) z) {
  vector t = t_in;
  if (t[2] < 0.0)
    t = -t;
  x = fold_unit((atan2(V[1], V[0]) - atan2(t[1], t[0])) * (1.0 / LOOM_M_PI));
  y = clamp(V[2], 0.0, 1.0);
  z = clamp(t[2] / LOOM_LUT_TZ_MAX, 0.0, 1.0) * (LOOM_LUT_SLICES - 1);
}

/// Image coordinates (lut_u, lut_v in [0,1], lut_v from the bottom) in the closure LUT image of
/// LUT coordinates (x, y) on integer slice `slice` in panel `panel` (0 reflection, 1
/// transmission), for the yarn kind as read from yarn_info (possibly interpolated: > 1.5 is the
/// weft, the rest, gaps included, the warp). Rows are kind-major, then slice, then cos theta;
/// panels are side by side; texel centres sit on the table's samples, so linear interpolation
/// never mixes panels or slices; callers blend the two slices around z linearly
/// (surface_lut_slices).
LOOM_FN void surface_lut_uv(float kind, float x, float y, float slice, float panel,
                            LOOM_OUT(float) lut_u, LOOM_OUT(float) lut_v) {
  float n = LOOM_CLOSURE_LUT_SIZE;
  float rows = n * LOOM_LUT_SLICES;
  float row0 = slice * n;
  if (kind > 1.5)
    row0 += rows;
  lut_u = (panel * n + 0.5 + clamp(x, 0.0, 1.0) * (n - 1.0)) / (LOOM_LUT_PANELS * n);
  lut_v = (row0 + 0.5 + clamp(y, 0.0, 1.0) * (n - 1.0)) / (2.0 * rows);
}

/// LUT x coordinate for the transmission panel. On a back face the fiber transmission goes
/// through the physical slab, whose tangent is the stored one mirrored through the tangent plane
/// (surface_bsdf.h); in LUT coordinates that mirror keeps the slice and maps x to 1 - x.
LOOM_FN float surface_lut_transmission_x(float x, int back) {
  if (back)
    return 1.0 - x;
  return x;
}

/// The two slices around slice coordinate z and the weight of the upper one.
LOOM_FN void surface_lut_slices(float z, LOOM_OUT(float) s0, LOOM_OUT(float) s1,
                                LOOM_OUT(float) f) {
  s0 = floor(clamp(z, 0.0, LOOM_LUT_SLICES - 1.0));
  s1 = min(s0 + 1.0, LOOM_LUT_SLICES - 1.0);
  f = clamp(z - s0, 0.0, 1.0);
}

/// Light-side visibility of the glossy lobe: V at its centre L* = reflect(V, N_c), or the ambient
/// visibility when L* points below the surface.
LOOM_FN float surface_glossy_light_visibility(vector V, vector Nc, float hor[LOOM_HORIZON_DIRS]) {
  vector Ls = 2.0 * dot(V, Nc) * Nc - V;
  if (Ls[2] <= 0.0)
    return horizon_ambient_visibility(hor);
  return horizon_visibility(Ls, hor);
}

/// The fiber transmission's tangent as the hair closure gets it (tangent frame of the view): on
/// a back face the physical slab's, the stored one mirrored through the tangent plane.
LOOM_FN vector surface_transmission_tangent(vector t, int back) {
  if (back)
    return vector(t[0], t[1], -t[2]);
  return t;
}

/// Closure weights of the table above (per unit of each closure). refl = (g, ax, ay, -) and
/// trans = (h, r1, r2, l) are the closure LUT's panels at this view; vis_v = V(V); vis_amb and
/// vis_gl the light-side visibilities of the diffuse and glossy lobes (1 when the cloth is seen
/// from below).
LOOM_FN void surface_closure_weights(float c, float w, float k_rs, color k_rd, float k_ts,
                                     color k_td, float vis_v, float vis_amb, float vis_gl,
                                     float lut_g, float lut_h, float lut_l,
                                     LOOM_OUT(float) w_gap, LOOM_OUT(color) w_diffuse_np,
                                     LOOM_OUT(color) w_diffuse_ns,
                                     LOOM_OUT(color) w_translucent_np,
                                     LOOM_OUT(color) w_translucent_ns,
                                     LOOM_OUT(float) w_glossy, LOOM_OUT(float) w_hair) {
  float open = 1.0 - clamp(c, 0.0, 1.0);
  w_gap = 1.0 - open;
  w_diffuse_np = k_rd * (open * w * vis_v * vis_amb);
  w_diffuse_ns = k_rd * (open * (1.0 - w) * vis_v * vis_amb);
  w_translucent_np = k_td * (open * w);
  w_glossy = open * k_rs * vis_v * vis_gl * max(lut_g, 0.0);
  w_hair = open * k_ts * max(lut_h, 0.0);
  w_translucent_ns = k_td * (open * (1.0 - w)) + color(open * k_ts * max(lut_l, 0.0));
}

#endif
