// Procedural plies (Luan et al. 2017, Eq. 1-3, section 4.5, 5.3) against independent computations.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "loom/procedural_ply.h"

namespace {
loom::PlyParams params() {
  loom::YarnSpec y;
  y.plies = 3;
  y.fibers_per_ply = 1000;
  return loom::ply_params_from_yarn(y);
}
}  // namespace

TEST(ProceduralPly, RadiiFollowTheCrossSectionDensity) {
  // Eq. 3 by rejection: the empirical CDF of R over many fibers matches the CDF of p(R)
  // integrated numerically (Kolmogorov-Smirnov distance).
  auto p = params();
  for (auto [eps, beta] : {std::pair{0.1, 0.5}, std::pair{0.02, 2.0}, std::pair{0.3, 1.0}}) {
    p.epsilon = eps, p.beta = beta;
    std::vector<double> R;
    for (uint32_t yarn = 0; yarn < 4; ++yarn)
      for (uint32_t ply = 0; ply < 3; ++ply)
        for (auto& f : loom::make_ply_fibers(p, yarn, ply)) R.push_back(f.R);
    std::sort(R.begin(), R.end());
    const int n = 4000;
    std::vector<double> cdf(n + 1, 0.0);
    for (int i = 0; i < n; ++i)
      cdf[i + 1] = cdf[i] + loom::fiber_radius_density((i + 0.5) / n, eps, beta) / n;
    double ks = 0;
    for (size_t k = 0; k < R.size(); ++k) {
      double model = cdf[std::min(n, int(R[k] * n))] / cdf[n];
      ks = std::max(ks, std::fabs(model - (k + 0.5) / R.size()));
    }
    EXPECT_LT(ks, 0.02) << "eps " << eps << " beta " << beta << " (" << R.size() << " fibers)";
  }
}

TEST(ProceduralPly, HelixAndMigrationFollowEq1And2) {
  auto p = params();
  auto f = loom::make_fiber(p, 3, 1, 17);
  double lo = 1e9, hi = 0;
  for (int k = 0; k < 2000; ++k) {
    double z = k * p.pitch / 500.0;
    auto q = loom::fiber_in_ply(p, f, z);
    double r = std::hypot(q.x, q.y);
    EXPECT_NEAR(r, loom::fiber_radius_at(p, f, z), 1e-9);
    lo = std::min(lo, r), hi = std::max(hi, r);
    // Eq. 1: the azimuth advances by 2 pi per pitch a.
    double ang = std::atan2(q.y, q.x);
    double want = std::remainder(f.theta + 2 * M_PI * z / p.pitch, 2 * M_PI);
    EXPECT_NEAR(std::remainder(ang - want, 2 * M_PI), 0.0, 1e-9);
  }
  // Eq. 2: R_j(z) sweeps [r_min R_j, r_max R_j] R_ply.
  EXPECT_NEAR(lo, p.r_min * f.R * p.ply_radius, 1e-3 * p.ply_radius);
  EXPECT_NEAR(hi, p.r_max * f.R * p.ply_radius, 1e-3 * p.ply_radius);
}

TEST(ProceduralPly, ConsistentSeedingIndependentOfOrder) {
  auto p = params();
  auto all = loom::make_ply_fibers(p, 5, 2);
  for (int j : {999, 0, 500, 17}) {
    auto f = loom::make_fiber(p, 5, 2, uint32_t(j));
    EXPECT_EQ(f.R, all[size_t(j)].R);
    EXPECT_EQ(f.theta, all[size_t(j)].theta);
    EXPECT_EQ(f.theta0, all[size_t(j)].theta0);
  }
  // Different plies and yarns get different fibers.
  EXPECT_NE(loom::make_fiber(p, 5, 1, 3).theta, loom::make_fiber(p, 5, 2, 3).theta);
  EXPECT_NE(loom::make_fiber(p, 4, 2, 3).theta, loom::make_fiber(p, 5, 2, 3).theta);
}

TEST(ProceduralPly, PliesTwistAboutTheYarnCentre) {
  loom::YarnSpec y;
  y.plies = 3;
  y.yarn_diameter_um = 300;
  y.ply_diameter_um = 150;
  y.ply_twist_deg = 30;
  y.twist = "Z";
  auto p = loom::ply_params_from_yarn(y);
  EXPECT_NEAR(p.ply_centre_radius, 75, 1e-9);
  // Helix angle of the ply centre line: tan(alpha) = 2 pi R_c / pitch.
  EXPECT_NEAR(std::atan(2 * M_PI * p.ply_centre_radius / p.ply_pitch), 30 * M_PI / 180, 1e-9);
  for (uint32_t k = 0; k < 3; ++k) {
    auto c0 = loom::ply_centre(p, k, 0), c1 = loom::ply_centre(p, k, p.ply_pitch / 4);
    EXPECT_NEAR(std::hypot(c0.x, c0.y), 75, 1e-9);
    // A quarter pitch later a Z twist has turned a quarter turn counter-clockwise.
    double turn = std::remainder(std::atan2(c1.y, c1.x) - std::atan2(c0.y, c0.x), 2 * M_PI);
    EXPECT_NEAR(turn, M_PI / 2, 1e-9);
  }
  // Plies are evenly spaced.
  auto a = loom::ply_centre(p, 0, 10), b = loom::ply_centre(p, 1, 10);
  EXPECT_NEAR(std::hypot(a.x - b.x, a.y - b.y), 2 * 75 * std::sin(M_PI / 3), 1e-9);
}

TEST(ProceduralPly, LoopCountFollowsItsDensity) {
  // Loops per um of ply: expected rho_loop; counted over many fibers' migration cycles.
  auto p = params();
  p.fibers = 200;
  p.loop_density = 0.002;  // 2 loops per mm
  const double length = 20000;  // 2 cm of ply
  long loops = 0, cycles = 0;
  for (uint32_t yarn = 0; yarn < 5; ++yarn)
    for (uint32_t j = 0; j < uint32_t(p.fibers); ++j) {
      auto f = loom::make_fiber(p, yarn, 0, j);
      int64_t c0 = loom::migration_cycle(p, f, 0), c1 = loom::migration_cycle(p, f, length);
      for (int64_t c = c0; c < c1; ++c) {
        ++cycles;
        loops += loom::is_loop_cycle(p, yarn, 0, j, c);
      }
    }
  double expected = p.loop_density * length * 5;  // five plies of this length
  // Binomial: mean n q, sd sqrt(n q (1 - q)); allow 4 sd.
  double q = loom::loop_probability(p), sd = std::sqrt(cycles * q * (1 - q));
  EXPECT_NEAR(double(loops), expected, 4 * sd + 0.02 * expected);
  EXPECT_NEAR(cycles * q, expected, 0.02 * expected);
  // Inside a loop cycle the fiber reaches out to loop_r_max R_j.
  p.loop_density = 1e9;  // every cycle a loop
  auto f = loom::make_fiber(p, 0, 0, 3);
  double hi = 0;
  for (int k = 0; k < 4000; ++k)
    hi = std::max(hi, loom::fiber_radius_with_loops(p, 0, 0, 3, f, k * p.pitch / 1000));
  EXPECT_NEAR(hi, p.loop_r_max * f.R * p.ply_radius, 1e-3 * p.ply_radius);
}

TEST(ProceduralPly, HairCountFollowsItsDensityAndEq4) {
  auto p = params();
  p.hair_density = 0.001;  // 1 hair per mm
  double total = 0;
  const int plies = 400;
  const double length = 10000;
  for (uint32_t k = 0; k < uint32_t(plies); ++k) {
    auto hairs = loom::make_ply_hairs(p, k, 0, length);
    total += double(hairs.size());
    for (auto& h : hairs) {
      EXPECT_GE(h.z1, 0.0);
      EXPECT_LT(h.z1, length);
      EXPECT_LE(h.R1, p.ply_radius + 1e-9);  // starts inside the ply
      EXPECT_GE(h.R2, p.ply_radius - 1e-9);  // ends outside it
      auto a = loom::hair_in_ply(h, h.z1), b = loom::hair_in_ply(h, h.z2);
      EXPECT_NEAR(std::hypot(a.x, a.y), h.R1, 1e-9);
      EXPECT_NEAR(std::hypot(b.x, b.y), h.R2, 1e-9);
      auto m = loom::hair_in_ply(h, 0.5 * (h.z1 + h.z2));  // Eq. 4: linear in R and theta
      EXPECT_NEAR(std::hypot(m.x, m.y), 0.5 * (h.R1 + h.R2), 1e-9);
    }
  }
  // Poisson: mean rho h per ply; over 400 plies the total is within 4 sd of 400 rho h.
  double mean = p.hair_density * length * plies;
  EXPECT_NEAR(total, mean, 4 * std::sqrt(mean));
  // Consistent: the same ply gives the same hairs.
  auto h1 = loom::make_ply_hairs(p, 7, 1, length), h2 = loom::make_ply_hairs(p, 7, 1, length);
  ASSERT_EQ(h1.size(), h2.size());
  for (size_t k = 0; k < h1.size(); ++k) EXPECT_EQ(h1[k].z1, h2[k].z1);
}

TEST(ProceduralPly, ParametersComeFromTheSpec) {
  auto r = loom::parse_spec(nlohmann::json{
      {"yarn", {{"migration_min", 0.2}, {"migration_max", 0.9}, {"migration_period", 3.0},
                {"density_epsilon", 0.05}, {"density_beta", 1.5}, {"loop_flyaways_per_mm", 4.0},
                {"hair_flyaways_per_mm", 7.0}, {"fiber_twist_pitch_um", 1500}}}});
  ASSERT_TRUE(r.ok()) << ::testing::PrintToString(r.errors);
  auto p = loom::ply_params_from_yarn(r.spec.warp);
  EXPECT_EQ(p.r_min, 0.2);
  EXPECT_EQ(p.r_max, 0.9);
  EXPECT_EQ(p.s, 3.0);
  EXPECT_EQ(p.epsilon, 0.05);
  EXPECT_EQ(p.beta, 1.5);
  EXPECT_DOUBLE_EQ(p.loop_density, 4e-3);
  EXPECT_DOUBLE_EQ(p.hair_density, 7e-3);
  EXPECT_EQ(p.pitch, 1500);
}
