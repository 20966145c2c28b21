// Double-layer scattering (Eq. S.20): energy bookkeeping of the layer factors and the totals at
// sigma = 0, the orderings the supplement states (B_total > B_t, F_total < F_t), and agreement of
// the closed form with the layers' full directional transfer iterated bounce by bounce.
#include <gtest/gtest.h>

#include <cmath>

#include "loom/double_layer.h"
#include "small_ply_sim.h"

namespace {

const loom::PlySimResult& sim() {
  static const loom::PlySimResult r = loom::test::small_ply_sim(9, 5);
  return r;
}

loom::Vec3d dir(double theta_deg, double phi_deg) {
  double t = theta_deg * M_PI / 180, p = phi_deg * M_PI / 180;
  return {std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t)};
}

double truncated_max() {
  double m = 0;
  for (auto& sl : sim().slices) m = std::max(m, sl.energy[0].truncated);
  return m;
}

}  // namespace

TEST(DoubleLayer, EnergyIsConservedWithoutAbsorption) {
  loom::Layer top{&sim(), {1, 0, 0}}, bottom{&sim(), {0, 1, 0}};
  const double lost = truncated_max() + 1e-9;
  for (auto xi : {dir(0, 0), dir(30, 10), dir(60, 100), dir(85, 45)}) {
    auto f = loom::double_layer_factors(top, bottom, xi, 0);
    EXPECT_LE(f.Bt + f.Ft, 1 + 1e-9);
    EXPECT_GE(f.Bt + f.Ft, 1 - lost);
    // The bottom layer (interpolated R, T) passes on what the top sent it.
    EXPECT_NEAR(f.Bb + f.Fb, f.Ft, 0.01 + lost);
    // Eq. S.20 with lossless layers: B_total + F_total = B_t + F_t.
    EXPECT_NEAR(f.Btotal + f.Ftotal, f.Bt + f.Ft, 0.01 + 2 * lost);
    EXPECT_GT(f.Btotal, f.Bt);
    EXPECT_LT(f.Ftotal, f.Ft);
  }
}

TEST(DoubleLayer, AbsorptionLowersTransmission) {
  loom::Layer top{&sim(), {1, 0, 0}}, bottom{&sim(), {0, 1, 0}};
  auto xi = dir(20, 30);
  double prev = 2;
  for (int k = 0; k < 3; ++k) {
    auto f = loom::double_layer_factors(top, bottom, xi, k);
    EXPECT_LT(f.Ftotal, prev);
    EXPECT_GE(f.Btotal, f.Bt);
    prev = f.Ftotal;
  }
}

TEST(DoubleLayer, ClosedFormTracksIteratedBounces) {
  // The closed form keeps the first two scattering steps exact and gives every later bounce the
  // second step's factors; iterating the full directional transfer shows what that costs.
  loom::Layer top{&sim(), {1, 0, 0}}, bottom{&sim(), {0, 1, 0}};
  for (int k : {0, 1})
    for (auto xi : {dir(10, 20), dir(50, 70)}) {
      auto f = loom::double_layer_factors(top, bottom, xi, k);
      auto [B, F] = loom::double_layer_brute_force(top, bottom, xi, k, 16);
      EXPECT_NEAR(f.Btotal, B, 0.01) << "k " << k;
      EXPECT_NEAR(f.Ftotal, F, 0.01) << "k " << k;
      std::printf("double layer k=%d: S.20 B %.4f F %.4f, iterated B %.4f F %.4f\n", k, f.Btotal,
                  f.Ftotal, B, F);
    }
}
