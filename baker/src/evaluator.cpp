#include "loom/evaluator.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <tbb/parallel_for.h>
#include <mutex>
#include <random>

#include "loom/closure_lut.h"
#include "loom/cycles_closures.h"

namespace loom {

using namespace shading;

void bilinear(const Image& img, float u, float v, float out[4]) {
  float px = u * img.width - 0.5f, py = v * img.height - 0.5f;
  int x0 = int(std::floor(px)), y0 = int(std::floor(py));
  float fx = px - x0, fy = py - y0;
  auto wrap = [](int i, int n) { return ((i % n) + n) % n; };
  int xa = wrap(x0, img.width), xb = wrap(x0 + 1, img.width);
  int ya = wrap(y0, img.height), yb = wrap(y0 + 1, img.height);
  for (int c = 0; c < img.channels; ++c) {
    float a = img.px(xa, ya)[c] * (1 - fx) + img.px(xb, ya)[c] * fx;
    float b = img.px(xa, yb)[c] * (1 - fx) + img.px(xb, yb)[c] * fx;
    out[c] = a * (1 - fy) + b * fy;
  }
}

namespace {

SurfacePoint from_values(const float f[4], const float n[4], const float in[4], const float ar[4],
                         const float at[4], const float pr[4], const float h0[4],
                         const float h1[4]) {
  SurfacePoint p;
  // The ply frame. The stored vectors are unit only to half precision: each is divided by its
  // length (bit for bit what this function always did for baked texels) when that length is a
  // positive finite float; otherwise (zero, NaN, Inf, or a squared length overflowing) the raw
  // vector goes on. texel_guard_frame (osl/include/loom/texel_guard.h, what the shaders apply)
  // then supplies the fallbacks: it keeps unit vectors as they are, scales the raw ones without
  // overflow, and replaces a degenerate normal or tangent.
  const auto unit = [](vec3 v) {
    const float l = length(v);
    return l > 0 && std::isfinite(l) ? v / l : v;
  };
  p.t = unit(vec3(f[0], f[1], f[2]));
  p.n_p = unit(vec3(n[0], n[1], n[2]));
  texel_guard_frame(p.t, p.n_p);
  p.height = f[3];
  p.h = n[3];
  p.kind = in[0];
  p.along = in[1], p.ply_id = in[2], p.gap = in[3];
  p.k_rd = vec3(ar[0], ar[1], ar[2]);
  p.k_rs = ar[3];
  p.k_td = vec3(at[0], at[1], at[2]);
  p.k_ts = at[3];
  p.roughness = pr[0], p.thickness = pr[1], p.blend = pr[2], p.ior = pr[3];
  for (int k = 0; k < 4; ++k) p.horizon[k] = h0[k], p.horizon[k + 4] = h1[k];
  return p;
}

const char* kMaps[] = {"ply_frame",   "ply_normal",      "yarn_info", "albedo_reflect",
                       "albedo_transmit", "spec_params", "horizon_0", "horizon_1"};

}  // namespace

SurfacePoint guard_surface_point(const SurfacePoint& in) {
  // The ranges live in texel_guard.h, whose functions the shaders apply too.
  SurfacePoint p = in;
  vec3 info(p.kind, p.along, p.ply_id), params(p.roughness, p.thickness, p.blend);
  texel_guard_geometry(p.t, p.height, p.n_p, p.h, info, p.gap);
  texel_guard_optics(p.k_rd, p.k_rs, p.k_td, p.k_ts, params, p.ior);
  p.kind = info[0], p.along = info[1], p.ply_id = info[2];
  p.roughness = params[0], p.thickness = params[1], p.blend = params[2];
  for (float& s : p.horizon) s = texel_guard_horizon(s);
  p.u = std::isfinite(p.u) ? p.u - std::floor(p.u) : 0.0f;
  p.v = std::isfinite(p.v) ? p.v - std::floor(p.v) : 0.0f;
  p.du = texel_guard(p.du, 0, 1, 0);
  p.dv = texel_guard(p.dv, 0, 1, 0);
  return p;
}

SurfacePoint sample_surface(const Atlas& a, float u, float v) {
  // Wrap first (any finite u, v; also keeps the texel index arithmetic in range; a non-finite
  // one reads the repeat's corner).
  u = std::isfinite(u) ? u - std::floor(u) : 0.0f;
  v = std::isfinite(v) ? v - std::floor(v) : 0.0f;
  float vals[8][4];
  for (int k = 0; k < 8; ++k) bilinear(a.map(kMaps[k]), u, v, vals[k]);
  SurfacePoint p = from_values(vals[0], vals[1], vals[2], vals[3], vals[4], vals[5], vals[6],
                               vals[7]);
  p.u = u, p.v = v;
  return p;
}

SurfacePoint texel_surface(const Atlas& a, int ix, int iy) {
  const float* v[8];
  for (int k = 0; k < 8; ++k) v[k] = a.map(kMaps[k]).px(ix, iy);
  SurfacePoint p = from_values(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7]);
  const Image& ref = a.map(kMaps[0]);
  p.u = (ix + 0.5f) / float(ref.width), p.v = (iy + 0.5f) / float(ref.height);
  p.du = 1.0f / float(ref.width), p.dv = 1.0f / float(ref.height);
  return p;
}

bool has_fitted_closures(const Atlas& a) {
  return std::find(a.names.begin(), a.names.end(), "fitted_closures") != a.names.end();
}

void sample_fitted_closures(const Atlas& a, float u, float v, int back, float fd[4],
                            float fs[4]) {
  const Image& img = a.map("fitted_closures");
  const float width = float(img.width / LOOM_FITTED_TILES - 2);
  u = std::isfinite(u) ? u - std::floor(u) : 0.0f;
  bilinear(img, fitted_closures_s(u, 0.0f, float(back), width), v, fd);
  bilinear(img, fitted_closures_s(u, 1.0f, float(back), width), v, fs);
  for (int c = 0; c < 4; ++c) fd[c] = fitted_weight_guard(fd[c]), fs[c] = fitted_weight_guard(fs[c]);
}

/// V(V) as the shaders read it with fitted closures: from the horizon strip (fitted_closures.h),
/// not the horizon maps (the same where the atlas is as baked; not where a map was edited).
float strip_view_visibility(const Atlas& a, float u, float v, vec3 V) {
  const Image& img = a.map("horizon_strip");
  const float width = float(img.width / LOOM_HORIZON_DIRS - 2);
  u = std::isfinite(u) ? u - std::floor(u) : 0.0f;
  float s, f, h[4];
  horizon_strip_coords(V, u, width, s, f);
  bilinear(img, s, v, h);
  return horizon_strip_visibility(V, h[0], h[1], f);
}

std::array<float, 3> eval_bsdf(const Atlas& a, const SurfacePoint& p_in, vec3 wi, vec3 wo,
                               Evaluator e, Backend backend) {
  const SurfacePoint p = guard_surface_point(p_in);
  if (!(std::isfinite(wi.x) && std::isfinite(wi.y) && std::isfinite(wi.z) &&
        std::isfinite(wo.x) && std::isfinite(wo.y) && std::isfinite(wo.z)))
    return {0, 0, 0};  // like the model: a non-finite direction scatters nothing
  float hor[LOOM_HORIZON_DIRS];
  for (int k = 0; k < LOOM_HORIZON_DIRS; ++k) hor[k] = p.horizon[k];
  float rough = sggx_fiber_roughness(p.roughness);
  if (e == Evaluator::Model) {
    vec3 f = surface_bsdf_eval(wi, wo, p.t, p.n_p, rough, p.thickness, p.blend, p.k_rs, p.k_rd,
                               p.k_ts, p.k_td, p.gap, hor);
    return {f.x, f.y, f.z};
  }
  // Closure mixture, as the shaders build it (closure_mapping.h), evaluated with Cycles' formulas.
  vec3 V = wo, L = wi, t = p.t, np = p.n_p;
  bool front = true;
  if (V.z < 0) {  // seen from below: Cycles turns N towards the viewer; the back mirrors the front
    V.z = -V.z, L.z = -L.z;
    front = false;
  }
  if (!(V.z > 0) || L.z == 0) return {0, 0, 0};
  const vec3 Nc = surface_glossy_normal(t);
  const bool fitted = has_fitted_closures(a);
  float vis_v = !front ? 1.0f : fitted ? strip_view_visibility(a, p.u, p.v, V) : horizon_visibility(V, hor);
  float lx, ly, lz;
  surface_lut_coords(V, t, lx, ly, lz);
  float refl[4], trans[4];  // the closure LUT's panels (g, ax, ay, 0) and (h, r1, r2, l)
  sample_closure_lut(a.closure_lut, p.kind, lx, ly, lz, 0, refl);
  sample_closure_lut(a.closure_lut, p.kind, surface_lut_transmission_x(lx, front ? 0 : 1), ly, lz,
                     1, trans);
  float w_glossy, w_hair;
  color w_dnp, w_dns, w_tnp, w_tns;
  if (fitted) {  // per-texel factors fitted at bake time (fitted_closures.h)
    float fd[4], fs[4];
    sample_fitted_closures(a, p.u, p.v, front ? 0 : 1, fd, fs);
    fitted_closure_weights(p.k_rd, p.k_rs, p.k_td, p.k_ts, fd[0], fd[1], fd[2], fd[3], fs[0],
                           fs[1], fs[2], refl[0], trans[0], vis_v, w_dnp, w_dns, w_tnp, w_tns,
                           w_glossy, w_hair);
  } else {  // mapped per sample (closure_mapping.h)
    float vis_amb = front ? horizon_ambient_visibility(hor) : 1.0f;
    float vis_gl = front ? surface_glossy_light_visibility(V, Nc, hor) : 1.0f;
    float w_gap;
    surface_closure_weights(p.gap, p.blend, p.k_rs, p.k_rd, p.k_ts, p.k_td, vis_v, vis_amb,
                            vis_gl, refl[0], trans[0], trans[3], w_gap, w_dnp, w_dns, w_tnp,
                            w_tns, w_glossy, w_hair);
  }
  const vec3 z(0, 0, 1);
  const vec3 Nv = cycles::ensure_valid_specular_reflection(z, V, Nc);
  // Node mode's Translucent BSDF raises its normal like a glossy one (Cycles svm/closure.h);
  // OSL's translucent() keeps it.
  const vec3 np_t =
      backend == Backend::Nodes ? cycles::ensure_valid_specular_reflection(z, V, np) : np;
  vec3 sum = w_dnp * cycles::diffuse_eval(np, L, z) + w_dns * cycles::diffuse_eval(z, L, z) +
             w_tnp * cycles::translucent_eval(np_t, L, z) + w_tns * cycles::translucent_eval(z, L, z) +
             vec3(w_glossy * cycles::ggx_eval(Nv, t, refl[1], refl[2], z, V, L)) +
             vec3(w_hair * cycles::HairLobe(z, surface_transmission_tangent(t, front ? 0 : 1),
                                            trans[1], trans[2], 0, V, true)
                               .eval(L));
  vec3 f = sum / std::fabs(L.z);
  return {f.x, f.y, f.z};
}

std::array<float, 3> eval_bsdf_average(const Atlas& a, vec3 wi, vec3 wo, Evaluator e,
                                       Backend backend) {
  const Image& ref = a.map("ply_frame");
  double acc[3] = {0, 0, 0};
  for (int iy = 0; iy < ref.height; ++iy)
    for (int ix = 0; ix < ref.width; ++ix) {
      auto f = eval_bsdf(a, texel_surface(a, ix, iy), wi, wo, e, backend);
      for (int c = 0; c < 3; ++c) acc[c] += f[c];
    }
  double n = double(ref.width) * ref.height;
  return {float(acc[0] / n), float(acc[1] / n), float(acc[2] / n)};
}

std::vector<vec3> fibonacci_sphere(int n, double z_scale) {
  std::vector<vec3> V;
  for (int k = 0; k < n; ++k) {
    const double z = (1.0 - 2.0 * (k + 0.5) / n) * z_scale, r = std::sqrt(1 - z * z);
    const double phi = k * 2.399963229728653;  // the golden angle
    V.push_back(vec3(float(r * std::cos(phi)), float(r * std::sin(phi)), float(z)));
  }
  return V;
}

std::vector<vec3> fibonacci_views(int n) { return fibonacci_sphere(n, 0.99); }

std::vector<vec3> sphere_grid(int n) {
  std::vector<vec3> L;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < 2 * n; ++j) {
      const double z = -1 + (i + 0.5) * 2.0 / n, r = std::sqrt(1 - z * z);
      const double ph = (j + 0.5) * M_PI / n;
      L.push_back(vec3(float(r * std::cos(ph)), float(r * std::sin(ph)), float(z)));
    }
  return L;
}

MappingError mapping_error_loop(const Atlas& a, int texels, int views, int sphere_n,
                                const std::function<MappingPair(const SurfacePoint&, vec3)>& setup) {
  const Image& ref = a.map("ply_frame");
  // Texels on a jittered lattice (one texel at a fixed pseudo-random place in each cell: a
  // lattice aligned with the repeat can see only gaps or only crossings); views on a spherical
  // Fibonacci set.
  int side = std::max(1, int(std::lround(std::sqrt(double(texels)))));
  const std::vector<vec3> V = fibonacci_views(views), L = sphere_grid(sphere_n);
  const double dw = sphere_grid_dw(sphere_n);
  MappingError out;
  std::mutex mu;
  tbb::parallel_for(0, side * side, [&](int idx) {
    std::mt19937 rng(0x9E3779B9u ^ unsigned(idx));
    std::uniform_real_distribution<double> jitter(0.0, 1.0);
    const double jx = jitter(rng), jy = jitter(rng);
    int ix = std::min(ref.width - 1, int((idx % side + jx) / side * ref.width));
    int iy = std::min(ref.height - 1, int((idx / side + jy) / side * ref.height));
    SurfacePoint p = texel_surface(a, ix, iy);
    double l1_sum = 0, l1_worst = 0, en_sum = 0, en_worst = 0;
    int counted = 0;
    for (const vec3& v : V) {
      const MappingPair f = setup(p, v);
      double num = 0, den = 0, ec = 0;
      for (const vec3& l : L) {
        const auto [fm, fc] = f(l);
        num += std::fabs(fc - fm) * dw;
        den += fm * dw;
        ec += fc * dw;
      }
      if (den < 1e-6) continue;  // open gaps: nothing to compare
      double l1 = num / den, en = std::fabs(ec - den) / den;
      l1_sum += l1, en_sum += en, ++counted;
      l1_worst = std::max(l1_worst, l1), en_worst = std::max(en_worst, en);
    }
    std::lock_guard lock(mu);
    out.mean_l1 += l1_sum, out.mean_energy += en_sum, out.views += counted;
    out.worst_l1 = std::max(out.worst_l1, l1_worst);
    out.worst_energy = std::max(out.worst_energy, en_worst);
    out.texels += counted > 0;
  });
  if (out.views > 0) out.mean_l1 /= out.views, out.mean_energy /= out.views;
  return out;
}

MappingError mapping_error(const Atlas& a, int texels, int views, int sphere_n, Backend backend) {
  return mapping_error_loop(a, texels, views, sphere_n, [&](const SurfacePoint& p, vec3 v) {
    return MappingPair([&a, p, v, backend](vec3 l) {
      const float c = std::fabs(l.z);
      return std::pair<float, float>(eval_bsdf(a, p, l, v, Evaluator::Model)[1] * c,
                                     eval_bsdf(a, p, l, v, Evaluator::Closures, backend)[1] * c);
    });
  });
}

}  // namespace loom
