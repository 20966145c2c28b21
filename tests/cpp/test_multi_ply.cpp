// Multi-ply scattering (Eq. S.13-S.19): at sigma = 0 the residual term makes the yarn conserve
// the single ply's energy (and is needed for it), absorption makes secondary scattering lose
// energy, single-ply yarns are left alone.
#include <gtest/gtest.h>

#include <cmath>

#include "loom/multi_ply.h"
#include "small_ply_sim.h"

namespace {

const loom::PlySimResult& single() {
  static const loom::PlySimResult r = loom::test::small_ply_sim(5, 5);
  return r;
}

double total(const loom::PlySimEnergy& e) {
  return e.reflected + e.higher_order + e.unscattered + e.truncated;
}

}  // namespace

TEST(MultiPly, ConservesEnergyWithoutAbsorption) {
  loom::YarnSpec y;  // two plies by default
  ASSERT_GE(y.plies, 2);
  auto g = loom::multi_ply_geometry(y, single());
  std::vector<loom::MultiPlyEnergy> en;
  auto multi = loom::multi_ply_scattering(single(), g, &en);
  const size_t K = single().settings.sigmas.size();
  double s1_max = 0, missing_without_residual = 0;
  for (size_t i = 0; i < single().slices.size(); ++i) {
    const auto& a = single().slices[i].energy[0];
    const auto& b = multi.slices[i].energy[0];
    EXPECT_NEAR(total(b), total(a), 0.01) << "slice " << i;
    const auto& e = en[i * K];
    EXPECT_NEAR(e.s2, e.s1, 0.01 + single().slices[i].energy[0].truncated) << "lossless plies";
    s1_max = std::max(s1_max, e.s1);
    missing_without_residual = std::max(missing_without_residual, e.s1 - e.s3);
  }
  // The neighbours matter here, and without the residual band energy would be lost.
  EXPECT_GT(s1_max, 0.2);
  EXPECT_GT(missing_without_residual, 0.05);
}

TEST(MultiPly, AbsorptionInTheNeighboursLosesEnergy) {
  loom::YarnSpec y;
  auto g = loom::multi_ply_geometry(y, single());
  std::vector<loom::MultiPlyEnergy> en;
  auto multi = loom::multi_ply_scattering(single(), g, &en);
  const size_t K = single().settings.sigmas.size();
  for (size_t i = 0; i < single().slices.size(); ++i)
    for (size_t k = 1; k < K; ++k) {
      const auto& e = en[i * K + k];
      if (e.s1 < 1e-3) continue;
      EXPECT_LT(e.s2, e.s1) << "slice " << i << " level " << k;
      EXPECT_LE(total(multi.slices[i].energy[k]), total(single().slices[i].energy[k]) + 1e-9);
      for (float v : multi.slices[i].high) ASSERT_TRUE(std::isfinite(v) && v >= 0);
    }
}

TEST(MultiPly, SinglePlyYarnsSkipIt) {
  loom::YarnSpec y;
  y.plies = 1;
  auto g = loom::multi_ply_geometry(y, single());
  auto same = loom::multi_ply_scattering(single(), g);
  for (size_t i = 0; i < single().slices.size(); ++i) {
    EXPECT_EQ(same.slices[i].high, single().slices[i].high);
    EXPECT_EQ(same.slices[i].refl, single().slices[i].refl);
  }
}
