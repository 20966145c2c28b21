// The surface tier's swatch reading (surface_swatch.h, issue 35): its assumption (the swatch's
// parts are affine in the albedo) against a direct evaluation, and the colour a bake with the
// reading renders against the picked colour, on a finer quadrature than the bake's.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "loom/atlas.h"
#include "loom/atlas_bsdf.h"
#include "loom/atlas_swatch.h"
#include "loom/colour.h"
#include "loom/delta_e.h"
#include "loom/ply_maps.h"
#include "loom/spec.h"
#include "loom/spectral_upsampling.h"
#include "loom/surface_swatch.h"
#include "sphere_quadrature.h"
#include "test_util.h"

namespace {

using loom::Evaluator;

loom::FabricSpec spec_of(const nlohmann::json& d) {
  const auto r = loom::parse_spec(d, "draft");
  EXPECT_TRUE(r.ok());
  loom::FabricSpec s = r.spec;
  loom::resolve_yarn_colours(s, loom::ColourConverter(""));
  return s;
}

/// `a` with its albedo maps' colour channels set to `scale` x those of `maps`.
loom::Atlas with_albedo(loom::Atlas a, const loom::SurfaceMaps& maps, double scale) {
  for (size_t i = 0; i < a.names.size(); ++i)
    for (size_t w = 0; w < maps.info.size(); ++w)
      if (a.names[i].rfind("albedo_", 0) == 0 && maps.info[w].name == a.names[i])
        for (int y = 0; y < a.images[i].height; ++y)
          for (int x = 0; x < a.images[i].width; ++x)
            for (int c = 0; c < 3; ++c)
              a.images[i].px(x, y)[c] = float(scale * maps.images[w].px(x, y)[c]);
  return a;
}

TEST(SurfaceSwatch, TheSwatchIsAffineInTheAlbedo) {
  // The solve's premise: rho's parts at albedo 0.37, evaluated directly, are those the two
  // ends predict (and rho itself is what surface_swatch_rho makes of them).
  const nlohmann::json d = loom::preset("twill");
  const loom::Atlas a = loom::load_atlas(loom::test::draft_atlas("twill", "surface"));
  const auto white = loom::bake_surface_maps(
      loom::with_colours(spec_of(d), [](auto) { return std::array<double, 3>{1, 1, 1}; }), {},
      false);
  loom::AtlasSwatchSettings s;
  s.points = 6, s.n = 8, s.n_views = 3;
  const loom::SurfaceSwatchCurve curve = loom::surface_swatch_curve(a, white, s);
  const double c = 0.37;
  const loom::Swatch mid = loom::atlas_swatch(with_albedo(a, white, c), Evaluator::Closures, s);
  for (int ch = 0; ch < 3; ++ch) {
    const size_t k = size_t(ch);
    for (auto part : {&loom::Swatch::reflect, &loom::Swatch::transmit, &loom::Swatch::up_reflect,
                      &loom::Swatch::down_reflect, &loom::Swatch::down_transmit}) {
      const double lo = (curve.at0.*part)[k], hi = (curve.at1.*part)[k];
      EXPECT_NEAR((mid.*part)[k], lo + c * (hi - lo), 1e-4 + 1e-3 * (mid.*part)[k]) << ch;
    }
    EXPECT_NEAR(loom::surface_swatch_rho(curve, ch, c), mid.rho[k], 1e-4 + 1e-3 * mid.rho[k]);
    ASSERT_EQ(mid.view_albedo.size(), curve.at0.view_albedo.size());
    for (size_t v = 0; v < mid.view_albedo.size(); ++v) {
      const double lo = curve.at0.view_albedo[v][k], hi = curve.at1.view_albedo[v][k];
      EXPECT_NEAR(mid.view_albedo[v][k], lo + c * (hi - lo), 1e-4 + 1e-3 * mid.view_albedo[v][k]);
    }
    EXPECT_LT(curve.at0.rho[k], curve.at1.rho[k]);  // a white yarn's cloth is the lighter
  }
}

TEST(SurfaceSwatch, ABakeWithTheReadingRendersThePickedColour) {
  // Colours within the surface tier's reach (between its cloth's swatch at albedo 0, the sheen
  // alone, and at albedo 1): gray wool twill, and plain in a brown. With "colour_reading":
  // "swatch" the closures' swatch, on other and more points of the repeat than the bake's, is
  // the picked colour within Delta E 2000 of 2; with the ply-albedo reading (gray wool twill's,
  // the control) it is far from it. (Three draft bakes, by the fixture baker (test_util.h), and
  // their swatches on 100 points under the sanitizers.)
  const loom::SpectralUpsampler up(loom::ColourConverter(""));
  for (const char* preset : {"gray_wool_twill", "plain"}) {
    nlohmann::json d = loom::preset(preset);
    d["model"]["tier"] = "surface";
    if (std::string(preset) == "plain") d["yarn"]["color"] = {{"linear", {0.30, 0.15, 0.08}}};
    loom::AtlasSwatchSettings fine;
    fine.points = 100, fine.n = 12, fine.n_views = 3;  // (other points than the bake's 64)
    const bool control = std::string(preset) == "gray_wool_twill";
    double de[2] = {0, 0};
    for (int swatch = control ? 0 : 1; swatch < 2; ++swatch) {
      d["model"]["colour_reading"] = swatch ? "swatch" : "ply_albedo";
      const std::string name =
          std::string(preset) + (std::string(preset) == "plain" ? "-brown" : "");
      const auto dir = loom::test::shared_atlas(
          name + (swatch ? "-surface-swatch" : "-surface-ply") + ".draft", d, "draft",
          loom::test::Baker::Fixture);
      const loom::Atlas a = loom::load_atlas(dir);
      const auto picked =
          a.manifest.at("yarn_colours_linear").at("warp").get<std::array<double, 3>>();
      const loom::Swatch shown = loom::atlas_swatch(a, Evaluator::Closures, fine);
      de[swatch] = loom::delta_e_2000(up.lab(picked), up.lab(shown.rho));
      if (swatch) {
        const auto& y = a.manifest.at("swatch").at("yarns").at("warp");
        for (int c = 0; c < 3; ++c) {
          EXPECT_FALSE(y.at("swatch_out_of_reach")[c].get<bool>()) << preset << " " << c;
          const double alb = y.at("albedo")[c].get<double>();
          EXPECT_GE(alb, 0.0);
          EXPECT_LE(alb, 1.0);
        }
      }
      std::cout << preset << (swatch ? " swatch" : " ply albedo") << ": rho " << shown.rho[0]
                << " " << shown.rho[1] << " " << shown.rho[2] << ", Delta E " << de[swatch]
                << "\n";
    }
    EXPECT_LT(de[1], 2.0) << preset;
    if (control) {
      EXPECT_GT(de[0], 5.0) << preset << ": the ply-albedo reading should be far off";
    }
  }
}

TEST(SurfaceSwatch, BrightColoursReachFurtherWithinEnergy) {
  // Cream cotton twill's and white silk organza's picked colours lie beyond the cloth at albedo
  // 1: the reading raises the albedo above 1 (standing in for the light the surface model
  // loses), as far as energy allows.
  // Checked on points and views the bake never sampled (7 x 7 points, 24 views on both sides,
  // lights on a 12 x 24 sphere grid): every directional albedo of the yarns (what is not open
  // gap), of the closures and the model, at most 1 (the bake holds its own points to 0.95); no
  // albedo texel above 1; and the swatch nearer the picked colour than at albedo 1.
  for (const std::string preset : {"cream_cotton_twill", "white_silk_organza"}) {
    SCOPED_TRACE(preset);
    nlohmann::json d = loom::preset(preset);
    d["model"]["tier"] = "surface";
    d["model"]["colour_reading"] = "swatch";
    const loom::Atlas a =
        loom::load_atlas(loom::test::shared_atlas(preset + "-surface-swatch.draft", d, "draft",
                                                  loom::test::Baker::Fixture));
    const auto& sw = a.manifest.at("swatch");
    const auto& y = sw.at("yarns").at("warp");
    const double cmax = sw.at("albedo_max").get<double>();
    EXPECT_GT(cmax, 1.0);
    double top = 0;
    for (int c = 0; c < 3; ++c) top = std::max(top, y.at("albedo")[c].get<double>());
    EXPECT_GT(top, 1.0) << y.dump();
    EXPECT_LE(top, cmax + 1e-9);
    for (const char* m : {"albedo_reflect", "albedo_transmit"}) {
      const loom::Image& img = a.map(m);
      for (size_t i = 0; i < img.data.size(); ++i) {
        if (i % 4 == 3) continue;  // (the specular share)
        ASSERT_LE(img.data[i], 1.0f + 1e-3f) << m;
      }
    }
    const auto picked = y.at("colour_linear").get<std::array<double, 3>>();
    const auto rho = y.at("swatch_rho").get<std::array<double, 3>>();
    const auto rho1 = sw.at("rho_at_albedo_1").get<std::array<double, 3>>();
    for (size_t c = 0; c < 3; ++c)
      EXPECT_LT(std::fabs(rho[c] - picked[c]), std::fabs(rho1[c] - picked[c])) << c;
    for (const auto e : {Evaluator::Closures, Evaluator::Model}) {
      const loom::AtlasBsdf bsdf(a, e);
      double worst = 0;
      for (int j = 0; j < 7; ++j)
        for (int i = 0; i < 7; ++i) {
          const float u = float((i + 0.31) / 7), v = float((j + 0.67) / 7);
          for (int k = 0; k < 24; ++k) {
            const double z = (k % 12 + 0.5) / 12 * (k < 12 ? 1 : -1), ph = 2.4 * k;
            const double r = std::sqrt(1 - z * z);
            const loom::shading::vec3 o{float(r * std::cos(ph)), float(r * std::sin(ph)), float(z)};
            const auto f = bsdf.at(u, v, o);
            std::array<double, 3> sum{};  // each channel's integral, one pass over the lights
            loom_test::sphere_integral([&](loom::shading::vec3 L) {
              const auto x = f(L);
              for (size_t c = 0; c < 3; ++c) sum[c] += double(x[c]);
              return 0.0;
            }, 16);
            const double cell = (2.0 / 16) * (M_PI / 16);  // (sphere_integral's cells)
            const double open = bsdf.open(u, v);  // the yarns' part: f covers 1 - open
            if (open < 0.999)
              for (size_t c = 0; c < 3; ++c) worst = std::max(worst, sum[c] * cell / (1 - open));
          }
        }
      std::cout << (e == Evaluator::Closures ? "closures" : "model") << ": largest directional "
                << "albedo of the yarns " << worst << ", albedo " << y.at("albedo").dump()
                << ", c_max " << cmax
                << ", rho " << rho[0] << " " << rho[1] << " " << rho[2] << "\n";
      EXPECT_LE(worst, 1.0);
    }
  }
}

TEST(SurfaceSwatch, ColoursOutOfReachAreClampedAndSaid) {
  // The plain preset's red: its green and blue lie below the swatch of the cloth's sheen alone
  // (albedo 0), so they are clamped there and flagged; red is reached.
  nlohmann::json d = loom::preset("plain");
  d["model"]["colour_reading"] = "swatch";
  const loom::Atlas a =
      loom::load_atlas(loom::test::shared_atlas("plain-red-surface-swatch.draft", d));
  const auto& sw = a.manifest.at("swatch");
  const auto& y = sw.at("yarns").at("warp");
  const auto picked = y.at("colour_linear").get<std::array<double, 3>>();
  const auto rho0 = sw.at("rho_at_albedo_0").get<std::array<double, 3>>();
  EXPECT_FALSE(y.at("swatch_out_of_reach")[0].get<bool>());
  EXPECT_NEAR(y.at("swatch_rho")[0].get<double>(), picked[0], 1e-6);
  for (int c = 1; c < 3; ++c) {
    ASSERT_LT(picked[size_t(c)], rho0[size_t(c)]) << c;  // (the premise of this test)
    EXPECT_TRUE(y.at("swatch_out_of_reach")[c].get<bool>()) << c;
    EXPECT_EQ(y.at("albedo")[c].get<double>(), 0.0) << c;
    EXPECT_NEAR(y.at("swatch_rho")[c].get<double>(), rho0[size_t(c)], 1e-9) << c;
  }
}

}  // namespace
