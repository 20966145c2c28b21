// Realization-free hair flyaways (Luan et al. 2017, Algorithm 3): the closed-form extent
// probabilities against Monte Carlo, the pruned descent against the full one, the hairs'
// distribution against the process, and the look-ups against full realization.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>

#include "loom/fiber_lookup.h"
#include "loom/hair_flyaways.h"
#include "loom/procedural_ply.h"
#include "loom/spec.h"
#include "loom/woven_patch.h"

namespace {

loom::PlyParams hairy() {
  loom::PlyParams p;
  p.hair_density = 0.02;  // 20 per mm
  p.hair_length_min = 200, p.hair_length_max = 1500;
  return p;
}

/// Kolmogorov-Smirnov distance of samples against the uniform distribution on [lo, hi].
double ks_uniform(std::vector<double> x, double lo, double hi) {
  std::sort(x.begin(), x.end());
  double d = 0, n = double(x.size());
  for (size_t i = 0; i < x.size(); ++i) {
    double F = (x[i] - lo) / (hi - lo);
    d = std::max({d, std::abs(F - i / n), std::abs(F - (i + 1) / n)});
  }
  return d;
}

}  // namespace

TEST(HairFlyaways, ExtentProbabilityMatchesMonteCarlo) {
  auto p = hairy();
  const double L = 5000;
  EXPECT_NEAR(loom::hair_extent_probability(p, L, 0, L, 0, L + p.hair_length_max), 1, 1e-12);
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> U(0, 1);
  const int N = 200000;
  std::vector<std::pair<double, double>> s(N);
  for (auto& e : s) {
    e.first = L * U(rng);
    e.second = e.first + p.hair_length_min + (p.hair_length_max - p.hair_length_min) * U(rng);
  }
  for (int t = 0; t < 20; ++t) {
    double a = L * U(rng), b = a + (L - a) * U(rng), c = (L + 1500) * U(rng),
           d = c + (L + 1500 - c) * U(rng);
    double P = loom::hair_extent_probability(p, L, a, b, c, d);
    int k = 0;
    for (auto& e : s) k += e.first >= a && e.first <= b && e.second >= c && e.second <= d;
    double sd = std::sqrt(std::max(P * (1 - P), 1e-12) / N);
    EXPECT_NEAR(double(k) / N, P, 4 * sd + 1e-5) << a << " " << b << " " << c << " " << d;
    // Quadrants add up to their parent.
    double mx = 0.5 * (a + b), my = 0.5 * (c + d);
    double q = loom::hair_extent_probability(p, L, a, mx, c, my) +
               loom::hair_extent_probability(p, L, mx, b, c, my) +
               loom::hair_extent_probability(p, L, a, mx, my, d) +
               loom::hair_extent_probability(p, L, mx, b, my, d);
    EXPECT_NEAR(q, P, 1e-12);
  }
}

TEST(HairFlyaways, PrunedDescentFindsExactlyTheActiveHairs) {
  auto p = hairy();
  const double L = 20000, margin = 7;
  auto all = loom::all_hairs_realization_free(p, 3, 1, L);
  EXPECT_EQ(all.size(), loom::ply_hair_count(p, 3, 1, L).count);
  std::set<uint64_t> ids;
  for (auto& h : all) ids.insert(h.id);
  EXPECT_EQ(ids.size(), all.size()) << "hair ids must be unique";
  std::mt19937_64 rng(8);
  int total = 0;
  for (int t = 0; t < 300; ++t) {
    double z = (L + 1600) * std::uniform_real_distribution<double>(-0.02, 1)(rng);
    std::vector<loom::HairFlyaway> act;
    loom::active_hairs(p, 3, 1, L, z, margin, act);
    std::set<uint64_t> got, want;
    for (auto& h : act) got.insert(h.id);
    for (auto& h : all)
      if (z >= h.hair.z1 - margin && z <= h.hair.z2 + margin) want.insert(h.id);
    EXPECT_EQ(got, want) << "z = " << z;
    for (auto& h : act) {  // and the same hair, not just the same id
      auto it = std::find_if(all.begin(), all.end(), [&](auto& x) { return x.id == h.id; });
      ASSERT_NE(it, all.end());
      EXPECT_EQ(it->hair.z1, h.hair.z1);
      EXPECT_EQ(it->hair.theta2, h.hair.theta2);
    }
    total += int(want.size());
  }
  EXPECT_GT(total, 1000);
}

TEST(HairFlyaways, HairsFollowTheProcess) {
  auto p = hairy();
  const double L = 100000;  // 2,000 hairs expected
  auto all = loom::all_hairs_realization_free(p, 0, 0, L);
  double mean = p.hair_density * L;
  EXPECT_NEAR(double(all.size()), mean, 4 * std::sqrt(mean));
  std::vector<double> z1, len, R1, R2;
  for (auto& h : all) {
    z1.push_back(h.hair.z1);
    len.push_back(h.hair.z2 - h.hair.z1);
    R1.push_back(h.hair.R1);
    R2.push_back(h.hair.R2);
  }
  // KS critical value at 0.1 %: 1.95 / sqrt(n).
  const double crit = 1.95 / std::sqrt(double(all.size()));
  EXPECT_LT(ks_uniform(z1, 0, L), crit);
  EXPECT_LT(ks_uniform(len, p.hair_length_min, p.hair_length_max), crit);
  EXPECT_LT(ks_uniform(R1, p.ply_radius * p.r_min, p.ply_radius), crit);
  EXPECT_LT(ks_uniform(R2, p.ply_radius, p.ply_radius * p.hair_r_max), crit);
}

TEST(HairFlyaways, LookupsEqualFullRealization) {
  auto r = loom::parse_spec_text(R"({"schema": "loom.fabric/1", "weave": {"pattern": "plain"},
    "yarn": {"plies": 2, "fibers_per_ply": 30, "hair_flyaways_per_mm": 25}})");
  ASSERT_TRUE(r.ok());
  auto patch = loom::make_woven_patch(r.spec, 6);
  loom::FiberLookupOptions o;
  o.realization_free_hairs = true;
  loom::FiberLookup mini(patch, o);
  loom::RealizedFibers full(patch, o);
  int mismatch = 0, brute = 0, hair = 0;
  auto pts = loom::fiber_test_points(patch, 8000, 21);
  for (size_t i = 0; i < pts.size(); ++i) {
    auto a = mini.lookup(pts[i]), b = full.lookup(pts[i]);
    mismatch += !a.same_fiber(b) || a.distance != b.distance;
    hair += a.covered && a.hair;
    if (i % 8 == 0) {
      auto d = loom::brute_force_fiber_lookup(patch, pts[i], o);
      brute += !a.same_fiber(d) || a.distance != d.distance;
    }
  }
  EXPECT_EQ(mismatch, 0);
  EXPECT_EQ(brute, 0);
  EXPECT_GT(hair, 20);
}
