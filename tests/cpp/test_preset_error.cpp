// The error of a quality preset against another (baker/include/loom/preset_error.h) and the lobe
// probe the trade's plots read (loom-bake eval lobes).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "loom/asg_fit.h"
#include "loom/atlas.h"
#include "loom/evaluator.h"
#include "loom/ply_tables.h"
#include "loom/preset_error.h"
#include "loom/raywave_bsdf.h"
#include "test_util.h"

namespace fs = std::filesystem;
using nlohmann::json;
using loom::shading::vec3;

namespace {

fs::path bake(const std::string& preset, const std::string& quality, const std::string& tier,
              bool noise = true) {
  auto d = loom::preset(preset);
  d["model"]["tier"] = tier;
  if (!noise) d["wave"] = {{"noise", false}};
  return loom::test::shared_atlas(
      preset + "-" + tier + (noise ? "" : "-quiet") + "." + quality, d, quality,
      loom::test::Baker::Fixture);
}

}  // namespace

TEST(PresetError, AnAtlasAgainstItselfIsExact) {
  const auto a = loom::load_atlas(bake("plain", "draft", "surface"));
  const auto e = loom::preset_error(a, a, 16, 4, 12);
  EXPECT_EQ(e.average, 0.0);
  EXPECT_EQ(e.pointwise_mean, 0.0);
  EXPECT_EQ(e.pointwise_worst, 0.0);
  EXPECT_EQ(e.energy, 0.0);
  EXPECT_EQ(e.points, 16);
  EXPECT_EQ(e.views, 4);
}

// The definitions of the header, summed serially from the public evaluators at the sampling
// preset_error() reports: draft against preview (different map resolutions, read bilinearly).
TEST(PresetError, EqualsTheSumsOfItsDefinition) {
  const auto a = loom::load_atlas(bake("plain", "draft", "surface"));
  const auto r = loom::load_atlas(bake("plain", "preview", "surface"));
  const int points = 9, views = 3, sphere_n = 10;
  const auto e = loom::preset_error(a, r, points, views, sphere_n);
  const auto s = loom::preset_error_sampling(points, views, sphere_n);
  ASSERT_EQ(s.uv.size(), 9u);
  ASSERT_EQ(s.lights.size(), size_t(2 * sphere_n * sphere_n));
  double pw = 0, worst = 0, avg = 0, energy = 0;
  int counted = 0, used = 0;
  for (const vec3& v : s.views) {
    std::vector<double> ma(s.lights.size(), 0.0), mr(s.lights.size(), 0.0);
    for (const auto& [u, w] : s.uv) {
      const auto pa = loom::sample_surface(a, u, w), pr = loom::sample_surface(r, u, w);
      double num = 0, den = 0;
      for (size_t l = 0; l < s.lights.size(); ++l) {
        const vec3 L = s.lights[l];
        const double fa = loom::eval_bsdf(a, pa, L, v, loom::Evaluator::Model)[1] * std::fabs(L.z);
        const double fr = loom::eval_bsdf(r, pr, L, v, loom::Evaluator::Model)[1] * std::fabs(L.z);
        ma[l] += fa, mr[l] += fr;
        num += std::fabs(fa - fr) * s.dw, den += fr * s.dw;
      }
      if (den < 1e-6) continue;
      pw += num / den, worst = std::max(worst, num / den), ++counted;
    }
    double num = 0, den = 0, ea = 0;
    for (size_t l = 0; l < s.lights.size(); ++l)
      num += std::fabs(ma[l] - mr[l]), den += mr[l], ea += ma[l];
    if (den == 0) continue;  // a grazing view the reference sends nothing to: not counted
    avg += num / den, energy += std::fabs(ea - den) / den, ++used;
  }
  EXPECT_EQ(e.views, used);
  ASSERT_GT(counted, 0);
  EXPECT_NEAR(e.pointwise_mean, pw / counted, 1e-9 * (1 + pw));
  EXPECT_NEAR(e.pointwise_worst, worst, 1e-9 * (1 + worst));
  ASSERT_GT(used, 0);
  EXPECT_NEAR(e.average, avg / used, 1e-9 * (1 + avg));
  EXPECT_NEAR(e.energy, energy / used, 1e-9 * (1 + energy));
  // Two presets of one fabric differ, but not wholly: a sanity range, not a target.
  EXPECT_GT(e.average, 0.0);
  EXPECT_LT(e.average, 1.0);
}

TEST(PresetError, RefusesAnotherTierOrAnotherFabric) {
  const auto plain = loom::load_atlas(bake("plain", "draft", "surface"));
  const auto twill = loom::load_atlas(bake("twill", "draft", "surface"));
  try {
    (void)loom::preset_error(plain, twill);
    FAIL() << "a plain atlas against a twill one was compared";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("weave repeats"), std::string::npos) << e.what();
  }
  loom::Atlas other = plain;
  other.manifest["tier"] = "raywave";
  try {
    (void)loom::preset_error(plain, other);
    FAIL() << "a surface atlas against a ray-wave one was compared";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("tier"), std::string::npos) << e.what();
  }
  EXPECT_THROW((void)loom::preset_error(plain, plain, 0), std::runtime_error);
  // One view is the grazing z = 0 one, which the reference sends nothing to: nothing was
  // compared, which is not a perfect score.
  try {
    (void)loom::preset_error(plain, plain, 16, 1, 12);
    FAIL() << "nothing compared, yet an error was reported";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("views"), std::string::npos) << e.what();
  }
}

// The ray-wave branch: the same sums from RaywavePoint at the nearest texel (Closest, as the
// shaders read ray-wave maps), gaps' diffraction left out; an atlas against itself is exact.
void expect_raywave_sums(const loom::Atlas& a, const loom::Atlas& r) {
  const int points = 4, views = 2, sphere_n = 8;
  const auto e = loom::preset_error(a, r, points, views, sphere_n);
  const auto s = loom::preset_error_sampling(points, views, sphere_n);
  const auto da = loom::load_raywave(a), dr = loom::load_raywave(r);
  auto texel = [](const loom::Atlas& at, float u, float v) {
    const loom::Image& m = at.map("ply_frame");
    return loom::texel_surface(at, std::min(m.width - 1, int(u * m.width)),
                               std::min(m.height - 1, int(v * m.height)));
  };
  double pw = 0, avg = 0;
  int counted = 0, used = 0;
  for (const vec3& v : s.views) {
    std::vector<double> ma(s.lights.size(), 0.0), mr(s.lights.size(), 0.0);
    for (const auto& [u, w] : s.uv) {
      const loom::RaywavePoint qa(da, texel(a, u, w), v, loom::Evaluator::Model, false);
      const loom::RaywavePoint qr(dr, texel(r, u, w), v, loom::Evaluator::Model, false);
      double num = 0, den = 0;
      for (size_t l = 0; l < s.lights.size(); ++l) {
        const double fa = qa.eval(s.lights[l])[1], fr = qr.eval(s.lights[l])[1];
        ma[l] += fa, mr[l] += fr;
        num += std::fabs(fa - fr) * s.dw, den += fr * s.dw;
      }
      if (den < 1e-6) continue;
      pw += num / den, ++counted;
    }
    double num = 0, den = 0;
    for (size_t l = 0; l < s.lights.size(); ++l) num += std::fabs(ma[l] - mr[l]), den += mr[l];
    if (den == 0) continue;
    avg += num / den, ++used;
  }
  ASSERT_GT(counted, 0);
  ASSERT_GT(used, 0);
  EXPECT_NEAR(e.pointwise_mean, pw / counted, 1e-9 * (1 + pw));
  EXPECT_NEAR(e.average, avg / used, 1e-9 * (1 + avg));
}

// eval lobes: each lobe's grid is Eq. S.1 of the lobe it prints, on the grid it documents; their
// sum is the tables' own S.8 / S.12 evaluation (asg_table_eval) at that slice; the simulated
// slice on that grid integrates to the energy the simulator's own bookkeeping reports (eval
// plysim, same slice: an independent path through the bins). And preset_error's ray-wave branch.
TEST(PresetError, LobeProbeIsTheFitOnItsGridAndTheSimulationIntegratesToItsEnergy) {
  const fs::path dir = bake("plain", "draft", "raywave");
  const auto atlas = loom::load_atlas(dir);
  {
    const auto e = loom::preset_error(atlas, atlas, 4, 2, 8);
    EXPECT_EQ(e.average, 0.0);
    EXPECT_EQ(e.pointwise_mean, 0.0);
  }
  // Against the same draft without speckle noise (a cheap second atlas of the same fabric).
  expect_raywave_sums(atlas, loom::load_atlas(bake("plain", "draft", "raywave", false)));
  const auto t = loom::load_ply_tables(atlas, "warp");
  // A grid slice of the draft tables, so that the probe's nearest slice is exactly this one.
  const double th_deg = t.high.theta_i[2] * 180 / M_PI, h = t.high.h[4];
  std::string out;
  const int res = 48;
  const std::string exe = loom::test::bake_exe(), args = " --theta-i " + std::to_string(th_deg) +
                                                 " --h " + std::to_string(h);
  ASSERT_EQ(loom::test::run(exe + " eval lobes --atlas " + dir.string() + args +
                                " --raw --snap --res " + std::to_string(res),
                            &out),
            0)
      << out;
  const json j = json::parse(out);
  ASSERT_EQ(j["grid"]["rows"].get<int>(), res);
  ASSERT_EQ(j["grid"]["cols"].get<int>(), 2 * res);
  double integral = 0;
  for (int r = 0; r < res; ++r) {
    const double el = -M_PI / 2 + M_PI * (r + 0.5) / res;
    for (int c = 0; c < 2 * res; ++c) {
      const double az = -M_PI + 2 * M_PI * (c + 0.5) / (2 * res);
      const loom::Vec3d v{std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)};
      double sum = 0;
      for (const char* which : {"high", "refl"})
        for (const json& lb : j[which]) {
          const loom::AsgLobe q{lb["theta_z"], lb["phi_z"], lb["phi_xy"], lb["mu1"], lb["mu2"],
                                lb["c"]};
          const double f = loom::asg_mixture_eval({q}, v);
          EXPECT_NEAR(lb["values"][r][c].get<double>(), f, 1e-9 * (1 + f));
          sum += f;
        }
      EXPECT_NEAR(j["total"][r][c].get<double>(), sum, 1e-9 * (1 + sum));
      const double table = loom::asg_table_eval(t.high, t.high.theta_i[2], h, 0, v) +
                           loom::asg_table_eval(t.refl, t.high.theta_i[2], h, 0, v);
      EXPECT_NEAR(sum, table, 1e-6 * (1 + table));
      const double raw = j["raw"]["values"][r][c].get<double>();
      ASSERT_TRUE(std::isfinite(raw) && raw >= 0);
      // cell solid angle: cos(el) d(el) d(az)
      integral += raw * std::cos(el) * (M_PI / res) * (2 * M_PI / (2 * res));
    }
  }
  EXPECT_NEAR(j["raw"]["theta_i_deg"].get<double>(), th_deg, 1e-9);
  const fs::path spec = loom::test::scratch("plysim_spec.json");
  {
    auto d = loom::preset("plain");
    d["model"]["tier"] = "raywave";
    std::ofstream(spec) << d.dump();
  }
  std::string sim;
  ASSERT_EQ(loom::test::run(exe + " eval plysim --spec " + spec.string() + " --quality draft" +
                                args, &sim),
            0)
      << sim;
  const json e = json::parse(sim);
  const double energy = e["reflected"].get<double>() + e["higher_order"].get<double>();
  // Different rays (seed) and the bins' edges against the grid's cells: a few per cent.
  EXPECT_NEAR(integral, energy, 0.05 * energy) << "integral " << integral << " energy " << energy;
}
