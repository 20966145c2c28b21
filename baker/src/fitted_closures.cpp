#include "loom/fitted_closures.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <vector>

#include "loom/closure_lut.h"
#include "loom/cycles_closures.h"
#include "loom/evaluator.h"

namespace loom {

using namespace shading;

FittedClosureOptions fitted_closure_options(Quality q) {
  FittedClosureOptions o;
  switch (q) {
    // A handful of views and lights fit the four small problems. Gray wool twill at `final`
    // (65,536 texels; eval mapping): 4 views and 6 x 12 lights 0.1263 in a bake of 11.1 s, 8 x 16
    // 0.1264 (13.8 s), 10 x 20 0.1263 (18.9 s); 3 views and 6 x 12 0.1306, worst pair 1.43
    // against 0.81. Plain at `preview`: 6 x 12 0.2693, 8 x 16 0.2699.
    case Quality::Draft:
    case Quality::Preview:
    case Quality::Final: o.views = 4, o.sphere_n = 6; break;
    case Quality::Reference: o.views = 6, o.sphere_n = 10; break;
  }
  return o;
}

namespace {

/// One colour term's rows: up to two closures' values b1, b2 (per unit weight, f |cos| as Cycles'
/// eval returns it), the model's term m, and each row's weight (solid angle over the view's
/// directional albedo: the fit's objective is the mapping error's relative L1).
struct Rows {
  std::vector<double> b1, b2, m, w;
  void add(double x1, double x2, double y, double wr) {
    b1.push_back(x1), b2.push_back(x2), m.push_back(y), w.push_back(wr);
  }
};

/// min sum w |x1 b1 + x2 b2 - m| over x >= 0 (x2 = 0 when !two), by iteratively reweighted
/// least squares from the least-squares solution; the non-negative 2 x 2 problem is solved by
/// trying the free solution and each single closure.
std::array<double, 2> fit_two(const Rows& r, bool two, int iterations) {
  const size_t n = r.m.size();
  std::vector<double> om(r.w);
  double scale = 0;
  for (size_t k = 0; k < n; ++k) scale += std::fabs(r.m[k]) * r.w[k];
  double wsum = 0;
  for (double w : r.w) wsum += w;
  const double delta = 1e-3 * (wsum > 0 ? scale / wsum : 0) + 1e-9;
  std::array<double, 2> x{0, 0};
  for (int it = 0; it <= iterations; ++it) {
    double a11 = 0, a12 = 0, a22 = 0, y1 = 0, y2 = 0, mm = 0;
    for (size_t k = 0; k < n; ++k) {
      a11 += om[k] * r.b1[k] * r.b1[k], a12 += om[k] * r.b1[k] * r.b2[k];
      a22 += om[k] * r.b2[k] * r.b2[k];
      y1 += om[k] * r.b1[k] * r.m[k], y2 += om[k] * r.b2[k] * r.m[k], mm += om[k] * r.m[k] * r.m[k];
    }
    auto sse = [&](double p, double q) {
      return mm - 2 * (p * y1 + q * y2) + p * p * a11 + 2 * p * q * a12 + q * q * a22;
    };
    std::array<double, 2> best{a11 > 0 ? std::max(y1 / a11, 0.0) : 0.0, 0};
    if (two) {
      const std::array<double, 2> only2{0, a22 > 0 ? std::max(y2 / a22, 0.0) : 0.0};
      if (sse(only2[0], only2[1]) < sse(best[0], best[1])) best = only2;
      const double det = a11 * a22 - a12 * a12;
      if (det > 1e-12 * (a11 * a22 + 1e-30)) {
        const double p = (a22 * y1 - a12 * y2) / det, q = (a11 * y2 - a12 * y1) / det;
        if (p >= 0 && q >= 0 && sse(p, q) <= sse(best[0], best[1])) best = {p, q};
      }
    }
    x = best;
    for (size_t k = 0; k < n; ++k)
      om[k] = r.w[k] / std::max(std::fabs(x[0] * r.b1[k] + x[1] * r.b2[k] - r.m[k]), delta);
  }
  return x;
}

/// One texel's two panels on one side.
struct SideFit {
  float fd[4] = {0, 0, 0, 0}, fs[4] = {0, 0, 0, 0};
};

SideFit fit_side(const Atlas& a, const SurfacePoint& p, bool front, const std::vector<vec3>& views,
                 const std::vector<vec3>& lights, double dw, int iterations) {
  float hor[LOOM_HORIZON_DIRS];
  for (int k = 0; k < LOOM_HORIZON_DIRS; ++k) hor[k] = p.horizon[k];
  const vec3 z(0, 0, 1), Nc = surface_glossy_normal(p.t);
  const vec3 tt = surface_transmission_tangent(p.t, front ? 0 : 1);
  const float rough = sggx_fiber_roughness(p.roughness);
  Rows D, S, T, X;
  struct Sample {
    vec3 L;
    double sum, spec;
  };
  std::vector<Sample> samples(lights.size());
  for (const vec3& V : views) {  // the view mirrored to the upper side, as the evaluators do
    const vec3 wo(V.x, V.y, front ? V.z : -V.z);
    double den = 0;
    for (size_t k = 0; k < lights.size(); ++k) {
      const vec3& L = lights[k];
      const vec3 wi(L.x, L.y, front ? L.z : -L.z);
      // Unit colours: red carries the diffuse and the specular term, green the specular alone.
      const color f = surface_bsdf_eval(wi, wo, p.t, p.n_p, rough, p.thickness, p.blend, 1.0f,
                                        color(1, 0, 0), 1.0f, color(1, 0, 0), p.gap, hor);
      const double c = std::fabs(L.z);
      samples[k] = {L, f[0] * c, f[1] * c};
      den += f[0] * c * dw;
    }
    if (den < 1e-6) continue;  // an open gap: nothing to fit at this view
    const double w = dw / den;
    // The specular closures as the LUT shapes and weighs them at this view (closure_mapping.h).
    float lx, ly, lz, refl[4], trans[4];
    surface_lut_coords(V, p.t, lx, ly, lz);
    sample_closure_lut(a.closure_lut, p.kind, lx, ly, lz, 0, refl);
    sample_closure_lut(a.closure_lut, p.kind, surface_lut_transmission_x(lx, front ? 0 : 1), ly,
                       lz, 1, trans);
    const float vis = front ? horizon_visibility(V, hor) : 1.0f;
    const cycles::GGXReflection ggx(cycles::ensure_valid_specular_reflection(z, V, Nc), p.t,
                                    refl[1], refl[2], z, V);
    const cycles::HairLobe hair(z, tt, trans[1], trans[2], 0, V, true);
    const double g = std::max(refl[0], 0.0f) * vis, h = std::max(trans[0], 0.0f);
    const vec3 np_t = cycles::ensure_valid_specular_reflection(z, V, p.n_p);  // node mode's
    for (const Sample& s : samples) {
      const vec3& L = s.L;
      if (L.z > 0) {
        D.add(cycles::diffuse_eval(p.n_p, L, z) * vis, cycles::diffuse_eval(z, L, z) * vis,
              s.sum - s.spec, w);
        S.add(g * ggx.eval(L), 0, s.spec, w);
      } else {
        const double tl = cycles::translucent_eval(z, L, z);
        T.add(cycles::translucent_eval(np_t, L, z), tl, s.sum - s.spec, w);
        X.add(h * hair.eval(L), tl, s.spec, w);
      }
    }
  }
  SideFit out;
  if (D.m.empty() && T.m.empty()) return out;
  // (Within the range the shaders' guard keeps, fitted_weight_guard.)
  auto fit = [&](const Rows& r, bool two) {
    auto x = fit_two(r, two, iterations);
    for (double& v : x) v = std::min(v, double(LOOM_FITTED_MAX_WEIGHT));
    return x;
  };
  const auto d = fit(D, true), s = fit(S, false), t = fit(T, true), x = fit(X, true);
  out.fd[0] = float(d[0]), out.fd[1] = float(d[1]), out.fd[2] = float(t[0]), out.fd[3] = float(t[1]);
  out.fs[0] = float(s[0]), out.fs[1] = float(x[0]), out.fs[2] = float(x[1]);
  return out;
}

/// Texel (ix, iy) of a map `W` wide into tile `tile` of a tiled texture (fitted_closures.h): its
/// column, and the padding column that repeats it across the tile's edge.
void put_tiled(Image& img, int tile, int W, int ix, int iy, const float v[4]) {
  for (int col : {ix + 1, ix == W - 1 ? 0 : -1, ix == 0 ? W + 1 : -1})
    if (col >= 0) std::copy(v, v + 4, img.px(tile * (W + 2) + col, iy));
}

}  // namespace

Image horizon_strip(const Atlas& a) {
  const Image &h0 = a.map("horizon_0"), &h1 = a.map("horizon_1");
  const int W = h0.width, H = h0.height;
  Image img(LOOM_HORIZON_DIRS * (W + 2), H, 4);
  for (int iy = 0; iy < H; ++iy)
    for (int ix = 0; ix < W; ++ix) {
      float h[LOOM_HORIZON_DIRS];
      for (int k = 0; k < 4; ++k) h[k] = h0.px(ix, iy)[k], h[k + 4] = h1.px(ix, iy)[k];
      for (int k = 0; k < LOOM_HORIZON_DIRS; ++k) {
        const float v[4] = {h[k], h[(k + 1) % LOOM_HORIZON_DIRS], 0, 0};
        put_tiled(img, k, W, ix, iy, v);
      }
    }
  return img;
}

Image fit_texel_closures(const Atlas& a, const FittedClosureOptions& o,
                         const std::function<void(double)>& progress) {
  const Image& ref = a.map("ply_frame");
  const int W = ref.width, H = ref.height;
  Image img(LOOM_FITTED_TILES * (W + 2), H, 4);
  std::vector<vec3> views;
  for (const vec3& v : fibonacci_sphere(2 * o.views, 0.99))
    if (v.z > 0) views.push_back(v);
  const std::vector<vec3> lights = sphere_grid(o.sphere_n);
  const double dw = sphere_grid_dw(o.sphere_n);
  // Progress after d of the H rows, reported each quarter only (a line each in the bake's
  // --progress output), as the average fit does.
  std::atomic<int> done{0};
  tbb::parallel_for(0, H, [&](int iy) {
    for (int ix = 0; ix < W; ++ix) {
      const SurfacePoint p = guard_surface_point(texel_surface(a, ix, iy));
      for (int back = 0; back < 2; ++back) {
        const SideFit f = fit_side(a, p, back == 0, views, lights, dw, o.irls_iterations);
        put_tiled(img, LOOM_FITTED_PANELS * back, W, ix, iy, f.fd);
        put_tiled(img, 1 + LOOM_FITTED_PANELS * back, W, ix, iy, f.fs);
      }
    }
    const int d = ++done;
    if (progress && 4 * d / H != 4 * (d - 1) / H) progress(double(d) / H);
  });
  if (progress) progress(1.0);
  return img;
}

}  // namespace loom
