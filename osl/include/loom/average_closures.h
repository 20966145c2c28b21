// The repeat-averaged closures (issue 31: level of detail by footprint). Where a pixel covers
// whole weave repeats, what it sees is the cloth's BSDF averaged over the repeat; the baker fits
// it per view direction (baker/src/average_fit.cpp) with four Cycles closures, the same for both
// tiers, and the shaders read them instead of shading each texel:
//
//   closure                                          weight (RGB)
//   diffuse(N)                                       d
//   translucent(N)                                   l
//   microfacet("ggx", N, T, a_x, a_y, 1, 0)          g
//   microfacet("ggx", V, V, a_t, a_t, ETA, 1)        r
//
// with N towards the viewer, T the warp direction (the UV map's tangent, made orthogonal to N) and
// V the view direction. The refraction about V is a lobe centred straight through the cloth (light
// that crosses it keeps its direction), a_t (1 - 1 / ETA) wide. The table holds the average of the
// yarns' part (no gaps): a shader scales it by this point's yarn coverage over the repeat's mean
// (average_closures_yarn_scale) and keeps the gaps' own closures per point, so the pixel's mean is
// the repeat's mean and the gaps' delta transmission and diffraction stay as they are.
//
// The table: LOOM_AVERAGE_PHI + 1 columns over the view azimuth phi_v in [0, 2 pi] (about N,
// from T towards B = N x T; the last column repeats the first, so linear interpolation wraps)
// and rows, from the bottom, by side (0: the view on the front normal's side, 1: behind), then
// panel, then LOOM_AVERAGE_THETA rows of cos theta_v over [0, 1]. Texel centres sit on the
// fitted views, so linear interpolation never mixes sides or panels. Panel p holds closure p's
// weight in RGB and in A the p-th of (a_x, a_y, a_t, 0).
#ifndef LOOM_AVERAGE_CLOSURES_H
#define LOOM_AVERAGE_CLOSURES_H
#include "osl_compat.h"

#define LOOM_AVERAGE_THETA 8
#define LOOM_AVERAGE_PHI 12
#define LOOM_AVERAGE_PANELS 4
#define LOOM_AVERAGE_ETA 2.0

/// Image coordinates (s, tv in [0, 1], tv from the bottom) of `panel` at view V (the frame
/// T, B, N with N towards the viewer: V.z >= 0), on side `back` (0 or 1).
LOOM_FN void average_closures_uv(vector V, float back, float panel, LOOM_OUT(float) s,
                                 LOOM_OUT(float) tv) {
  float np = LOOM_AVERAGE_PHI;
  float nt = LOOM_AVERAGE_THETA;
  float phi = atan2(V[1], V[0]);
  if (phi < 0.0)
    phi = phi + 2.0 * LOOM_M_PI;
  s = (0.5 + phi * (np / (2.0 * LOOM_M_PI))) / (np + 1.0);
  float c = clamp(V[2] / max(length(V), 1e-8), 0.0, 1.0);
  float row0 = (back * LOOM_AVERAGE_PANELS + panel) * nt;
  tv = (row0 + 0.5 + c * (nt - 1.0)) / (2.0 * LOOM_AVERAGE_PANELS * nt);
}

/// What the averaged closures are multiplied by at a point of yarn coverage 1 - gap, when the
/// repeat's mean gap is gap_mean: over the repeat it averages to 1.
LOOM_FN float average_closures_yarn_scale(float gap, float gap_mean) {
  return (1.0 - gap) / max(1.0 - gap_mean, 1e-3);
}

#endif
