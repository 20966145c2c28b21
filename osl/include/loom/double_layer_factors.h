// Double-layer corrections at render time (ray-wave supplement section 3, Eq. S.20-S.22).
//
// The baker tabulates B_t, F_t, B_total, F_total (Eq. S.20) over the direction xi of the incident
// beam and the absorption levels (double_layer_front/back), and, for the yarn colours, the render
// table layer_factors_<side>: two blocks of RGB factors side by side,
//   block 0: k_b = (B_total - B_t) / F_t   the backward light the layers below return per unit
//                                         of a point's forward light
//   block 1: k_f = F_total / F_t           the forward light that leaves the stack per unit of a
//                                         point's forward light
// (both 0 and 1 where F_t vanishes; k_b >= 0; when k_b + k_f exceeds 1, both are scaled down to
// sum 1: Eq. S.20 gives k_b + k_f = F_tb / (1 - B_tb), at most 1 while the bottom layer does not
// scatter more than it receives, baker/src/raywave_bsdf.cpp layer_factor_pair)
// each phi_count + 2 columns (the azimuth bins (p + 0.5) 360 / phi_count degrees, with one wrapped
// bin added on each side so that bilinear filtering crosses phi = 0 without a wrap mode) by
// theta_count rows (angle from the normal (t + 0.5) 90 / theta_count degrees, from the bottom).
// Each channel holds the factors at that channel's absorption, the mean of the warp's and the
// weft's (the table's two layers share one level; choice where the text is silent), interpolated
// linearly between the simulated levels as Eq. S.10 does.
//
// Choice where the text's model is not energy-conserving: Eq. S.21 and S.22 multiply a point's
// own backward light R and forward light T by B_total / B_t and F_total / F_t, ratios of the
// top layer's averages over h. A point that scatters more backwards than that average then
// leaves with more than it received (white yarns seen from below: up to 1.57 at cos_o 0.95, 2.2
// at some texels, 1.08-1.15 averaged over the repeat). Loom gives the layers' extra light to
// the point's forward light instead, the only light that reaches the layer below:
//   backward  R + k_b T      (k_b T as diffuse reflection: light back through the top layer)
//   forward   k_f T          ((1 - s) in the point's own forward lobes, s as the diffuse BTDF
//                            L_d of Eq. S.22)
// Averaged over h (R -> B_t, T -> F_t) these are exactly B_total and F_total, the text's layer
// totals, and per point R + (k_b + k_f) T <= R + T.
//
// At a shading point the beam is the camera ray (reciprocity): xi = V, mirrored to +z on a back
// face, where the back table (weft over warp) is used.
#ifndef LOOM_DOUBLE_LAYER_FACTORS_H
#define LOOM_DOUBLE_LAYER_FACTORS_H
#include "osl_compat.h"

/// Blocks of a layer_factors table: k_b, k_f (header comment).
#define LOOM_DOUBLE_LAYER_BLOCKS 2

/// Image coordinates (s from the left, tv from the bottom) of `block` (0 k_b, 1 k_f) at the
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
  s = (block * w + col + 0.5) / (LOOM_DOUBLE_LAYER_BLOCKS * w);
  tv = (row + 0.5) / theta_count;
}

#endif
