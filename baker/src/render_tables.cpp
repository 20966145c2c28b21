// The render tables of a ray-wave atlas (render_tables.h): what the shaders read at the yarn
// colours, computed by the bake from the colour-independent tables.
#include "loom/render_tables.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <tbb/parallel_for.h>

#include "loom/asg_residual.h"
#include "loom/cycles_closures.h"

namespace loom {

using namespace shading;

/// The per-point double-layer factors of double_layer_factors.h from Eq. S.20's tabulated
/// values: k_b = (B_total - B_t) / F_t >= 0 and k_f = F_total / F_t, with k_b + k_f <= 1 (both
/// scaled down to sum 1 where interpolation or the simulation's noise would give more: Eq. S.20
/// gives F_tb / (1 - B_tb), at most 1 for a bottom layer that conserves energy); 0 and 1 (one
/// layer) where F_t vanishes or a value is not finite.
void layer_factor_pair(const DoubleLayerFactors& f, float& kb, float& kf) {
  kb = 0.0f;
  kf = 1.0f;
  if (!(f.Ft > 1e-6) || !std::isfinite(f.Bt) || !std::isfinite(f.Btotal) ||
      !std::isfinite(f.Ftotal) || !std::isfinite(f.Ft))
    return;
  double b = std::max((f.Btotal - f.Bt) / f.Ft, 0.0), t = std::max(f.Ftotal / f.Ft, 0.0);
  if (b + t > 1) {
    const double sum = b + t;
    b /= sum;
    t /= sum;
  }
  kb = float(b);
  kf = float(t);
}

Image ply_residual_rgb_image(const AsgTable& high, const AsgTable& refl,
                             const std::array<double, 3>& sigma_rgb) {
  const int M = int(high.theta_i.size()), N = int(high.h.size());
  if (refl.theta_i.size() != size_t(M) || refl.h.size() != size_t(N))
    throw std::invalid_argument("ply_residual_rgb_image: f_high and f_refl grids differ");
  Image img(2 * N, M, 3);
  for (int m = 0; m < M; ++m)
    for (int n = 0; n < N; ++n)
      for (int c = 0; c < 3; ++c) {
        double hb, hf, rb, rf;
        asg_residual_at(high, high.theta_i[size_t(m)], high.h[size_t(n)], sigma_rgb[size_t(c)], hb,
                        hf);
        asg_residual_at(refl, high.theta_i[size_t(m)], high.h[size_t(n)], 0.0, rb, rf);
        img.px(n, m)[c] = float(hb + rb);
        img.px(N + n, m)[c] = float(hf + rf);
      }
  return img;
}

Image ply_tint_image(const AsgTable& high, const std::array<double, 3>& sigma_rgb) {
  const int rows = high.node_rows(), cols = high.node_cols(), L = high.lobes,
            K = int(high.sigmas.size());
  Image img(L * cols, rows, 3);
  for (int c = 0; c < 3; ++c) {
    int k;
    double t;
    sigma_interval(high.sigmas, sigma_rgb[size_t(c)], high.absorption, k, t);
    for (int i = 0; i < rows; ++i)
      for (int j = 0; j < cols; ++j)
        for (int l = 0; l < L; ++l) {
          double s = 1;
          if (K > 1) s = (1 - t) * high.scale_at(k, i, j, l) + t * high.scale_at(k + 1, i, j, l);  // S.11
          img.px(l * cols + j, i)[c] = float(s);
        }
  }
  return img;
}

DoubleLayerFactors double_layer_at(const DoubleLayerGrid& g, const vec3& xi, double sigma) {
  const int T = g.theta_count, P = g.phi_count;
  const double theta = std::acos(std::clamp(double(xi.z), 0.0, 1.0)) * 180.0 / M_PI;
  double tf = std::clamp(theta * T / 90.0 - 0.5, 0.0, double(T - 1));
  double phi = std::fabs(xi.x) + std::fabs(xi.y) > 1e-9 ? std::atan2(xi.y, xi.x) * 180 / M_PI : 0;
  if (!std::isfinite(tf)) tf = 0;
  if (!std::isfinite(phi)) phi = 0;
  if (phi < 0) phi += 360;
  double pf = phi * P / 360.0 - 0.5;
  int t0 = int(std::floor(tf)), p0 = int(std::floor(pf));
  const double ft = tf - t0, fp = pf - p0;
  const int t1 = std::min(t0 + 1, T - 1);
  auto wrap = [P](int p) { return ((p % P) + P) % P; };
  const int pa = wrap(p0), pb = wrap(p0 + 1);
  int k;
  double st;
  sigma_interval(g.sigmas, sigma, g.absorption, k, st);
  const int K = int(g.sigmas.size());
  double v[4] = {0, 0, 0, 0};
  for (int kk = 0; kk < (K > 1 ? 2 : 1); ++kk) {
    const double wk = K > 1 ? (kk == 0 ? 1 - st : st) : 1.0;
    const int level = std::min(k + kk, K - 1);
    auto at = [&](int t, int p) { return g.table.px(p, level * T + t); };
    for (int c = 0; c < 4; ++c) {
      double a = at(t0, pa)[c] * (1 - fp) + at(t0, pb)[c] * fp;
      double b = at(t1, pa)[c] * (1 - fp) + at(t1, pb)[c] * fp;
      v[c] += wk * (a * (1 - ft) + b * ft);
    }
  }
  DoubleLayerFactors f;
  f.Bt = v[0], f.Ft = v[1], f.Btotal = v[2], f.Ftotal = v[3];
  return f;
}

Image layer_factors_image(const DoubleLayerGrid& g, const std::array<double, 3>& sigma_rgb) {
  const int T = g.theta_count, P = g.phi_count, W = P + 2;
  Image img(LOOM_DOUBLE_LAYER_BLOCKS * W, T, 3);
  for (int t = 0; t < T; ++t)
    for (int col = 0; col < W; ++col) {
      const int p = ((col - 1) % P + P) % P;
      const double th = (t + 0.5) * 90.0 / T * M_PI / 180, ph = (p + 0.5) * 360.0 / P * M_PI / 180;
      const vec3 xi(float(std::sin(th) * std::cos(ph)), float(std::sin(th) * std::sin(ph)),
                    float(std::cos(th)));
      for (int c = 0; c < 3; ++c) {
        float kb, kf;
        layer_factor_pair(double_layer_at(g, xi, sigma_rgb[size_t(c)]), kb, kf);
        img.px(col, t)[c] = kb;
        img.px(W + col, t)[c] = kf;
      }
    }
  return img;
}

Image asg_integral_lut_image() {
  const int S = LOOM_ASG_INTEGRAL_LUT_SIZE;
  Image img(S, S, 1);
  const double top = std::log1p(double(LOOM_ASG_MU_MAX));
  for (int r = 0; r < S; ++r)
    for (int i = 0; i < S; ++i) {
      // The bandwidths at the texel centres (asg_integral_lut_uv inverted).
      const double mu1 = std::expm1(top * i / (S - 1)), mu2 = std::expm1(top * r / (S - 1));
      img.px(i, r)[0] = float(asg_integral(float(mu1), float(mu2), 1.0f) *
                              std::sqrt((1 + mu1) * (1 + mu2)) / M_PI);
    }
  return img;
}

Image microfacet_albedo_image(int n) {
  const int S = LOOM_MICROFACET_ALBEDO_SIZE;
  Image img(S, S, 3);
  const vec3 N(0, 0, 1), T(1, 0, 0);
  const float eta = LOOM_RAYWAVE_ETA;
  tbb::parallel_for(0, S * S, [&](int idx) {
    const int i = idx % S, r = idx / S;
    const double cv = std::max(double(i) / (S - 1), 1e-3);
    const double sq = double(r) / (S - 1);
    const double a = std::max(sq * sq, double(LOOM_RAYWAVE_MIN_ALPHA));
    const vec3 V(float(std::sqrt(1 - cv * cv)), 0, float(cv));
    const cycles::MicrofacetReflection refl(N, T, float(a), float(a), N, V,
                                            cycles::Distribution::Beckmann);
    const cycles::MicrofacetRefraction refr(N, float(a), eta, N, V, cycles::Distribution::Beckmann);
    // Half vectors distributed as D(H) cos(theta_h) (midpoint rule in the sampling variables):
    // E = int eval(L) dL = int eval(L) |dL/dH| / (D(H) cos theta_h) (D cos theta_h dH), with
    // |dL/dH| = 4 (H.V) for reflection.
    double sum_r = 0, sum_t = 0;
    for (int u = 0; u < n; ++u)
      for (int w = 0; w < 4 * n; ++w) {
        const double x1 = (u + 0.5) / n, x2 = (w + 0.5) / (4.0 * n);
        const double th = std::atan(a * std::sqrt(-std::log(1 - x1))), ph = 2 * M_PI * x2;
        const double ct = std::cos(th), tt = std::tan(th);
        const vec3 H(float(std::sin(th) * std::cos(ph)), float(std::sin(th) * std::sin(ph)),
                     float(ct));
        const double hv = dot(H, V);
        const double D = std::exp(-tt * tt / (a * a)) / (M_PI * a * a * std::pow(ct, 4));
        if (hv > 0) sum_r += refl.eval(H * float(2 * hv) - V) * 4 * hv / (D * ct);
        // Refraction: Cycles evaluates every L below the surface through its half vector
        // H = -(eta L + V) / m, also where H.V < 0 (no validity check), and its D depends on
        // cos^2(N, H) only; so every H on the sphere maps to one L = -(m H + V) / eta with
        // m = -H.V + sqrt((H.V)^2 + eta^2 - 1), and |dL/dH| = m^2 / (eta^2 |H.L|).
        for (const vec3& Hr : {H, vec3(H.x, H.y, -H.z)}) {
          const double ci = dot(Hr, V);
          const double m = -ci + std::sqrt(ci * ci + double(eta) * eta - 1);
          const vec3 Lt = (Hr * float(m) + V) * (-1 / eta);
          const double hl = std::fabs(dot(Hr, Lt));
          if (hl < 1e-9) continue;
          sum_t += refr.eval(Lt) * (m * m / (double(eta) * eta * hl)) / (D * ct);
        }
      }
    img.px(i, r)[0] = float(sum_r / (double(n) * 4 * n));
    img.px(i, r)[1] = float(sum_t / (double(n) * 4 * n));
  });
  return img;
}

}  // namespace loom
