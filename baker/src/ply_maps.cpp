// Ply-level maps of the surface model. Geometry choices (the supplement gives none; these are
// ours, stated once here):
//  * Yarns are circular in cross-section with the spec's yarn diameter D; a yarn covers the band
//    |lateral offset| < D/2 around its centre line, spaced 1e4/density um apart. Where neither
//    a warp nor a weft covers a point, the cloth is open (a gap).
//  * Crimp: a yarn's centre line is at +A over a crossing where it lies on top, -A where under,
//    with a cosine blend between crossings; A is a quarter of the crossing yarn's diameter.
//  * Plies: a P-ply yarn shows P stripes running at the ply twist angle alpha to the yarn axis
//    (S or Z). The stripe coordinate is xi = (a tan(alpha) - s y') P / (2 pi R_p) with a the
//    position along the yarn, y' across it, R_p the ply-centre radius; its along-yarn frequency is
//    rounded to a whole number of stripes per repeat so that the maps tile (alpha is adjusted by
//    less than one stripe per repeat). h = 2 frac(xi) - 1 is the position across the ply.
//    A single-ply yarn is one ply: h is the position across the yarn and the tangent follows the
//    surface fibres at the twist angle.
//  * The ply normal tilts with h about the ply tangent: n_p = normalize(sqrt(1-h^2) n_y + k h b),
//    n_y the yarn surface normal (cross-section tilt limited to 60 degrees), b the across-ply
//    direction, k = 0.8; both stay in the upper hemisphere.
//  * Height = crimp + cross-section + a groove of 0.3 R_ply between plies.
//  * Gap coverage is the fraction of 4x4 sub-samples of a texel that hit no yarn.
//  * Horizon (visibility.h): per texel and azimuth, the highest elevation sine of the height field
//    within two weave cells, marched at one texel per step, the field sampled bilinearly and
//    periodically; open gaps do not occlude.
//  * Perlin (optional): tileable gradient noise, seeded, rotates the ply tangent in the tangent
//    plane by amplitude * noise.
#include "loom/ply_maps.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "loom/shading.h"

namespace loom {

using shading::cross;
using shading::dot;
using shading::normalize;
using shading::vec3;

namespace {

uint32_t pcg(uint32_t v) {
  uint32_t state = v * 747796405u + 2891336453u;
  uint32_t word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}

/// Tileable 2D gradient noise with integer period, values in about [-1, 1].
struct Perlin {
  int period;
  uint32_t seed;
  vec3 grad(int ix, int iy) const {
    ix = ((ix % period) + period) % period;
    iy = ((iy % period) + period) % period;
    uint32_t h = pcg(seed ^ pcg(uint32_t(ix) * 73856093u ^ pcg(uint32_t(iy) * 19349663u)));
    float ang = float(h) / 4294967296.0f * 2.0f * float(M_PI);
    return {std::cos(ang), std::sin(ang), 0};
  }
  float operator()(float x, float y) const {  // x, y in lattice units
    int x0 = int(std::floor(x)), y0 = int(std::floor(y));
    float fx = x - x0, fy = y - y0;
    auto fade = [](float t) { return t * t * t * (t * (t * 6 - 15) + 10); };
    auto dotg = [&](int ix, int iy, float dx, float dy) {
      vec3 g = grad(ix, iy);
      return g.x * dx + g.y * dy;
    };
    float n00 = dotg(x0, y0, fx, fy), n10 = dotg(x0 + 1, y0, fx - 1, fy);
    float n01 = dotg(x0, y0 + 1, fx, fy - 1), n11 = dotg(x0 + 1, y0 + 1, fx - 1, fy - 1);
    float u = fade(fx), v = fade(fy);
    float a = n00 + (n10 - n00) * u, b = n01 + (n11 - n01) * u;
    return 1.41421356f * (a + (b - a) * v);
  }
};

struct YarnGeom {
  double R;          // yarn radius (um)
  double R_ply;      // ply radius
  double R_p;        // ply-centre radius
  int P;             // plies
  double s;          // +1 Z twist, -1 S twist
  double tan_alpha;  // effective (tiling) tan of ply twist
  double k_a;        // stripes per um along the yarn (tiling), 0 if lateral bands
  double A;          // crimp amplitude
  double lateral_freq;  // P / (2 pi R_p) stripes per um across
  int stripes_per_repeat;
};

YarnGeom yarn_geom(const YarnSpec& y, double crossing_diameter, double repeat_len) {
  YarnGeom g{};
  g.R = 0.5 * y.yarn_diameter_um;
  g.R_ply = 0.5 * y.ply_diameter_um;
  g.P = y.plies;
  g.s = y.twist == "Z" ? 1.0 : -1.0;
  g.R_p = g.P > 1 ? std::max(g.R - g.R_ply, 0.25 * g.R) : 0.5 * g.R;
  g.A = 0.25 * crossing_diameter;
  g.lateral_freq = g.P / (2.0 * M_PI * g.R_p);
  double ta = std::tan(y.ply_twist_deg * M_PI / 180.0);
  if (g.P == 1) {  // one ply: no stripes, nothing periodic depends on the angle
    g.stripes_per_repeat = 0;
    g.k_a = 0;
    g.tan_alpha = ta;
    return g;
  }
  // Stripes per repeat along the yarn, rounded to a whole number so that the map tiles; a twisted
  // yarn keeps at least one stripe (a small angle is adjusted up rather than lost).
  double raw = repeat_len * ta * g.lateral_freq;
  g.stripes_per_repeat = int(std::lround(raw));
  if (g.stripes_per_repeat == 0 && ta > 0) g.stripes_per_repeat = 1;
  g.k_a = g.stripes_per_repeat / repeat_len;
  g.tan_alpha = g.k_a / g.lateral_freq;
  return g;
}

/// A yarn's sample at a point: its surface height and local ply geometry.
struct YarnSample {
  bool covers = false;
  double height = -1e30;
  vec3 t, n;
  float h = 0, along = 0, id = 0;
};

/// Evaluates one yarn (warp if kind == 1, weft if 2) at axis position a and lateral offset y'
/// (um), crimp phase from the interlacing states of the neighbouring crossings.
YarnSample sample_yarn(int kind, int index, double a, double yl, double crimp_z,
                       double crimp_slope, const YarnGeom& g, double repeat_len, bool clamp_edge,
                       float perlin_angle) {
  YarnSample out;
  double u = yl / g.R;
  if (std::fabs(u) >= 1.0) {
    if (!clamp_edge) return out;
    u = u > 0 ? 0.999 : -0.999;
    yl = u * g.R;
  }
  out.covers = true;
  double cross_h = g.R * std::sqrt(1.0 - u * u);
  // Frame: axis direction, lateral direction, up (yarn-local, in the cloth tangent frame).
  vec3 axis = kind == 1 ? vec3(1, 0, 0) : vec3(0, 1, 0);
  vec3 lat = kind == 1 ? vec3(0, 1, 0) : vec3(-1, 0, 0);
  vec3 up(0, 0, 1);
  vec3 T_axis = normalize(axis + up * float(crimp_slope));
  double psi = std::asin(std::clamp(u, -1.0, 1.0)) * (60.0 / 90.0);  // limit tilt to 60 deg
  vec3 n_y = normalize(up * float(std::cos(psi)) + lat * float(std::sin(psi)) -
                       axis * float(crimp_slope * std::cos(psi)));
  double xi, h;
  vec3 t;
  if (g.P > 1) {
    xi = (a * g.k_a - g.s * yl * g.lateral_freq);
    h = 2.0 * (xi - std::floor(xi)) - 1.0;
    t = T_axis + lat * float(g.s * g.tan_alpha);
  } else {
    xi = 0.0;
    h = u;
    t = T_axis + lat * float(g.s * g.tan_alpha);
  }
  if (perlin_angle != 0.0f) {  // rotate in the tangent plane about +z
    float c = std::cos(perlin_angle), s = std::sin(perlin_angle);
    t = vec3(c * t.x - s * t.y, s * t.x + c * t.y, t.z);
  }
  t = normalize(t - n_y * dot(t, n_y));
  vec3 b = normalize(cross(n_y, t));
  // b must point towards increasing xi (so that h grows along it): grad xi ~ k_a axis - s f lat.
  vec3 grad = g.P > 1 ? axis * float(g.k_a) - lat * float(g.s * g.lateral_freq) : lat;
  if (dot(b, grad) < 0) b = -b;
  float hh = float(std::clamp(h, -1.0, 1.0));
  vec3 n = normalize(n_y * std::sqrt(std::max(0.0f, 1.0f - hh * hh)) + b * (0.8f * hh));
  // Keep n_p in the upper hemisphere without leaving the plane orthogonal to t: tilt it towards
  // that plane's upward direction.
  vec3 up_t = normalize(up - t * t.z);
  for (int it = 0; it < 32 && n.z < 0.05f; ++it) n = normalize(n + up_t * 0.1f);
  out.t = t;
  out.n = n;
  out.h = hh;
  double groove = g.P > 1 ? 0.3 * g.R_ply * (std::sqrt(1.0 - hh * hh) - 1.0) : 0.0;
  out.height = crimp_z + cross_h + groove;
  double al = a / repeat_len;
  out.along = float(al - std::floor(al));
  int stripe = int(std::floor(xi));
  if (g.stripes_per_repeat > 0)
    stripe = ((stripe % g.stripes_per_repeat) + g.stripes_per_repeat) % g.stripes_per_repeat;
  out.id = ply_id_hash(kind, index, stripe);
  return out;
}

/// Crimp: centre-line height and slope of a yarn along its axis. `state(k)` is +1 where the yarn
/// is on top at crossing k, -1 where under; crossings at (k + 0.5) * spacing.
template <class State>
void crimp(double a, double spacing, double A, State state, double& z, double& slope) {
  double x = a / spacing - 0.5;
  int k = int(std::floor(x));
  double f = x - k;
  double s0 = state(k), s1 = state(k + 1);
  double w = 0.5 * (1.0 - std::cos(M_PI * f));
  z = A * (s0 + (s1 - s0) * w);
  slope = A * (s1 - s0) * 0.5 * M_PI * std::sin(M_PI * f) / spacing;
}

}  // namespace

float ply_id_hash(int kind, int yarn, int stripe) {
  uint32_t h = pcg(uint32_t(kind) * 0x9E3779B9u ^ pcg(uint32_t(yarn) ^ pcg(uint32_t(stripe))));
  return float(h >> 8) / 16777216.0f;
}

struct SurfaceGeometry::Impl {
  FabricSpec spec;
  Weave weave;
  int rows, cols;
  double sx, sy, Lx, Ly;
  YarnGeom gw, gf;
  Perlin perlin;
};

SurfaceGeometry::SurfaceGeometry(const FabricSpec& spec) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.spec = spec;
  m.weave = make_weave(spec.weave);
  m.rows = m.weave.rows();
  m.cols = m.weave.cols();
  m.sx = 1e4 / spec.weft_per_cm;  // weft yarns are stacked along x
  m.sy = 1e4 / spec.warp_per_cm;  // warp yarns are stacked along y
  m.Lx = m.cols * m.sx;
  m.Ly = m.rows * m.sy;
  m.gw = yarn_geom(spec.warp, spec.weft.yarn_diameter_um, m.Lx);
  m.gf = yarn_geom(spec.weft, spec.warp.yarn_diameter_um, m.Ly);
  m.perlin = Perlin{spec.perlin.cells_per_repeat, spec.perlin.seed * 2654435761u + 1u};
}
SurfaceGeometry::~SurfaceGeometry() = default;
double SurfaceGeometry::repeat_x() const { return impl_->Lx; }
double SurfaceGeometry::repeat_y() const { return impl_->Ly; }

GeometrySample SurfaceGeometry::sample(double x, double y, bool clamp_edge) const {
  const Impl& m = *impl_;
  const int rows = m.rows, cols = m.cols;
  // Reduce to one repeat first: every quantity below is then a function of the point modulo the
  // repeat, which is what makes the maps tile.
  x -= m.Lx * std::floor(x / m.Lx);
  y -= m.Ly * std::floor(y / m.Ly);
  int r = int(std::floor(y / m.sy)), c = int(std::floor(x / m.sx));
  double yl_w = y - (r + 0.5) * m.sy, xl_f = x - (c + 0.5) * m.sx;
  float pa = 0.0f;
  if (m.spec.perlin.enabled)
    pa = float(m.spec.perlin.amplitude) *
         m.perlin(float(x / m.Lx * m.spec.perlin.cells_per_repeat),
                  float(y / m.Ly * m.spec.perlin.cells_per_repeat));
  double zw, sw, zf, sf;
  crimp(x, m.sx, m.gw.A, [&](int k) { return m.weave.at(r, k) ? 1.0 : -1.0; }, zw, sw);
  crimp(y, m.sy, m.gf.A, [&](int k) { return m.weave.at(k, c) ? -1.0 : 1.0; }, zf, sf);
  const int ri = ((r % rows) + rows) % rows, ci = ((c % cols) + cols) % cols;
  YarnSample ys = sample_yarn(1, ri, x, yl_w, zw, sw, m.gw, m.Lx, false, pa);
  YarnSample fs = sample_yarn(2, ci, y, -xl_f, zf, sf, m.gf, m.Ly, false, pa);
  int kind;
  YarnSample s;
  if (!ys.covers && !fs.covers) {
    kind = 0;
    if (clamp_edge) {
      // Nearest yarn, clamped to its edge: for texels whose centre is open but which are partly
      // covered.
      double dw = std::fabs(yl_w) - m.gw.R, df = std::fabs(xl_f) - m.gf.R;
      if (dw <= df) {
        kind = 1;
        s = sample_yarn(1, ri, x, yl_w, zw, sw, m.gw, m.Lx, true, pa);
      } else {
        kind = 2;
        s = sample_yarn(2, ci, y, -xl_f, zf, sf, m.gf, m.Ly, true, pa);
      }
    }
  } else if (ys.covers && (!fs.covers || ys.height >= fs.height)) {
    kind = 1;
    s = ys;
  } else {
    kind = 2;
    s = fs;
  }
  GeometrySample g;
  g.kind = kind;
  g.yarn = kind == 2 ? ci : ri;
  if (!s.covers) return g;
  g.height = s.height;
  g.t[0] = s.t.x, g.t[1] = s.t.y, g.t[2] = s.t.z;
  g.n[0] = s.n.x, g.n[1] = s.n.y, g.n[2] = s.n.z;
  g.h = s.h, g.along = s.along, g.ply_id = s.id;
  return g;
}

SurfaceMaps bake_surface_maps(const FabricSpec& spec, const ProgressFn& progress, bool horizons) {
  const SurfaceGeometry geom(spec);
  const Weave weave = make_weave(spec.weave);
  const int rows = weave.rows(), cols = weave.cols();
  const int tpc = texels_per_cell(spec.quality);
  const int W = cols * tpc, H = rows * tpc;
  const double Lx = geom.repeat_x(), Ly = geom.repeat_y();

  SurfaceMaps maps;
  maps.repeat_um[0] = Lx;
  maps.repeat_um[1] = Ly;
  maps.warp_yarns = rows;
  maps.weft_yarns = cols;
  auto F = [](float lo, float hi) { return std::array<float, 2>{lo, hi}; };
  maps.info = {
      {"ply_frame", {"t.x", "t.y", "t.z", "height"},
       {F(-1, 1), F(-1, 1), F(-1, 1), F(-5000, 5000)}, {"", "", "", "um"},
       "ply tangent in the tangent frame (x warp, y weft, z normal) and surface height"},
      {"ply_normal", {"n.x", "n.y", "n.z", "h"}, {F(-1, 1), F(-1, 1), F(0, 1), F(-1, 1)},
       {"", "", "", ""}, "ply normal (upper hemisphere) and position across the ply"},
      {"yarn_info", {"kind", "along", "ply_id", "gap"}, {F(0, 2), F(0, 1), F(0, 1), F(0, 1)},
       {"", "", "", ""},
       "0 gap / 1 warp / 2 weft on top, position along the yarn, per-ply ID hash, gap coverage"},
      {"albedo_reflect", {"k_rd.r", "k_rd.g", "k_rd.b", "k_rs"},
       {F(0, 1), F(0, 1), F(0, 1), F(0, 1)}, {"", "", "", ""},
       "diffuse reflection albedo (Eq. 3, scene-linear) and fiber specular albedo (Eq. 1)"},
      {"albedo_transmit", {"k_td.r", "k_td.g", "k_td.b", "k_ts"},
       {F(0, 1), F(0, 1), F(0, 1), F(0, 1)}, {"", "", "", ""},
       "diffuse transmission albedo (Eq. 6, scene-linear) and fiber transmission albedo (Eq. 4)"},
      {"spec_params", {"roughness", "optical_thickness", "diffuse_blend", "ior"},
       {F(0.001f, 1), F(0.01f, 100), F(0, 1), F(1, 3)}, {"", "", "", ""},
       "SGGX fiber roughness, SpongeCake optical thickness T, Eq. 3 blend w, fiber IOR"},
      {"horizon_0", {"az0", "az45", "az90", "az135"}, {F(-1, 1), F(-1, 1), F(-1, 1), F(-1, 1)},
       {"sin", "sin", "sin", "sin"}, "sine of the horizon elevation, azimuths 0-135 deg from +x"},
      {"horizon_1", {"az180", "az225", "az270", "az315"},
       {F(-1, 1), F(-1, 1), F(-1, 1), F(-1, 1)}, {"sin", "sin", "sin", "sin"},
       "sine of the horizon elevation, azimuths 180-315 deg from +x"},
  };
  for (size_t k = 0; k < maps.info.size(); ++k) maps.images.emplace_back(W, H, 4);
  Image& frame = maps.images[0];
  Image& nrm = maps.images[1];
  Image& info = maps.images[2];
  Image& alb_r = maps.images[3];
  Image& alb_t = maps.images[4];
  Image& params = maps.images[5];

  const double texel_x = Lx / W, texel_y = Ly / H;
  if (progress) progress("ply maps", 0.0);
  tbb::parallel_for(0, H, [&](int iy) {
    for (int ix = 0; ix < W; ++ix) {
      double x = (ix + 0.5) * texel_x, y = (iy + 0.5) * texel_y;
      int open = 0;
      for (int sj = 0; sj < 4; ++sj)
        for (int si = 0; si < 4; ++si) {
          open += geom.sample(ix * texel_x + (si + 0.5) * texel_x / 4,
                              iy * texel_y + (sj + 0.5) * texel_y / 4, false)
                      .kind == 0;
        }
      float gap = spec.components.gaps ? open / 16.0f : 0.0f;
      GeometrySample s = geom.sample(x, y, true);
      const int kind = s.kind;
      const YarnSpec& ys = kind == 2 ? spec.weft : spec.warp;
      float* f = frame.px(ix, iy);
      f[0] = s.t[0], f[1] = s.t[1], f[2] = s.t[2], f[3] = float(s.height);
      float* n = nrm.px(ix, iy);
      n[0] = s.n[0], n[1] = s.n[1], n[2] = s.n[2], n[3] = s.h;
      float* in = info.px(ix, iy);
      in[0] = gap >= 1.0f ? 0.0f : float(kind);
      in[1] = s.along, in[2] = s.ply_id, in[3] = gap;
      double tau = spec.components.transmission ? ys.transmission : 0.0;
      double spec_w = ys.specular;
      float* ar = alb_r.px(ix, iy);
      float* at = alb_t.px(ix, iy);
      // This thread's colour (its yarn type's under a sequence, else its system's).
      const std::array<double, 3> colour = thread_colour_linear(spec, kind == 2 ? 2 : 1, s.yarn);
      for (int ch = 0; ch < 3; ++ch) {
        ar[ch] = float((1 - spec_w) * (1 - tau) * colour[size_t(ch)]);
        at[ch] = float((1 - spec_w) * tau * colour[size_t(ch)]);
      }
      ar[3] = float(spec_w * (1 - tau));
      at[3] = float(spec_w * tau);
      float* p = params.px(ix, iy);
      p[0] = shading::sggx_fiber_roughness(float(ys.roughness));
      p[1] = float(spec.optical_thickness);
      p[2] = float(spec.diffuse_blend);
      p[3] = float(ys.ior);
    }
  });
  if (progress) progress("ply maps", 1.0);
  if (!horizons) return maps;

  // Horizon map from the height field; open gaps do not occlude.
  Image& h0 = maps.images[6];
  Image& h1 = maps.images[7];
  const float kLow = -1e30f;
  auto height_at = [&](double px, double py) {  // periodic bilinear, texel coordinates
    px -= 0.5, py -= 0.5;
    int x0 = int(std::floor(px)), y0 = int(std::floor(py));
    double fx = px - x0, fy = py - y0;
    auto hv = [&](int ix, int iy) {
      ix = ((ix % W) + W) % W;
      iy = ((iy % H) + H) % H;
      return info.px(ix, iy)[3] >= 1.0f ? double(kLow) : double(frame.px(ix, iy)[3]);
    };
    double a = hv(x0, y0), b = hv(x0 + 1, y0), c = hv(x0, y0 + 1), d = hv(x0 + 1, y0 + 1);
    if (a <= kLow || b <= kLow || c <= kLow || d <= kLow) return std::max({a, b, c, d});
    return (a * (1 - fx) + b * fx) * (1 - fy) + (c * (1 - fx) + d * fx) * fy;
  };
  const int steps = 2 * tpc;
  if (progress) progress("horizon", 0.0);
  tbb::parallel_for(0, H, [&](int iy) {
    for (int ix = 0; ix < W; ++ix) {
      double h_here = frame.px(ix, iy)[3];
      for (int k = 0; k < 8; ++k) {
        double best = -1.0;
        if (spec.components.shadowing) {
          double ang = k * M_PI / 4.0;
          double dx_um = std::cos(ang), dy_um = std::sin(ang);
          double step_um = std::min(texel_x, texel_y);
          for (int st = 1; st <= steps; ++st) {
            double d = st * step_um;
            double hv = height_at(ix + 0.5 + dx_um * d / texel_x, iy + 0.5 + dy_um * d / texel_y);
            if (hv <= kLow) continue;
            double dz = hv - h_here;
            double sine = dz / std::sqrt(dz * dz + d * d);
            best = std::max(best, sine);
          }
          best = std::clamp(best, 0.0, 1.0);  // the tangent plane itself is the lowest horizon
        }
        (k < 4 ? h0 : h1).px(ix, iy)[k % 4] = float(best);
      }
    }
  });
  if (progress) progress("horizon", 1.0);
  return maps;
}

}  // namespace loom
