// Invariants of the baked ply-level maps.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "loom/ply_maps.h"

namespace {

loom::FabricSpec spec_of(const std::string& preset, loom::Quality q = loom::Quality::Draft) {
  auto r = loom::parse_spec(loom::preset(preset));
  EXPECT_TRUE(r.ok());
  r.spec.quality = q;
  for (auto* y : {&r.spec.warp, &r.spec.weft}) y->color_linear = {0.5, 0.4, 0.3};
  return r.spec;
}

}  // namespace

class PlyMaps : public ::testing::TestWithParam<const char*> {};

TEST_P(PlyMaps, UnitTangentsNormalsUpAndRanges) {
  auto spec = spec_of(GetParam());
  auto maps = loom::bake_surface_maps(spec);
  ASSERT_EQ(maps.images.size(), maps.info.size());
  const auto& frame = maps.images[0];
  const auto& nrm = maps.images[1];
  for (int y = 0; y < frame.height; ++y)
    for (int x = 0; x < frame.width; ++x) {
      const float* t = frame.px(x, y);
      const float* n = nrm.px(x, y);
      EXPECT_NEAR(t[0] * t[0] + t[1] * t[1] + t[2] * t[2], 1.0, 1e-4);
      EXPECT_NEAR(n[0] * n[0] + n[1] * n[1] + n[2] * n[2], 1.0, 1e-4);
      EXPECT_GT(n[2], 0.0f);
      EXPECT_LT(std::fabs(t[0] * n[0] + t[1] * n[1] + t[2] * n[2]), 1e-3);  // n_p _|_ t
      EXPECT_GE(n[3], -1.0f);
      EXPECT_LE(n[3], 1.0f);
    }
  for (size_t m = 0; m < maps.images.size(); ++m)
    for (float v : maps.images[m].data) {
      ASSERT_TRUE(std::isfinite(v)) << maps.info[m].name;
    }
  // Energy split of the albedos: k_rs + k_ts + k_rd + k_td <= 1 per channel.
  const auto& ar = maps.images[3];
  const auto& at = maps.images[4];
  for (size_t i = 0; i < ar.data.size(); i += 4)
    for (int c = 0; c < 3; ++c)
      EXPECT_LE(ar.data[i + c] + at.data[i + c] + ar.data[i + 3] + at.data[i + 3], 1.0 + 1e-6);
}

TEST_P(PlyMaps, GeometryIsContinuousAcrossTheRepeatBorder) {
  // The maps tile when the field is continuous across the repeat's border wherever it is
  // continuous inside: along a warp yarn that stays on top across x = 0 (and a weft yarn across
  // y = 0), the ply geometry just before the border (x = Lx - e) must continue just after it
  // (x = e). A non-periodic ingredient (a non-integer number of ply stripes per repeat, a
  // non-periodic Perlin lattice, a crimp phase) breaks this.
  auto spec = spec_of(GetParam(), loom::Quality::Preview);
  spec.perlin.enabled = true;
  loom::SurfaceGeometry g(spec);
  const double Lx = g.repeat_x(), Ly = g.repeat_y(), e = 1e-3;
  int compared = 0;
  for (int k = 0; k < 4000; ++k) {
    double s = (k + 0.5) / 4000;
    for (int axis = 0; axis < 2; ++axis) {
      auto a = axis == 0 ? g.sample(Lx - e, s * Ly, false) : g.sample(s * Lx, Ly - e, false);
      auto b = axis == 0 ? g.sample(e, s * Ly, false) : g.sample(s * Lx, e, false);
      int along = axis == 0 ? 1 : 2;  // the yarn that runs across this border
      if (a.kind != along || b.kind != along) continue;
      if (std::fabs(a.h) > 0.98f || std::fabs(b.h) > 0.98f) continue;  // a ply's own edge
      ++compared;
      EXPECT_NEAR(a.height, b.height, 0.05) << axis << " " << s;
      EXPECT_NEAR(a.h, b.h, 0.01) << axis << " " << s;
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(a.t[c], b.t[c], 0.01) << axis << " " << s;
        EXPECT_NEAR(a.n[c], b.n[c], 0.01) << axis << " " << s;
      }
      EXPECT_EQ(a.ply_id, b.ply_id);
    }
  }
  EXPECT_GT(compared, 500);
}

TEST_P(PlyMaps, WarpAndWeftOnTopFollowTheWeave) {
  auto spec = spec_of(GetParam());
  spec.components.gaps = false;
  auto maps = loom::bake_surface_maps(spec);
  auto weave = loom::make_weave(spec.weave);
  const auto& info = maps.images[2];
  int tpc = loom::texels_per_cell(spec.quality);
  // At the centre of each crossing the yarn on top is the weave's.
  for (int r = 0; r < weave.rows(); ++r)
    for (int c = 0; c < weave.cols(); ++c) {
      float kind = info.px(c * tpc + tpc / 2, r * tpc + tpc / 2)[0];
      EXPECT_EQ(kind, weave.at(r, c) ? 1.0f : 2.0f) << "crossing " << r << "," << c;
    }
}

INSTANTIATE_TEST_SUITE_P(Presets, PlyMaps, ::testing::Values("plain", "twill", "satin", "basket"));

TEST(PlyMapsGaps, OpenWeaveHasGapsDenseHasNone) {
  auto spec = spec_of("plain");
  spec.warp_per_cm = spec.weft_per_cm = 10;  // 1000 um spacing, 300 um yarns: open
  auto open = loom::bake_surface_maps(spec);
  double open_mean = 0;
  for (size_t i = 3; i < open.images[2].data.size(); i += 4) open_mean += open.images[2].data[i];
  open_mean /= open.images[2].data.size() / 4;
  // Open area of a grid of yarns of width d at spacing s: (1 - d/s)^2.
  EXPECT_NEAR(open_mean, (1 - 0.3) * (1 - 0.3), 0.03);
  spec.warp_per_cm = spec.weft_per_cm = 40;  // 250 um spacing, 300 um yarns: closed
  auto dense = loom::bake_surface_maps(spec);
  for (size_t i = 3; i < dense.images[2].data.size(); i += 4)
    EXPECT_EQ(dense.images[2].data[i], 0.0f);
}

TEST(PlyMapsPerlin, SeededAndDeterministic) {
  auto spec = spec_of("twill");
  spec.perlin.enabled = true;
  auto a = loom::bake_surface_maps(spec);
  auto b = loom::bake_surface_maps(spec);
  EXPECT_EQ(a.images[0].data, b.images[0].data);
  spec.perlin.seed = 7;
  auto c = loom::bake_surface_maps(spec);
  EXPECT_NE(a.images[0].data, c.images[0].data);
}
