// Colour from absorption (section 6): RGB -> sigmoid spectrum -> RGB round trip in CIELAB,
// the simulated sigma -> energy curve's limits, S.42's fit on an exact exponential, and a
// colour carried through the whole chain.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>

#include "loom/absorption.h"
#include "loom/ply_scattering.h"
#include "loom/procedural_ply.h"

namespace {

double delta_e(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                   (a[2] - b[2]) * (a[2] - b[2]));
}

TEST(SpectralUpsampling, RoundTripOverTheSrgbGamut) {
  // Every sRGB colour on a 7^3 grid (corners and edges included) comes back within a small
  // CIELAB difference (Delta E 1 is about the threshold of perception).
  const loom::ColourConverter cc;
  const loom::SpectralUpsampler up(cc, 5.0);
  double worst = 0;
  int n = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (int r = 0; r <= 6; ++r)
    for (int g = 0; g <= 6; ++g)
      for (int b = 0; b <= 6; ++b) {
        const auto lin = cc.srgb_to_linear({r / 6.0, g / 6.0, b / 6.0});
        const auto s = up.fit(lin);
        for (double l = 380; l <= 780; l += 20) {
          ASSERT_GE(s(l), 0.0);
          ASSERT_LE(s(l), 1.0);
        }
        const double de = delta_e(up.lab(lin), up.lab(up.rgb(s)));
        worst = std::max(worst, de);
        EXPECT_LT(de, 0.5) << r << "," << g << "," << b;
        ++n;
      }
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  RecordProperty("worst_delta_e", std::to_string(worst));
  RecordProperty("ms_per_fit", std::to_string(ms / n));
  // White is the constant spectrum 1 (up to the clamp), grey a constant.
  const auto w = up.fit({1, 1, 1});
  for (double l : {380.0, 550.0, 780.0}) EXPECT_GT(w(l), 0.999);
  const auto g = up.fit({0.3, 0.3, 0.3});
  for (double l : {400.0, 550.0, 700.0}) EXPECT_NEAR(g(l), 0.3, 2e-3);
}

const loom::AbsorptionCurve& plain_curve() {
  static const loom::AbsorptionCurve c =
      loom::absorption_curve(loom::load_spec("plain").spec.warp, loom::Quality::Draft);
  return c;
}

TEST(Absorption, CurveFallsFromOneToTheFirstSurfaceReflection) {
  const auto& c = plain_curve();
  ASSERT_GT(c.energy.size(), 8u);
  EXPECT_EQ(c.sigma_per_mm.front(), 0.0);
  // No absorption: everything that hit a fiber leaves it (up to truncated paths).
  EXPECT_GT(c.energy.front(), 0.99);
  for (size_t k = 1; k < c.energy.size(); ++k) EXPECT_LE(c.energy[k], c.energy[k - 1]);
  // Very strong absorption: only first-surface reflection survives. That is the simulation's
  // "reflected" category at sigma = 0, traced independently of the absorption weights.
  const auto yarn = loom::load_spec("plain").spec.warp;
  const loom::PlyParams p = loom::ply_params_from_yarn(yarn);
  loom::PlyGeometry geo(p, loom::make_ply_fibers(p, 0, 0));
  auto s = loom::ply_sim_settings(loom::Quality::Draft);
  s.sigmas = {0};
  double refl = 0, hit = 0;
  for (int n = 0; n < 17; ++n) {
    s.beam_halfwidth = 1.0 / 17;
    const auto sl = loom::simulate_ply_slice(geo, yarn.ior, s, 0.0, -1 + (2.0 * n + 1) / 17, 77 + n);
    refl += sl.energy[0].reflected;
    hit += sl.energy[0].reflected + sl.energy[0].higher_order + sl.energy[0].absorbed +
           sl.energy[0].truncated;
  }
  // Different rays (seeds): Monte Carlo error of a ~4 % fraction over 136k rays, about 0.001.
  EXPECT_NEAR(c.energy.back(), refl / hit, 0.005);
  EXPECT_GT(c.energy.back(), 0.02);
  EXPECT_LT(c.energy.back(), 0.08);
}

TEST(Absorption, S42FitRecoversAnExactExponentialAndInverts) {
  loom::AbsorptionCurve c;
  const double a = -0.02, b = 1.7;
  for (double s = 0; s <= 200; s += 10) {
    c.sigma_per_mm.push_back(s);
    c.energy.push_back(std::pow(b * std::exp(s), a));
  }
  const auto f = loom::fit_absorption(c);
  EXPECT_NEAR(f.a, a, 1e-12);
  EXPECT_NEAR(f.b, b, 1e-9);
  EXPECT_LT(f.rms_log_error, 1e-12);
  for (double s : {0.5, 20.0, 150.0}) EXPECT_NEAR(f.sigma(f.energy(s), 1e4), s, 1e-9);
  // Clamps: no negative sigma for bright colours, the table's maximum for black or NaN.
  EXPECT_EQ(f.sigma(1.0, 3000), 0.0);
  EXPECT_EQ(f.sigma(0.0, 3000), 3000.0);
  EXPECT_EQ(f.sigma(NAN, 3000), 3000.0);
}

TEST(Absorption, ColourThroughTheWholeChain) {
  const auto& curve = plain_curve();
  const auto fit = loom::fit_absorption(curve);
  const loom::ColourConverter cc;
  const loom::SpectralUpsampler up(cc, 5.0);
  // curve_sigma inverts curve_energy inside the reachable range.
  for (double e : {0.9, 0.5, 0.2, 0.08}) {
    const double s = loom::curve_sigma(curve, e, 3000);
    EXPECT_NEAR(loom::curve_energy(curve, s), e, 1e-6 * e);
  }
  // White: no absorption to speak of. (The spectrum stops at 1 - 1e-4, the sigmoid's clamp,
  // and the curve's E(0) is a hair below 1 from truncated paths: sigma of a few 1e-3 per mm,
  // a transmittance of 0.997 over a whole millimetre of fiber.)
  const auto white = loom::yarn_absorption({1, 1, 1}, up, fit, curve, 3000);
  for (double s : white.sigma_per_mm) EXPECT_LT(s, 0.01);
  // Reachable colours come back as the ply's scattered energy (the spectrum's round trip plus
  // the curve's interpolation, both small).
  for (auto rgb : {std::array<double, 3>{0.5, 0.5, 0.5}, {0.6, 0.3, 0.1}, {0.2, 0.25, 0.6}}) {
    const auto ya = loom::yarn_absorption(rgb, up, fit, curve, 3000);
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(ya.rgb_ply[size_t(c)], rgb[size_t(c)], 0.01) << c;
      EXPECT_GE(ya.sigma_rgb[size_t(c)], 0.0);
    }
    // Redder light is absorbed less in an orange yarn.
    if (rgb[0] > rgb[2]) {
      EXPECT_LT(ya.sigma_rgb[0], ya.sigma_rgb[2]);
    }
  }
  // Below the reflection floor a channel is lifted towards it (a black fiber still glints): not
  // exactly to it, since the working space's matching functions have negative lobes where the
  // spectrum is bright.
  const auto dark = loom::yarn_absorption({0.34, 0.013, 0.01}, up, fit, curve, 3000);
  EXPECT_NEAR(dark.rgb_ply[0], 0.34, 0.02);
  EXPECT_GT(dark.rgb_ply[2], 0.02);
  EXPECT_LT(dark.rgb_ply[2], 0.08);
  for (double s : dark.sigma_per_mm) {
    EXPECT_GE(s, 0.0);
    EXPECT_LE(s, 3000.0);
  }
}

}  // namespace
