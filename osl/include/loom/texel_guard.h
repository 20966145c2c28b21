// Loom: texel values brought back into the ranges the baker writes, before any shading math.
//
// An atlas that passed validation holds only what the baker wrote, so for every such texel these
// functions return their input unchanged (Extremes.TexelGuardKeepsEveryBakedTexel). They exist for
// what validation cannot see: a texel edited or decoded wrongly, a NaN from upstream, a filtered
// mix of values the baker never pairs. The choices, where the papers are silent:
//   * NaN becomes the field's neutral value (`fallback`); +-Inf and every other value outside the
//     range are clamped to the nearest end (Inf in the optical thickness is the thickest slab);
//   * the ply frame: a normal that is not finite, zero or not above the cloth becomes the cloth
//     normal (0, 0, 1); a tangent that is not finite, zero or (nearly) along the normal becomes a
//     tangent perpendicular to it; otherwise both are only normalised, as before.
#ifndef LOOM_TEXEL_GUARD_H
#define LOOM_TEXEL_GUARD_H

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
/// vector when v is zero or not finite. A vector of length 1 within 1e-5 is returned as it is.
LOOM_FN vector texel_guard_unit(vector v) {
  if (!(isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2])))
    return vector(0.0);
  float l = length(v);
  float off = l - 1.0;
  if (abs(off) < 1e-5)
    return v;  // unit already (to float rounding): kept as it is, bit for bit
  if (l > 0.0 && isfinite(l))
    return v / l;
  float m = max(max(abs(v[0]), abs(v[1])), abs(v[2]));
  if (!(m > 0.0))
    return vector(0.0);
  return normalize(v / m);
}

/// The ply frame (t, n) of a texel in the tangent frame: unit, n above the cloth, t not along n.
LOOM_FN void texel_guard_frame(LOOM_OUT(vector) t, LOOM_OUT(vector) n) {
  vector nn = texel_guard_unit(n);
  if (!(nn[2] > 0.0))
    nn = vector(0.0, 0.0, 1.0);
  vector tt = texel_guard_unit(t);
  if (!(length(cross(tt, nn)) > 1e-6)) {
    // Any direction perpendicular to the normal: the one nearest to the cloth's x axis (or y).
    vector a = vector(1.0, 0.0, 0.0);
    if (abs(nn[0]) > 0.9)
      a = vector(0.0, 1.0, 0.0);
    tt = normalize(a - nn * dot(a, nn));
  }
  t = tt;
  n = nn;
}

#endif  // LOOM_TEXEL_GUARD_H
