// SGGX microflake distribution, fiber-like case (Heitz et al. 2015), as used by the surface model
// (Zhu et al. 2023, supplement Eq. 1 and 4: "D is the SGGX distribution centered in the fiber
// tangent distribution").
//
// For a ply whose fibers run along the unit tangent t with roughness a (0 < a <= 1):
//   S = a^2 t t^T + (I - t t^T),  det S = a^2,  S^-1 = t t^T / a^2 + (I - t t^T)
//   D(w)     = 1 / (pi sqrt(det S) (w^T S^-1 w)^2)            (SGGX D, Heitz Eq. 9)
//   sigma(w) = sqrt(w^T S w)                                  (projected area, Heitz Eq. 6)
// Choice: `a` is the spec's yarn `roughness` clamped to [1e-3, 1]; a -> 0 is a perfect fiber
// (D concentrates on the great circle orthogonal to t), a = 1 is an isotropic sphere (D = 1/pi).
#ifndef LOOM_SGGX_H
#define LOOM_SGGX_H
#include "osl_compat.h"

#define LOOM_SGGX_MIN_ROUGHNESS 1e-3

LOOM_FN float sggx_fiber_roughness(float roughness) {
  return clamp(roughness, LOOM_SGGX_MIN_ROUGHNESS, 1.0);
}

/// SGGX fiber D(w) for unit w; D(w) = D(-w).
LOOM_FN float sggx_fiber_D(vector w, vector t, float a) {
  float wt = dot(w, t);
  float q = wt * wt / (a * a) + max(1.0 - wt * wt, 0.0);
  return 1.0 / (LOOM_M_PI * a * q * q);
}

/// SGGX fiber projected area sigma(w) for unit w.
LOOM_FN float sggx_fiber_sigma(vector w, vector t, float a) {
  float wt = dot(w, t);
  return sqrt(max(a * a * wt * wt + 1.0 - wt * wt, 0.0));
}

#endif
