// The surface tier's per-texel fitted closures (fitted_closures.h, model.closures "fitted"):
// the texture's layout as the shaders read it (a closed form), the fitted closures against the
// model on views and lights the fit never saw (they must beat the per-sample mapping, the
// issue's objective), the fit's independence of colour, and the spec's and the validator's refusals.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "loom/atlas.h"
#include "loom/evaluator.h"
#include "loom/fitted_closures.h"
#include "test_util.h"

using namespace loom::shading;

namespace {

nlohmann::json surface_spec(const std::string& preset, const char* closures) {
  nlohmann::json d = loom::preset(preset);
  d["model"]["tier"] = "surface";
  d["model"]["closures"] = closures;
  return d;
}

/// A preset's surface tier with fitted closures: the default (draft_atlas).
const std::filesystem::path& fitted_atlas(const std::string& preset) {
  return loom::test::draft_atlas(preset, "surface");
}

const std::filesystem::path& mapped_atlas(const std::string& preset) {
  return loom::test::shared_atlas(preset + "-surface-mapped.draft", surface_spec(preset, "mapped"),
                                  "draft", loom::test::Baker::Fixture);
}

}  // namespace

TEST(FittedClosures, TheShadersReadEachTileAsThePeriodicMap) {
  // A texture whose texel (ix, iy) of tile k holds 1000 k + 100 c + 10 iy + ix (channel c),
  // padded as the bake pads it: a read at a texel centre gives that texel, one on the repeat's
  // seam (u = 0) the mean of the first and the last column, never another tile.
  const int W = 6, H = 4, tw = W + 2;
  loom::Atlas a;
  a.names = {"ply_frame", "fitted_closures"};
  a.images = {loom::Image(W, H, 4), loom::Image(LOOM_FITTED_TILES * tw, H, 4)};
  loom::Image& img = a.images[1];
  for (int k = 0; k < LOOM_FITTED_TILES; ++k)
    for (int iy = 0; iy < H; ++iy)
      for (int col = 0; col < tw; ++col) {
        const int ix = (col - 1 + W) % W;
        for (int c = 0; c < 4; ++c)
          img.px(k * tw + col, iy)[c] = float(1000 * k + 100 * c + 10 * iy + ix) / 1000.0f;
      }
  ASSERT_TRUE(loom::has_fitted_closures(a));
  for (int back = 0; back < 2; ++back)
    for (int iy = 0; iy < H; ++iy) {
      const float v = (iy + 0.5f) / H;
      for (int ix = 0; ix < W; ++ix) {
        float fd[4], fs[4];
        loom::sample_fitted_closures(a, (ix + 0.5f) / W, v, back, fd, fs);
        for (int c = 0; c < 4; ++c) {
          const int k0 = LOOM_FITTED_PANELS * back;
          EXPECT_NEAR(fd[c], (1000 * k0 + 100 * c + 10 * iy + ix) / 1000.0, 1e-5);
          EXPECT_NEAR(fs[c], (1000 * (k0 + 1) + 100 * c + 10 * iy + ix) / 1000.0, 1e-5);
        }
      }
      float fd[4], fs[4];
      loom::sample_fitted_closures(a, 1.0f, v, back, fd, fs);  // the seam, wrapped to u = 0
      const int k0 = LOOM_FITTED_PANELS * back;
      EXPECT_NEAR(fd[0], (1000 * k0 + 10 * iy + 0.5 * (W - 1)) / 1000.0, 1e-5);
    }
}

TEST(FittedClosures, TheHorizonStripGivesTheHorizonMapsSine) {
  // V(V) with fitted closures reads the horizon strip once, at V's azimuth; what it gives must be
  // horizon_sine of the horizon maps read bilinearly at the same point, for any point and
  // azimuth (the bins' edges and the wrap from the last azimuth to the first included).
  const loom::Atlas a = loom::load_atlas(fitted_atlas("plain"));
  const loom::Image strip = loom::horizon_strip(a);
  EXPECT_EQ(strip.width, LOOM_HORIZON_DIRS * (a.map("horizon_0").width + 2));
  const float width = float(a.map("horizon_0").width);
  int n = 0;
  for (int i = 0; i < 400; ++i) {
    const float u = std::fmod(0.6180339f * i, 1.0f), v = std::fmod(0.7548776f * i + 0.1f, 1.0f);
    const double phi = (i % 40 == 0) ? M_PI * (i / 40) / 4 : 0.37 * i;  // on bin edges too
    const vec3 w(float(std::cos(phi)), float(std::sin(phi)), 0.3f);
    float hs, hf, h2[4], m0[4], m1[4];
    horizon_strip_coords(w, u, width, hs, hf);
    loom::bilinear(strip, hs, v, h2);
    loom::bilinear(a.map("horizon_0"), u, v, m0);
    loom::bilinear(a.map("horizon_1"), u, v, m1);
    float hor[LOOM_HORIZON_DIRS] = {m0[0], m0[1], m0[2], m0[3], m1[0], m1[1], m1[2], m1[3]};
    EXPECT_NEAR(h2[0] + (h2[1] - h2[0]) * hf, horizon_sine(w, hor), 2e-6)
        << u << " " << v << " " << phi;
    n += std::fabs(hor[0]) > 1e-3;
  }
  EXPECT_GT(n, 100);  // the cloth's horizons are not all flat: the check means something
}

TEST(FittedClosures, CloserToTheModelThanThePerSampleMapping) {
  // The mapping error (relative L1 over the sphere of lights, 16 views on both sides, 36
  // texels; evaluator.h) against the model, on views and lights the fit never used (it fits 4
  // views a side on a 6 x 12 grid of lights, this measures on a 48 x 96 grid): the fitted
  // factors must beat the mapping's moment matching, and keep its energy within 3 points.
  // Measured (draft, loom-bake eval mapping's 64 texels and 24 views): plain 0.271 against
  // 0.291, gray wool twill 0.117 against 0.138. The worst (texel, view) pair is not held to the
  // mapping's: a view-independent factor can miss where the mapping's does not (plain, here:
  // 2.26 against 1.83; with eval mapping's texels 2.30 against 2.34).
  // (Plain only: the fabric where the mapping is the hardest to beat; the eight fabrics' numbers
  // are in docs/surface.md.)
  for (const char* preset : {"plain"}) {
    const loom::Atlas fitted = loom::load_atlas(fitted_atlas(preset));
    const loom::Atlas mapped = loom::load_atlas(mapped_atlas(preset));
    ASSERT_TRUE(loom::has_fitted_closures(fitted));
    ASSERT_FALSE(loom::has_fitted_closures(mapped));
    const loom::MappingError f = loom::mapping_error(fitted, 36, 16, 48),
                            m = loom::mapping_error(mapped, 36, 16, 48);
    std::printf("%s: fitted %.4f (energy %.4f, worst %.3f), mapped %.4f (energy %.4f, worst "
                "%.3f)\n", preset, f.mean_l1, f.mean_energy, f.worst_l1, m.mean_l1,
                m.mean_energy, m.worst_l1);
    EXPECT_GT(f.views, 400);
    EXPECT_LT(f.mean_l1, m.mean_l1) << preset;
    EXPECT_LT(f.mean_energy, m.mean_energy + 0.03) << preset;
  }
}

TEST(FittedClosures, TheFitHoldsNoColour) {
  // Colour enters the closures through the albedo maps only, so two colours of one cloth get the
  // same fitted texture (a colour change needs no refit), and their closures differ as the
  // albedos do.
  nlohmann::json other = surface_spec("plain", "fitted");
  other["name"] = "plain_other_colour";
  other["yarn"]["color"] = {{"srgb", {0.2, 0.6, 0.3}}};
  const loom::Atlas a = loom::load_atlas(fitted_atlas("plain"));
  const loom::Atlas b =
      loom::load_atlas(loom::test::shared_atlas("plain-surface-fitted-other.draft", other));
  const loom::Image &fa = a.map("fitted_closures"), &fb = b.map("fitted_closures");
  ASSERT_EQ(fa.data.size(), fb.data.size());
  EXPECT_EQ(fa.data, fb.data);
  EXPECT_NE(a.map("albedo_reflect").data, b.map("albedo_reflect").data);
}

TEST(FittedClosures, OnlyTheSurfaceTierFitsAndTheChoiceIsNamed) {
  nlohmann::json d = surface_spec("plain", "fitted");
  d["model"]["tier"] = "raywave";
  loom::SpecResult r = loom::parse_spec(d);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.errors.at(0).find("$.model.closures"), std::string::npos) << r.errors.at(0);
  d = surface_spec("plain", "fited");
  r = loom::parse_spec(d);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.errors.at(0).find("closures"), std::string::npos) << r.errors.at(0);
  EXPECT_NE(r.errors.at(0).find("fitted"), std::string::npos) << r.errors.at(0);
  // The canonical spec names the surface tier's choice and reads back to it (the default,
  // "fitted", included); the ray-wave tier's, the mapping, is left out.
  for (const char* closures : {"mapped", "fitted"}) {
    r = loom::parse_spec(surface_spec("plain", closures));
    ASSERT_TRUE(r.ok());
    const nlohmann::json c = loom::canonical_spec(r.spec);
    EXPECT_EQ(c["model"]["closures"], closures);
    const loom::SpecResult back = loom::parse_spec(c);
    ASSERT_TRUE(back.ok());
    EXPECT_EQ(loom::canonical_spec(back.spec), c) << closures;
  }
  d = loom::preset("plain");
  d["model"]["tier"] = "surface";
  r = loom::parse_spec(d);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(loom::canonical_spec(r.spec)["model"]["closures"], "fitted");
  d["model"]["tier"] = "raywave";
  r = loom::parse_spec(d);
  ASSERT_TRUE(r.ok());
  EXPECT_FALSE(loom::canonical_spec(r.spec)["model"].contains("closures"));
}

TEST(FittedClosures, AnAtlasWhoseTilesDoNotFollowItsMapsIsRefused) {
  for (const char* name : {"fitted_closures", "horizon_strip"}) {
    const auto dir =
        loom::test::copy_atlas_dir(fitted_atlas("plain"), std::string("fitted-bad-") + name);
    loom::test::edit_atlas_manifest(dir, [&](nlohmann::json& m) {
      nlohmann::json& size = m["textures"][name]["size"];
      size[0] = size[0].get<int>() - 2;
    });
    const auto errors = loom::validate_atlas(dir);
    bool named = false;
    for (const auto& e : errors)
      named |= e.find(std::string("textures.") + name) != std::string::npos;
    EXPECT_TRUE(named) << name << ": " << (errors.empty() ? std::string("no error") : errors[0]);
  }
}
