// Speckle noise tiles (Eq. S.37, S.38) and the shared look-up math (S.40, the ply-ID hash):
// statistics against what the PSD predicts, seamless tiling in phi, the prefilter's smoothing
// towards the poles, determinism.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "loom/shading.h"
#include "loom/speckle_noise.h"

namespace {

namespace sh = loom::shading;
constexpr double kPi = 3.14159265358979323846;

struct Moments {
  double mean = 0, var = 0;
};

/// Mean and variance of band c over the rows whose theta (row centre) satisfies `keep`, over
/// every instance.
template <class Keep>
Moments moments(const loom::Image& t, int H, int c, Keep keep) {
  double s = 0, s2 = 0, n = 0;
  for (int y = 0; y < t.height; ++y) {
    const double theta = -0.5 * kPi + ((y % H) + 0.5) * kPi / H;
    if (!keep(theta)) continue;
    for (int x = 0; x < t.width; ++x) {
      const double v = t.px(x, y)[c];
      s += v, s2 += v * v, n += 1;
    }
  }
  return {s / n, s2 / n - (s / n) * (s / n)};
}

TEST(SpeckleNoise, UnfilteredTileHasUnitMeanAndExponentialVariance) {
  // N = |c|^2 with c circular complex Gaussian, E|c|^2 = 1: N ~ Exp(1), mean 1 and variance 1
  // at every point (S.38). Tolerances are 4 standard errors: with grains of correlation width
  // sigma_g = lambda / (sqrt 2 pi w) about 2600 independent grains per instance here, so the
  // mean is good to +-0.014 and the variance (kurtosis 9) to +-0.04 per estimate.
  const loom::NoiseSettings s{128, 2};
  const auto t = loom::speckle_noise_tile(s, 5.0, 42, false);
  ASSERT_EQ(t.width, 256);
  ASSERT_EQ(t.height, 256);
  for (int c = 0; c < 3; ++c) {
    const auto m = moments(t, 128, c, [](double) { return true; });
    EXPECT_NEAR(m.mean, 1.0, 0.06) << "band " << c;
    EXPECT_NEAR(m.var, 1.0, 0.17) << "band " << c;
  }
  for (float v : t.data) ASSERT_TRUE(std::isfinite(v) && v >= 0);
}

TEST(SpeckleNoise, GrainSizeFollowsThePsdAndScalesWithWavelength) {
  // The field's correlation is the Fourier transform of the PSD: for P_1D = exp(-2 (l f / w)^2)
  // N's correlation at lag d is exp(-d^2 / (2 sigma_g^2)). One texel is pi / 128 rad.
  const loom::NoiseSettings s{128, 2};
  const double w = 5.0;
  const auto t = loom::speckle_noise_tile(s, w, 7, false);
  const double d = kPi / 128;
  for (int c = 0; c < 3; ++c) {
    // Lag-one correlation in theta (the unfiltered field is isotropic), over the whole tile.
    double s0 = 0, s1 = 0, n = 0;
    for (int inst = 0; inst < 2; ++inst)
      for (int y = inst * 128; y < inst * 128 + 127; ++y)
        for (int x = 0; x < t.width; ++x) {
          const double a = t.px(x, y)[c] - 1.0, b = t.px(x, y + 1)[c] - 1.0;
          s0 += a * a, s1 += a * b, n += 1;
        }
    const double measured = s1 / s0;
    const double sg = loom::speckle_grain_sigma(loom::kNoiseBandsNm[size_t(c)] * 1e-3, w);
    const double predicted = std::exp(-d * d / (2 * sg * sg));
    EXPECT_NEAR(measured, predicted, 0.06) << "band " << loom::kNoiseBandsNm[size_t(c)] << " nm";
  }
}

TEST(SpeckleNoise, PrefilterSmoothsTowardsThePolesAsPredicted) {
  // Blurring N (correlation width sigma_g) in phi with sigma_g |tan theta| leaves the mean at 1
  // and the variance at 1 / sqrt(1 + 2 tan^2 theta) (Gaussian correlation and kernel).
  const loom::NoiseSettings s{128, 4};
  const double w = 5.0;
  const auto t = loom::speckle_noise_tile(s, w, 11, true);
  auto predicted = [&](double lo, double hi) {
    double sum = 0, n = 0;
    for (int k = 0; k < 128; ++k) {
      const double th = -0.5 * kPi + (k + 0.5) * kPi / 128;
      if (std::fabs(th) < lo || std::fabs(th) >= hi) continue;
      sum += 1 / std::sqrt(1 + 2 * std::tan(th) * std::tan(th)), n += 1;
    }
    return sum / n;
  };
  const double deg = kPi / 180;
  for (int c = 0; c < 3; ++c) {
    const auto eq = moments(t, 128, c, [&](double th) { return std::fabs(th) < 15 * deg; });
    const auto mid = moments(t, 128, c, [&](double th) {
      return std::fabs(th) >= 55 * deg && std::fabs(th) < 65 * deg;
    });
    const auto pole = moments(t, 128, c, [&](double th) { return std::fabs(th) >= 80 * deg; });
    EXPECT_NEAR(eq.mean, 1.0, 0.05);
    EXPECT_NEAR(mid.mean, 1.0, 0.05);
    EXPECT_NEAR(pole.mean, 1.0, 0.05);
    EXPECT_NEAR(eq.var, predicted(0, 15 * deg), 0.12) << "band " << c;
    EXPECT_NEAR(mid.var, predicted(55 * deg, 65 * deg), 0.08) << "band " << c;
    EXPECT_LT(pole.var, 0.25) << "band " << c;
    EXPECT_GT(eq.var, 2 * mid.var);
  }
}

TEST(SpeckleNoise, SeamlessInPhiAndDeterministic) {
  const loom::NoiseSettings s{64, 1};
  const auto a = loom::speckle_noise_tile(s, 10.0, 3);
  const auto b = loom::speckle_noise_tile(s, 10.0, 3);
  const auto c = loom::speckle_noise_tile(s, 10.0, 4);
  EXPECT_EQ(a.data, b.data);
  EXPECT_NE(a.data, c.data);
  // The step across the seam (last column to the first) is like any other step in phi.
  for (int band = 0; band < 3; ++band) {
    double seam = 0, inner = 0;
    for (int y = 0; y < a.height; ++y) {
      seam += std::fabs(a.px(0, y)[band] - a.px(a.width - 1, y)[band]);
      for (int x = 0; x + 1 < a.width; ++x)
        inner += std::fabs(a.px(x + 1, y)[band] - a.px(x, y)[band]);
    }
    inner /= (a.width - 1);
    EXPECT_GT(seam, 0.7 * inner);
    EXPECT_LT(seam, 1.4 * inner);
  }
}

TEST(SpeckleNoise, MemoryEffectDirectionKeepsTheHalfVector) {
  // S.40: the half vector of (w_i^n, w'_o) equals that of (w_i, w_o).
  std::mt19937 rng(5);
  std::normal_distribution<float> g;
  const sh::vec3 n(0, 1, 0);
  int checked = 0;
  for (int k = 0; k < 2000; ++k) {
    const sh::vec3 wi = sh::normalize(sh::vec3(g(rng), g(rng), g(rng)));
    const sh::vec3 wo = sh::normalize(sh::vec3(g(rng), g(rng), g(rng)));
    const sh::vec3 H = sh::normalize(wi + wo);
    const sh::vec3 w2 = sh::noise_memory_effect_direction(wi, wo);
    EXPECT_NEAR(sh::length(w2), 1.0f, 1e-4f);
    if (sh::dot(n, H) <= 0.05f) continue;
    const sh::vec3 H2 = sh::normalize(n + w2);
    EXPECT_NEAR(sh::dot(H, H2), 1.0f, 1e-4f);
    ++checked;
  }
  EXPECT_GT(checked, 500);
  // At theta_i = 0 (w_i = w_i^n) the look-up is w_o itself.
  const sh::vec3 wo = sh::normalize(sh::vec3(0.3f, 0.5f, -0.2f));
  const sh::vec3 w2 = sh::noise_memory_effect_direction(n, wo);
  EXPECT_NEAR(w2.x, wo.x, 1e-5f);
  EXPECT_NEAR(w2.y, wo.y, 1e-5f);
  EXPECT_NEAR(w2.z, wo.z, 1e-5f);
  // No half vector: w_o.
  const sh::vec3 w3 = sh::noise_memory_effect_direction(-wo, wo);
  EXPECT_NEAR(w3.x, wo.x, 1e-5f);
}

TEST(SpeckleNoise, PlyHashIsExactUniformAndCoordinatesWrap) {
  // The hash runs in float on integers below 2^24, so it must equal the same recurrence in
  // double precision (which would differ at the first rounding).
  auto round_d = [](double x, double a, double c) {
    return std::fmod(a * std::fmod(x, 65521.0) + c, 65521.0);
  };
  int bins[16] = {0};
  for (int id = 0; id < 4096; id += 3)
    for (int seg = 0; seg < 64; ++seg) {
      const float pid = float(id) / 4096.0f;
      const float h = sh::noise_hash(pid, float(seg));
      ASSERT_GE(h, 0.0f);
      ASSERT_LT(h, 1.0f);
      const double a = std::floor(double(std::clamp(pid, 0.0f, 1.0f) * 4095.0f));
      double r = round_d(a * 16 + std::fmod(seg, 16.0), 251, 17);
      r = round_d(r + std::floor(seg / 16.0) * 97, 223, 41);
      r = round_d(r, 199, 7);
      r = round_d(r, 241, 113);
      ASSERT_EQ(double(h), double(float(r / 65521.0))) << id << " " << seg;
      ++bins[int(h * 16)];
    }
  // Chi-square over 16 bins (15 degrees of freedom; 99.9 % quantile 37.7).
  double n = 0;
  for (int b : bins) n += b;
  double chi2 = 0;
  for (int b : bins) chi2 += (b - n / 16) * (b - n / 16) / (n / 16);
  EXPECT_LT(chi2, 37.7);
  // Coordinates: phi = 0 at u = 0.5, theta = 0 in the middle of an instance; a full-turn shift
  // wraps; NaN directions stay inside the tile.
  float u = 0, v = 0;
  sh::noise_tile_uv(sh::vec3(1, 0, 0), 0.0f, 1, 2, u, v);
  EXPECT_NEAR(u, 0.5f, 1e-6f);
  EXPECT_NEAR(v, 0.75f, 1e-6f);
  sh::noise_tile_uv(sh::vec3(1, 0, 0), 0.75f, 0, 1, u, v);
  EXPECT_NEAR(u, 0.25f, 1e-6f);
  sh::noise_tile_uv(sh::vec3(NAN, 0, 1), 0.0f, 0, 1, u, v);
  EXPECT_TRUE(u >= 0 && u <= 1 && v >= 0 && v <= 1);
}

}  // namespace
