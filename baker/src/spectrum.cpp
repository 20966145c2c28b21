#include "loom/spectrum.h"

#include <cmath>
#include <stdexcept>

namespace loom {

namespace {
/// The piecewise Gaussian of Wyman et al. 2013: width s1 left of the peak, s2 right of it.
double lobe(double x, double mu, double s1, double s2) {
  const double t = (x - mu) / (x < mu ? s1 : s2);
  return std::exp(-0.5 * t * t);
}
}  // namespace

std::array<double, 3> cie1931_cmf(double l) {
  // Wyman, Sloan, Shirley 2013, Eq. 2 (multi-lobe fit of the 1931 2-degree observer).
  const double x = 1.056 * lobe(l, 599.8, 37.9, 31.0) + 0.362 * lobe(l, 442.0, 16.0, 26.7) -
                   0.065 * lobe(l, 501.1, 20.4, 26.2);
  const double y = 0.821 * lobe(l, 568.8, 46.9, 40.5) + 0.286 * lobe(l, 530.9, 16.3, 31.1);
  const double z = 1.217 * lobe(l, 437.0, 11.8, 36.0) + 0.681 * lobe(l, 459.0, 26.0, 13.8);
  return {x, y, z};
}

SpectralRgb spectral_rgb(const ColourConverter& cc, double step_nm) {
  if (!(step_nm > 0) || step_nm > kLambdaMaxNm - kLambdaMinNm)
    throw std::invalid_argument("spectral_rgb: step_nm must be in (0, 400]");
  const auto M = cc.xyz_to_linear_matrix();
  const int n = int(std::floor((kLambdaMaxNm - kLambdaMinNm) / step_nm + 1e-9)) + 1;
  SpectralRgb out;
  std::array<double, 3> total{0, 0, 0};
  for (int k = 0; k < n; ++k) {
    const double l = kLambdaMinNm + k * step_nm;
    const auto xyz = cie1931_cmf(l);
    std::array<double, 3> w{};
    for (int c = 0; c < 3; ++c) {
      w[c] = M[c][0] * xyz[0] + M[c][1] * xyz[1] + M[c][2] * xyz[2];
      // Trapezoid rule: half weight at both ends.
      if (k == 0 || k == n - 1) w[c] *= 0.5;
      total[c] += w[c];
    }
    out.lambda_nm.push_back(l);
    out.weight.push_back(w);
  }
  for (auto& w : out.weight)
    for (int c = 0; c < 3; ++c) w[c] /= total[c];
  return out;
}

}  // namespace loom
