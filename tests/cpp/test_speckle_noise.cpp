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

namespace {

TEST(SpeckleNoise, LevelsAreTheTileBlurredOnTheSphere) {
  // Level 0 is the tile; level l, at a texel near the equator, equals an independent
  // brute-force Gaussian blur of the tile over the sphere (great-circle distances, texel solid
  // angles) with noise_level_blur(l); the levels keep the unit mean and lose contrast.
  // At the final preset's resolution (0.012 rad texels, grains 0.012 rad): the first level's
  // blur is about one texel.
  loom::NoiseSettings s;
  s.theta_count = 256;
  s.instances = 1;
  const loom::Image tile = loom::speckle_noise_tile(s, 10.0, 77);
  const loom::Image lv = loom::speckle_noise_levels(tile, s);
  const int H = s.theta_count, W = 2 * H;
  ASSERT_EQ(lv.height, H * LOOM_NOISE_LEVELS);
  for (size_t i = 0; i < tile.data.size(); ++i) ASSERT_EQ(lv.data[i], tile.data[i]);
  auto dir = [&](int m, int k) {
    const double th = -0.5 * kPi + (k + 0.5) * kPi / H, ph = -kPi + (m + 0.5) * 2 * kPi / W;
    return std::array<double, 3>{std::cos(th) * std::cos(ph), std::cos(th) * std::sin(ph),
                                 std::sin(th)};
  };
  double prev_var = 1e9;
  for (int l = 1; l < LOOM_NOISE_LEVELS; ++l) {
    const double sigma = sh::noise_level_blur(l);
    double worst = 0;
    for (int probe = 0; probe < 12; ++probe) {
      const int m = (probe * 37) % W, k = H / 2 - 4 + (probe * 5) % 8;  // |theta| < 0.25 rad
      const auto p = dir(m, k);
      double num = 0, den = 0;
      for (int kk = 0; kk < H; ++kk)
        for (int mm = 0; mm < W; ++mm) {
          const auto q = dir(mm, kk);
          const double c = std::clamp(p[0] * q[0] + p[1] * q[1] + p[2] * q[2], -1.0, 1.0);
          const double a = std::acos(c);
          if (a > 5 * sigma) continue;
          const double th = -0.5 * kPi + (kk + 0.5) * kPi / H;
          const double w = std::exp(-0.5 * a * a / (sigma * sigma)) * std::cos(th);
          num += w * tile.px(mm, kk)[1], den += w;
        }
      worst = std::max(worst, std::fabs(lv.px(m, l * H + k)[1] - num / den));
    }
    // Moments of level l's block (moments() walks every row of the image it is given).
    loom::Image block(W, H, 3);
    std::copy(lv.data.begin() + size_t(l) * W * H * 3, lv.data.begin() + size_t(l + 1) * W * H * 3,
              block.data.begin());
    const Moments b = moments(block, H, 1, [](double th) { return std::fabs(th) < 1.0; });
    std::printf("level %d (blur %.3f rad): worst difference to the sphere blur %.4f, mean %.3f, "
                "variance %.4f\n", l, sigma, worst, b.mean, b.var);
    EXPECT_LT(worst, 0.05);
    EXPECT_NEAR(b.mean, 1.0, 0.1);
    EXPECT_LT(b.var, prev_var);
    prev_var = b.var;
  }
}

TEST(SpeckleNoise, ALobeReadsTheLevelOfItsWidth) {
  // The levels' own blurs map to whole levels, the coordinate grows with the width, and the
  // look-up of a lobe lands in the two levels around it (v blocks of the stacked image).
  for (int l = 0; l < LOOM_NOISE_LEVELS; ++l)
    EXPECT_NEAR(sh::noise_level_coord(sh::noise_level_blur(l)), float(l), 1e-5) << l;
  float last = -1;
  for (float s = 0; s < 0.5f; s += 0.002f) {
    const float c = sh::noise_level_coord(s);
    EXPECT_GE(c, last);
    last = c;
  }
  EXPECT_EQ(sh::noise_level_coord(float(NAN)), float(LOOM_NOISE_LEVELS - 1));
  EXPECT_NEAR(sh::noise_lobe_sigma(50.0f, 50.0f), 0.1f, 1e-6);
  float u, v0, v1, t;
  const sh::vec3 z = sh::normalize(sh::vec3(0.3f, -0.8f, 0.2f)), wi(0, 1, 0);
  sh::noise_lobe_uv(z, wi, 0, 1e6f, 1e6f, 0, 0.0f, 2, u, v0, v1, t);  // sharp: level 0
  EXPECT_LT(v0, 1.0f / LOOM_NOISE_LEVELS);
  EXPECT_LT(t, 0.1f);
  sh::noise_lobe_uv(z, wi, 0, 1.0f, 1.0f, 1, 0.0f, 2, u, v0, v1, t);  // broad: the top levels
  EXPECT_GT(v1, float(LOOM_NOISE_LEVELS - 1) / LOOM_NOISE_LEVELS);
  EXPECT_NEAR(t, 1.0f, 1e-6);
  // f_refl lobes read at the memory-effect direction: at normal incidence that is the centre.
  float ur, vr0, vr1, tr, uh, vh0, vh1, th;
  sh::noise_lobe_uv(z, wi, 1, 200.0f, 200.0f, 0, 0.25f, 1, ur, vr0, vr1, tr);
  sh::noise_lobe_uv(sh::noise_memory_effect_direction(wi, z), wi, 0, 200.0f, 200.0f, 0, 0.25f, 1,
                    uh, vh0, vh1, th);
  EXPECT_EQ(ur, uh);
  EXPECT_EQ(vr0, vh0);
  // The pick is one of the instances and a rotation in [0, 1).
  int inst;
  float shift;
  for (float id : {0.0f, 0.37f, 0.999f}) {
    sh::noise_pick(id, 0.6f, 3, inst, shift);
    EXPECT_GE(inst, 0);
    EXPECT_LT(inst, 3);
    EXPECT_GE(shift, 0.0f);
    EXPECT_LT(shift, 1.0f);
  }
}

}  // namespace
