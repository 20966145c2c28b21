#include "loom/closure_lut.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace loom {

using namespace shading;
constexpr int N = LOOM_CLOSURE_LUT_SIZE;
constexpr int S = LOOM_LUT_SLICES;
constexpr int W = LOOM_LUT_PANELS * N;

void lut_configuration(int ix, int j, int slice, vec3& V, vec3& t) {
  float phi = float(ix) / (N - 1) * float(M_PI);
  float ct = std::max(float(j) / (N - 1), kLutMinCos), st = std::sqrt(1 - ct * ct);
  float tz = float(slice) / (S - 1) * float(LOOM_LUT_TZ_MAX);
  t = vec3(std::sqrt(1 - tz * tz), 0, tz);
  V = vec3(st * std::cos(phi), st * std::sin(phi), ct);
}

ClosureFitOptions closure_fit_options(Quality q) {
  ClosureFitOptions o;
  switch (q) {
    case Quality::Draft:
      o.n = 8, o.m = 12, o.max_iterations = 5, o.judge_n = 64, o.judge_m = 24;
      break;
    case Quality::Preview: o.n = 12, o.m = 16, o.max_iterations = 8; break;
    case Quality::Final: o.n = 16, o.m = 20, o.max_iterations = 10; break;
    case Quality::Reference: o.n = 24, o.m = 32, o.max_iterations = 25; break;
  }
  return o;
}

Image bake_closure_lut(const FabricSpec& spec, const ProgressFn& progress) {
  Image lut(W, 2 * S * N, 4);
  const ClosureFitOptions o = closure_fit_options(spec.quality);
  const float T = float(spec.optical_thickness);
  auto rows = [&](int kind) { return kind * S * N; };
  if (progress) progress("closure lut", 0.0);
  for (int kind = 0; kind < 2; ++kind) {
    const YarnSpec& y = kind == 0 ? spec.warp : spec.weft;
    const float a = sggx_fiber_roughness(float(y.roughness));
    if (kind == 1 && sggx_fiber_roughness(float(spec.warp.roughness)) == a) {
      // The same lobes as the warp's: the same fits.
      std::copy_n(lut.data.begin(), size_t(W) * size_t(S * N) * 4,
                  lut.data.begin() + ptrdiff_t(size_t(W) * size_t(rows(1)) * 4));
      break;
    }
    tbb::parallel_for(0, S * N * N, [&](int idx) {
      const int ix = idx % N, j = (idx / N) % N, slice = idx / (N * N);
      vec3 V, t;
      lut_configuration(ix, j, slice, V, t);
      const SpecularClosures p = fit_specular_closures(V, t, a, T, o).p;
      float* r = lut.px(ix, rows(kind) + slice * N + j);
      const float cap = kClosureLutMaxWeight;
      r[0] = std::min(p.ggx_w, cap), r[1] = p.ggx_ax, r[2] = p.ggx_ay, r[3] = 0;
      float* q = lut.px(N + ix, rows(kind) + slice * N + j);
      q[0] = std::min(p.ht_w, cap), q[1] = p.ht_r1, q[2] = p.ht_r2, q[3] = std::min(p.tl_w, cap);
    });
    if (progress) progress("closure lut", (kind + 1) / 2.0);
  }
  if (progress) progress("closure lut", 1.0);
  return lut;
}

void sample_closure_lut(const Image& lut, float kind, float x, float y, float z, int panel,
                        float out[4]) {
  float s0, s1, f;
  surface_lut_slices(z, s0, s1, f);
  float res[2][4];
  for (int k = 0; k < 2; ++k) {
    float u, v;
    surface_lut_uv(kind, x, y, k == 0 ? s0 : s1, float(panel), u, v);
    // Linear interpolation with texel centres at (i + 0.5) / size, clamped at the borders.
    float px = u * lut.width - 0.5f, py = v * lut.height - 0.5f;
    int x0 = std::clamp(int(std::floor(px)), 0, lut.width - 1);
    int y0 = std::clamp(int(std::floor(py)), 0, lut.height - 1);
    int x1 = std::min(x0 + 1, lut.width - 1), y1 = std::min(y0 + 1, lut.height - 1);
    float fx = std::clamp(px - x0, 0.0f, 1.0f), fy = std::clamp(py - y0, 0.0f, 1.0f);
    for (int c = 0; c < 4; ++c) {
      float a = lut.px(x0, y0)[c] * (1 - fx) + lut.px(x1, y0)[c] * fx;
      float b = lut.px(x0, y1)[c] * (1 - fx) + lut.px(x1, y1)[c] * fx;
      res[k][c] = a * (1 - fy) + b * fy;
    }
  }
  for (int c = 0; c < 4; ++c) out[c] = res[0][c] * (1 - f) + res[1][c] * f;
}

}  // namespace loom
