#include "loom/diffraction_tables.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "loom/aperture_diffraction.h"
#include "loom/shading.h"

#include <stdexcept>

namespace loom {

DiffractionSettings diffraction_settings(Quality q) {
  switch (q) {
    case Quality::Draft: return {32, 20.0, 3, 4};
    case Quality::Preview: return {48, 10.0, 4, 6};
    case Quality::Final: return {64, 5.0, 5, 8};
    case Quality::Reference: return {128, 2.0, 7, 12};
  }
  return {};
}

std::array<double, 2> gap_widths(const FabricSpec& spec) {
  // Weft yarns are stacked along x, warp yarns along y (ply_maps.cpp).
  return {1e4 / spec.weft_per_cm - spec.weft.yarn_diameter_um,
          1e4 / spec.warp_per_cm - spec.warp.yarn_diameter_um};
}

namespace {

/// Fills one tile: D_c(s) = sum_k w_c(lambda_k) |J_x|^2 |J_y|^2 / (lambda_k^2 P_beam), the
/// separable K of Eq. S.34 evaluated per axis and wavelength, then combined.
void fill_tile(DiffractionTable& t, int tile_x, int tile_y, const Aperture& A, double w0,
               const SpectralRgb& rgb) {
  const int N = t.size, L = int(rgb.lambda_nm.size());
  std::vector<double> X(size_t(L) * N), Y(size_t(L) * N);
  for (int k = 0; k < L; ++k) {
    const double lambda_um = rgb.lambda_nm[size_t(k)] * 1e-3;
    for (int u = 0; u < N; ++u) {
      const double s = shading::diffraction_table_s(float(u) / float(N - 1));
      X[size_t(k) * N + u] = std::norm(gaussian_window_integral(A.xw, A.xe, s / lambda_um, w0));
      Y[size_t(k) * N + u] = std::norm(gaussian_window_integral(A.ys, A.yn, s / lambda_um, w0));
    }
  }
  std::vector<std::array<double, 3>> wk(static_cast<size_t>(L));
  const double P = beam_power(w0);
  for (int k = 0; k < L; ++k) {
    const double lambda_um = rgb.lambda_nm[size_t(k)] * 1e-3;
    for (int c = 0; c < 3; ++c)
      wk[size_t(k)][c] = rgb.weight[size_t(k)][c] / (lambda_um * lambda_um * P);
  }
  for (int r = 0; r < N; ++r)
    for (int u = 0; u < N; ++u) {
      double acc[3] = {0, 0, 0};
      for (int k = 0; k < L; ++k) {
        const double v = X[size_t(k) * N + u] * Y[size_t(k) * N + r];
        for (int c = 0; c < 3; ++c) acc[c] += wk[size_t(k)][c] * v;
      }
      float* px = &t.rgb[(size_t(tile_y * N + r) * t.width() + size_t(tile_x * N + u)) * 3];
      // The working space's matching functions have negative lobes: a saturated fringe can
      // integrate below zero, which no closure weight can express. Clamped at 0.
      for (int c = 0; c < 3; ++c) px[c] = float(std::max(acc[c], 0.0));
    }
}

DiffractionTable make_table(int size, int tx, int ty) {
  DiffractionTable t;
  t.size = size, t.tiles_x = tx, t.tiles_y = ty;
  t.rgb.assign(size_t(t.width()) * t.height() * 3, 0.0f);
  return t;
}

}  // namespace

DiffractionTable diffraction_gap_table(double gx, double gy, double w0, const SpectralRgb& rgb,
                                       const DiffractionSettings& s) {
  const int n = std::max(s.gap_offsets, 1);
  DiffractionTable t = make_table(s.size, n, n);
  tbb::parallel_for(0, n * n, [&](int idx) {
    const int i = idx % n, j = idx / n;
    // Offsets spaced towards the edge (diffraction_sampling.h: diffraction_tile_coord).
    auto offset = [n](int k) {
      const double f = n > 1 ? 1.0 - double(k) / (n - 1) : 1.0;
      return 1.0 - f * f;
    };
    const double cx = offset(i) * 0.5 * gx, cy = offset(j) * 0.5 * gy;
    const Aperture A{-0.5 * gx - cx, 0.5 * gx - cx, -0.5 * gy - cy, 0.5 * gy - cy};
    fill_tile(t, i, j, A, w0, rgb);
  });
  return t;
}

DiffractionTable diffraction_edge_table(double w0, const SpectralRgb& rgb,
                                        const DiffractionSettings& s) {
  const int n = std::max(s.edge_tiles, 2);
  DiffractionTable t = make_table(s.size, n, 1);
  const double d_cut = LOOM_DIFFRACTION_DCUT_WAISTS * w0;
  tbb::parallel_for(0, n, [&](int j) {
    const double xw = double(j) / (n - 1) * d_cut;
    // R - |h| = x_w: any R with h = R - x_w gives the same aperture.
    fill_tile(t, j, 0, ply_edge_aperture(d_cut, d_cut - xw, d_cut), w0, rgb);
  });
  return t;
}

double DiffractionTable::at(int tile_x, int tile_y, double t_x, double t_y, int c) const {
  const int C = size - 1;
  const double fx = std::clamp(t_x, 0.0, 1.0) * C, fy = std::clamp(t_y, 0.0, 1.0) * C;
  const int ix = std::min(int(fx), C - 1), iy = std::min(int(fy), C - 1);
  const double ax = fx - ix, ay = fy - iy;
  const int x0 = tile_x * size + ix, y0 = tile_y * size + iy;
  return (px(x0, y0)[c] * (1 - ax) + px(x0 + 1, y0)[c] * ax) * (1 - ay) +
         (px(x0, y0 + 1)[c] * (1 - ax) + px(x0 + 1, y0 + 1)[c] * ax) * ay;
}

double diffraction_spot_radius(double w0_um) {
  const double sigma = 0.7 / (2 * M_PI * std::max(w0_um, 1e-6));
  return std::min(3 * sigma, 0.05);
}

DiffractionSampler diffraction_sampler(const DiffractionTable& t, int tx, int ty, int c,
                                       double spot_s, int sub) {
  const int N = t.size, C = N - 1, F = C * sub;
  DiffractionSampler out;
  out.cells = C, out.sub = sub;
  out.marginal.assign(size_t(F), 0.0);
  out.conditional.assign(size_t(C) * F, 0.0);
  const double dt = 1.0 / F;
  for (int jf = 0; jf < F; ++jf)
    for (int i_f = 0; i_f < F; ++i_f) {
      const double tcx = (i_f + 0.5) * dt, tcy = (jf + 0.5) * dt;
      const double d = t.at(tx, ty, tcx, tcy, c);  // the table at the sub-cell centre
      const double jac = (2 * LOOM_DIFFRACTION_S_MAX * tcx) * (2 * LOOM_DIFFRACTION_S_MAX * tcy);
      const double m = std::max(d, 0.0) * jac * dt * dt;
      const double sx = shading::diffraction_table_s(float(tcx));
      const double sy = shading::diffraction_table_s(float(tcy));
      if (sx * sx + sy * sy < spot_s * spot_s) {
        out.spot += m;
        continue;
      }
      out.outside += m;
      out.marginal[size_t(jf)] += m;
      out.conditional[size_t(jf / sub) * F + i_f] += m;
    }
  out.row_total.assign(size_t(C), 0.0);
  for (int j = 0; j < C; ++j)
    for (int i = 0; i < F; ++i) out.row_total[size_t(j)] += out.conditional[size_t(j) * F + i];
  return out;
}

double DiffractionSampler::density(double s_x, double s_y) const {
  if (!(outside > 0)) return 0;
  const double tx = std::sqrt(std::fabs(s_x) / LOOM_DIFFRACTION_S_MAX);
  const double ty = std::sqrt(std::fabs(s_y) / LOOM_DIFFRACTION_S_MAX);
  if (!(tx < 1 && ty < 1)) return 0;
  const int F = cells * sub;
  const int i = std::min(int(tx * F), F - 1), jf = std::min(int(ty * F), F - 1), j = jf / sub;
  const double row = row_total[size_t(j)];
  if (!(row > 0)) return 0;
  // p(t) = marginal(t_y) conditional_j(t_x), each a mass over its sub-cell width 1 / F.
  const double pt = (marginal[size_t(jf)] / outside * F) * (conditional[size_t(j) * F + i] / row * F);
  const double jac = (2 * LOOM_DIFFRACTION_S_MAX * tx) * (2 * LOOM_DIFFRACTION_S_MAX * ty);
  return jac > 0 ? 0.25 * pt / jac : 0.0;
}

namespace {

/// The parts [lo, hi] (|s| >= 0, table coordinates) of a signed interval of s, each with the
/// probability 1/2 of its sign.
int unsigned_parts(double a, double b, double lo[2], double hi[2]) {
  auto t = [](double s) { return std::min(std::sqrt(std::fabs(s) / LOOM_DIFFRACTION_S_MAX), 1.0); };
  if (a >= 0) return lo[0] = t(a), hi[0] = t(b), 1;
  if (b <= 0) return lo[0] = t(b), hi[0] = t(a), 1;
  lo[0] = 0, hi[0] = t(a), lo[1] = 0, hi[1] = t(b);
  return 2;
}

/// Mass of the piecewise uniform masses m[0 .. n) on cells [k, k + 1] / n between t0 and t1.
double uniform_mass(const double* m, int n, double t0, double t1) {
  double sum = 0;
  const int k0 = std::max(0, int(std::floor(t0 * n))), k1 = std::min(n - 1, int(std::floor(t1 * n)));
  for (int k = k0; k <= k1; ++k) {
    const double a = std::max(t0, double(k) / n), b = std::min(t1, double(k + 1) / n);
    if (b > a) sum += m[k] * (b - a) * n;
  }
  return sum;
}

}  // namespace

double DiffractionSampler::probability(double sx0, double sx1, double sy0, double sy1) const {
  if (!(outside > 0) || !(sx1 > sx0) || !(sy1 > sy0)) return 0;
  const int F = cells * sub;
  double xl[2], xh[2], yl[2], yh[2];
  const int nx = unsigned_parts(sx0, sx1, xl, xh), ny = unsigned_parts(sy0, sy1, yl, yh);
  double p = 0;
  for (int a = 0; a < ny; ++a) {
    const int k0 = std::max(0, int(std::floor(yl[a] * F))), k1 = std::min(F - 1, int(std::floor(yh[a] * F)));
    for (int jf = k0; jf <= k1; ++jf) {
      const double lo = std::max(yl[a], double(jf) / F), hi = std::min(yh[a], double(jf + 1) / F);
      const int j = jf / sub;
      if (!(hi > lo) || !(row_total[size_t(j)] > 0)) continue;
      double x = 0;
      for (int b = 0; b < nx; ++b) x += uniform_mass(&conditional[size_t(j) * F], F, xl[b], xh[b]);
      p += marginal[size_t(jf)] / outside * (hi - lo) * F * 0.5 * (x / row_total[size_t(j)] * 0.5);
    }
  }
  return p;
}

namespace {

/// Quantiles u = k / (n - 1) of the piecewise-uniform distribution of `mass` over cells
/// [i, i + 1] / cells, as positions in [0, 1]; uniform quantiles if the total is 0.
void inverse_cdf(const double* mass, int cells, int stride, int n, float* out, int out_stride) {
  std::vector<double> cdf(size_t(cells) + 1, 0.0);
  for (int i = 0; i < cells; ++i) cdf[size_t(i) + 1] = cdf[size_t(i)] + mass[size_t(i) * stride];
  const double total = cdf.back();
  int i = 0;
  for (int k = 0; k < n; ++k) {
    const double u = double(k) / (n - 1);
    double t = u;
    if (total > 0) {
      // Below the total, so that the cell found holds mass (also for u = 1 before empty cells).
      const double target = std::min(u, 1 - 1e-9) * total;
      while (i + 1 < cells && cdf[size_t(i) + 1] <= target) ++i;
      const double m = mass[size_t(i) * stride];
      const double f = m > 0 ? std::clamp((target - cdf[size_t(i)]) / m, 0.0, 1.0) : 0.5;
      t = (i + f) / cells;
    }
    out[size_t(k) * out_stride] = float(t);
  }
}

}  // namespace

DiffractionSampling diffraction_sampling_table(const DiffractionTable& gap, double spot_s) {
  const int N = gap.size, C = N - 1, K = LOOM_DIFFRACTION_ICDF_SIZE;
  DiffractionSampling out;
  out.width = K * gap.tiles_x;
  out.height = (N + 1) * gap.tiles_y;
  out.rgb.assign(size_t(out.width) * out.height * 3, 0.0f);
  out.p_out.assign(size_t(gap.tiles_x) * gap.tiles_y, {0, 0, 0});
  tbb::parallel_for(0, gap.tiles_x * gap.tiles_y * 3, [&](int idx) {
    const int c = idx % 3, tile = idx / 3, tx = tile % gap.tiles_x, ty = tile / gap.tiles_x;
    const DiffractionSampler d = diffraction_sampler(gap, tx, ty, c, spot_s);
    const int F = d.cells * d.sub;
    auto at = [&](int col, int row) {
      return &out.rgb[(size_t(ty * (N + 1) + row) * out.width + size_t(tx * K + col)) * 3 + c];
    };
    inverse_cdf(d.marginal.data(), F, 1, K, at(0, 0), 3);
    for (int j = 0; j < C; ++j) inverse_cdf(&d.conditional[size_t(j) * F], F, 1, K, at(0, 1 + j), 3);
    for (int k = 0; k < K; ++k) *at(k, N) = float(d.p_out());
    out.p_out[size_t(tile)][size_t(c)] = float(d.p_out());
  });
  return out;
}

DiffractionTable diffraction_table_from_rgb(int width, int height, const float* rgb, int size) {
  if (size < 2 || width % size != 0 || height % size != 0)
    throw std::runtime_error("diffraction table: the image does not tile by its tile size");
  DiffractionTable t = make_table(size, width / size, height / size);
  std::copy(rgb, rgb + size_t(width) * height * 3, t.rgb.begin());
  return t;
}

}  // namespace loom
