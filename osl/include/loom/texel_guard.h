// Loom: texel values brought back into the ranges the baker writes, before any shading math.
//
// An atlas that passed validation holds only what the baker wrote, so for every such texel these
// functions return their input unchanged (Extremes.TexelGuardKeepsEveryBakedTexel). They exist for
// what validation cannot see: a texel edited or decoded wrongly, a NaN from upstream, a filtered
// mix of values the baker never pairs. The choices, where the papers are silent:
//   * NaN becomes the field's neutral value (`fallback`); +-Inf and every other value outside the
//     range are clamped to the nearest end (Inf in the optical thickness is the thickest slab);
//   * the ply frame: a normal that is not finite, zero or not above the cloth becomes the cloth
//     normal (0, 0, 1); a tangent that is not finite, zero, (nearly) along the normal or (nearly)
//     along the cloth normal z becomes a tangent perpendicular to the normal; otherwise both are
//     only normalised, as before. A tangent along z has no glossy normal (surface_glossy_normal
//     falls back to z itself, and a microfacet closure whose tangent lies along its normal has
//     no frame: Cycles' renders and the C++ emulator then disagree). "Nearly" is within 1e-3
//     (sine of the angle; baked tangents are >= 0.3 from either): well above what node mode reads
//     for a stored 0 of a half map (Cycles' SVM image textures turn it into 2^-15 = 3.1e-5), so
//     that node mode and the C++ evaluators take the same branch.
#ifndef LOOM_TEXEL_GUARD_H
#define LOOM_TEXEL_GUARD_H
#include "osl_compat.h"

/// x in [lo, hi]; NaN gives `fallback`.
LOOM_FN float texel_guard(float x, float lo, float hi, float fallback) {
  if (isnan(x))
    return fallback;
  return clamp(x, lo, hi);
}

/// Each channel of c in [lo, hi]; NaN channels give `fallback`.
LOOM_FN color texel_guard_color(color c, float lo, float hi, float fallback) {
  return color(texel_guard(c[0], lo, hi, fallback), texel_guard(c[1], lo, hi, fallback),
               texel_guard(c[2], lo, hi, fallback));
}

/// v scaled to unit length without overflow (components up to the float maximum), or the zero
/// vector when v is not finite or no longer than 1e-3 (no direction: the baker stores unit
/// vectors, and node mode reads a stored 0 of a half map as 2^-15 per component, so a zero
/// vector must stay one there too). Node mode tests the same length (addon/node_mode.py). A
/// vector of length 1 within 1e-5 is returned as it is; one whose length overflows a float is
/// scaled by its largest component first. The 1e-3 is held in a float, as OSL and node mode's
/// sockets hold it: a C++ literal would compare in double, against 0.001 instead of
/// 0.0010000000475, and take the other branch for a length of exactly float(1e-3).
LOOM_FN vector texel_guard_unit(vector v) {
  if (!(isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2])))
    return vector(0.0);
  float l = length(v);
  float eps = 1e-3;
  if (!(l > eps))
    return vector(0.0);
  float off = l - 1.0;
  if (abs(off) < 1e-5)
    return v;  // unit already (to float rounding): kept as it is, bit for bit
  if (isfinite(l))
    return v / l;
  float m = max(max(abs(v[0]), abs(v[1])), abs(v[2]));
  return normalize(v / m);
}

/// The ply frame (t, n) of a texel in the tangent frame: unit, n above the cloth, t along
/// neither n (|t x n| > 1e-3) nor the cloth normal (t's xy part longer than 1e-3, which for a
/// unit t is the length surface_glossy_normal divides by). The fallback tangent's xy part has
/// length >= 0.43. Both tests are the ones node mode makes (lengths against a float 1e-3).
LOOM_FN void texel_guard_frame(LOOM_OUT(vector) t, LOOM_OUT(vector) n) {
  vector nn = texel_guard_unit(n);
  if (!(nn[2] > 0.0))
    nn = vector(0.0, 0.0, 1.0);
  vector tt = texel_guard_unit(t);
  float eps = 1e-3;
  if (!(length(cross(tt, nn)) > eps) || !(length(vector(tt[0], tt[1], 0.0)) > eps)) {
    // Any direction perpendicular to the normal: the one nearest to the cloth's x axis (or y).
    vector a = vector(1.0, 0.0, 0.0);
    if (abs(nn[0]) > 0.9)
      a = vector(0.0, 1.0, 0.0);
    tt = normalize(a - nn * dot(a, nn));
  }
  t = tt;
  n = nn;
}

/// One horizon sine (visibility.h) in [-1, 1]; NaN gives 0 (the horizon of a flat cloth).
LOOM_FN float texel_guard_horizon(float s) { return texel_guard(s, -1.0, 1.0, 0.0); }

/// The geometry texels as both shaders read them, colour and alpha of each map of the manifest:
/// ply_frame (t, height), ply_normal (n, h), yarn_info (kind, along, ply_id; gap). Ranges: what
/// the baker writes (ply_maps.cpp): yarn kind 0 (gap) to 2 (weft), along, ply id and gap 0-1,
/// h -1..1, height +-1e6 (NaN: 0). The frame: texel_guard_frame on the raw stored vectors.
/// Horizon sines: texel_guard_horizon.
LOOM_FN void texel_guard_geometry(LOOM_OUT(vector) t, LOOM_OUT(float) height, LOOM_OUT(vector) n,
                                  LOOM_OUT(float) h, LOOM_OUT(color) info, LOOM_OUT(float) gap) {
  texel_guard_frame(t, n);
  height = texel_guard(height, -1e6, 1e6, 0.0);
  h = texel_guard(h, -1.0, 1.0, 0.0);
  info = color(texel_guard(info[0], 0.0, 2.0, 0.0), texel_guard(info[1], 0.0, 1.0, 0.0),
               texel_guard(info[2], 0.0, 1.0, 0.0));
  gap = texel_guard(gap, 0.0, 1.0, 0.0);
}

/// The surface tier's optical texels: albedo_reflect (k_rd; k_rs), albedo_transmit (k_td; k_ts),
/// spec_params (roughness, optical thickness, blend; ior). Ranges: the spec's limits (spec.cpp)
/// as ply_maps.cpp writes them: albedos 0-1, roughness 0.001-1 (NaN: 0.25), optical thickness
/// 0-1e4 (+Inf: the thickest slab the model takes; NaN: 1), blend 0-1 (NaN: 0.5), IOR 1-3
/// (NaN: 1.5).
LOOM_FN void texel_guard_optics(LOOM_OUT(color) k_rd, LOOM_OUT(float) k_rs, LOOM_OUT(color) k_td,
                                LOOM_OUT(float) k_ts, LOOM_OUT(color) params,
                                LOOM_OUT(float) ior) {
  k_rd = texel_guard_color(k_rd, 0.0, 1.0, 0.0);
  k_rs = texel_guard(k_rs, 0.0, 1.0, 0.0);
  k_td = texel_guard_color(k_td, 0.0, 1.0, 0.0);
  k_ts = texel_guard(k_ts, 0.0, 1.0, 0.0);
  params = color(texel_guard(params[0], 0.001, 1.0, 0.25), texel_guard(params[1], 0.0, 1e4, 1.0),
                 texel_guard(params[2], 0.0, 1.0, 0.5));
  ior = texel_guard(ior, 1.0, 3.0, 1.5);
}

#endif  // LOOM_TEXEL_GUARD_H
