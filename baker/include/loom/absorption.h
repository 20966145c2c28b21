// Fabric colour from absorption (ray-wave supplement, section 6, Eq. S.42).
//
// A ply's colour is an absorption spectrum sigma(lambda) of its fibers, not an albedo. The
// relation between sigma and the ply's total scattered energy comes from the ply simulation:
// a wide beam at theta_i = 0 (slices tiling h over [-1, 1]) with a dense set of absorption
// levels (free: one trace weights each path by exp(-sigma l) per level). The energy is
//   E(sigma) = (reflected + higher order) / (everything that hit a fiber),
// averaged over h (light that misses every fiber is not the ply's to colour). E falls
// monotonically (every path's weight does) from 1 to the first-surface reflection, which no
// absorption removes (about 4 % for IOR 1.55): colours darker than that are out of reach of
// any fiber and get the largest sigma.
//
// The text fits an exponential and inverts it; written as
//   E(sigma) = (b e^sigma)^a   <=>   sigma(lambda) = log(c(lambda)^(1/a) / b)        (S.42)
// (a < 0 in mm when sigma is in 1/mm), fitted by least squares on log E over the levels with
// E >= max(kAbsorptionFitMinEnergy, twice the reflection floor). Measured on our plies the
// curve is a mixture of exponentials (one per path length) above that floor, and S.42 misses
// it by about 0.1 in log E (rms; the plain preset's mid grey 0.5 comes back as 0.43).
// Choice: Loom maps colours through the simulated curve itself (monotone, interpolated linearly
// in log E between levels, inverted by bisection) and reports S.42's (a, b) and what they would
// give next to it, so the paper's model stays measurable. sigma is clamped to [0, the ply tables' largest level] so the shaders never
// extrapolate. c(lambda) is the yarn colour's sigmoid spectrum (spectral_upsampling.h).
#pragma once

#include <array>
#include <vector>

#include "loom/absorption_curve.h"
#include "loom/spec.h"
#include "loom/spectral_upsampling.h"

namespace loom {

inline constexpr double kAbsorptionFitMinEnergy = 0.05;

/// The wide-beam sigma -> energy relation of the yarn's ply at the quality's ray count.
AbsorptionCurve absorption_curve(const YarnSpec& y, Quality q);

struct AbsorptionFit {
  double a = -1e-3, b = 1;  ///< S.42; a in mm, b dimensionless
  double rms_log_error = 0; ///< of the fit over the levels it used
  /// E(sigma) of the fitted model.
  double energy(double sigma_per_mm) const;
  /// S.42: sigma (1/mm) for albedo c, clamped to [0, sigma_max].
  double sigma(double c, double sigma_max) const;
};
AbsorptionFit fit_absorption(const AbsorptionCurve& curve);

/// A yarn colour turned into absorption: the spectrum, sigma(lambda) at the upsampler's
/// wavelengths, and per RGB channel the sigma whose energy equals the channel's share of the
/// spectrum's scattered energy (what an RGB renderer can use: E(sigma_c) = sum_k w_c E(sigma_k)).
struct YarnAbsorption {
  SigmoidSpectrum spectrum;
  std::vector<double> lambda_nm, sigma_per_mm;  ///< through the simulated curve
  std::vector<double> sigma_s42_per_mm;         ///< through S.42's fit, for comparison
  std::array<double, 3> sigma_rgb{0, 0, 0};
  std::array<double, 3> rgb_spectrum{0, 0, 0};  ///< RGB of c(lambda): the round trip
  std::array<double, 3> rgb_ply{0, 0, 0};       ///< RGB of the simulated E(sigma(lambda))
  std::array<double, 3> rgb_s42{0, 0, 0};       ///< the same with S.42's sigma(lambda)
};
/// sigma_max: the largest absorption level of the ply tables (sigma is clamped to it).
YarnAbsorption yarn_absorption(const std::array<double, 3>& rgb_linear,
                               const SpectralUpsampler& up, const AbsorptionFit& fit,
                               const AbsorptionCurve& curve, double sigma_max);

}  // namespace loom
