// The fiber tier's look-ups (Luan et al. 2017, sections 4-5): yarn curves and their frames,
// realization-minimising look-ups against full realization and against the definition itself.
#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <random>

#include "loom/fiber_lookup.h"
#include "loom/spec.h"
#include "loom/woven_patch.h"

namespace {

loom::FabricSpec spec_of(const std::string& text) {
  auto r = loom::parse_spec_text(text);
  EXPECT_TRUE(r.ok()) << (r.errors.empty() ? "" : r.errors[0]);
  return r.spec;
}

/// Three plies, loops and dense hairs: every branch of the look-up.
loom::FabricSpec flyaway_spec() {
  return spec_of(R"({"schema": "loom.fabric/1", "name": "flyaway", "weave": {"pattern": "twill"},
    "yarn": {"plies": 3, "fibers_per_ply": 30, "yarn_diameter_um": 320, "ply_diameter_um": 160,
             "fiber_diameter_um": 14, "fiber_twist_pitch_um": 1500, "ply_twist_deg": 30,
             "twist": "Z", "loop_flyaways_per_mm": 8, "hair_flyaways_per_mm": 20},
    "density": {"warp_per_cm": 30, "weft_per_cm": 26}})");
}

loom::FabricSpec single_ply_spec() {
  return spec_of(R"({"schema": "loom.fabric/1", "name": "mono", "weave": {"pattern": "satin"},
    "yarn": {"plies": 1, "fibers_per_ply": 60, "yarn_diameter_um": 200, "ply_diameter_um": 200,
             "fiber_diameter_um": 12, "fiber_twist_pitch_um": 3000, "hair_flyaways_per_mm": 3},
    "density": {"warp_per_cm": 40, "weft_per_cm": 40}})");
}

double len(loom::Vec3d a) { return std::sqrt(loom::dot(a, a)); }

}  // namespace

TEST(YarnCurve, YarnSpaceRoundTripsThroughFabricSpace) {
  auto patch = loom::make_woven_patch(flyaway_spec(), 6);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> U(0, 1);
  for (const auto& y : patch) {
    // Within the yarn's own radius: further out, on the inside of a bend, another part of the
    // curve is nearer and the projection rightly picks it.
    double reach = 0.5 * 320.0;
    for (int i = 0; i < 200; ++i) {
      loom::Vec3d yp{reach * (2 * U(rng) - 1) * 0.7, reach * (2 * U(rng) - 1) * 0.7,
                     y.curve.length() * (0.05 + 0.9 * U(rng))};
      loom::Vec3d p = y.curve.to_fabric(yp);  // Eq. 7
      loom::YarnProjection best;
      for (int k = 0; k < y.curve.pieces(); ++k) {
        auto pr = y.curve.project_piece(p, k);
        if (pr.distance < best.distance) best = pr;
      }
      loom::Vec3d back = y.curve.to_yarn(p, best);  // Eq. 8-9
      EXPECT_NEAR(back.z, yp.z, 1e-6 * y.curve.length());
      EXPECT_NEAR(back.x, yp.x, 1e-6 * reach);
      EXPECT_NEAR(back.y, yp.y, 1e-6 * reach);
      EXPECT_NEAR(best.distance, std::hypot(yp.x, yp.y), 1e-6 * reach);
    }
  }
}

TEST(YarnCurve, FramesAreOrthonormalContinuousAndRotationMinimising) {
  // A helix-like 3D curve (not planar) so that the frame must turn.
  std::vector<loom::Vec3d> pts;
  for (int i = 0; i <= 24; ++i)
    pts.push_back({400 * std::cos(i * 0.5), 400 * std::sin(i * 0.5), 90.0 * i});
  loom::YarnCurve c(pts, {0, 0, 1});
  double worst_twist = 0, worst_jump = 0;
  for (int k = 0; k < c.pieces(); ++k) {
    for (int s = 0; s <= 64; ++s) {
      double u = s / 64.0;
      auto f = c.frame(k, u);
      EXPECT_NEAR(len(f.t), 1, 1e-12);
      EXPECT_NEAR(len(f.n), 1, 1e-12);
      EXPECT_NEAR(loom::dot(f.t, f.n), 0, 1e-12);
      EXPECT_NEAR(loom::dot(f.b, loom::cross(f.t, f.n)), 1, 1e-12);
      // Rotation-minimising: n turns only towards t, never about it (dn/ds . b = 0).
      double h = 1e-4;
      if (u + h <= 1) {
        auto g = c.frame(k, u + h);
        double ds = len(c.position(k, u + h) - c.position(k, u));
        worst_twist = std::max(worst_twist, std::abs(loom::dot(g.n - f.n, f.b)) / ds);
      }
    }
    if (k + 1 < c.pieces()) {
      auto a = c.frame(k, 1.0), b = c.frame(k + 1, 0.0);
      worst_jump = std::max(worst_jump, len(a.n - b.n));
    }
  }
  // A Frenet frame turns about the tangent at the helix's torsion tau = c / (r^2 + c^2)
  // (c = 90 / 0.5 um per radian); the rotation-minimising frame within 5 % of it.
  const double cc = 90 / 0.5, tau = cc / (400.0 * 400.0 + cc * cc);
  EXPECT_LT(worst_twist, 0.05 * tau);
  EXPECT_LT(worst_jump, 1e-9);
}

TEST(YarnCurve, DeltaBoundsTheDistanceToTheNearestVertex) {
  // Section 5.2: every curve point lies within delta of a vertex; checked densely.
  for (auto* mk : {&flyaway_spec, &single_ply_spec}) {
    auto patch = loom::make_woven_patch(mk(), 8);
    for (const auto& y : patch) {
      double worst = 0;
      for (int k = 0; k < y.curve.pieces(); ++k)
        for (int s = 0; s <= 200; ++s) {
          auto q = y.curve.position(k, s / 200.0);
          double d = std::min(len(q - y.curve.points()[size_t(k)]),
                              len(q - y.curve.points()[size_t(k) + 1]));
          worst = std::max(worst, d);
        }
      EXPECT_LE(worst, y.curve.delta());
      EXPECT_GT(worst, 0.5 * y.curve.delta());  // and it is not wildly loose
    }
  }
}

TEST(FiberLookup, EqualsFullRealizationAndTheDefinition) {
  struct Case {
    const char* name;
    loom::FabricSpec spec;
    int yarns;
  };
  std::vector<Case> cases = {{"plain", loom::load_spec("plain").spec, 10},
                             {"organza", loom::load_spec("white_silk_organza").spec, 10},
                             {"flyaway", flyaway_spec(), 10},
                             {"mono", single_ply_spec(), 12}};
  for (auto& c : cases) {
    SCOPED_TRACE(c.name);
    auto patch = loom::make_woven_patch(c.spec, c.yarns);
    loom::FiberLookup mini(patch);
    loom::RealizedFibers full(patch);
    auto pts = loom::fiber_test_points(patch, 20000, 11);
    int mismatch = 0, covered = 0, hair = 0, brute_mismatch = 0;
    for (size_t i = 0; i < pts.size(); ++i) {
      auto a = mini.lookup(pts[i]), b = full.lookup(pts[i]);
      mismatch += !a.same_fiber(b) || a.distance != b.distance;
      covered += a.covered;
      hair += a.covered && a.hair;
      if (a.covered) {
        EXPECT_NEAR(len(a.direction), 1, 1e-9);
        EXPECT_LT(a.distance, patch[a.yarn].ply.fiber_radius);
      }
      if (i % 10 == 0) {  // the definition itself on a tenth of the points
        auto d = loom::brute_force_fiber_lookup(patch, pts[i]);
        brute_mismatch += !a.same_fiber(d) || a.distance != d.distance;
      }
    }
    EXPECT_EQ(mismatch, 0);
    EXPECT_EQ(brute_mismatch, 0);
    EXPECT_GT(covered, 1000) << "too few covered points for the comparison to mean anything";
    if (c.spec.warp.hair_flyaways_per_mm > 0) {
      EXPECT_GT(hair, 20) << "the hair branch must be exercised";
    } else {
      EXPECT_EQ(hair, 0);
    }
  }
}

TEST(FiberLookup, DirectionIsTheFibersTangentInTheFabric) {
  // Against finite differences of the fiber's own polyline mapped into the fabric (Eq. 7), on
  // bent yarns: the frame's turning enters the tangent (n' = -(t'.n) t).
  auto patch = loom::make_woven_patch(flyaway_spec(), 8);
  loom::FiberLookup mini(patch);
  int checked = 0;
  double worst = 0;
  for (auto& p : loom::fiber_test_points(patch, 20000, 17)) {
    auto h = mini.lookup(p);
    if (!h.covered || h.hair) continue;
    const auto& y = patch[h.yarn];
    loom::YarnProjection pr;
    for (int k = 0; k < y.curve.pieces(); ++k) {
      auto q = y.curve.project_piece(p, k);
      if (q.distance < pr.distance) pr = q;
    }
    const double z = pr.z, dz = loom::fiber_step(y.ply);
    const auto f = loom::make_fiber(y.ply, y.seed_index, h.ply, uint32_t(h.fiber));
    const int64_t k = int64_t(std::floor(z / dz));
    auto v0 = loom::regular_vertex(y.ply, y.seed_index, h.ply, uint32_t(h.fiber), f, k, dz);
    auto v1 = loom::regular_vertex(y.ply, y.seed_index, h.ply, uint32_t(h.fiber), f, k + 1, dz);
    auto at = [&](double zz) {
      double t = (zz - double(k) * dz) / dz;
      return y.curve.to_fabric({v0.x + (double(v1.x) - v0.x) * t, v0.y + (double(v1.y) - v0.y) * t, zz});
    };
    const double e = 1e-3 * dz;
    if (z - e < double(k) * dz || z + e > double(k + 1) * dz) continue;  // stay in the segment
    auto d = loom::normalized(at(z + e) - at(z - e));
    worst = std::max(worst, len(d - h.direction));
    ++checked;
  }
  EXPECT_GT(checked, 500);
  EXPECT_LT(worst, 2e-3);
}

TEST(FiberLookup, TheComparisonCanFail) {
  // Pruning with a third of the safe margin drops fibers: the comparison must notice.
  auto patch = loom::make_woven_patch(flyaway_spec(), 6);
  loom::FiberLookupOptions o;
  o.margin_scale = 0.3;
  loom::FiberLookup unsafe(patch, o);
  loom::RealizedFibers full(patch);
  int mismatch = 0;
  for (auto& p : loom::fiber_test_points(patch, 20000, 5))
    mismatch += !unsafe.lookup(p).same_fiber(full.lookup(p));
  EXPECT_GT(mismatch, 0);
}

TEST(FiberLookup, LoopsReachBeyondTheMigrationRange) {
  // Section 4.4.1: with loops, regular fibers are found beyond r_max R_ply of their ply centre;
  // without, never.
  for (bool loops : {false, true}) {
    auto s = flyaway_spec();
    s.warp.hair_flyaways_per_mm = s.weft.hair_flyaways_per_mm = 0;
    double rho = loops ? 20 : 0;  // about every other migration cycle a loop
    s.warp.loop_flyaways_per_mm = s.weft.loop_flyaways_per_mm = rho;
    auto patch = loom::make_woven_patch(s, 6);
    loom::FiberLookup mini(patch);
    int beyond = 0;
    for (auto& p : loom::fiber_test_points(patch, 40000, 2)) {
      auto h = mini.lookup(p);
      if (!h.covered) continue;
      const auto& y = patch[h.yarn];
      auto pr = loom::YarnProjection{};
      for (int k = 0; k < y.curve.pieces(); ++k) {
        auto q = y.curve.project_piece(p, k);
        if (q.distance < pr.distance) pr = q;
      }
      auto yp = y.curve.to_yarn(p, pr);
      auto c = loom::ply_centre(y.ply, h.ply, yp.z);
      double r = std::hypot(yp.x - c.x, yp.y - c.y);
      beyond += r > y.ply.r_max * y.ply.ply_radius + y.ply.fiber_radius +
                        loom::polyline_error(y.ply, loom::fiber_step(y.ply));
    }
    if (loops) {
      EXPECT_GT(beyond, 10);
    } else {
      EXPECT_EQ(beyond, 0);
    }
  }
}

TEST(FiberLookup, ConsistentSeedingAcrossBuildsAndThreads) {
  auto patch = loom::make_woven_patch(flyaway_spec(), 8);
  for (bool free_hairs : {false, true}) {  // hybrid bins, and Algorithm 3's per-thread lists
    SCOPED_TRACE(free_hairs ? "realization-free hairs" : "hybrid hairs");
    loom::FiberLookupOptions o;
    o.realization_free_hairs = free_hairs;
    auto pts = loom::fiber_test_points(patch, free_hairs ? 4000 : 20000, 9);
    loom::FiberLookup a(patch, o);
    std::vector<loom::FiberHit> serial;
    for (auto& p : pts) serial.push_back(a.lookup(p));
    // Another build of the same patch, looked up from many threads in any order.
    auto patch2 = loom::make_woven_patch(flyaway_spec(), 8);
    loom::FiberLookup b(patch2, o);
    std::vector<loom::FiberHit> parallel(pts.size());
    tbb::parallel_for(size_t(0), pts.size(), [&](size_t i) { parallel[i] = b.lookup(pts[i]); });
    int diff = 0, hair = 0;
    for (size_t i = 0; i < pts.size(); ++i) {
      diff += !serial[i].same_fiber(parallel[i]) || serial[i].distance != parallel[i].distance;
      hair += serial[i].covered && serial[i].hair;
    }
    EXPECT_EQ(diff, 0);
    EXPECT_GT(hair, 10);
  }
  // The same yarn in a bigger patch has the same fibers: seeding is per yarn, not per patch.
  auto big = loom::make_woven_patch(flyaway_spec(), 20);
  EXPECT_EQ(loom::make_fiber(big[3].ply, big[3].seed_index, 1, 7).R,
            loom::make_fiber(patch[3].ply, patch[3].seed_index, 1, 7).R);
}

TEST(FiberLookup, HairCountsFollowTheSpecDensity) {
  auto s = flyaway_spec();
  auto patch = loom::make_woven_patch(s, 40);
  loom::FiberLookup mini(patch);
  double expected = 0;
  for (const auto& y : patch) expected += y.ply.plies * y.curve.length() * y.ply.hair_density;
  // Poisson: within 4 standard deviations.
  EXPECT_NEAR(double(mini.hair_count()), expected, 4 * std::sqrt(expected));
  EXPECT_GT(expected, 1000);
}

TEST(FiberLookup, BadAndExtremeInput) {
  auto s = flyaway_spec();
  EXPECT_THROW(loom::make_woven_patch(s, 1), std::invalid_argument);
  EXPECT_THROW(loom::make_woven_patch(s, loom::kMaxPatchYarns + 1), std::invalid_argument);
  try {
    loom::make_woven_patch(s, 0);
    ADD_FAILURE() << "no error for 0 yarns";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("yarns"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("[2, "), std::string::npos);
  }
  auto patch = loom::make_woven_patch(s, 4);
  loom::FiberLookup mini(patch);
  loom::RealizedFibers full(patch);
  const double inf = std::numeric_limits<double>::infinity(), nan = std::nan("");
  for (loom::Vec3d p : {loom::Vec3d{nan, 0, 0}, loom::Vec3d{0, inf, 0}, loom::Vec3d{0, 0, -inf},
                        loom::Vec3d{1e300, 1e300, 1e300}, loom::Vec3d{-1e9, 0, 0}}) {
    EXPECT_FALSE(mini.lookup(p).covered);
    EXPECT_FALSE(full.lookup(p).covered);
  }
}
