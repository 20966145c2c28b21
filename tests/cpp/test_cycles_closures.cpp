// The closure emulator against closed forms of Cycles' diffuse and GGX closures.
#include <gtest/gtest.h>

#include <cmath>

#include "loom/cycles_closures.h"
#include "sphere_quadrature.h"

using loom::shading::normalize;
using loom::shading::vec3;
namespace cy = loom::cycles;

namespace {
template <class F>
double hemisphere_integral(F f, int n) {  // over the upper hemisphere, midpoint in (cos, phi)
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    double z = (i + 0.5) / n, r = std::sqrt(1 - z * z);
    for (int j = 0; j < 4 * n; ++j) {
      double p = (j + 0.5) * 2 * M_PI / (4 * n);
      sum += f(vec3{float(r * std::cos(p)), float(r * std::sin(p)), float(z)});
    }
  }
  return sum * (1.0 / n) * (2 * M_PI / (4 * n));
}
const vec3 Z(0, 0, 1);
}  // namespace

TEST(CyclesClosures, DiffuseAndTranslucent) {
  EXPECT_NEAR(cy::diffuse_eval(Z, normalize(vec3(1, 0, 1)), Z), std::sqrt(0.5) / M_PI, 1e-6);
  EXPECT_EQ(cy::diffuse_eval(Z, vec3(0, 0, -1), Z), 0.0f);
  EXPECT_NEAR(cy::translucent_eval(Z, vec3(0, 0, -1), Z), 1 / M_PI, 1e-6);
  EXPECT_NEAR(hemisphere_integral([](vec3 L) { return cy::diffuse_eval(Z, L, Z); }, 300), 1.0, 1e-4);
}

TEST(CyclesClosures, GGXClosedFormAtNormalIncidence) {
  // I = L = N: D = 1 / (pi a^2), Lambda = 0, eval = D / 4.
  for (float a : {0.1f, 0.5f, 1.0f})
    EXPECT_NEAR(cy::ggx_eval(Z, vec3(1, 0, 0), a, a, Z, Z, Z), 1.0 / (M_PI * a * a) / 4,
                1e-5 / (a * a));
  // Anisotropic: D = 1 / (pi ax ay) at H = N.
  EXPECT_NEAR(cy::ggx_eval(Z, vec3(1, 0, 0), 0.2f, 0.7f, Z, Z, Z), 1.0 / (M_PI * 0.14) / 4, 1e-4);
}

TEST(CyclesClosures, GGXOffSpecularClosedForm) {
  // I at 60 deg, L mirror: H = N, D = 1/(pi a^2); Lambda(tan 60) = (sqrt(1 + 3 a^2) - 1) / 2.
  float a = 0.4f;
  vec3 I = normalize(vec3(std::sqrt(3.0f), 0, 1)), L = normalize(vec3(-std::sqrt(3.0f), 0, 1));
  double lam = 0.5 * (std::sqrt(1 + 3 * a * a) - 1);
  double expect = 1 / (M_PI * a * a) / (4 * 0.5) / (1 + 2 * lam);
  EXPECT_NEAR(cy::ggx_eval(Z, vec3(1, 0, 0), a, a, Z, I, L), expect, 1e-4 * expect);
  // Rotating the tangent changes nothing for an isotropic closure; the anisotropic one with the
  // roughness axes swapped equals the one with the tangent turned 90 degrees.
  EXPECT_NEAR(cy::ggx_eval(Z, vec3(0.6f, 0.8f, 0), a, a, Z, I, L), expect, 1e-4 * expect);
  EXPECT_NEAR(cy::ggx_eval(Z, vec3(1, 0, 0), 0.2f, 0.6f, Z, I, L),
              cy::ggx_eval(Z, vec3(0, 1, 0), 0.6f, 0.2f, Z, I, L), 1e-5);
}

TEST(CyclesClosures, GGXEnergyAndHemispheres) {
  // Single-scattering GGX loses little energy when smooth, more when rough, never gains.
  vec3 I = normalize(vec3(0.3f, 0.1f, 1));
  double e_smooth = hemisphere_integral(
      [&](vec3 L) { return cy::ggx_eval(Z, vec3(1, 0, 0), 0.1f, 0.1f, Z, I, L); }, 1500);
  EXPECT_NEAR(e_smooth, 1.0, 0.02);
  // alpha = 1 at normal incidence: D = 1/pi, G = 2 mu / (1 + mu), so the albedo is
  // (1/2) int_0^1 2 mu / (1 + mu) dmu = 1 - ln 2.
  double e_rough = hemisphere_integral(
      [&](vec3 L) { return cy::ggx_eval(Z, vec3(1, 0, 0), 1.0f, 1.0f, Z, Z, L); }, 400);
  EXPECT_NEAR(e_rough, 1 - std::log(2.0), 2e-3);
  // Below the closure normal or the geometric normal: zero.
  EXPECT_EQ(cy::ggx_eval(Z, vec3(1, 0, 0), 0.3f, 0.3f, Z, I, vec3(0, 0, -1)), 0.0f);
  EXPECT_EQ(cy::ggx_eval(Z, vec3(1, 0, 0), 0.3f, 0.3f, Z, vec3(0, 0, -1), Z), 0.0f);
}

TEST(CyclesClosures, BumpShadowingTerm) {
  // Chiang et al. 2019: g = <Ng.L> / (<N.L> <Ng.N>); 1 when g >= 1, 0 when g < 0, smooth between.
  vec3 N = normalize(vec3(0.5f, 0, 1));
  EXPECT_EQ(cy::bump_shadowing_term(Z, N, vec3(0, 0, 1)), 1.0f);  // g = 1 / (cos * cos) > 1
  EXPECT_EQ(cy::bump_shadowing_term(Z, N, normalize(vec3(1, 0, -0.1f))), 0.0f);
  vec3 L = normalize(vec3(1, 0, 0.1f));
  double g = L.z / (loom::shading::dot(N, L) * N.z);
  ASSERT_GT(g, 0.0);
  ASSERT_LT(g, 1.0);
  EXPECT_NEAR(cy::bump_shadowing_term(Z, N, L), -g * g * g + g * g + g, 1e-6);
  EXPECT_NEAR(cy::diffuse_eval(N, L, Z), loom::shading::dot(N, L) / M_PI * (-g * g * g + g * g + g),
              1e-6);
}

TEST(CyclesClosures, ValidSpecularReflectionLiftsTheMirrorDirection) {
  vec3 I = normalize(vec3(1, 0, 0.2f));
  vec3 N = normalize(vec3(-0.6f, 0, 1));  // mirror of I about N dips below the surface
  vec3 R = N * (2 * loom::shading::dot(N, I)) - I;
  ASSERT_LT(R.z, 0.0f);
  vec3 N2 = cy::ensure_valid_specular_reflection(Z, I, N);
  vec3 R2 = N2 * (2 * loom::shading::dot(N2, I)) - I;
  EXPECT_NEAR(R2.z, std::min(0.9f * I.z, 0.01f), 1e-4);  // just above the threshold
  EXPECT_NEAR(loom::shading::length(N2), 1.0f, 1e-5);
  vec3 N3 = normalize(vec3(0.1f, 0, 1));  // already valid: unchanged
  vec3 K = cy::ensure_valid_specular_reflection(Z, I, N3);
  EXPECT_EQ(K.x, N3.x);
  EXPECT_EQ(K.z, N3.z);
}

using loom_test::sphere_integral;

TEST(CyclesClosures, HairLobesIntegrateToTheirClosedForms) {
  // With N along the view's direction across the fiber (locy), the normal's cut keeps exactly
  // the azimuths |phi| <= pi/2 (reflection, light on N's side) and |phi - pi| <= pi/2
  // (transmission, light on the other side). The theta
  // factor integrates to 1 over the cone's Cauchy; the azimuth factors to
  // sin(min(pi / (4 r2), pi / 2)) (reflection) and 2 atan(pi / (2 r2)) / c_TT = 1
  // (transmission).
  const vec3 T = normalize(vec3(1, 0.3f, 0.2f));
  for (float r2 : {0.3f, 1.0f}) {
    const vec3 I = normalize(vec3(0.2f, -0.5f, 0.8f));
    const vec3 locy = normalize(I - T * loom::shading::dot(T, I));
    const cy::HairLobe refl(locy, T, 0.15f, r2, 0, I, false), trans(locy, T, 0.15f, r2, 0, I, true);
    const double er = sphere_integral([&](vec3 L) { return double(refl.eval(L)); }, 1000);
    const double et = sphere_integral([&](vec3 L) { return double(trans.eval(L)); }, 1000);
    EXPECT_NEAR(er, std::sin(std::min(M_PI / (4 * r2), M_PI / 2)), 0.01) << "r2 " << r2;
    EXPECT_NEAR(et, 1.0, 0.01) << "r2 " << r2;
  }
}

TEST(CyclesClosures, HairTransmissionPeaksOnTheConeOppositeTheView) {
  // The lobe's density in (latitude, azimuth) about T (eval cos theta: eval is a pdf in solid
  // angle) peaks on the specular cone L.T = -I.T, on the far side of the fiber from the viewer;
  // the closure does not change when the tangent is reversed.
  const vec3 T = normalize(vec3(1, 0.1f, 0.3f)), I = normalize(vec3(0.3f, 0.2f, 0.9f));
  const cy::HairLobe h(Z, T, 0.1f, 0.4f, 0, I, true), hm(Z, -T, 0.1f, 0.4f, 0, I, true);
  float best = 0;
  vec3 arg;
  for (int i = 0; i < 400; ++i)
    for (int j = 0; j < 800; ++j) {
      const double z = -(i + 0.5) / 400, r = std::sqrt(1 - z * z), p = (j + 0.5) * M_PI / 400;
      const vec3 L{float(r * std::cos(p)), float(r * std::sin(p)), float(z)};
      const float f = h.eval(L);
      EXPECT_NEAR(hm.eval(L), f, 1e-4f * (1 + f));
      const float lat = std::sqrt(std::max(0.0f, 1 - loom::shading::dot(L, T) * loom::shading::dot(L, T)));
      if (f * lat > best) best = f * lat, arg = L;
    }
  using loom::shading::dot;
  EXPECT_NEAR(dot(arg, T), -dot(I, T), 0.02);
  const vec3 locy = normalize(I - T * dot(T, I)), across = normalize(arg - T * dot(T, arg));
  EXPECT_LT(dot(across, locy), -0.99f);
  EXPECT_EQ(h.eval(normalize(vec3(0.1f, 0.2f, 0.5f))), 0.0f);  // above N: no transmission
}
