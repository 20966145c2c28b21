// The surface BSDF's shared math (osl/include/loom/*.h, compiled as C++) against independent
// computations: quadrature identities, closed-form limits, brute-force energy sums.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "loom/shading.h"
#include "sphere_quadrature.h"

using namespace loom::shading;
using loom_test::sph;
using loom_test::sphere_integral;

namespace {

float no_horizon[LOOM_HORIZON_DIRS] = {-1, -1, -1, -1, -1, -1, -1, -1};

}  // namespace

TEST(SGGX, ProjectedAreaIdentity) {
  // Heitz et al. 2015, Eq. 3: int max(0, w.m) D(m) dm = sigma(w), for every w.
  for (float a : {0.3f, 0.6f, 1.0f})
    for (vec3 t : {vec3(1, 0, 0), normalize(vec3(1, 1, 0.5f))})
      for (vec3 w : {vec3(0, 0, 1), normalize(vec3(1, 0, 1)), normalize(vec3(0.2f, -1, 0.1f))}) {
        double I = sphere_integral(
            [&](vec3 m) { return std::max(0.0f, dot(w, m)) * sggx_fiber_D(m, t, a); }, 800);
        EXPECT_NEAR(I, sggx_fiber_sigma(w, t, a), 2e-3 * (1 + 1 / a)) << a;
      }
}

TEST(SGGX, EqualsAnisotropicGGXAboutTheFiberNormal) {
  // The claim closure_mapping.h rests on: D_SGGX(h) = GGX(h; N_c, t, alpha_t = a, alpha_b = 1).
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> U(-1, 1);
  for (int k = 0; k < 200; ++k) {
    vec3 t = normalize(vec3(U(rng), U(rng), 0.3f * U(rng)));
    float a = 0.05f + 0.9f * (U(rng) + 1) / 2;
    vec3 Nc = surface_glossy_normal(t);
    vec3 b = cross(Nc, t);
    vec3 h = normalize(vec3(U(rng), U(rng), U(rng)));
    if (dot(h, Nc) < 0) h = -h;
    float hx = dot(h, t) / a, hy = dot(h, b) / 1.0f, hz = dot(h, Nc);
    float l2 = hx * hx + hy * hy + hz * hz;
    double ggx = 1.0 / (M_PI * a * 1.0 * l2 * l2);
    EXPECT_NEAR(sggx_fiber_D(h, t, a) / ggx, 1.0, 1e-4);
  }
}

TEST(SpongeCake, AttenuationLimitsAndDirectForm) {
  for (float T : {0.01f, 1.0f, 7.0f})
    for (float la : {0.3f, 1.0f, 5.0f})
      for (float lb : {0.3f, 1.2f, 40.0f}) {
        double direct_r = (1 - std::exp(-double(T) * (la + lb))) / (la + lb);  // Eq. 2
        EXPECT_NEAR(spongecake_G_reflect(la, lb, T), direct_r, 1e-5 * (1 + direct_r));
        double direct_t = la == lb ? T * std::exp(-double(T) * la)
                                   : (std::exp(-double(T) * lb) - std::exp(-double(T) * la)) /
                                         (la - lb);  // Eq. 5 with Lambda_o = -lb
        EXPECT_NEAR(spongecake_G_transmit(la, lb, T), direct_t, 1e-5 * (1 + direct_t));
        EXPECT_FLOAT_EQ(spongecake_G_transmit(la, lb, T), spongecake_G_transmit(lb, la, T));
      }
  // Thin layer: G -> T; thick: G^r -> 1 / (la + lb), G^t -> 0. No overflow far out.
  EXPECT_NEAR(spongecake_G_reflect(2, 3, 1e-6f), 1e-6, 1e-9);
  EXPECT_NEAR(spongecake_G_reflect(2, 3, 1e4f), 0.2, 1e-6);
  EXPECT_EQ(spongecake_G_transmit(2, 3, 1e4f), 0.0f);
  EXPECT_TRUE(std::isfinite(spongecake_G_transmit(1e-3f, 1e6f, 100.0f)));
  EXPECT_NEAR(spongecake_G_transmit(1.0f, 1.0f + 1e-7f, 2.0f), 2 * std::exp(-2.0), 1e-5);
}

TEST(SurfaceBSDF, SingleScatteringNeverExceedsExtinction) {
  // A layer scatters at most the light it extinguishes: for unit albedo,
  //   int f^{r,s} cos + int f^{t,s} cos <= 1 - exp(-T Lambda(V)).
  for (float a : {0.15f, 0.4f, 1.0f})
    for (float T : {0.3f, 3.0f, 30.0f})
      for (double th : {0.0, 0.7, 1.3, 1.5}) {
        vec3 V = sph(th, 0.4);
        vec3 t(1, 0, 0);
        double E = sphere_integral(
            [&](vec3 i) {
              if (i.z > 0) return double(surface_specular_reflect(i, V, t, a, T)) * i.z;
              if (i.z < 0) return double(surface_specular_transmit(i, V, t, a, T)) * -i.z;
              return 0.0;
            },
            900);
        double ext = 1 - std::exp(-T * spongecake_lambda(sggx_fiber_sigma(V, t, a), V.z));
        EXPECT_LE(E, ext * 1.02 + 1e-3) << "a=" << a << " T=" << T << " theta=" << th;
        EXPECT_GT(E, 0.0);
      }
}

TEST(SurfaceBSDF, WhiteFurnaceWithBakerAlbedos) {
  // The baker's albedo split (k_rs + k_ts + k_rd + k_td = s + (1 - s) rho <= 1): total energy
  // <= 1 over dense direction sets, transmission included, for white yarn (rho = 1).
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> U(-1, 1);
  for (int k = 0; k < 12; ++k) {
    float s = (U(rng) + 1) / 2, tau = (U(rng) + 1) / 2, w = (U(rng) + 1) / 2;
    float a = 0.2f + 0.8f * (U(rng) + 1) / 2, T = 0.5f + 10 * (U(rng) + 1) / 2;
    vec3 t = normalize(vec3(U(rng), U(rng), 0.2f * U(rng)));
    vec3 np = normalize(vec3(0.6f * U(rng), 0.6f * U(rng), 1));
    vec3 V = normalize(vec3(U(rng), U(rng), 0.05f + (U(rng) + 1) / 2));
    color krd((1 - s) * (1 - tau)), ktd((1 - s) * tau);
    double E = sphere_integral(
        [&](vec3 i) {
          return double(surface_bsdf_eval(i, V, t, np, a, T, w, s * (1 - tau), krd, s * tau, ktd,
                                          0.0f, no_horizon)
                            .x) *
                 std::fabs(i.z);
        },
        600);
    EXPECT_LE(E, 1.0 + 5e-3) << k;
  }
}

TEST(SurfaceBSDF, ReciprocalWhereTheModelIs) {
  // Eq. 1, 4 and the flat part of Eq. 3/6 are symmetric in (i, o); the ply-normal part is not.
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> U(-1, 1);
  for (int k = 0; k < 500; ++k) {
    vec3 t = normalize(vec3(U(rng), U(rng), 0.3f * U(rng)));
    vec3 np = normalize(vec3(0.5f * U(rng), 0.5f * U(rng), 1));
    vec3 i = normalize(vec3(U(rng), U(rng), U(rng)));
    vec3 o = normalize(vec3(U(rng), U(rng), 0.05f + std::fabs(U(rng))));
    if (i.z < 0) {  // transmission: compare f(i, o) with f(o', i') seen from the other side
      color f1 = surface_bsdf_eval(i, o, t, np, 0.3f, 2.0f, 0.0f, 0.3f, color(0.2f), 0.3f,
                                   color(0.2f), 0.0f, no_horizon);
      color f2 = surface_bsdf_eval(o, i, t, np, 0.3f, 2.0f, 0.0f, 0.3f, color(0.2f), 0.3f,
                                   color(0.2f), 0.0f, no_horizon);
      EXPECT_NEAR(f1.x, f2.x, 1e-4 * (1 + f1.x));
    } else {
      color f1 = surface_bsdf_eval(i, o, t, np, 0.3f, 2.0f, 0.0f, 0.3f, color(0.2f), 0.3f,
                                   color(0.2f), 0.0f, no_horizon);
      color f2 = surface_bsdf_eval(o, i, t, np, 0.3f, 2.0f, 0.0f, 0.3f, color(0.2f), 0.3f,
                                   color(0.2f), 0.0f, no_horizon);
      EXPECT_NEAR(f1.x, f2.x, 1e-4 * (1 + f1.x));
    }
  }
}

TEST(SurfaceBSDF, FiniteAtGrazingAndDegenerateInputs) {
  std::vector<vec3> dirs = {vec3(1, 0, 0),       vec3(0, 1, 0),  normalize(vec3(1, 0, 1e-6f)),
                            normalize(vec3(1, 1, -1e-6f)), vec3(0, 0, 1), vec3(0, 0, -1),
                            normalize(vec3(-1, 0, 1e-6f))};
  std::vector<vec3> tangents = {vec3(1, 0, 0), vec3(0, 0, 1), vec3(0, 0, 0), normalize(vec3(1, 1, 1))};
  float hor[LOOM_HORIZON_DIRS] = {0, 0.2f, 0.9f, 1, 0, 0, 0.5f, 0.1f};
  for (vec3 i : dirs)
    for (vec3 o : dirs)
      for (vec3 t : tangents)
        for (float a : {1e-3f, 1.0f})
          for (float T : {0.01f, 100.0f}) {
            color f = surface_bsdf_eval(i, o, t, vec3(0, 0, 1), a, T, 0.5f, 0.3f, color(0.3f),
                                        0.2f, color(0.2f), 0.5f, hor);
            ASSERT_TRUE(std::isfinite(f.x) && std::isfinite(f.y) && std::isfinite(f.z));
            ASSERT_GE(f.x, 0.0f);
          }
}

TEST(Visibility, HorizonInterpolationAndRamp) {
  float hor[LOOM_HORIZON_DIRS] = {0.0f, 0.5f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
  // Azimuth 22.5 deg lies halfway between bins 0 and 1: horizon sine 0.25.
  vec3 w = normalize(vec3(std::cos(M_PI / 8), std::sin(M_PI / 8), 0));
  EXPECT_NEAR(horizon_sine(w, hor), 0.25, 1e-5);
  vec3 above = normalize(vec3(float(std::cos(M_PI / 8)), float(std::sin(M_PI / 8)), 1.0f));
  EXPECT_FLOAT_EQ(horizon_visibility(above, hor), 1.0f);  // elevation 45 deg, sine .71 > .3
  vec3 low = vec3(0.8f * float(std::cos(M_PI / 4)), 0.8f * float(std::sin(M_PI / 4)), 0.2f);
  EXPECT_FLOAT_EQ(horizon_visibility(normalize(low), hor), 0.0f);  // below 0.5 - 0.05
  EXPECT_FLOAT_EQ(horizon_visibility(vec3(0, 0, -1), hor), 1.0f);
}

TEST(ClosureMapping, LutCoordinatesAreTheViewsAzimuthAboutTheTangent) {
  // x: the angle between V's and t's projections onto the cloth (t taken with t_z >= 0, the
  // LUT's convention), over pi, computed here from their dot product; y = cos theta_V; z the
  // slice coordinate of |t_z|. fold_unit against a wrap written out.
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> U(-1, 1);
  for (int k = 0; k < 2000; ++k) {
    const vec3 V = normalize(vec3(U(rng), U(rng), 0.05f + std::fabs(U(rng))));
    vec3 t = normalize(vec3(U(rng), U(rng), U(rng)));
    float x, y, z;
    surface_lut_coords(V, t, x, y, z);
    if (t.z < 0) t = -t;
    const double vl = std::hypot(V.x, V.y), tl = std::hypot(t.x, t.y);
    const double c = (double(V.x) * t.x + double(V.y) * t.y) / (vl * tl);
    EXPECT_NEAR(x, std::acos(std::clamp(c, -1.0, 1.0)) / M_PI, 2e-5) << k;
    EXPECT_FLOAT_EQ(y, V.z);
    EXPECT_NEAR(z, std::min(t.z / LOOM_LUT_TZ_MAX, 1.0) * (LOOM_LUT_SLICES - 1), 1e-5);
    const float a = 4 * U(rng);
    const float wrapped = a - 2 * std::round(a / 2);  // into [-1, 1]
    EXPECT_NEAR(fold_unit(a), std::fabs(wrapped), 1e-6) << a;
  }
}
