#include "loom/swatch.h"

#include <cmath>
#include <stdexcept>

#include "loom/ply_scattering.h"

namespace loom {

SwatchPaths::SwatchPaths(const FiberTruthScene& scene, const SwatchSettings& s)
    : scene_(scene), s_(s) {
  if (!(s.card <= 1) || !(s.light_deg >= 0 && s.light_deg < 89))
    throw std::invalid_argument("swatch: card <= 1, light_deg in [0, 89)");
  TruthSettings t = s.truth;
  t.res = 2;  // only the hemispheres are used
  const double a = s.light_deg * M_PI / 180;
  front_ = scene.paths({std::sin(a) * M_SQRT1_2, std::sin(a) * M_SQRT1_2, std::cos(a)}, t);
  t.seed = s.truth.seed + 0x632be59bd9b4e019ull;
  up_ = scene.diffuse_paths(/*from_above=*/false, t);
  t.seed = s.truth.seed + 0x2545f4914f6cdd1dull;
  if (s.card < 0) down_ = scene.diffuse_paths(/*from_above=*/true, t);
}

Swatch SwatchPaths::swatch(const std::vector<FiberMaterial>& m) const {
  const TruthResult f = scene_.tally(front_, m), u = scene_.tally(up_, m);
  const bool pile = s_.card < 0;
  const TruthResult d = pile ? scene_.tally(down_, m) : TruthResult{};
  Swatch out;
  for (size_t c = 0; c < 3; ++c) {
    out.reflect[c] = f.reflect[c], out.transmit[c] = f.transmit[c];
    out.up_reflect[c] = u.reflect[c], out.up_transmit[c] = u.transmit[c];
    double x = s_.card;
    if (pile) {
      out.down_reflect[c] = d.reflect[c], out.down_transmit[c] = d.transmit[c];
      x = pile_reflectance(d.reflect[c], d.transmit[c]);
    }
    out.below[c] = x;
    out.rho[c] = swatch_rho(f.reflect[c], f.transmit[c], x, u.transmit[c], u.reflect[c]);
  }
  return out;
}

double pile_reflectance(double r, double t) {
  const double b = 1 + r * r - t * t;
  return r > 1e-12 ? (b - std::sqrt(std::max(b * b - 4 * r * r, 0.0))) / (2 * r) : 0.0;
}

double swatch_rho(double R, double T, double X, double T_back, double R_back) {
  return R + T * X * T_back / (1 - R_back * X);
}

SwatchSolve SwatchPaths::solve(const std::array<double, 3>& target) const {
  std::vector<FiberMaterial> m = scene_.materials();
  auto with = [&](const std::array<double, 3>& sigma) {
    for (FiberMaterial& x : m) x.sigma_per_um = sigma;
    return swatch(m);
  };
  SwatchSolve out;
  const Swatch clear = with({0, 0, 0}), dark = with({kSigmaMaxPerUm, kSigmaMaxPerUm, kSigmaMaxPerUm});
  // Bisection on log sigma, the three channels at once (one tally serves all three).
  std::array<double, 3> lo{}, hi{};
  for (size_t c = 0; c < 3; ++c) lo[c] = std::log(1e-8), hi[c] = std::log(kSigmaMaxPerUm);
  for (int it = 0; it < 48; ++it) {
    std::array<double, 3> mid{};
    for (size_t c = 0; c < 3; ++c) mid[c] = std::exp(0.5 * (lo[c] + hi[c]));
    const Swatch s = with(mid);
    for (size_t c = 0; c < 3; ++c)
      (s.rho[c] > target[c] ? lo : hi)[c] = std::log(mid[c]);  // too bright: absorb more
  }
  for (size_t c = 0; c < 3; ++c) {
    out.sigma_per_um[c] = std::exp(0.5 * (lo[c] + hi[c]));
    if (target[c] >= clear.rho[c]) out.sigma_per_um[c] = 0, out.clamped[c] = true;
    if (target[c] <= dark.rho[c]) out.sigma_per_um[c] = kSigmaMaxPerUm, out.clamped[c] = true;
  }
  out.swatch = with(out.sigma_per_um);
  return out;
}

SwatchCurve SwatchPaths::curve() const {
  SwatchCurve c;
  std::vector<FiberMaterial> m = scene_.materials();
  constexpr int kLevels = 64;
  for (int k = -1; k < kLevels; ++k) {
    const double sigma =
        k < 0 ? 0.0 : 1e-6 * std::pow(kSigmaMaxPerUm / 1e-6, double(k) / (kLevels - 1));
    for (FiberMaterial& x : m) x.sigma_per_um = {sigma, sigma, sigma};
    c.sigma_per_um.push_back(sigma);
    c.rho.push_back(swatch(m).rho[0]);
  }
  return c;
}

double swatch_rho_at(const SwatchCurve& c, double sigma) {
  const size_t n = c.rho.size();
  if (n < 3 || c.sigma_per_um.size() != n)
    throw std::invalid_argument("swatch curve: sigma 0 and at least two levels are needed");
  if (!(sigma > c.sigma_per_um[1])) return sigma <= 0 ? c.rho[0] : c.rho[1];
  for (size_t k = 1; k + 1 < n; ++k)
    if (sigma <= c.sigma_per_um[k + 1]) {
      const double t = std::log(sigma / c.sigma_per_um[k]) /
                       std::log(c.sigma_per_um[k + 1] / c.sigma_per_um[k]);
      return c.rho[k] + t * (c.rho[k + 1] - c.rho[k]);
    }
  return c.rho.back();
}

double swatch_sigma(const SwatchCurve& c, double rho, bool* clamped) {
  const size_t n = c.rho.size();
  if (n < 3 || c.sigma_per_um.size() != n)
    throw std::invalid_argument("swatch curve: sigma 0 and at least two levels are needed");
  if (clamped) *clamped = false;
  if (rho >= c.rho[0]) {
    if (clamped) *clamped = rho > c.rho[0];
    return 0;
  }
  if (rho >= c.rho[1]) return 0;  // between sigma 0 and the first level: as clear as 0
  for (size_t k = 1; k + 1 < n; ++k)
    if (rho >= c.rho[k + 1]) {
      const double a = c.rho[k], b = c.rho[k + 1];
      const double t = a > b ? (a - rho) / (a - b) : 0;
      return std::exp(std::log(c.sigma_per_um[k]) +
                      t * (std::log(c.sigma_per_um[k + 1]) - std::log(c.sigma_per_um[k])));
    }
  if (clamped) *clamped = true;
  return c.sigma_per_um.back();
}

SwatchAbsorption swatch_absorption(const SwatchCurve& c, const std::array<double, 3>& colour,
                                   double sigma_max_per_mm) {
  SwatchAbsorption out;
  for (size_t k = 0; k < 3; ++k) {
    bool clamped = false;
    const double per_mm = 1e3 * swatch_sigma(c, colour[k], &clamped);
    out.sigma_per_mm[k] = std::min(per_mm, sigma_max_per_mm);
    out.out_of_reach[k] = clamped || per_mm > sigma_max_per_mm;
    out.rho[k] = swatch_rho_at(c, out.sigma_per_mm[k] * 1e-3);
  }
  return out;
}

uint64_t swatch_rays(Quality q) {
  return q == Quality::Draft ? 20000 : q == Quality::Preview ? 50000 : q == Quality::Final ? 100000 : 400000;
}

std::vector<FiberMaterial> reading_materials(const FiberTruthScene& scene, const FabricSpec& spec) {
  std::vector<FiberMaterial> m = scene.materials();
  if (spec.colour_reading == ColourReading::PlyAlbedo) {
    const auto ply = truth_materials(spec);
    for (size_t k = 0; k < m.size() && k < 2; ++k) m[k].sigma_per_um = ply[k].sigma_per_um;
    return m;
  }
  SwatchSettings ss;
  ss.truth.rays = swatch_rays(spec.quality);
  const SwatchCurve curve = SwatchPaths(scene, ss).curve();
  const double sigma_max = ply_sim_settings(spec.quality).sigmas.back();
  for (size_t k = 0; k < m.size() && k < 2; ++k) {
    const auto a = swatch_absorption(curve, (k == 0 ? spec.warp : spec.weft).color_linear, sigma_max);
    for (size_t c = 0; c < 3; ++c) m[k].sigma_per_um[c] = a.sigma_per_mm[c] * 1e-3;
  }
  return m;
}

}  // namespace loom
