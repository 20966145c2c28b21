#include "loom/atlas_swatch.h"

#include <tbb/parallel_for.h>

#include <cmath>
#include <stdexcept>
#include <vector>

#include "loom/atlas_bsdf.h"
#include "loom/preset_error.h"

namespace loom {

using namespace shading;

namespace {

/// Midpoints of n x 2n cells over one hemisphere (uniform in |z|), each of solid angle dw.
std::vector<vec3> hemisphere(int n, bool upper) {
  std::vector<vec3> out;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < 2 * n; ++j) {
      const double z = (i + 0.5) / n, r = std::sqrt(1 - z * z), ph = (j + 0.5) * M_PI / n;
      out.push_back(vec3(float(r * std::cos(ph)), float(r * std::sin(ph)), float(upper ? z : -z)));
    }
  return out;
}

/// Per channel: int over `lights` of f(L, V) |cos L| dL, at one point.
std::array<double, 3> integrate(const std::function<std::array<float, 3>(vec3)>& f,
                                const std::vector<vec3>& lights, double dw) {
  std::array<double, 3> s{0, 0, 0};
  for (const vec3& L : lights) {
    const auto v = f(L);
    for (size_t c = 0; c < 3; ++c) s[c] += double(v[c]) * dw;
  }
  return s;
}

}  // namespace

Swatch atlas_swatch(const Atlas& a, Evaluator e, const AtlasSwatchSettings& s) {
  if (s.points < 1 || s.n < 1 || s.n_views < 1 || !(s.card <= 1) || !(s.light_deg >= 0 && s.light_deg < 89))
    throw std::invalid_argument("atlas_swatch: points, n >= 1; card <= 1; light_deg in [0, 89)");
  const AtlasBsdf bsdf(a, e);
  const PresetErrorSampling sp = preset_error_sampling(s.points, 1, 2);
  const std::vector<vec3> up = hemisphere(s.n, true), down = hemisphere(s.n, false);
  const std::vector<vec3> views_up = hemisphere(s.n_views, true),
                          views_down = hemisphere(s.n_views, false);
  const double dw = M_PI / (double(s.n) * s.n);  // (1 / n) in z times (pi / n) in phi
  const double dv = M_PI / (double(s.n_views) * s.n_views);
  const double t8 = s.light_deg * M_PI / 180;
  const vec3 V8(float(std::sin(t8) * M_SQRT1_2), float(std::sin(t8) * M_SQRT1_2), float(std::cos(t8)));
  // Per point: R, T at V8; and, over views o, the diffuse r, t (o above / below, light above)
  // and R_u, T_u (light below), each weighted |cos o| do / pi.
  struct Parts {
    std::array<double, 3> R{}, T{}, r{}, t{}, Ru{}, Tu{};
    double open = 0;
    std::vector<std::array<double, 3>> albedo;  // per view
  };
  std::vector<Parts> per(sp.uv.size());
  tbb::parallel_for(size_t(0), sp.uv.size(), [&](size_t k) {
    const auto [u, v] = sp.uv[k];
    Parts& p = per[k];
    p.open = bsdf.open(u, v);
    const auto f8 = bsdf.at(u, v, V8);
    p.R = integrate(f8, up, dw), p.T = integrate(f8, down, dw);
    for (bool view_up : {true, false})
      for (const vec3& o : view_up ? views_up : views_down) {
        const auto fo = bsdf.at(u, v, o);
        const double w = std::fabs(o.z) * dv / M_PI;
        const auto from_above = integrate(fo, up, dw), from_below = integrate(fo, down, dw);
        std::array<double, 3> albedo{};
        if (p.open < 1)  // (f holds the yarns' part, 1 - open, of the point)
          for (size_t c = 0; c < 3; ++c) albedo[c] = (from_above[c] + from_below[c]) / (1 - p.open);
        p.albedo.push_back(albedo);
        for (size_t c = 0; c < 3; ++c) {
          (view_up ? p.r : p.t)[c] += w * from_above[c];
          (view_up ? p.Tu : p.Ru)[c] += w * from_below[c];
        }
      }
  });
  Parts m;
  for (const Parts& p : per) {
    for (size_t c = 0; c < 3; ++c) {
      m.R[c] += p.R[c], m.T[c] += p.T[c], m.r[c] += p.r[c], m.t[c] += p.t[c];
      m.Ru[c] += p.Ru[c], m.Tu[c] += p.Tu[c];
    }
    m.open += p.open;
  }
  Swatch out;
  for (const Parts& p : per)
    out.view_albedo.insert(out.view_albedo.end(), p.albedo.begin(), p.albedo.end());
  const double n = double(per.size());
  for (size_t c = 0; c < 3; ++c) {
    // The gaps' delta: seen through (T), and passing diffuse light both ways (t, T_u).
    const double open = m.open / n;
    out.reflect[c] = m.R[c] / n, out.transmit[c] = m.T[c] / n + open;
    out.down_reflect[c] = m.r[c] / n, out.down_transmit[c] = m.t[c] / n + open;
    out.up_reflect[c] = m.Ru[c] / n, out.up_transmit[c] = m.Tu[c] / n + open;
    out.below[c] = s.card < 0 ? pile_reflectance(out.down_reflect[c], out.down_transmit[c]) : s.card;
    out.rho[c] = swatch_rho(out.reflect[c], out.transmit[c], out.below[c], out.down_transmit[c],
                            out.up_reflect[c]);
  }
  return out;
}

}  // namespace loom
