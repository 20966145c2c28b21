// Eq. S.10 between absorption levels with the weight of absorption_curve.h: linear in the ply's
// simulated energy rather than in sigma. Checked against a closed form (an exponential curve)
// and against the simulation itself at absorptions between the levels.
#include <gtest/gtest.h>

#include <cmath>

#include "loom/absorption.h"
#include "loom/absorption_curve.h"
#include "loom/ply_scattering.h"
#include "loom/procedural_ply.h"
#include "loom/spec.h"

namespace {

/// E(sigma) = floor + (1 - floor) exp(-sigma l) on a log grid like absorption_curve's.
loom::AbsorptionCurve exponential_curve(double l_mm, double floor_e) {
  loom::AbsorptionCurve c;
  c.sigma_per_mm.push_back(0);
  for (int k = 0; k < 32; ++k) c.sigma_per_mm.push_back(std::pow(1e4, k / 31.0));
  for (double s : c.sigma_per_mm) c.energy.push_back(floor_e + (1 - floor_e) * std::exp(-s * l_mm));
  return c;
}

double interpolate(const std::vector<double>& levels, const std::vector<double>& values,
                   double sigma, const loom::AbsorptionCurve& curve) {
  int k;
  double t;
  loom::sigma_interval(levels, sigma, curve, k, t);
  return (1 - t) * values[size_t(k)] + t * values[size_t(k + 1)];
}

TEST(AbsorptionCurve, SigmaIntervalLimits) {
  const std::vector<double> levels{0, 10, 173, 3000};
  const loom::AbsorptionCurve curve = exponential_curve(0.02, 0.04), none;
  for (const auto* c : {&curve, &none}) {
    int k;
    double t;
    // The levels themselves are reproduced (fractional level index k + t = j).
    for (size_t j = 0; j < levels.size(); ++j) {
      loom::sigma_interval(levels, levels[j], *c, k, t);
      EXPECT_NEAR(k + t, double(j), 1e-12);
    }
    loom::sigma_interval(levels, 3000, *c, k, t);
    EXPECT_EQ(k, 2);
    EXPECT_EQ(t, 1.0);
    loom::sigma_interval(levels, 1e9, *c, k, t);
    EXPECT_EQ(k, 2);
    EXPECT_EQ(t, 1.0);
    for (double bad : {double(NAN), -5.0, double(-INFINITY)}) {
      loom::sigma_interval(levels, bad, *c, k, t);
      EXPECT_EQ(k, 0);
      EXPECT_EQ(t, 0.0);
    }
    loom::sigma_interval({0.0}, 50, *c, k, t);  // a single level
    EXPECT_EQ(k, 0);
    EXPECT_EQ(t, 0.0);
    // Monotone in sigma.
    double last = -1;
    for (double s = 0; s < 3000; s *= 1.05, s += 0.1) {
      loom::sigma_interval(levels, s, *c, k, t);
      const double u = k + t;
      EXPECT_GE(u, last - 1e-12) << s;
      last = u;
    }
  }
  // No curve: S.10's weight, linear in sigma.
  int k;
  double t;
  loom::sigma_interval(levels, 91.5, none, k, t);
  EXPECT_EQ(k, 1);
  EXPECT_NEAR(t, 0.5, 1e-12);
}

TEST(AbsorptionCurve, ExactForAQuantityThatFallsLikeTheCurve) {
  // A quantity that is an affine function of the curve's energy (an amplitude times E plus a
  // constant floor) comes back exactly between levels; S.10 is far off.
  const loom::AbsorptionCurve curve = exponential_curve(0.02, 0.04);
  const std::vector<double> levels{0, 10, 173, 3000};
  auto q = [&](double s) { return 0.7 * loom::curve_energy(curve, s) + 0.01; };
  std::vector<double> values;
  for (double s : levels) values.push_back(q(s));
  double worst_linear = 0;
  for (double s : {2.0, 5.0, 30.0, 76.0, 120.0, 500.0, 2000.0}) {
    EXPECT_NEAR(interpolate(levels, values, s, curve), q(s), 1e-9) << s;
    worst_linear = std::max(worst_linear, std::fabs(interpolate(levels, values, s, {}) / q(s) - 1));
  }
  EXPECT_GT(worst_linear, 1.0);  // the case this weight is for
}

TEST(AbsorptionCurve, FollowsTheSimulationBetweenLevels) {
  // The gray wool ply (the fabric where S.10 overshot most), simulated once with the draft
  // preset's levels 0, 10, 173, 3000 / mm and absorptions between them. One trace weights each
  // path by exp(-sigma l) at every level, so the in-between levels are the simulation's own
  // answer there: an independent check of the interpolated values.
  auto spec = loom::parse_spec(loom::preset("gray_wool_twill"), "draft");
  ASSERT_TRUE(spec.ok());
  const loom::YarnSpec& y = spec.spec.warp;
  loom::PlySimSettings s;
  s.theta_i_count = 5, s.h_count = 5, s.theta_o_count = 12, s.phi_o_count = 24;
  s.rays_per_slice = 3000;
  const std::vector<size_t> level_index{0, 1, 6, 7};
  s.sigmas = {0, 10, 20, 40, 76, 120, 173, 3000};
  const loom::PlySimResult sim =
      loom::simulate_ply_scattering(loom::ply_params_from_yarn(y), y.ior, s);
  const loom::AbsorptionCurve curve = loom::absorption_curve(y, loom::Quality::Draft);
  std::vector<double> levels;
  for (size_t k : level_index) levels.push_back(s.sigmas[k]);

  double err_curve = 0, err_linear = 0;
  int n = 0;
  for (const loom::PlySimSlice& sl : sim.slices) {
    std::vector<double> values;
    for (size_t k : level_index) values.push_back(sl.energy[k].higher_order);
    for (size_t k : {2, 3, 4, 5}) {
      const double truth = sl.energy[k].higher_order;
      if (truth < 1e-3) continue;
      err_curve += std::fabs(interpolate(levels, values, s.sigmas[k], curve) / truth - 1);
      err_linear += std::fabs(interpolate(levels, values, s.sigmas[k], {}) / truth - 1);
      ++n;
    }
  }
  ASSERT_GT(n, 50);
  err_curve /= n;
  err_linear /= n;
  std::printf("mean relative error of f_high between levels: energy weight %.3f, S.10 %.3f (%d)\n",
              err_curve, err_linear, n);
  EXPECT_LT(err_curve, 0.2);
  EXPECT_GT(err_linear, 4 * err_curve);
}

}  // namespace
