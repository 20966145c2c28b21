// An atlas against the fibers (truth_error.h): the atlas's bins against closed forms, the bins'
// directions against where the traced light can go, the truth's own Monte Carlo error against a
// trace a hundred times longer, the hemispheres against the ray-wave tier's own albedo
// quadrature, and the command line.
#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <vector>

#include "fiber_row.h"
#include "loom/atlas.h"
#include "loom/raywave_bsdf.h"
#include "loom/spec.h"
#include "loom/truth_error.h"
#include "test_util.h"

namespace {

using loom::shading::vec3;

TEST(TruthError, BinsIntegrateClosedForms) {
  const int res = 24, sub = 3;
  const size_t n = size_t(res) * res * 3;
  // Lambertian on both sides, f |cos| = rho / pi |z|: each hemisphere sends rho (linear in z
  // along a row, which the midpoints integrate exactly; rows split at z = 0).
  const std::array<double, 3> rho{0.2, 0.5, 0.9};
  std::vector<double> lam(n, 0.0);
  loom::add_bin_averages(
      [&](vec3 w) {
        const float c = std::fabs(w.z) / float(M_PI);
        return std::array<float, 3>{float(rho[0]) * c, float(rho[1]) * c, float(rho[2]) * c};
      },
      res, sub, 1.0, lam);
  for (bool up : {true, false}) {
    const auto s = loom::hemisphere_sum(lam, res, up);
    for (size_t k = 0; k < 3; ++k) EXPECT_NEAR(s[k], rho[k], 1e-6) << up << k;
  }
  // A normalised cosine lobe (n + 1)/(2 pi) z^n above only: 1 up, 0 down (midpoint error
  // (h^2 / 24) n (n + 1) = 2.3e-3 for rows of h = 1/36).
  const int p = 8;
  std::vector<double> lobe(n, 0.0);
  loom::add_bin_averages(
      [&](vec3 w) {
        const float v = w.z > 0 ? float((p + 1) / (2 * M_PI) * std::pow(w.z, p)) : 0.0f;
        return std::array<float, 3>{v, v, v};
      },
      res, sub, 0.5, lobe);  // weight 0.5: half of it
  EXPECT_NEAR(loom::hemisphere_sum(lobe, res, true)[1], 0.5, 0.5 * 4e-3);
  EXPECT_EQ(loom::hemisphere_sum(lobe, res, false)[1], 0.0);
  // relative L1: itself 0, twice itself 1, the Lambertian against the lobe far off.
  std::vector<double> twice = lobe;
  for (double& v : twice) v *= 2;
  EXPECT_EQ(loom::relative_l1(lobe, lobe), 0.0);
  EXPECT_NEAR(loom::relative_l1(twice, lobe), 1.0, 1e-12);
  EXPECT_GT(loom::relative_l1(lam, lobe), 1.0);
}

TEST(TruthError, BinsLookWhereTheTracedLightGoes) {
  // Straight fibers along x keep a ray's x component: all light scattered by a row of them
  // leaves on the cone d.x = -wi.x. The bins an indicator of that cone reaches (by
  // add_bin_averages' directions) must hold all of the truth's tally (by the tracer's own
  // binning): a mirrored or swapped axis or an offset azimuth would put it elsewhere.
  const loom::test::Row row{10.0, 60.0, 30.0, {0.0, 0.0, 0.0}, 1.55};
  loom::FiberTruthScene scene(loom::test::row_curves(row, 40.0), {0}, {loom::FiberMaterial{}},
                              {0.0, 0.0, 40.0, row.period});
  loom::TruthSettings s;
  s.rays = 40000;
  s.res = 24;
  const loom::Vec3d wi = loom::normalized({0.6, 0.3, 0.7});
  const auto t = scene.trace(wi, s);
  std::vector<double> cone(size_t(s.res) * s.res * 3, 0.0);
  loom::add_bin_averages(
      [&](vec3 w) {
        // A band a little wider than the samples' spacing (1/15 of a bin), so that every bin
        // the cone crosses has a sample in it.
        const float v = std::fabs(w.x + float(wi.x)) < 0.05f ? 1.0f : 0.0f;
        return std::array<float, 3>{v, v, v};
      },
      s.res, 15, 1.0, cone);
  double on = 0, off = 0, cone_bins = 0;
  for (size_t k = 0; k < cone.size(); k += 3) {
    (cone[k] > 0 ? on : off) += t.density[k];
    cone_bins += cone[k] > 0;
  }
  EXPECT_GT(on, 0.0);
  EXPECT_EQ(off, 0.0);
  EXPECT_LT(cone_bins, 0.25 * s.res * s.res);  // the test means something: most bins are off
}

TEST(TruthError, NoiseEstimateMatchesTheErrorAgainstALongTrace) {
  // noise_l1 from two halves of 20,000 rays against the actual relative L1 of their mean to a
  // trace of 2,000,000 rays (whose own error is a tenth of theirs).
  const loom::test::Row row{10.0, 60.0, 30.0, {0.0, 0.05, 0.01}, 1.55};
  loom::FiberMaterial m;
  m.sigma_per_um = row.sigma;
  loom::FiberTruthScene scene(loom::test::row_curves(row, 40.0), {0}, {m},
                              {0.0, 0.0, 40.0, row.period});
  const loom::Vec3d wi = loom::normalized({0.3, 0.2, 0.9});
  loom::TruthSettings s;
  s.res = 8;
  s.rays = 2000000;
  s.seed = 7;
  const auto ref = scene.trace(wi, s);
  const std::vector<double> truth(ref.density.begin(), ref.density.end());
  for (uint64_t seed : {1u, 3u, 5u}) {
    SCOPED_TRACE(seed);
    s.rays = 20000;
    s.seed = seed;
    const auto a = scene.trace(wi, s);
    s.seed = seed + 1;
    const auto b = scene.trace(wi, s);
    const loom::TruthTally t = loom::combine_halves(a, b);
    const double actual = loom::relative_l1(t.density, truth);
    EXPECT_GT(t.noise_l1, 0.0);
    EXPECT_GT(actual / t.noise_l1, 0.75);
    EXPECT_LT(actual / t.noise_l1, 1.33);
  }
}

TEST(TruthError, HemispheresAgreeWithTheRaywaveAlbedo) {
  // The atlas's side of truth_error (its bins, reflect on the view's side, the open fraction
  // in transmit) against raywave_albedo's own quadrature (the midpoints of a 48 x 96 grid over the sphere): the
  // same BSDF, two integrations. Both read every texel of the 32 x 32 draft maps once (a
  // jittered 32 x 32 lattice of points, one per texel, and 1,024 texels), so only the
  // quadratures differ.
  const auto dir = loom::test::draft_atlas("plain", "raywave");
  const auto atlas = loom::load_atlas(dir.string());
  ASSERT_EQ(atlas.map("ply_frame").width, 32);
  ASSERT_EQ(atlas.map("ply_frame").height, 32);
  auto spec = loom::parse_spec(atlas.manifest.at("spec"));
  ASSERT_TRUE(spec.ok());
  loom::TruthErrorSettings s;
  s.views = 2;  // one from each side
  s.points = 1024;
  s.sub = 2;
  s.truth.rays = 2000;
  s.truth.res = 24;
  s.truth.min_yarns = 2;
  const auto e = loom::truth_error(atlas, spec.spec, s);
  ASSERT_EQ(e.views.size(), 2u);
  const auto data = loom::load_raywave(atlas);
  for (const auto& v : e.views) {
    SCOPED_TRACE(v.view.z);
    const auto q = loom::raywave_albedo(atlas, data, v.view, loom::Evaluator::Model, 1024, 48);
    EXPECT_NEAR(v.open, q.gap, 1e-6);
    for (size_t k = 0; k < 3; ++k) {
      EXPECT_NEAR(v.model.reflect[k], q.reflect[k], 0.02 * q.reflect[k]);
      EXPECT_NEAR(v.model.transmit[k], q.transmit[k] + q.gap, 0.02 * q.transmit[k]);
    }
    EXPECT_GT(v.truth_reflect[0] + v.truth_transmit[0], 0.0);
  }
}

TEST(TruthErrorCli, ComparesModelAndClosuresAndRefusesBadInput) {
  const std::string exe = loom::test::bake_exe();
  const auto dir = loom::test::draft_atlas("plain", "surface").string();
  std::string out;
  // Nothing to compare with, both, an odd --res: exit 2 with the option named.
  int rc = loom::test::run(exe + " eval error --atlas " + dir + " 2>&1", &out);
  EXPECT_EQ(rc, 2) << out;
  EXPECT_NE(out.find("--truth"), std::string::npos) << out;
  rc = loom::test::run(exe + " eval error --atlas " + dir + " --truth --reference " + dir +
                           " 2>&1", &out);
  EXPECT_EQ(rc, 2) << out;
  rc = loom::test::run(exe + " eval error --atlas " + dir + " --truth --res 5 2>&1", &out);
  EXPECT_EQ(rc, 2) << out;
  EXPECT_NE(out.find("--res"), std::string::npos) << out;
  rc = loom::test::run(exe + " eval error --atlas " + dir +
                           " --truth --views 2 --points 16 --rays 4000 --min-yarns 2",
                       &out);
  ASSERT_EQ(rc, 0) << out;
  const auto j = nlohmann::json::parse(out);
  for (const char* side : {"model", "closures"})
    for (const char* key : {"relative_l1", "albedo_error", "reflect_ratio", "transmit_ratio"}) {
      const double v = j.at(side).at(key).get<double>();
      EXPECT_TRUE(std::isfinite(v) && v > 0) << side << " " << key << " " << v;
    }
  EXPECT_EQ(j.at("views").size(), 2u);
  EXPECT_GT(j.at("noise_l1").get<double>(), 0.0);
}

}  // namespace
