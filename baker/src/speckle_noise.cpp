#include "loom/speckle_noise.h"

#include "loom/shading.h"

#include <fftw3.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <mutex>
#include <stdexcept>

namespace loom {

namespace {

constexpr double kPi = 3.14159265358979323846;

/// The FFTW planner is not thread-safe (executing a plan is).
std::mutex& fftw_planner_mutex() {
  static std::mutex m;
  return m;
}

uint64_t splitmix64(uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

/// A standard complex normal (E|z|^2 = 1) from a counter: Box-Muller on two hashed uniforms.
std::complex<double> complex_normal(uint64_t seed, uint64_t index) {
  const uint64_t a = splitmix64(seed ^ splitmix64(2 * index));
  const uint64_t b = splitmix64(seed ^ splitmix64(2 * index + 1));
  const double u1 = (double(a >> 11) + 0.5) * 0x1.0p-53, u2 = double(b >> 11) * 0x1.0p-53;
  const double r = std::sqrt(-std::log(u1));  // |z|^2 ~ Exp(1)
  return std::polar(r, 2 * kPi * u2);
}

struct FftwPlan {
  fftw_plan plan = nullptr;
  ~FftwPlan() {
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    if (plan) fftw_destroy_plan(plan);
  }
};

}  // namespace

NoiseSettings noise_settings(Quality q) {
  switch (q) {
    case Quality::Draft: return {64, 1};
    case Quality::Preview: return {128, 2};
    case Quality::Final: return {256, 2};
    case Quality::Reference: return {512, 4};
  }
  return {};
}

double speckle_psd_1d(double lambda_um, double f, double w_um) {
  const double t = lambda_um * f / w_um;
  return std::exp(-2 * t * t);
}

double speckle_grain_sigma(double lambda_um, double w_um) {
  return lambda_um / (std::sqrt(2.0) * kPi * w_um);
}

Image speckle_noise_tile(const NoiseSettings& s, double w_um, uint64_t seed, bool prefilter) {
  const int H = s.theta_count, W = 2 * s.theta_count;
  if (H < 4 || s.instances < 1 || !(w_um > 0))
    throw std::invalid_argument("speckle_noise_tile: theta_count >= 4, instances >= 1, w > 0");
  Image out(W, H * s.instances, 3);
  // Grid: theta rows of pitch pi / H, phi columns of pitch 2 pi / W (the same pitch): the tile
  // spans pi x 2 pi, so frequencies are k / pi and m / (2 pi) cycles per radian.
  const double dang = kPi / H;
  std::vector<std::complex<double>> buf(size_t(W) * H);
  FftwPlan plan2d, plan_row_f, plan_row_b;
  std::vector<std::complex<double>> row_tmp(static_cast<size_t>(W));
  {
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    auto* p = reinterpret_cast<fftw_complex*>(buf.data());
    plan2d.plan = fftw_plan_dft_2d(H, W, p, p, FFTW_BACKWARD, FFTW_ESTIMATE);
    auto* r = reinterpret_cast<fftw_complex*>(row_tmp.data());
    // Executed on other rows' buffers (fftw_execute_dft): planned without alignment assumptions.
    plan_row_f.plan = fftw_plan_dft_1d(W, r, r, FFTW_FORWARD, FFTW_ESTIMATE | FFTW_UNALIGNED);
    plan_row_b.plan = fftw_plan_dft_1d(W, r, r, FFTW_BACKWARD, FFTW_ESTIMATE | FFTW_UNALIGNED);
  }
  for (int inst = 0; inst < s.instances; ++inst)
    for (int band = 0; band < 3; ++band) {
      const double lambda_um = kNoiseBandsNm[size_t(band)] * 1e-3;
      // sqrt(P_2D) Z, P_2D normalised to sum 1 so that E|c|^2 = 1 after the unnormalised
      // inverse DFT (which sums the coefficients).
      double total = 0;
      for (int k = 0; k < H; ++k)
        for (int m = 0; m < W; ++m) {
          const int kk = k <= H / 2 ? k : k - H, mm = m <= W / 2 ? m : m - W;
          const double f = std::hypot(kk / kPi, mm / (2 * kPi));
          total += speckle_psd_1d(lambda_um, f, w_um);
        }
      for (int k = 0; k < H; ++k)
        for (int m = 0; m < W; ++m) {
          const int kk = k <= H / 2 ? k : k - H, mm = m <= W / 2 ? m : m - W;
          const double f = std::hypot(kk / kPi, mm / (2 * kPi));
          const double amp = std::sqrt(speckle_psd_1d(lambda_um, f, w_um) / total);
          // One Z for every band (same surface); a new one per instance.
          const uint64_t idx = (uint64_t(inst) * H + k) * W + m;
          buf[size_t(k) * W + m] = amp * complex_normal(seed, idx);
        }
      fftw_execute(plan2d.plan);
      std::vector<double> N(size_t(W) * H);
      for (size_t i = 0; i < N.size(); ++i) N[i] = std::norm(buf[i]);  // (r^2 + i^2) / 2
      if (prefilter) {
        const double sg = speckle_grain_sigma(lambda_um, w_um);
        tbb::parallel_for(0, H, [&](int k) {
          const double theta = -0.5 * kPi + (k + 0.5) * dang;
          const double sigma = sg * std::fabs(std::tan(theta)) / dang;  // in texels
          if (sigma < 1e-3) return;
          std::vector<std::complex<double>> row(static_cast<size_t>(W));
          for (int m = 0; m < W; ++m) row[size_t(m)] = N[size_t(k) * W + m];
          auto* r = reinterpret_cast<fftw_complex*>(row.data());
          fftw_execute_dft(plan_row_f.plan, r, r);
          for (int m = 0; m < W; ++m) {
            const double fm = double(m <= W / 2 ? m : m - W) / W;  // cycles per texel
            row[size_t(m)] *= std::exp(-2 * kPi * kPi * sigma * sigma * fm * fm) / W;
          }
          fftw_execute_dft(plan_row_b.plan, r, r);
          for (int m = 0; m < W; ++m) N[size_t(k) * W + m] = std::max(row[size_t(m)].real(), 0.0);
        });
      }
      for (int k = 0; k < H; ++k)
        for (int m = 0; m < W; ++m) out.px(m, inst * H + k)[band] = float(N[size_t(k) * W + m]);
    }
  return out;
}

Image speckle_noise_levels(const Image& tile, const NoiseSettings& s) {
  const int H = s.theta_count, W = 2 * s.theta_count, I = s.instances, K = LOOM_NOISE_LEVELS;
  if (tile.width != W || tile.height != H * I || tile.channels != 3)
    throw std::invalid_argument("speckle_noise_levels: the tile does not have the settings' size");
  Image out(W, H * I * K, 3);
  std::copy(tile.data.begin(), tile.data.end(), out.data.begin());  // level 0
  const double dang = kPi / H;
  FftwPlan plan_f, plan_b;
  {
    std::vector<std::complex<double>> tmp(static_cast<size_t>(W));
    auto* r = reinterpret_cast<fftw_complex*>(tmp.data());
    std::lock_guard<std::mutex> lock(fftw_planner_mutex());
    plan_f.plan = fftw_plan_dft_1d(W, r, r, FFTW_FORWARD, FFTW_ESTIMATE | FFTW_UNALIGNED);
    plan_b.plan = fftw_plan_dft_1d(W, r, r, FFTW_BACKWARD, FFTW_ESTIMATE | FFTW_UNALIGNED);
  }
  for (int l = 1; l < K; ++l) {
    const double blur = shading::noise_level_blur(l);
    tbb::parallel_for(0, I * 3, [&](int job) {
      const int inst = job / 3, band = job % 3;
      std::vector<double> N(size_t(W) * H);
      for (int k = 0; k < H; ++k)
        for (int m = 0; m < W; ++m) N[size_t(k) * W + m] = tile.px(m, inst * H + k)[band];
      // phi: periodic, by the row's DFT times the Gaussian's transfer function.
      std::vector<std::complex<double>> row(static_cast<size_t>(W));
      auto* r = reinterpret_cast<fftw_complex*>(row.data());
      for (int k = 0; k < H; ++k) {
        const double theta = -0.5 * kPi + (k + 0.5) * dang;
        const double sigma = blur / (dang * std::max(std::cos(theta), 1e-3));  // texels
        for (int m = 0; m < W; ++m) row[size_t(m)] = N[size_t(k) * W + m];
        fftw_execute_dft(plan_f.plan, r, r);
        for (int m = 0; m < W; ++m) {
          const double fm = double(m <= W / 2 ? m : m - W) / W;
          row[size_t(m)] *= std::exp(-2 * kPi * kPi * sigma * sigma * fm * fm) / W;
        }
        fftw_execute_dft(plan_b.plan, r, r);
        for (int m = 0; m < W; ++m) N[size_t(k) * W + m] = row[size_t(m)].real();
      }
      // theta: a truncated Gaussian, edges clamped (the poles).
      const double st = blur / dang;
      const int rad = int(std::ceil(3 * st));
      std::vector<double> w(size_t(2 * rad + 1));
      double wsum = 0;
      for (int d = -rad; d <= rad; ++d) wsum += w[size_t(d + rad)] = std::exp(-0.5 * d * d / (st * st));
      for (int m = 0; m < W; ++m)
        for (int k = 0; k < H; ++k) {
          double acc = 0;
          for (int d = -rad; d <= rad; ++d)
            acc += w[size_t(d + rad)] * N[size_t(std::clamp(k + d, 0, H - 1)) * W + m];
          out.px(m, (l * I + inst) * H + k)[band] = float(std::max(acc / wsum, 0.0));
        }
    });
  }
  return out;
}

}  // namespace loom
