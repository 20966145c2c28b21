// The colour of a swatch (swatch.h) and the colour difference it is judged by (delta_e.h):
// CIEDE2000 against Sharma, Wu and Dalal's published test pairs, the
// swatch's limit cases (a white non-absorbing cloth folded to opacity is white; on a black card
// it is its own reflectance), the pile against the layers added one by one, and the solve
// against the forward computation.
#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>

#include "fiber_row.h"
#include "loom/atlas.h"
#include "loom/atlas_swatch.h"
#include "loom/delta_e.h"
#include "loom/raywave_bsdf.h"
#include "loom/colour.h"
#include "loom/spec.h"
#include "loom/spectral_upsampling.h"
#include "loom/swatch.h"
#include "test_util.h"

namespace {

TEST(DeltaE2000, MatchesSharmaWuDalalTestData) {
  struct Pair {
    loom::Lab a, b;
    double de;
  };
  // Pairs 1-4, 7, 9, 10, 17, 25 and 34 of the paper's Table 1, and (50, 2.5, 0)-(50, 0, -2.5).
  const Pair pairs[] = {
      {{50.0, 2.6772, -79.7751}, {50.0, 0.0, -82.7485}, 2.0425},
      {{50.0, 3.1571, -77.2803}, {50.0, 0.0, -82.7485}, 2.8615},
      {{50.0, 2.8361, -74.0200}, {50.0, 0.0, -82.7485}, 3.4412},
      {{50.0, -1.3802, -84.2814}, {50.0, 0.0, -82.7485}, 1.0000},
      {{50.0, 0.0, 0.0}, {50.0, -1.0, 2.0}, 2.3669},
      {{50.0, 2.4900, -0.0010}, {50.0, -2.4900, 0.0009}, 7.1792},
      {{50.0, 2.4900, -0.0010}, {50.0, -2.4900, 0.0011}, 7.2195},
      {{50.0, 2.5, 0.0}, {73.0, 25.0, -18.0}, 27.1492},
      {{60.2574, -34.0099, 36.2677}, {60.4626, -34.1751, 39.4387}, 1.2644},
      {{2.0776, 0.0795, -1.1350}, {0.9033, -0.0636, -0.5514}, 0.9082},
      {{50.0, 2.5, 0.0}, {50.0, 0.0, -2.5}, 4.3065},
  };
  for (const Pair& p : pairs) {
    EXPECT_NEAR(loom::delta_e_2000(p.a, p.b), p.de, 1e-4) << p.de;
    EXPECT_NEAR(loom::delta_e_2000(p.b, p.a), p.de, 1e-4) << p.de;
  }
  EXPECT_EQ(loom::delta_e_2000({40, 10, -20}, {40, 10, -20}), 0.0);
}

/// A small scene: the plain preset's tile of 2 x 2 yarns.
struct PlainScene {
  std::unique_ptr<loom::FiberTruthScene> scene;
  PlainScene() {
    auto spec = loom::load_spec("plain");
    if (!spec.ok()) throw std::runtime_error("plain");
    scene = loom::make_truth_scene(spec.spec, 2);
  }
};

std::vector<loom::FiberMaterial> absorbing(const loom::FiberTruthScene& scene,
                                           std::array<double, 3> sigma) {
  auto m = scene.materials();
  for (auto& x : m) x.sigma_per_um = sigma;
  return m;
}

TEST(Swatch, LimitCases) {
  const PlainScene p;
  loom::SwatchSettings s;
  s.truth.rays = 20000;
  const loom::SwatchPaths folded(*p.scene, s);
  // Fibers that absorb nothing lose nothing: folded to opacity the swatch is white (R_inf = 1
  // of non-absorbing layers, then everything comes back), up to the truncated paths.
  const auto w = folded.swatch(absorbing(*p.scene, {0, 0, 0}));
  for (size_t c = 0; c < 3; ++c) {
    EXPECT_NEAR(w.rho[c], 1.0, 2e-3);
    EXPECT_NEAR(w.below[c], 1.0, 2e-3);
    EXPECT_NEAR(w.reflect[c] + w.transmit[c], 1.0, 2e-3);
  }
  // On a black card the swatch is the cloth's own reflectance; on a white card a
  // non-absorbing cloth is white too.
  s.card = 0;
  const auto black = loom::SwatchPaths(*p.scene, s).swatch(absorbing(*p.scene, {0.01, 0.01, 0.01}));
  for (size_t c = 0; c < 3; ++c) EXPECT_DOUBLE_EQ(black.rho[c], black.reflect[c]);
  s.card = 1;
  const auto white = loom::SwatchPaths(*p.scene, s).swatch(absorbing(*p.scene, {0, 0, 0}));
  EXPECT_NEAR(white.rho[1], 1.0, 2e-3);
  // The pile: R_inf against layers added one at a time (R_{n+1} = r + t^2 R_n / (1 - r R_n)).
  const auto g = folded.swatch(absorbing(*p.scene, {0.002, 0.01, 0.05}));
  for (size_t c = 0; c < 3; ++c) {
    const double r = g.down_reflect[c], t = g.down_transmit[c];
    double R = 0;
    for (int n = 0; n < 100000 && R < 1; ++n) R = r + t * t * R / (1 - r * R);
    EXPECT_NEAR(g.below[c], R, 1e-9) << c;
  }
  // Darker fibers make a darker swatch.
  const auto d = folded.swatch(absorbing(*p.scene, {0.004, 0.02, 0.1}));
  for (size_t c = 0; c < 3; ++c) EXPECT_LT(d.rho[c], g.rho[c]);
}

TEST(Swatch, SolveFindsTheAbsorptionThatMadeAColour) {
  const PlainScene p;
  loom::SwatchSettings s;
  s.truth.rays = 20000;
  const loom::SwatchPaths paths(*p.scene, s);
  const std::array<double, 3> sigma{0.001, 0.01, 0.1};
  const auto target = paths.swatch(absorbing(*p.scene, sigma)).rho;
  const auto sol = paths.solve(target);
  for (size_t c = 0; c < 3; ++c) {
    EXPECT_FALSE(sol.clamped[c]);
    EXPECT_NEAR(sol.sigma_per_um[c], sigma[c], 1e-4 * sigma[c]) << c;
    EXPECT_NEAR(sol.swatch.rho[c], target[c], 1e-7) << c;
  }
  // Out of reach: brighter than no absorption, darker than the fibers' gloss.
  const auto clear = paths.swatch(absorbing(*p.scene, {0, 0, 0})).rho;
  const auto out = paths.solve({std::min(clear[0] + 0.01, 1.0), 1e-6, 0.9 * target[1]});
  EXPECT_TRUE(out.clamped[0]);
  EXPECT_EQ(out.sigma_per_um[0], 0.0);
  EXPECT_TRUE(out.clamped[1]);
  EXPECT_EQ(out.sigma_per_um[1], loom::kSigmaMaxPerUm);
  EXPECT_FALSE(out.clamped[2]);
}

TEST(Swatch, CurveInvertsLikeTheSolve) {
  const PlainScene p;
  loom::SwatchSettings s;
  s.truth.rays = 20000;
  const loom::SwatchPaths paths(*p.scene, s);
  const loom::SwatchCurve curve = paths.curve();
  const std::array<double, 3> sigma{0.0007, 0.01, 0.15};
  const auto target = paths.swatch(absorbing(*p.scene, sigma)).rho;
  for (size_t c = 0; c < 3; ++c) {
    bool clamped = true;
    const double got = loom::swatch_sigma(curve, target[c], &clamped);
    EXPECT_FALSE(clamped);
    // Interpolation between levels 0.27 decades apart: a few per cent in sigma, less in rho.
    EXPECT_NEAR(got, sigma[c], 0.05 * sigma[c]) << c;
    EXPECT_NEAR(loom::swatch_rho_at(curve, sigma[c]), target[c], 0.01 * target[c]) << c;
    EXPECT_NEAR(loom::swatch_rho_at(curve, got), target[c], 1e-9) << c;
  }
  bool clamped = false;
  EXPECT_EQ(loom::swatch_sigma(curve, 2.0, &clamped), 0.0);
  EXPECT_TRUE(clamped);
  EXPECT_EQ(loom::swatch_sigma(curve, 0.0, &clamped), loom::kSigmaMaxPerUm);
  EXPECT_TRUE(clamped);
}

TEST(Swatch, RaywaveBakeAbsorbsWhatShowsThePickedColour) {
  // The ray-wave atlas's absorption, put on the fibers and traced again (new seeds, more rays
  // than the draft bake's), shows the picked colour as a swatch: Delta E 2000 under 3 (the
  // preset's red is partly out of reach in blue: the fibers' gloss).
  nlohmann::json d = loom::preset("plain");
  d["model"]["tier"] = "raywave";
  d["model"]["colour_reading"] = "swatch";
  const auto atlas = loom::load_atlas(loom::test::shared_atlas("plain-raywave-swatch.draft", d).string());
  const auto& y = atlas.manifest.at("raywave").at("yarns").at("warp").at("absorption");
  ASSERT_EQ(y.at("reading").get<std::string>(), "swatch");
  const auto sigma_mm = y.at("sigma_rgb_per_mm").get<std::array<double, 3>>();
  const auto picked = atlas.manifest.at("yarn_colours_linear").at("warp").get<std::array<double, 3>>();
  loom::SwatchSettings s;
  s.truth.rays = 60000;
  s.truth.seed = 99;
  s.truth.min_yarns = 8;
  auto spec = loom::load_spec("plain");
  const auto scene = loom::make_truth_scene(spec.spec, 8);
  const loom::SwatchPaths paths(*scene, s);
  const auto shown =
      paths.swatch(absorbing(*scene, {sigma_mm[0] * 1e-3, sigma_mm[1] * 1e-3, sigma_mm[2] * 1e-3}));
  const loom::SpectralUpsampler up(loom::ColourConverter(""));  // CIELAB of linear Rec.709
  auto lab = [&](const std::array<double, 3>& c) { return up.lab(c); };
  EXPECT_LT(loom::delta_e_2000(lab(picked), lab(shown.rho)), 3.0)
      << shown.rho[0] << " " << shown.rho[1] << " " << shown.rho[2];
}

TEST(AtlasSwatch, PartsAgreeWithTheRaywaveAlbedo) {
  // atlas_swatch's integrals against raywave_albedo's own quadrature (another grid over the
  // sphere): R and T at the 8 degree view, and the diffuse parts over the view cells' midpoints
  // (n_views 1: (0, +-0.866, +-0.5), each pi sr of a hemisphere). Both read every texel of the
  // 32 x 32 draft maps once, so only the quadratures differ. And on a black card the swatch is R.
  const auto atlas = loom::load_atlas(loom::test::draft_atlas("plain", "raywave").string());
  ASSERT_EQ(atlas.map("ply_frame").width, 32);
  loom::AtlasSwatchSettings st;
  st.points = 1024;
  st.n = 16;
  st.n_views = 1;
  const loom::Swatch sw = loom::atlas_swatch(atlas, loom::Evaluator::Model, st);
  const auto d = loom::load_raywave(atlas);
  const double t8 = 8 * M_PI / 180;
  const loom::shading::vec3 V8(float(std::sin(t8) * M_SQRT1_2), float(std::sin(t8) * M_SQRT1_2),
                               float(std::cos(t8)));
  auto albedo = [&](loom::shading::vec3 o) {
    return loom::raywave_albedo(atlas, d, o, loom::Evaluator::Model, 1024, 32);
  };
  const auto q8 = albedo(V8);
  std::array<double, 3> r{}, t{}, Ru{}, Tu{};
  for (float side : {1.0f, -1.0f})
    for (float y : {0.8660254f, -0.8660254f}) {
      const auto q = albedo(loom::shading::vec3(0.0f, y, 0.5f * side));
      const double w = 0.5 * M_PI / M_PI;  // |cos o| dv / pi
      for (size_t c = 0; c < 3; ++c) {
        (side > 0 ? r : Ru)[c] += w * q.reflect[c];  // light on the view's side
        (side > 0 ? Tu : t)[c] += w * (q.transmit[c] + q.gap);
      }
    }
  for (size_t c = 0; c < 3; ++c) {
    SCOPED_TRACE(c);
    EXPECT_NEAR(sw.reflect[c], q8.reflect[c], 0.03 * q8.reflect[c]);
    EXPECT_NEAR(sw.transmit[c], q8.transmit[c] + q8.gap, 0.03 * (q8.transmit[c] + q8.gap));
    EXPECT_NEAR(sw.down_reflect[c], r[c], 0.03 * r[c]);
    EXPECT_NEAR(sw.down_transmit[c], t[c], 0.03 * t[c]);
    EXPECT_NEAR(sw.up_reflect[c], Ru[c], 0.03 * Ru[c]);
    EXPECT_NEAR(sw.up_transmit[c], Tu[c], 0.03 * Tu[c]);
  }
  st.card = 0;
  st.n_views = 1;
  const loom::Swatch black = loom::atlas_swatch(atlas, loom::Evaluator::Model, st);
  for (size_t c = 0; c < 3; ++c) EXPECT_DOUBLE_EQ(black.rho[c], black.reflect[c]);
}

TEST(SwatchCli, PrintsTheColoursAndRefusesBadInput) {
  const std::string exe = loom::test::bake_exe();
  std::string out;
  int rc = loom::test::run(exe + " eval swatch --spec plain --card 2 2>&1", &out);
  EXPECT_EQ(rc, 2) << out;
  EXPECT_NE(out.find("--card"), std::string::npos) << out;
  rc = loom::test::run(exe + " eval swatch 2>&1", &out);  // neither --spec nor --atlas
  EXPECT_EQ(rc, 2) << out;
  EXPECT_NE(out.find("--atlas"), std::string::npos) << out;
  const auto dir = loom::test::draft_atlas("plain", "surface").string();
  rc = loom::test::run(exe + " eval swatch --atlas " + dir, &out);
  ASSERT_EQ(rc, 0) << out;
  for (const char* k : {"model", "closures"}) {
    const auto j = nlohmann::json::parse(out).at(k);
    const double de = j.at("delta_e_2000").get<double>();  // one red for warp and weft
    EXPECT_TRUE(std::isfinite(de) && de >= 0) << k;
    for (double v : j.at("rho").get<std::array<double, 3>>()) EXPECT_TRUE(v > 0 && v < 1) << k;
  }
  rc = loom::test::run(exe + " eval swatch --spec plain --rays 4000 --min-yarns 2", &out);
  ASSERT_EQ(rc, 0) << out;
  const auto j = nlohmann::json::parse(out);
  const auto& y = j.at("yarns").at("warp_and_weft");  // the preset's warp and weft are one red
  EXPECT_EQ(y.at("picked").size(), 3u);
  for (const char* k : {"as_ply_albedo", "solved"}) {
    const double de = y.at(k).at("delta_e_2000").get<double>();
    EXPECT_TRUE(std::isfinite(de) && de >= 0) << k;
  }
  // The solve reaches the red within what a swatch of this cloth can show.
  EXPECT_LT(y.at("solved").at("delta_e_2000").get<double>(), 3.0);
}

}  // namespace
