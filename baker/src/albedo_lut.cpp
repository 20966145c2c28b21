#include "loom/albedo_lut.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "loom/cycles_closures.h"

namespace loom {

using namespace shading;
constexpr int N = LOOM_ALBEDO_LUT_SIZE;
constexpr int S = LOOM_LUT_SLICES;

void lut_configuration(int ix, int j, int slice, vec3& V, vec3& t) {
  float phi = float(ix) / (N - 1) * float(M_PI);
  float ct = std::max(float(j) / (N - 1), kLutMinCos), st = std::sqrt(1 - ct * ct);
  float tz = float(slice) / (S - 1) * float(LOOM_LUT_TZ_MAX);
  t = vec3(std::sqrt(1 - tz * tz), 0, tz);
  V = vec3(st * std::cos(phi), st * std::sin(phi), ct);
}

void lut_quadrature(Quality q, int& n, int& m) {
  switch (q) {
    case Quality::Draft: n = 32, m = 24; break;
    case Quality::Preview: n = 48, m = 32; break;
    case Quality::Final: n = 96, m = 64; break;
    case Quality::Reference: n = 192, m = 128; break;
  }
}

namespace {

/// int f(i) di over the sphere, with f concentrated on the cone i . axis = c (width ~ a):
/// u = i . axis = c + a tan(zeta), zeta uniform (n samples), azimuth psi about the axis uniform
/// (m samples).
template <class F>
void cone_quadrature(vec3 axis, double c, double a, int n, int m, F f) {
  vec3 e1 = std::fabs(axis.z) < 0.9f ? normalize(cross(axis, vec3(0, 0, 1)))
                                     : normalize(cross(axis, vec3(1, 0, 0)));
  vec3 e2 = cross(axis, e1);
  std::vector<float> cs(m), sn(m);
  for (int j = 0; j < m; ++j) {
    cs[j] = float(std::cos((j + 0.5) * 2.0 * M_PI / m));
    sn[j] = float(std::sin((j + 0.5) * 2.0 * M_PI / m));
  }
  const double z0 = std::atan((-1.0 - c) / a), z1 = std::atan((1.0 - c) / a);
  for (int k = 0; k < n; ++k) {
    double zeta = z0 + (k + 0.5) * (z1 - z0) / n;
    double u = std::clamp(c + a * std::tan(zeta), -1.0, 1.0);
    double du = a / (std::cos(zeta) * std::cos(zeta)) * (z1 - z0) / n;
    double r = std::sqrt(std::max(0.0, 1.0 - u * u));
    double dw = du * 2.0 * M_PI / m;  // solid angle: du dpsi
    for (int j = 0; j < m; ++j) f(axis * float(u) + e1 * float(r * cs[j]) + e2 * float(r * sn[j]), dw);
  }
}

}  // namespace

LobeAlbedo lobe_albedos(vec3 V, vec3 t, float a, float T, int n, int m) {
  const vec3 z(0, 0, 1);
  LobeAlbedo out;
  // The model's fiber lobes sit on the specular cone i . t = -V . t.
  cone_quadrature(t, -dot(V, t), a, n, m, [&](vec3 i, double dw) {
    if (i.z > 1e-7f)
      out.rs += surface_specular_reflect(i, V, t, a, T) * i.z * dw;
    else if (i.z < -1e-7f)
      out.ts += surface_specular_transmit(i, V, t, a, T) * (-i.z) * dw;
  });
  // The closure as Cycles sets it up for this view (its normal raised by
  // ensure_valid_specular_reflection), integrated about its own narrow axis.
  const cycles::GGXReflection ggx(
      cycles::ensure_valid_specular_reflection(z, V, surface_glossy_normal(t)), t, a, 1.0f, z, V);
  const vec3 X = ggx.tangent();
  cone_quadrature(X, -dot(V, X), a, n, m, [&](vec3 i, double dw) { out.ggx += ggx.eval(i) * dw; });
  return out;
}

Image bake_albedo_lut(const FabricSpec& spec, const ProgressFn& progress) {
  Image lut(N, 2 * S * N, 4);
  int qn, qm;
  lut_quadrature(spec.quality, qn, qm);
  for (int kind = 0; kind < 2; ++kind) {
    const YarnSpec& y = kind == 0 ? spec.warp : spec.weft;
    float a = sggx_fiber_roughness(float(y.roughness));
    float T = float(spec.optical_thickness);
    tbb::parallel_for(0, S * N * N, [&](int idx) {
      int ix = idx % N, j = (idx / N) % N, slice = idx / (N * N);
      vec3 V, t;
      lut_configuration(ix, j, slice, V, t);
      LobeAlbedo A = lobe_albedos(V, t, a, T, qn, qm);
      float* p = lut.px(ix, (kind * S + slice) * N + j);
      p[0] = float(A.rs), p[1] = float(A.ggx), p[2] = float(A.ts), p[3] = 1.0f;
    });
    if (progress) progress("albedo lut", (kind + 1) / 2.0);
  }
  return lut;
}

void sample_albedo_lut(const Image& lut, float kind, float x, float y, float z, float out[3]) {
  float s0, s1, f;
  surface_lut_slices(z, s0, s1, f);
  float res[2][3];
  for (int k = 0; k < 2; ++k) {
    float u, v;
    surface_lut_uv(kind, x, y, k == 0 ? s0 : s1, u, v);
    // Linear interpolation with texel centres at (i + 0.5) / size, clamped at the borders.
    float px = u * lut.width - 0.5f, py = v * lut.height - 0.5f;
    int x0 = std::clamp(int(std::floor(px)), 0, lut.width - 1);
    int y0 = std::clamp(int(std::floor(py)), 0, lut.height - 1);
    int x1 = std::min(x0 + 1, lut.width - 1), y1 = std::min(y0 + 1, lut.height - 1);
    float fx = std::clamp(px - x0, 0.0f, 1.0f), fy = std::clamp(py - y0, 0.0f, 1.0f);
    for (int c = 0; c < 3; ++c) {
      float a = lut.px(x0, y0)[c] * (1 - fx) + lut.px(x1, y0)[c] * fx;
      float b = lut.px(x0, y1)[c] * (1 - fx) + lut.px(x1, y1)[c] * fx;
      res[k][c] = a * (1 - fy) + b * fy;
    }
  }
  for (int c = 0; c < 3; ++c) out[c] = res[0][c] * (1 - f) + res[1][c] * f;
}

}  // namespace loom
