#include "loom/absorption.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "loom/ply_scattering.h"
#include "loom/procedural_ply.h"

namespace loom {

namespace {
/// Slices across the ply for the wide beam; the beam of each covers its share of [-1, 1].
constexpr int kWideBeamSlices = 17;
/// Absorption levels of the curve: 0, then log-spaced over [1, 10^4] per mm.
constexpr int kCurveLevels = 33;
}  // namespace

AbsorptionCurve absorption_curve(const YarnSpec& y, Quality q) {
  const PlyParams p = ply_params_from_yarn(y);
  PlyGeometry g(p, make_ply_fibers(p, 0, 0));
  PlySimSettings s = ply_sim_settings(q);
  s.theta_o_count = 4, s.phi_o_count = 8;  // only the energies are used
  s.sigmas = {0};
  for (int k = 0; k < kCurveLevels - 1; ++k) s.sigmas.push_back(std::pow(1e4, double(k) / (kCurveLevels - 2)));
  s.beam_halfwidth = 1.0 / kWideBeamSlices;
  std::vector<PlySimSlice> slices(kWideBeamSlices);
  tbb::parallel_for(0, kWideBeamSlices, [&](int n) {
    const double h = -1 + (2.0 * n + 1) / kWideBeamSlices;
    slices[size_t(n)] = simulate_ply_slice(g, y.ior, s, 0.0, h, uint64_t(900000 + n));
  });
  AbsorptionCurve c;
  c.sigma_per_mm = s.sigmas;
  for (size_t k = 0; k < s.sigmas.size(); ++k) {
    double scattered = 0, hit = 0;
    for (const auto& sl : slices) {
      const PlySimEnergy& e = sl.energy[k];
      scattered += e.reflected + e.higher_order;
      hit += e.reflected + e.higher_order + e.absorbed + e.truncated;
    }
    c.energy.push_back(hit > 0 ? scattered / hit : 0.0);
  }
  c.rays = uint64_t(kWideBeamSlices) * uint64_t(s.rays_per_slice);
  return c;
}

double AbsorptionFit::energy(double sigma) const { return std::pow(b * std::exp(sigma), a); }

double AbsorptionFit::sigma(double c, double sigma_max) const {
  if (!(c > 0)) return sigma_max;  // black (or NaN): as absorbing as the tables go
  const double s = std::log(std::pow(c, 1 / a) / b);
  if (!std::isfinite(s)) return s > 0 ? sigma_max : 0.0;
  return std::clamp(s, 0.0, sigma_max);
}

AbsorptionFit fit_absorption(const AbsorptionCurve& curve) {
  // log E = a log b + a sigma: a line in sigma, slope a, intercept a log b. Levels on the
  // reflection floor (E below twice the curve's last value) are left out with the too dark.
  const double floor_e = curve.energy.empty() ? 0.0 : curve.energy.back();
  const double min_e = std::max(kAbsorptionFitMinEnergy, 2 * floor_e);
  double n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (size_t k = 0; k < curve.energy.size(); ++k) {
    if (curve.energy[k] < min_e) continue;
    const double x = curve.sigma_per_mm[k], yv = std::log(curve.energy[k]);
    n += 1, sx += x, sy += yv, sxx += x * x, sxy += x * yv;
  }
  AbsorptionFit f;
  const double den = n * sxx - sx * sx;
  if (n < 2 || !(std::fabs(den) > 0)) return f;
  const double slope = (n * sxy - sx * sy) / den, icpt = (sy - slope * sx) / n;
  if (!(slope < 0)) return f;
  f.a = slope;
  f.b = std::exp(icpt / slope);
  double se = 0;
  for (size_t k = 0; k < curve.energy.size(); ++k) {
    if (curve.energy[k] < min_e) continue;
    const double r = std::log(curve.energy[k]) - (icpt + slope * curve.sigma_per_mm[k]);
    se += r * r;
  }
  f.rms_log_error = std::sqrt(se / n);
  return f;
}

YarnAbsorption yarn_absorption(const std::array<double, 3>& rgb, const SpectralUpsampler& up,
                               const AbsorptionFit& fit, const AbsorptionCurve& curve,
                               double sigma_max) {
  YarnAbsorption out;
  out.spectrum = up.fit(rgb);
  out.rgb_spectrum = up.rgb(out.spectrum);
  const SpectralRgb& w = up.weights();
  for (size_t k = 0; k < w.lambda_nm.size(); ++k) {
    const double c = out.spectrum(w.lambda_nm[k]);
    const double sg = curve_sigma(curve, c, sigma_max), s42 = fit.sigma(c, sigma_max);
    out.lambda_nm.push_back(w.lambda_nm[k]);
    out.sigma_per_mm.push_back(sg);
    out.sigma_s42_per_mm.push_back(s42);
    const double e = curve_energy(curve, sg), e42 = curve_energy(curve, s42);
    for (int ch = 0; ch < 3; ++ch) {
      out.rgb_ply[size_t(ch)] += w.weight[k][size_t(ch)] * e;
      out.rgb_s42[size_t(ch)] += w.weight[k][size_t(ch)] * e42;
    }
  }
  for (int ch = 0; ch < 3; ++ch)
    out.sigma_rgb[size_t(ch)] = curve_sigma(curve, out.rgb_ply[size_t(ch)], sigma_max);
  return out;
}

}  // namespace loom
