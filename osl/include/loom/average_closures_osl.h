// OSL only (closures have no C++ counterpart; baker/src/average_fit.cpp emulates them): the
// repeat-averaged closures of average_closures.h as both tiers' shaders emit them.
#ifndef LOOM_AVERAGE_CLOSURES_OSL_H
#define LOOM_AVERAGE_CLOSURES_OSL_H
#include "average_closures.h"

/// The closures of the atlas's average_closures table `file` at view V (the frame T, B, N with N
/// towards the viewer; Vw the view direction in world space) on side `back`, scaled by the
/// point's yarn coverage 1 - gap over the repeat's mean.
closure color average_closures(string file, vector V, int back, vector T, normal N, vector Vw,
                               float gap, float gap_mean) {
  color c[LOOM_AVERAGE_PANELS];
  float a[LOOM_AVERAGE_PANELS];
  for (int p = 0; p < LOOM_AVERAGE_PANELS; p += 1) {
    float s, tv, alpha;
    average_closures_uv(V, float(back), float(p), s, tv);
    c[p] = texture(file, s, 1.0 - tv, "interp", "linear", "wrap", "clamp", "width", 0.0,
                   "alpha", alpha);
    a[p] = alpha;
  }
  float k = average_closures_yarn_scale(gap, gap_mean);
  normal nv = normalize(Vw);
  return (k * c[0]) * diffuse(N) + (k * c[1]) * translucent(N) +
         (k * c[2]) * microfacet("ggx", N, T, a[0], a[1], 1.0, 0) +
         (k * c[3]) * microfacet("ggx", nv, nv, a[2], a[2], LOOM_AVERAGE_ETA, 1);
}

#endif
