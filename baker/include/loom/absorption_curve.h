// A ply's simulated sigma -> energy curve, and its use as the interpolation variable between the
// absorption levels of the ply tables (ray-wave supplement Eq. S.10).
//
// The curve (absorption.h: absorption_curve) is the energy a wide beam at theta_i = 0 keeps
// after absorption sigma (1/mm of fiber path): (reflected + higher order) / hit, at 33 levels
// from 0 to 10^4 / mm, interpolated linearly in log E between them.
//
// Eq. S.10 interpolates every absorption-dependent quantity (the scale-downs s_{l,k}, and in Loom
// the energy residual and the double-layer factors) linearly in sigma between the simulated
// levels sigma_k, sigma_{k+1}. Energy falls roughly exponentially in sigma, so on the levels the
// presets can afford (draft: 0, 10, 173, 3000 / mm) that overshoots by a large factor: on the
// gray wool ply at theta_i = 0, h = 0.2, f_high is 0.093 at 76 / mm, S.10 gives 0.39 (4.2x).
// Choice where the text is silent: the weight is linear in the curve's energy instead,
//   t = (E(sigma_k) - E(sigma)) / (E(sigma_k) - E(sigma_{k+1})),
// which is exact for any quantity that falls like the ply's mean energy and equals S.10's weight
// where E is linear. Quantities then still interpolate linearly (with weight t) between the
// levels, so monotone data stay monotone and the levels themselves are reproduced exactly.
// An empty curve (or a flat stretch of it) gives S.10's weight.
#pragma once

#include <cstdint>
#include <vector>

namespace loom {

/// The manifest's raywave.shading.sigma_interpolation for the weight below.
inline constexpr const char* kSigmaInterpolation = "energy";

struct AbsorptionCurve {
  std::vector<double> sigma_per_mm, energy;
  uint64_t rays = 0;
  bool empty() const { return sigma_per_mm.empty(); }
};

/// Energy of the simulated curve at any sigma (linear in log E between levels, clamped).
double curve_energy(const AbsorptionCurve& curve, double sigma_per_mm);
/// The sigma in [0, sigma_max] whose curve energy is e (0 for e >= E(0), sigma_max below the
/// reachable range).
double curve_sigma(const AbsorptionCurve& curve, double e, double sigma_max);

/// The mean of two curves (for the double layer, whose two layers are the warp and the weft),
/// on the first curve's levels.
AbsorptionCurve mean_curve(const AbsorptionCurve& a, const AbsorptionCurve& b);

/// Eq. S.10 with the weight of the header comment: the absorption interval
/// [sigmas[k], sigmas[k + 1]] holding sigma and the weight t in [0, 1] of level k + 1; clamped to
/// the levels (non-finite or negative sigma: 0; beyond the last level: k = K - 2, t = 1);
/// k = 0, t = 0 for a single level.
void sigma_interval(const std::vector<double>& sigmas, double sigma, const AbsorptionCurve& curve,
                    int& k, double& t);

}  // namespace loom
