#include "loom/diffraction_tables.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "loom/aperture_diffraction.h"
#include "loom/shading.h"

namespace loom {

DiffractionSettings diffraction_settings(Quality q) {
  switch (q) {
    case Quality::Draft: return {32, 20.0, 2, 4};
    case Quality::Preview: return {48, 10.0, 3, 6};
    case Quality::Final: return {64, 5.0, 4, 8};
    case Quality::Reference: return {128, 2.0, 6, 12};
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
    const double cx = n > 1 ? double(i) / (n - 1) * 0.5 * gx : 0.0;
    const double cy = n > 1 ? double(j) / (n - 1) * 0.5 * gy : 0.0;
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

}  // namespace loom
