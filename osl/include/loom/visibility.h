// Shadowing-masking between plies and yarns from the baked horizon map (the surface model's
// precomputed visibility V; Zhu et al. 2023 precompute it from the ply-level geometry).
//
// The baker stores, per texel, the sine of the horizon elevation in LOOM_HORIZON_DIRS azimuths
// phi_k = 2 pi k / LOOM_HORIZON_DIRS measured in the tangent plane from +x (the warp direction):
// the highest elevation of the cloth's own height field seen from that texel in that direction.
// A direction w above the surface is visible when its elevation clears the horizon. Choices where
// the text is silent: linear interpolation of the horizon between azimuth bins, and a soft ramp
// of half-width LOOM_HORIZON_SOFTNESS in sine of elevation (an area light or a pixel footprint
// never sees a hard horizon). Directions below the surface (transmission) are not occluded by the
// upper height field: visibility 1.
#ifndef LOOM_VISIBILITY_H
#define LOOM_VISIBILITY_H
#include "osl_compat.h"

#define LOOM_HORIZON_DIRS 8
#define LOOM_HORIZON_SOFTNESS 0.05

/// Horizon sine at the azimuth of w (tangent frame), from the 8 stored sines h0..h7.
LOOM_FN float horizon_sine(vector w, float h[LOOM_HORIZON_DIRS]) {
  float phi = atan2(w[1], w[0]);
  if (phi < 0.0)
    phi += 2.0 * LOOM_M_PI;
  float x = phi / (2.0 * LOOM_M_PI) * LOOM_HORIZON_DIRS;
  int k = (int)floor(x);
  float f = x - k;
  k = k % LOOM_HORIZON_DIRS;
  if (k < 0)
    k += LOOM_HORIZON_DIRS;
  int k1 = (k + 1) % LOOM_HORIZON_DIRS;
  return mix(h[k], h[k1], clamp(f, 0.0, 1.0));
}

/// V(w) in [0, 1] for unit w in the tangent frame, given the horizon sine s at w's azimuth
/// (horizon_sine): the soft ramp.
LOOM_FN float horizon_ramp(vector w, float s) {
  if (w[2] <= 0.0)
    return 1.0;
  float x = clamp((w[2] - (s - LOOM_HORIZON_SOFTNESS)) / (2.0 * LOOM_HORIZON_SOFTNESS), 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}

/// V(w) in [0, 1] for unit w in the tangent frame.
LOOM_FN float horizon_visibility(vector w, float h[LOOM_HORIZON_DIRS]) {
  if (w[2] <= 0.0)
    return 1.0;
  return horizon_ramp(w, horizon_sine(w, h));
}

/// Cosine-weighted mean visibility of the upper hemisphere (the fraction of a uniform sky that a
/// Lambertian lobe about n_s sees), in closed form from the horizon: for a sector of azimuth
/// width 2 pi / K whose horizon has elevation e, int_{elevation > e} cos(theta) dw / pi over it is
/// cos^2(e) / K; the ramp of horizon_visibility is ignored.
LOOM_FN float horizon_ambient_visibility(float h[LOOM_HORIZON_DIRS]) {
  float sum = 0.0;
  for (int k = 0; k < LOOM_HORIZON_DIRS; ++k) {
    float s = clamp(h[k], 0.0, 1.0);
    sum += 1.0 - s * s;
  }
  return sum / LOOM_HORIZON_DIRS;
}

#endif
