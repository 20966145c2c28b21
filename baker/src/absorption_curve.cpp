#include "loom/absorption_curve.h"

#include <algorithm>
#include <cmath>

namespace loom {

double curve_energy(const AbsorptionCurve& c, double sigma) {
  const auto& s = c.sigma_per_mm;
  if (s.empty()) return 0;
  if (!(sigma > s.front())) return c.energy.front();
  if (sigma >= s.back()) return c.energy.back();
  size_t k = size_t(std::upper_bound(s.begin(), s.end(), sigma) - s.begin());
  const double t = (sigma - s[k - 1]) / (s[k] - s[k - 1]);
  const double e0 = std::max(c.energy[k - 1], 1e-300), e1 = std::max(c.energy[k], 1e-300);
  return std::exp((1 - t) * std::log(e0) + t * std::log(e1));
}

double curve_sigma(const AbsorptionCurve& c, double e, double sigma_max) {
  if (c.energy.empty() || !(e < c.energy.front())) return 0.0;  // also NaN: no absorption
  if (!(curve_energy(c, sigma_max) < e)) return sigma_max;
  double lo = 0, hi = sigma_max;
  for (int it = 0; it < 100 && hi - lo > 1e-9 * sigma_max; ++it) {
    const double mid = 0.5 * (lo + hi);
    (curve_energy(c, mid) > e ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

AbsorptionCurve mean_curve(const AbsorptionCurve& a, const AbsorptionCurve& b) {
  AbsorptionCurve m = a;
  if (b.empty()) return m;
  if (a.empty()) return b;
  for (size_t k = 0; k < m.energy.size(); ++k)
    m.energy[k] = 0.5 * (a.energy[k] + curve_energy(b, a.sigma_per_mm[k]));
  m.rays = a.rays + b.rays;
  return m;
}

void sigma_interval(const std::vector<double>& sig, double sigma, const AbsorptionCurve& curve,
                    int& k, double& t) {
  k = 0, t = 0;
  const int K = int(sig.size());
  const double s = std::isfinite(sigma) ? std::max(sigma, 0.0) : 0.0;
  if (K < 2) return;
  if (s >= sig.back()) {
    k = K - 2, t = 1;
    return;
  }
  while (k + 2 < K && s > sig[size_t(k + 1)]) ++k;
  const double s0 = sig[size_t(k)], s1 = sig[size_t(k + 1)];
  t = std::clamp((s - s0) / (s1 - s0), 0.0, 1.0);  // S.10
  if (curve.empty()) return;
  const double e0 = curve_energy(curve, s0), e1 = curve_energy(curve, s1);
  // A flat stretch (or a curve that is not decreasing there) keeps S.10's weight.
  if (!(e0 - e1 > 1e-9 * std::max(e0, 1e-300))) return;
  t = std::clamp((e0 - curve_energy(curve, s)) / (e0 - e1), 0.0, 1.0);
}

}  // namespace loom
