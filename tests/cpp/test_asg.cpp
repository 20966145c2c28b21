// ASG lobes (ray-wave supplement Eq. S.1, S.2) in the shared math, against independent
// computations: an orthonormal frame, brute-force quadrature of the integral over the sphere, and
// central differences of the value for the gradient.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "loom/render_tables.h"
#include "loom/shading.h"

namespace sh = loom::shading;

namespace {
/// Brute-force integral over the sphere in double: a fine (theta, phi) midpoint grid.
double sphere_integral(float tz, float pz, float pxy, float m1, float m2, float c, int n) {
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    double th = -M_PI / 2 + M_PI * (i + 0.5) / n;
    for (int j = 0; j < 2 * n; ++j) {
      double ph = -M_PI + M_PI * (j + 0.5) / n;
      sh::vec3 v{float(std::cos(th) * std::cos(ph)), float(std::cos(th) * std::sin(ph)),
                 float(std::sin(th))};
      sum += sh::asg_eval(tz, pz, pxy, m1, m2, c, v) * std::cos(th);
    }
  }
  return sum * (M_PI / n) * (M_PI / n);
}
}  // namespace

TEST(Asg, FrameIsOrthonormalAndRightHanded) {
  for (float tz : {-1.5f, -0.3f, 0.0f, 0.7f, 1.5707f})
    for (float pz : {-3.0f, 0.0f, 1.0f, 2.5f})
      for (float pxy : {0.0f, 0.4f, -2.0f}) {
        sh::vec3 x, y, z;
        sh::asg_frame(tz, pz, pxy, x, y, z);
        EXPECT_NEAR(sh::dot(x, x), 1, 1e-5);
        EXPECT_NEAR(sh::dot(y, y), 1, 1e-5);
        EXPECT_NEAR(sh::dot(z, z), 1, 1e-5);
        EXPECT_NEAR(sh::dot(x, y), 0, 1e-5);
        EXPECT_NEAR(sh::dot(x, z), 0, 1e-5);
        EXPECT_NEAR(sh::dot(y, z), 0, 1e-5);
        sh::vec3 xy = sh::cross(x, y);  // x0 x y0 = z for S.2, preserved by the rotation
        EXPECT_NEAR(sh::dot(xy, z), 1, 1e-5);
        // Eq. S.2's lobe centre from the angles.
        EXPECT_NEAR(z.z, std::sin(tz), 1e-6);
      }
}

TEST(Asg, ValueAtCentreAndAlongAxes) {
  const float tz = 0.3f, pz = 1.2f, pxy = 0.5f, m1 = 20, m2 = 5, c = 2;
  sh::vec3 x, y, z;
  sh::asg_frame(tz, pz, pxy, x, y, z);
  EXPECT_NEAR(sh::asg_eval(tz, pz, pxy, m1, m2, c, z), c, 1e-5);
  const float a = 0.2f;
  sh::vec3 vx = sh::normalize(z * std::cos(a) + x * std::sin(a));
  sh::vec3 vy = sh::normalize(z * std::cos(a) + y * std::sin(a));
  EXPECT_NEAR(sh::asg_eval(tz, pz, pxy, m1, m2, c, vx),
              c * std::cos(a) * std::exp(-m1 * std::sin(a) * std::sin(a)), 1e-5);
  EXPECT_NEAR(sh::asg_eval(tz, pz, pxy, m1, m2, c, vy),
              c * std::cos(a) * std::exp(-m2 * std::sin(a) * std::sin(a)), 1e-5);
  EXPECT_EQ(sh::asg_eval(tz, pz, pxy, m1, m2, c, -z), 0.0f);  // the max(v.z, 0) hemisphere
}

TEST(Asg, IntegralMatchesQuadratureInBothRegimes) {
  // Wide lobes (numerical path), the switch point, and sharp lobes (closed form).
  struct Case {
    float m1, m2;
  };
  for (Case k : {Case{0, 0}, Case{0.5f, 3}, Case{2, 15}, Case{15.9f, 16.1f}, Case{16, 40},
                 Case{100, 300}, Case{800, 900},
                 // Very anisotropic lobes, as the fits produce them (one mu near 0).
                 Case{0, 3000}, Case{3000, 0}, Case{0.5f, 800}, Case{3, 200}, Case{1e-3f, 60},
                 Case{15, 5000}, Case{0, 36}, Case{0.1f, 16}}) {
    double ref = sphere_integral(0.4f, -0.7f, 1.1f, k.m1, k.m2, 1.5f, 1200);
    double got = sh::asg_integral(k.m1, k.m2, 1.5f);
    EXPECT_NEAR(got / ref, 1.0, 2e-3) << "mu " << k.m1 << ", " << k.m2 << ": " << got << " vs "
                                      << ref;
  }
  // Limits: mu = 0 is a clamped cosine lobe (integral pi c); c <= 0 and NaN give 0.
  EXPECT_NEAR(sh::asg_integral(0, 0, 1), M_PI, 1e-5);
  EXPECT_EQ(sh::asg_integral(10, 10, 0), 0.0f);
  EXPECT_EQ(sh::asg_integral(10, 10, NAN), 0.0f);
  EXPECT_TRUE(std::isfinite(sh::asg_integral(1e9f, 1e-9f, 1)));
  EXPECT_TRUE(std::isfinite(sh::asg_integral(0, 1e30f, 1)));
}

// What the shaders take for a lobe's integral: the baked LUT (render_tables.h), read bilinearly
// at asg_integral_lut_uv as Blender's Image Texture reads it, through asg_integral_from_lut,
// against the quadrature of asg_integral (itself checked against the sphere above) over
// bandwidths from 0 to the clamp, log-uniform, with a third of them in the numerical regime.
TEST(Asg, IntegralFromTheLutMatchesTheQuadrature) {
  const loom::Image lut = loom::asg_integral_lut_image();
  ASSERT_EQ(lut.width, LOOM_ASG_INTEGRAL_LUT_SIZE);
  auto bilinear = [&](float s, float tv) {  // Image Texture, Linear, EXTEND
    const int S = lut.width;
    const float px = std::clamp(s * S - 0.5f, 0.0f, float(S - 1));
    const float py = std::clamp(tv * S - 0.5f, 0.0f, float(S - 1));
    const int x0 = int(px), y0 = int(py), x1 = std::min(x0 + 1, S - 1), y1 = std::min(y0 + 1, S - 1);
    const float fx = px - float(x0), fy = py - float(y0);
    return (lut.px(x0, y0)[0] * (1 - fx) + lut.px(x1, y0)[0] * fx) * (1 - fy) +
           (lut.px(x0, y1)[0] * (1 - fx) + lut.px(x1, y1)[0] * fx) * fy;
  };
  std::mt19937 g(11);
  std::uniform_real_distribution<double> u(0, 1);
  const double top = std::log1p(double(LOOM_ASG_MU_MAX));
  double worst = 0, sum = 0;
  const int n = 20000;
  for (int it = 0; it < n; ++it) {
    const float m1 = float(u(g) < 0.3 ? 30 * u(g) : std::expm1(top * u(g)));
    const float m2 = float(std::expm1(top * u(g)));
    float s, tv;
    sh::asg_integral_lut_uv(m1, m2, s, tv);
    const double got = sh::asg_integral_from_lut(bilinear(s, tv), m1, m2, 1.5f);
    const double want = sh::asg_integral(m1, m2, 1.5f);
    const double e = std::fabs(got / want - 1);
    worst = std::max(worst, e);
    sum += e;
    EXPECT_LT(e, 5e-3) << "mu " << m1 << ", " << m2;
  }
  EXPECT_LT(sum / n, 1e-3);  // measured: mean 2.3e-4, worst 2.4e-3 (at the closed form's switch)
  // c <= 0 and NaN give 0, as asg_integral does.
  EXPECT_EQ(sh::asg_integral_from_lut(1.0f, 10, 10, 0), 0.0f);
  EXPECT_EQ(sh::asg_integral_from_lut(1.0f, 10, 10, NAN), 0.0f);
}

TEST(Asg, GradientMatchesCentralDifferences) {
  const float q[6] = {0.35f, -0.8f, 0.6f, 12.0f, 4.0f, 1.3f};
  for (sh::vec3 v : {sh::normalize(sh::vec3(0.5f, -0.4f, 0.6f)),
                     sh::normalize(sh::vec3(0.2f, -0.9f, 0.1f)),
                     sh::normalize(sh::vec3(0.6f, -0.7f, 0.5f))}) {
    sh::vec3 ga, gs;
    float val = sh::asg_eval_grad(q[0], q[1], q[2], q[3], q[4], q[5], v, ga, gs);
    ASSERT_NEAR(val, sh::asg_eval(q[0], q[1], q[2], q[3], q[4], q[5], v), 1e-6);
    ASSERT_GT(val, 1e-4f);  // a direction where the lobe is not negligible
    const float g[6] = {ga.x, ga.y, ga.z, gs.x, gs.y, gs.z};
    for (int i = 0; i < 6; ++i) {
      // Central differences in double through the float function: step large enough for float.
      double hstep = i < 3 ? 1e-3 : (i < 5 ? 1e-2 : 1e-3);
      float qp[6], qm[6];
      for (int j = 0; j < 6; ++j) qp[j] = qm[j] = q[j];
      qp[i] += float(hstep), qm[i] -= float(hstep);
      double fd = (double(sh::asg_eval(qp[0], qp[1], qp[2], qp[3], qp[4], qp[5], v)) -
                   sh::asg_eval(qm[0], qm[1], qm[2], qm[3], qm[4], qm[5], v)) /
                  (double(qp[i]) - double(qm[i]));
      EXPECT_NEAR(g[i], fd, 2e-3 * std::max(1.0, std::fabs(fd))) << "parameter " << i;
    }
  }
}
