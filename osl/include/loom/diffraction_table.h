// Gaussian-beam aperture diffraction (ray-wave supplement, section 4): the part the shaders
// evaluate. The baker (baker/src/aperture_diffraction.cpp, diffraction_tables.cpp) integrates
// the spectral intensity of Eq. S.35 into RGB tables; these functions turn a pair of directions
// into the table's coordinates and restore the factor the tables leave out.
//
// Eq. S.35 in the aperture's frame (z the aperture normal, both directions pointing away from
// the aperture, xi_i on the light's side and xi_o on the far side):
//   I(A, lambda, xi_i; xi_o) = (|xi_i.z| + |xi_o.z|)^2 / (4 lambda^2) |K(A; f_x, f_y)|^2,
//   f = (xi_i.xy + xi_o.xy) / lambda.
// The tables hold, per RGB channel c with spectral weight w_c (spectrum.h),
//   D_c(s) = int w_c(lambda) |K(A; s / lambda)|^2 / (lambda^2 P_beam) dlambda,
//   s = xi_i.xy + xi_o.xy (the direction sum; s = 0 for straight-through transmission),
//   P_beam = pi w_0^2 / 2 (the power of the Gaussian beam of Eq. S.25),
// so that the transmitted radiant intensity per unit incident power is
//   diffraction_obliquity(xi_i, xi_o) * D_c(s)
// and, by Parseval, its integral over directions is the share of the beam's power the aperture
// lets through. The BTDF is that intensity divided by |xi_o.z|.
//
// |K|^2 is even in f_x and in f_y separately (the Gaussian window is real, so
// K(A; -f) = conj(K(A; f)) factor by factor), so the tables cover the quadrant |s_x|, |s_y|.
// Choice: a square-root warp t = sqrt(|s| / LOOM_DIFFRACTION_S_MAX) puts half the samples in
// |s| < S_MAX / 4, where the central peak (width about lambda / w_0) and the first fringes are.
#ifndef LOOM_DIFFRACTION_TABLE_H
#define LOOM_DIFFRACTION_TABLE_H
#include "osl_compat.h"

/// |s_x|, |s_y| never exceed 2 (sums of two unit vectors' components).
#define LOOM_DIFFRACTION_S_MAX 2.0
/// d_cut of section 4.3, in beam waists: the distance from the beam centre beyond which the beam
/// carries nothing. The text gives no value; at 3 w_0 the amplitude exp(-9) is about 1e-4.
#define LOOM_DIFFRACTION_DCUT_WAISTS 3.0

/// The factor of Eq. S.35 the tables leave out: (|xi_i.z| + |xi_o.z|)^2 / 4 (the 1 / lambda^2
/// is inside the spectral integral). 1 for normal incidence straight through.
LOOM_FN float diffraction_obliquity(vector xi_i, vector xi_o) {
  float a = abs(xi_i[2]) + abs(xi_o[2]);
  return 0.25 * a * a;
}

/// Table coordinate in [0, 1] of one component of the direction sum s (either sign).
LOOM_FN float diffraction_table_coord(float s_component) {
  return sqrt(min(abs(s_component) / LOOM_DIFFRACTION_S_MAX, 1.0));
}

/// The direction sum component at table coordinate t in [0, 1] (inverse of the above, s >= 0).
LOOM_FN float diffraction_table_s(float t) { return LOOM_DIFFRACTION_S_MAX * t * t; }

/// Texture coordinate (Blender's convention: 0 at the left and at the bottom) of table
/// coordinate t in [0, 1] inside tile `tile` of `tiles` tiles of `size` texels along one axis. Texel k of a tile
/// holds t = k / (size - 1), so t = 0 (the central peak) and t = 1 sit on texel centres.
LOOM_FN float diffraction_tile_uv(float t, int tile, int tiles, int size) {
  float k = clamp(t, 0.0, 1.0) * (size - 1) + 0.5;
  return (tile * size + k) / (tiles * size);
}

/// Section 4.3: for a beam whose centre lands on a ply of radius `ply_radius` at distance
/// `h_dist` from the ply's centre line (same length unit, e.g. um), the aperture past the ply's
/// edge is [x_w, x_e] x [y_s, y_n] = [R - |h|, d_cut] x [-d_cut, d_cut] (x across the ply, away
/// from its centre; y along it). Returns x_w / d_cut: in [0, 1) the beam is clipped by the edge
/// and the ply-edge table applies; >= 1 nothing passes the edge; < 0 the centre misses the ply.
LOOM_FN float diffraction_edge_param(float h_dist, float ply_radius, float d_cut) {
  return (ply_radius - abs(h_dist)) / max(d_cut, 1e-12);
}

#endif
