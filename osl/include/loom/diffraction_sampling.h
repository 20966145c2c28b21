// Gap diffraction at render time (ray-wave supplement section 4, Eq. S.34, S.35) from Cycles'
// built-in closures, by sampling the diffraction pattern.
//
// Through an open gap the transmitted light is the pattern D_c(s) of diffraction_table.h around
// the straight-through direction (s = xi_i.xy + xi_o.xy, xi_o = V towards the camera, xi_i = L
// towards the light on the far side). A Cycles closure cannot depend on the light direction
// beyond its own shape, and Cycles' refraction closures are isotropic (its *_refraction_setup
// sets alpha_y = alpha_x), so the cross-shaped pattern cannot be one closure. Choice: the shader
// samples it. At each shading point (each camera sample, each path vertex) it draws, per colour
// channel, a direction sum s from the pattern with four random numbers (a hash of the shading
// position, which differs between samples) and emits one narrow Beckmann refraction closure
// aimed at that direction, weighted by the importance ratio; averaged over a pixel's samples this
// converges to the pattern itself (the same argument as the supplement's noise, S.41: "such
// randomness averages out across samples in Monte Carlo rendering"). The three channels share
// the random numbers and each follows its own spectrally integrated pattern, so the colour
// fringes survive.
//
// What is sampled (the baker's diffraction_gap_sampling image, baker/include/loom/
// diffraction_tables.h):
//  * the pattern normalised to the texel's open fraction: the energy of the gap is what delta
//    transmission gives (the beam's clipped power 1 - P_A belongs to the yarns beside the gap,
//    whose own texels scatter it), the wave variant only redistributes it;
//  * outside the central spot |s| < s_spot (the beam's own Gaussian divergence, about three
//    standard deviations of the reddest channel): the spot, nearly all of the energy of a beam in
//    the middle of a hole, stays transparent() with weight 1 - p_out, so background seen through
//    the gap stays sharp and shadow rays still pass there; the sampled part carries p_out (per
//    channel), which is the arms of the cross and the fringes that the yarn edges add;
//  * per tile of the gap table (beam-centre offsets from the hole's centre, per axis), one
//    picked at random between the two neighbours of the shading point's offset with the linear
//    weight (in expectation the linear blend of the tiles);
//  * in the quadrant |s_x|, |s_y| of the table coordinates t = sqrt(|s| / S_MAX)
//    (diffraction_table.h), with the sign of each component drawn from its random number.
// Per tile the image holds, in a block of LOOM_DIFFRACTION_ICDF_SIZE columns by size + 1 rows
// (rows from the bottom): row 0 the inverse CDF of t_y (the marginal of the cells' masses in t
// space, Jacobian included), rows 1 .. size - 1 the inverse CDF of t_x in cell row 0 .. size - 2,
// row size p_out; RGB per channel. Column k of a row holds the quantile u = k / (ICDF_SIZE - 1);
// a linear look-up between columns interpolates the quantiles.
//
// A sample at direction sum s aims a refraction closure (raywave_lobes.h's, LOOM_RAYWAVE_ETA) at
// L(s) with the angular width LOOM_DIFFRACTION_KERNEL_RAD. Choice, a trade of blur against
// noise: the arms of the cross are as wide as the beam's divergence, lambda / (2 pi w_0) = 0.009
// rad for a 10 um beam, and a lobe half as wide widens them by 12 %; a lit point behind the
// cloth is found by a lobe with a probability that grows with the lobe's solid angle, so a
// narrower one would make the arms far noisier. Each channel draws LOOM_DIFFRACTION_SAMPLES
// lobes, stratified (sample k shifts the random numbers by k / SAMPLES and k times the golden
// ratio, diffraction_stratum), each with 1 / SAMPLES of the weight. Its weight per
// unit open fraction is p_out obliquity(L, V) / |L.z| / E_t: the pattern is sampled in s, whose
// measure is |L.z| times the solid angle, and the eval quantity is obliquity D (diffraction_
// table.h); E_t is the closure's albedo (the LUT's refraction channel). |L.z| is floored at
// LOOM_DIFFRACTION_MIN_COS (a sample that grazes the cloth). A sample whose direction leaves
// the unit disk (evanescent), or that the refraction closure cannot reach, gives its energy to
// transparent() instead.
//
// Not here yet (later slices): ply-edge diffraction (the diffraction_edge table), and the
// unscattered light that crosses a ply between its fibers.
#ifndef LOOM_DIFFRACTION_SAMPLING_H
#define LOOM_DIFFRACTION_SAMPLING_H
#include "osl_compat.h"
#include "diffraction_table.h"
#include "raywave_lobes.h"

/// Quantiles per inverse CDF row of the sampling image.
#define LOOM_DIFFRACTION_ICDF_SIZE 128
/// Angular width (standard deviation, radians) of one sampled lobe.
#define LOOM_DIFFRACTION_KERNEL_RAD 0.0045
/// Lobes drawn per colour channel at a shading point.
#define LOOM_DIFFRACTION_SAMPLES 2
/// Floor of |L.z| in the importance ratio.
#define LOOM_DIFFRACTION_MIN_COS 0.05

/// Gap coverage at and below which a point has no gap closures (the sampled diffraction and
/// transparent()): Blender's image textures read a stored coverage of 0 as a positive value
/// below 1e-4, which would otherwise run the diffraction sampling on every yarn point.
#define LOOM_DIFFRACTION_MIN_GAP 1e-3

LOOM_FN int diffraction_gap_sampled(float gap) {
  return gap > LOOM_DIFFRACTION_MIN_GAP;
}

/// The beam centre's offset from the nearest hole centre along one axis, in units of the half
/// gap (0 at the centre, 1 at the yarn's edge, clamped there): `coord` is the repeat coordinate
/// in [0, 1) (u for x, v for y), `yarns` the yarns per repeat stacked along that axis (centred at
/// (k + 0.5) / yarns, so holes sit at k / yarns), `gap_fraction` the gap width over the spacing.
LOOM_FN float diffraction_gap_offset(float coord, int yarns, float gap_fraction) {
  float x = coord * yarns;
  float c = x - floor(x + 0.5);
  return min(abs(c) * 2.0 / max(gap_fraction, 1e-6), 1.0);
}

/// The fractional tile coordinate of offset o in [0, 1] on n tiles. Choice: tile k holds the
/// offset o_k = 1 - (1 - k / (n - 1))^2, spaced more densely towards the yarn's edge, where the
/// beam starts to be clipped and its pattern changes fastest (a 10 um beam in the organza's
/// 127 um hole: within the last 15 um); so k = (n - 1) (1 - sqrt(1 - o)).
LOOM_FN float diffraction_tile_coord(float o, int n) {
  float c = clamp(o, 0.0, 1.0);
  if (!(c >= 0.0))
    c = 0.0;  // (NaN)
  return (n - 1) * (1.0 - sqrt(1.0 - c));
}

/// One of the n tiles at offset o in [0, 1] (diffraction_tile_coord): the upper neighbour with
/// probability equal to the fraction, for a uniform random number r.
LOOM_FN int diffraction_tile_pick(float o, int n, float r) {
  if (n < 2)
    return 0;
  float f = diffraction_tile_coord(o, n);
  int i = (int)floor(f);
  if (i >= n - 1)
    return n - 1;
  if (r < f - i)
    return i + 1;
  return i;
}

/// The random number r of stratum k (of LOOM_DIFFRACTION_SAMPLES): shifted by k times `step`
/// (1 / SAMPLES for one number, the golden ratio 0.618... for the other) modulo 1.
LOOM_FN float diffraction_stratum(float r, int k, float step) {
  float x = r + k * step;
  return x - floor(x);
}

/// A uniform random number r split into a sign (r < 0.5: -1) and a uniform number in [0, 1].
LOOM_FN float diffraction_split(float r, LOOM_OUT(float) sgn) {
  sgn = 1.0;
  if (r < 0.5)
    sgn = -1.0;
  float a = 2.0 * r - 1.0;
  return clamp(abs(a), 0.0, 1.0);
}

/// Image coordinates (s from the left, tv from the bottom) of quantile u in row `row` of tile
/// (tx, ty) of a sampling image of tiles_x x tiles_y tiles of tables `size` texels wide.
LOOM_FN void diffraction_sample_uv(float u, int row, int tx, int ty, int tiles_x, int tiles_y,
                                   int size, LOOM_OUT(float) s, LOOM_OUT(float) tv) {
  float k = clamp(u, 0.0, 1.0) * (LOOM_DIFFRACTION_ICDF_SIZE - 1) + 0.5;
  s = (tx * LOOM_DIFFRACTION_ICDF_SIZE + k) / (tiles_x * LOOM_DIFFRACTION_ICDF_SIZE);
  tv = (ty * (size + 1) + row + 0.5) / (tiles_y * (size + 1));
}

/// The row of the conditional inverse CDF of t_x given table coordinate t_y.
LOOM_FN int diffraction_cell_row(float t_y, int size) {
  float f = clamp(t_y, 0.0, 1.0) * (size - 1);
  if (!(f >= 0.0))
    f = 0.0;  // (NaN)
  int j = (int)floor(f);
  return 1 + max(0, min(j, size - 2));
}

/// The light direction L (tangent frame, on the far side of the cloth from V, V.z > 0) of
/// direction sum (s_x, s_y) = L.xy + V.xy; 0 when that leaves the unit disk.
LOOM_FN int diffraction_light_direction(vector V, float s_x, float s_y, LOOM_OUT(vector) L) {
  float lx = s_x - V[0];
  float ly = s_y - V[1];
  float r2 = lx * lx + ly * ly;
  L = vector(0.0, 0.0, -1.0);
  if (!(r2 < 1.0))
    return 0;
  L = vector(lx, ly, -sqrt(1.0 - r2));
  return 1;
}

/// Weight of one sampled lobe per unit open fraction (header comment): p_out obliquity / |L.z|
/// over the closure's albedo and the number of lobes per channel.
LOOM_FN float diffraction_lobe_weight(vector V, vector L, float p_out, float albedo) {
  float w = p_out * diffraction_obliquity(L, V) / max(abs(L[2]), LOOM_DIFFRACTION_MIN_COS);
  return w / (max(albedo, LOOM_RAYWAVE_MIN_ALBEDO) * LOOM_DIFFRACTION_SAMPLES);
}

/// The refraction closure of a lobe aimed at L (raywave_lobes.h): its normal N and Beckmann
/// alpha; 0 when the closure cannot reach L.
LOOM_FN int diffraction_lobe_closure(vector V, vector L, LOOM_OUT(vector) N,
                                     LOOM_OUT(float) alpha) {
  float mag;
  float mu = 0.5 / (LOOM_DIFFRACTION_KERNEL_RAD * LOOM_DIFFRACTION_KERNEL_RAD);
  int ok = asg_lobe_refraction_frame(V, L, N, mag);
  alpha = asg_refraction_alpha(mu, mu, mag, N, L);
  return ok;
}

#endif
