// Double-layer corrections at render time (ray-wave supplement section 3, Eq. S.21 and S.22).
//
// The baker tabulates B_t, F_t, B_total, F_total (Eq. S.20) over the direction xi of the incident
// beam and the absorption levels (double_layer_front/back), and, for the yarn colours, the render
// table layer_factors_<side>: three blocks of RGB factors side by side,
//   block 0: B_total / B_t   (Eq. S.21, backward light)
//   block 1: F_total / F_t   (Eq. S.22, the directional forward part, times 1 - s)
// (the ratios are 1 where the denominator vanishes and at most 10, baker/src/raywave_bsdf.cpp)
//   block 2: F_total         (Eq. S.22, the diffuse forward part, times s)
// each phi_count + 2 columns (the azimuth bins (p + 0.5) 360 / phi_count degrees, with one wrapped
// bin added on each side so that bilinear filtering crosses phi = 0 without a wrap mode) by
// theta_count rows (angle from the normal (t + 0.5) 90 / theta_count degrees, from the bottom).
// Each channel holds the factors at that channel's absorption, the mean of the warp's and the
// weft's (the table's two layers share one level; choice where the text is silent), interpolated
// linearly between the simulated levels as Eq. S.10 does.
//
// At a shading point the beam is the camera ray (reciprocity): xi = V, mirrored to +z on a back
// face, where the back table (weft over warp) is used.
#ifndef LOOM_DOUBLE_LAYER_FACTORS_H
#define LOOM_DOUBLE_LAYER_FACTORS_H
#include "osl_compat.h"

/// Image coordinates (s from the left, tv from the bottom) of `block` (0, 1, 2 above) at the
/// direction xi (unit, tangent frame, xi_z >= 0).
LOOM_FN void double_layer_uv(vector xi, int block, int theta_count, int phi_count,
                             LOOM_OUT(float) s, LOOM_OUT(float) tv) {
  float theta = acos(clamp(xi[2], 0.0, 1.0)) * 180.0 / LOOM_M_PI;
  float row = clamp(theta * theta_count / 90.0 - 0.5, 0.0, theta_count - 1.0);
  float phi = 0.0;
  if (fabs(xi[0]) + fabs(xi[1]) > 1e-9)
    phi = atan2(xi[1], xi[0]) * 180.0 / LOOM_M_PI;
  if (phi < 0.0)
    phi += 360.0;
  float col = clamp(phi * phi_count / 360.0 + 0.5, 0.5, phi_count + 0.5);
  float w = phi_count + 2.0;
  s = (block * w + col + 0.5) / (3.0 * w);
  tv = (row + 0.5) / theta_count;
}

#endif
