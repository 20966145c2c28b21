// Wave-optics speckle noise (ray-wave supplement, section 5): the part the shaders evaluate.
// The baker (baker/src/speckle_noise.cpp) synthesises the noise tiles N_2D over outgoing
// directions (Eq. S.37, S.38); these functions find where to read them.
//
// Tile coordinates. A direction w in ply space (the ply along +z) has theta = asin(w.z) in
// [-pi/2, pi/2] (elevation from the plane normal to the ply) and phi = atan2(w.y, w.x) in
// (-pi, pi]. A tile spans phi over [-pi, pi) across (u) and theta over [-pi/2, pi/2] up (v),
// periodic in phi.
//
// Spatial variation (section 5.2): "different noise instances for different positions on the
// fabric, through a hash of the ply ID and the position along the ply". Choice: the ply is cut
// into segments LOOM_NOISE_SEGMENTS_PER_REPEAT per unit of the atlas's `along` coordinate; a
// hash of (ply ID, segment) picks one of the baked instances and a rotation of the tile in phi
// (seamless, since the tile is periodic in phi). The hash uses only float arithmetic on exact
// integers below 2^24, so OSL and C++ give bit-identical results.
//
// At render time (Eq. S.39), per lobe. A Cycles closure cannot vary inside its lobe, so S.39's
// f N(w_o) becomes, for each fitted lobe, its weight times the noise averaged over the lobe at
// the lobe's centre (choice: what a closure can carry). The baker stores each tile at
// LOOM_NOISE_LEVELS blur widths (noise_level_blur: the tile itself, then Gaussians of 0.015,
// 0.05, 0.15 rad, about the widths of the presets' lobes), stacked in v above the tile; a lobe
// of angular width sigma = 1 / sqrt(2 sqrt(mu1 mu2)) (asg.h's exp(-mu theta^2) as a Gaussian)
// reads the two levels around sigma, blended linearly in sigma. The centre is the lobe's z in
// ply space for f_high, and its memory-effect direction S.40 (with the beam's incidence) for
// f_refl. What is lost: the speckle inside a lobe (a narrow lobe keeps its full contrast, a
// broad one averages it away, as its integral would) and its variation with the light's
// direction across a lobe; kept: the variation from lobe to lobe, with the view, and from
// ply segment to ply segment. The energy residual (broad multiple scattering) and the gaps'
// diffraction are not modulated.
#ifndef LOOM_SPECKLE_NOISE_H
#define LOOM_SPECKLE_NOISE_H
#include "osl_compat.h"

#define LOOM_NOISE_SEGMENTS_PER_REPEAT 16.0
#define LOOM_NOISE_HASH_MOD 65521.0
/// Blur levels stacked in a noise image (noise_level_blur).
#define LOOM_NOISE_LEVELS 4

/// One round of a multiplicative hash on exact float integers: x is reduced mod p = 65521 first,
/// so a x + c (a, c < 256) stays below 2^24, where float arithmetic is exact.
LOOM_FN float noise_hash_round(float x, float a, float c) {
  return mod(a * mod(x, LOOM_NOISE_HASH_MOD) + c, LOOM_NOISE_HASH_MOD);
}

/// A hash of (ply ID in [0, 1), segment index) to [0, 1). Deterministic and identical in OSL
/// and C++ (exact integer arithmetic in float).
LOOM_FN float noise_hash(float ply_id, float segment) {
  float a = floor(clamp(ply_id, 0.0, 1.0) * 4095.0);
  float b = mod(floor(segment), 4096.0);
  float h = noise_hash_round(a * 16.0 + mod(b, 16.0), 251.0, 17.0);
  h = noise_hash_round(h + floor(b / 16.0) * 97.0, 223.0, 41.0);
  h = noise_hash_round(h, 199.0, 7.0);
  h = noise_hash_round(h, 241.0, 113.0);
  return h / LOOM_NOISE_HASH_MOD;
}

/// (theta, phi) of a ply-space direction; zero or NaN directions give (0, 0).
LOOM_FN void noise_angles(vector w, LOOM_OUT(float) theta, LOOM_OUT(float) phi) {
  vector n = normalize(w);
  float z = clamp(n[2], -1.0, 1.0);
  theta = 0.0;
  phi = 0.0;
  if (isfinite(z) && z == z) {
    theta = asin(z);
    float r = n[0] * n[0] + n[1] * n[1];
    if (r > 0.0) phi = atan2(n[1], n[0]);
  }
}

/// Texture coordinates of a ply-space direction in noise instance `instance` of `instances`
/// (stacked bottom to top), with the tile rotated by `phi_shift` (a fraction of a turn).
LOOM_FN void noise_tile_uv(vector w, float phi_shift, int instance, int instances,
                           LOOM_OUT(float) u, LOOM_OUT(float) v) {
  float theta = 0.0, phi = 0.0;
  noise_angles(w, theta, phi);
  u = mod((phi + LOOM_M_PI) / (2.0 * LOOM_M_PI) + phi_shift, 1.0);
  float t = clamp((theta + 0.5 * LOOM_M_PI) / LOOM_M_PI, 0.0, 1.0);
  v = (instance + t) / max(instances, 1);
}

/// Eq. S.40, the memory effect of surface reflection: the outgoing direction w'_o whose half
/// vector with the nominal incidence w_i^n = (0, 1, 0) (theta_i = 0) equals the half vector of
/// (w_i, w_o): the mirror of w_i^n about that half vector, w'_o = 2 (w_i^n . H) H - w_i^n. When
/// w_i^n . H < 0 no direction satisfies S.40 exactly (the half vectors would point apart); the
/// same mirror is used, which keeps the look-up continuous. When w_i = -w_o (no half vector),
/// w_o itself.
LOOM_FN vector noise_memory_effect_direction(vector wi, vector wo) {
  vector s = normalize(wi) + normalize(wo);
  float l = length(s);
  if (!(l > 1e-6)) return normalize(wo);
  vector H = s / l;
  vector n = vector(0.0, 1.0, 0.0);
  return 2.0 * dot(n, H) * H - n;
}

/// The blur (Gaussian standard deviation, radians of outgoing angle) of level l of a noise image.
LOOM_FN float noise_level_blur(int l) {
  if (l <= 0)
    return 0.0;
  if (l == 1)
    return 0.015;
  if (l == 2)
    return 0.05;
  return 0.15;
}

/// The fractional level of a lobe of angular width sigma: linear in sigma between the levels'
/// blurs, clamped to [0, LOOM_NOISE_LEVELS - 1] (NaN: the broadest).
LOOM_FN float noise_level_coord(float sigma) {
  float top = LOOM_NOISE_LEVELS - 1;
  if (!(sigma < noise_level_blur(LOOM_NOISE_LEVELS - 1)))
    return top;
  float c = 0.0;
  for (int l = 0; l < LOOM_NOISE_LEVELS - 1; l += 1) {
    float a = noise_level_blur(l), b = noise_level_blur(l + 1);
    if (sigma >= a && sigma < b)
      c = l + (sigma - a) / (b - a);
  }
  return c;
}

/// The angular width of a lobe exp(-mu1 x^2 - mu2 y^2) as one Gaussian: 1 / sqrt(2 sqrt(mu1 mu2))
/// (bandwidths clamped to [1e-6, 1e12]).
LOOM_FN float noise_lobe_sigma(float mu1, float mu2) {
  float m = sqrt(clamp(mu1, 1e-6, 1e12) * clamp(mu2, 1e-6, 1e12));
  return 1.0 / sqrt(2.0 * m);
}

/// v of level `level` of `levels` stacked tiles, for v in [0, 1] of one tile (noise_tile_uv).
LOOM_FN float noise_level_v(float v, int level, int levels) {
  return (level + clamp(v, 0.0, 1.0)) / max(levels, 1);
}

/// The noise instance and phi rotation of a shading point (header comment): a hash of the ply ID
/// and of the ply segment at `along` (the position along the yarn over one repeat, [0, 1)).
LOOM_FN void noise_pick(float ply_id, float along, int instances, LOOM_OUT(int) instance,
                        LOOM_OUT(float) phi_shift) {
  float h = noise_hash(ply_id, floor(clamp(along, 0.0, 1.0) * LOOM_NOISE_SEGMENTS_PER_REPEAT));
  float x = h * max(instances, 1);
  instance = min((int)floor(x), max(instances, 1) - 1);
  phi_shift = x - instance;
}

/// Where a lobe with centre z (ply space) reads its noise (header comment): u and the two
/// levels' v, and the weight of the upper one. `refl`: an f_refl lobe, read at the memory-effect
/// direction with the beam's ply-space direction wi = (0, cos theta_i, sin theta_i).
LOOM_FN void noise_lobe_uv(vector z, vector wi, int refl, float mu1, float mu2, int instance,
                           float phi_shift, int instances, LOOM_OUT(float) u,
                           LOOM_OUT(float) v0, LOOM_OUT(float) v1, LOOM_OUT(float) t) {
  vector w = z;
  if (refl)
    w = noise_memory_effect_direction(wi, z);
  float v;
  noise_tile_uv(w, phi_shift, instance, instances, u, v);
  float c = noise_level_coord(noise_lobe_sigma(mu1, mu2));
  int l = (int)floor(c);
  if (l > LOOM_NOISE_LEVELS - 2)
    l = LOOM_NOISE_LEVELS - 2;
  t = c - l;
  v0 = noise_level_v(v, l, LOOM_NOISE_LEVELS);
  v1 = noise_level_v(v, l + 1, LOOM_NOISE_LEVELS);
}

#endif
