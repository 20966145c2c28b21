// Per-texel fitted closures of the surface tier (issue 31: what Cycles renders, fitted to the
// model at bake time). The seven closures of closure_mapping.h, the specular ones shaped by the
// closure LUT at the view as there, but every weight a per-texel, view-independent factor fitted
// against the model over the sphere of lights and a set of views (baker/src/fitted_closures.cpp),
// per unit of each colour term:
//
//   closure                                      weight (front; on a back face V(V) = 1)
//   diffuse(n_p)                                 k_rd a_np V(V)
//   diffuse(n_s)                                 k_rd a_ns V(V)
//   translucent(n_p)                             k_td b_np
//   translucent(n_s)                             k_td b_ns + k_ts l
//   microfacet("ggx", N_c, t, ax, ay, 1, 0)      k_rs m_g g V(V)
//   hair_transmission(n_s, r1, r2, t_t, 0)       k_ts m_h h
//
// with (g, ax, ay) and (h, r1, r2) the closure LUT's at this view. The factors take the place of
// the mapping's moment matching (the gap coverage, the diffuse blend, the light-side
// visibilities V_amb and V(L*), the LUT's translucent share l): fitted, they bring the closures
// closer to the model than the mapping (loom-bake eval mapping), with fewer nodes per sample.
// Colour stays out of the fit (the model is linear in k_rd, k_td, k_rs, k_ts), so a colour
// change needs no refit.
//
// The texture: LOOM_FITTED_TILES tiles side by side, tile = panel + LOOM_FITTED_PANELS * back,
// panels (a_np, a_ns, b_np, b_ns) and (m_g, m_h, l, 0); each tile is the map's width plus a
// column on either side repeating the opposite edge, so a bilinear read inside a tile is the
// periodic bilinear read of the map and never mixes tiles. V(V) is read from the horizon strip,
// laid out alike: LOOM_HORIZON_DIRS tiles, tile k holding (h_k, h_k+1, 0, 0) of the horizon maps
// (visibility.h), so that one read at the tile of V's azimuth gives the two sines horizon_sine
// interpolates between.
#ifndef LOOM_FITTED_CLOSURES_H
#define LOOM_FITTED_CLOSURES_H
#include "osl_compat.h"
#include "texel_guard.h"
#include "visibility.h"

#define LOOM_FITTED_PANELS 2
#define LOOM_FITTED_TILES 4
#define LOOM_FITTED_MAX_WEIGHT 50.0

/// A fitted factor (a_np, a_ns, b_np, b_ns, m_g, m_h, l) as the baker writes it: in [0,
/// LOOM_FITTED_MAX_WEIGHT] (an edited or NaN texel: 0).
LOOM_FN float fitted_weight_guard(float x) {
  return texel_guard(x, 0.0, LOOM_FITTED_MAX_WEIGHT, 0.0);
}

/// Image coordinate s (in [0, 1]) of `panel` on side `back` (0 front, 1 back) at the repeat's
/// su in [0, 1) for a map `width` texels wide; the row coordinate is the maps' own.
LOOM_FN float fitted_closures_s(float su, float panel, float back, float width) {
  float tile = panel + LOOM_FITTED_PANELS * back;
  return (tile * (width + 2.0) + 1.0 + su * width) / (LOOM_FITTED_TILES * (width + 2.0));
}

/// The weights of the table above from the guarded factors (fitted_weight_guard), the closure
/// LUT's weights lut_g and lut_h at this view, and vis_v = V(V) (1 on a back face).
LOOM_FN void fitted_closure_weights(color k_rd, float k_rs, color k_td, float k_ts, float a_np,
                                    float a_ns, float b_np, float b_ns, float m_g, float m_h,
                                    float l, float lut_g, float lut_h, float vis_v,
                                    LOOM_OUT(color) w_diffuse_np, LOOM_OUT(color) w_diffuse_ns,
                                    LOOM_OUT(color) w_translucent_np,
                                    LOOM_OUT(color) w_translucent_ns, LOOM_OUT(float) w_glossy,
                                    LOOM_OUT(float) w_hair) {
  w_diffuse_np = k_rd * (a_np * vis_v);
  w_diffuse_ns = k_rd * (a_ns * vis_v);
  w_translucent_np = k_td * b_np;
  w_translucent_ns = k_td * b_ns + color(k_ts * l);
  w_glossy = k_rs * m_g * max(lut_g, 0.0) * vis_v;
  w_hair = k_ts * m_h * max(lut_h, 0.0);
}

/// Image coordinate s of the horizon strip's tile for w's azimuth at the repeat's su, and the
/// weight f of the tile's second sine: horizon_sine(w, h) = mix(h_k, h_k+1, f) with (h_k, h_k+1)
/// read there.
LOOM_FN void horizon_strip_coords(vector w, float su, float width, LOOM_OUT(float) s,
                                  LOOM_OUT(float) f) {
  float phi = atan2(w[1], w[0]);
  if (phi < 0.0)
    phi += 2.0 * LOOM_M_PI;
  float x = phi / (2.0 * LOOM_M_PI) * LOOM_HORIZON_DIRS;
  float k = min(floor(x), LOOM_HORIZON_DIRS - 1.0);
  f = clamp(x - k, 0.0, 1.0);
  s = (k * (width + 2.0) + 1.0 + su * width) / (LOOM_HORIZON_DIRS * (width + 2.0));
}

/// V(V) from the horizon strip's two sines (h_k, h_k+1) read at horizon_strip_coords's s, mixed
/// by its f: horizon_visibility of the horizon maps (guarded as texel_guard_horizon).
LOOM_FN float horizon_strip_visibility(vector w, float h_k, float h_k1, float f) {
  return horizon_ramp(w, mix(texel_guard_horizon(h_k), texel_guard_horizon(h_k1), f));
}

#endif
