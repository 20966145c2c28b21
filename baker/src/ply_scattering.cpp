#include "loom/ply_scattering.h"

#include "loom/fiber_optics.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace loom {
namespace {

int64_t floor_div(int64_t a, int64_t b) { return a / b - ((a % b != 0) && ((a < 0) != (b < 0))); }

/// Smallest multiple q (1..8) of the pitch that holds whole migration cycles.
int period_in_pitches(double s) {
  for (int q = 1; q <= 8; ++q)
    if (std::fabs(q * s - std::round(q * s)) < 1e-6) return q;
  return 8;
}

constexpr double kEps = 1e-4;  // um: self-intersection guard (fiber radii are >= 0.5 um)

}  // namespace

PlySimSettings ply_sim_settings(Quality q) {
  PlySimSettings s;
  auto levels = [](int K) {
    // sigma_0 = 0, then log-spaced from 10/mm to 3000/mm (a 15 um fiber path keeps 86% .. 1e-20).
    std::vector<double> v{0};
    for (int k = 1; k < K; ++k) v.push_back(10 * std::pow(300.0, double(k - 1) / (K - 2)));
    return v;
  };
  switch (q) {
    case Quality::Draft:
      s.theta_i_count = 7, s.h_count = 7, s.theta_o_count = 24, s.phi_o_count = 48;
      s.rays_per_slice = 8000, s.sigmas = levels(4);
      break;
    case Quality::Preview:
      s.theta_i_count = 9, s.h_count = 9, s.theta_o_count = 32, s.phi_o_count = 64;
      s.rays_per_slice = 20000, s.sigmas = levels(5);
      break;
    case Quality::Final:
      s.theta_i_count = 13, s.h_count = 13, s.theta_o_count = 48, s.phi_o_count = 96;
      s.rays_per_slice = 60000, s.sigmas = levels(6);
      break;
    case Quality::Reference:
      s.theta_i_count = 17, s.h_count = 17, s.theta_o_count = 64, s.phi_o_count = 128;
      s.rays_per_slice = 200000, s.sigmas = levels(8);
      break;
  }
  return s;
}

double ply_sim_bin_solid_angle(const PlySimSettings& s, int t) {
  double lo = -M_PI / 2 + M_PI * t / s.theta_o_count, hi = lo + M_PI / s.theta_o_count;
  return (std::sin(hi) - std::sin(lo)) * 2 * M_PI / s.phi_o_count;
}

Vec3d ply_sim_bin_direction(const PlySimSettings& s, int t, int p) {
  double th = -M_PI / 2 + M_PI * (t + 0.5) / s.theta_o_count;
  double ph = -M_PI + 2 * M_PI * (p + 0.5) / s.phi_o_count;
  return {std::cos(th) * std::cos(ph), std::cos(th) * std::sin(ph), std::sin(th)};
}

void ply_sim_bin_of(const PlySimSettings& s, const Vec3d& w, int& t, int& p) {
  double th = std::asin(std::clamp(w.z, -1.0, 1.0)), ph = std::atan2(w.y, w.x);
  t = std::clamp(int(std::floor((th + M_PI / 2) / M_PI * s.theta_o_count)), 0, s.theta_o_count - 1);
  p = int(std::floor((ph + M_PI) / (2 * M_PI) * s.phi_o_count));
  p = ((p % s.phi_o_count) + s.phi_o_count) % s.phi_o_count;
}

// ---------------------------------------------------------------- geometry

PlyGeometry::PlyGeometry(const PlyParams& p, const std::vector<Fiber>& fibers) {
  if (!(p.pitch > 0) || !(p.fiber_radius > 0) || fibers.empty())
    throw std::invalid_argument("ply geometry needs a positive pitch, fiber radius and fibers");
  const int q = period_in_pitches(p.s);
  period_ = p.pitch * q;
  r_ = p.fiber_radius;
  const int n = kSegmentsPerPitch * q;
  double bound = 0;
  std::vector<std::pair<Vec3d, Vec3d>> ends;
  for (const Fiber& f : fibers) {
    Vec3d a = fiber_in_ply(p, f, 0);
    for (int k = 0; k < n; ++k) {
      Vec3d b = fiber_in_ply(p, f, period_ * (k + 1) / n);
      Segment sg;
      sg.p0 = a;
      Vec3d ab = b - a;
      sg.len = std::sqrt(dot(ab, ab));
      sg.axis = ab * (1 / sg.len);
      bound = std::max({bound, std::hypot(a.x, a.y), std::hypot(b.x, b.y)});
      seg_.push_back(sg);
      ends.push_back({a, b});
      a = b;
    }
  }
  bound_ = bound + r_ * 1.001;
  // Cells about one fiber diameter wide (at most 64 per side), one segment step high.
  nx_ = std::clamp(int(std::ceil(2 * bound_ / (2 * r_))), 1, 64);
  cell_xy_ = 2 * bound_ / nx_;
  nz_ = n;
  cell_z_ = period_ / nz_;
  std::vector<std::vector<int>> cells(size_t(nx_) * size_t(nx_) * size_t(nz_));
  for (size_t id = 0; id < ends.size(); ++id) {
    auto [a, b] = ends[id];
    auto cx = [&](double v) { return std::clamp(int(std::floor((v + bound_) / cell_xy_)), 0, nx_ - 1); };
    int x0 = cx(std::min(a.x, b.x) - r_), x1 = cx(std::max(a.x, b.x) + r_);
    int y0 = cx(std::min(a.y, b.y) - r_), y1 = cx(std::max(a.y, b.y) + r_);
    int z0 = int(std::floor((a.z - r_) / cell_z_)), z1 = int(std::floor((b.z + r_) / cell_z_));
    for (int iz = z0; iz <= z1; ++iz)
      for (int iy = y0; iy <= y1; ++iy)
        for (int ix = x0; ix <= x1; ++ix)
          cells[size_t(cell_index(ix, iy, ((iz % nz_) + nz_) % nz_))].push_back(int(id));
  }
  cell_start_.assign(cells.size() + 1, 0);
  for (size_t c = 0; c < cells.size(); ++c) cell_start_[c + 1] = cell_start_[c] + int(cells[c].size());
  cell_seg_.reserve(size_t(cell_start_.back()));
  for (auto& c : cells) cell_seg_.insert(cell_seg_.end(), c.begin(), c.end());
}

bool PlyGeometry::intersect_entry(const Vec3d& o, const Vec3d& d, double t_min, Hit& hit) const {
  // The span of the ray inside the bounding cylinder.
  double a = d.x * d.x + d.y * d.y, b = 2 * (o.x * d.x + o.y * d.y),
         c = o.x * o.x + o.y * o.y - bound_ * bound_;
  double t0, t1;
  if (a < 1e-18) {
    if (c > 0) return false;
    t0 = t_min;
    t1 = t_min + period_ / std::max(std::fabs(d.z), 1e-12);  // one period along the axis suffices
  } else {
    double disc = b * b - 4 * a * c;
    if (disc <= 0) return false;
    double sq = std::sqrt(disc);
    t0 = (-b - sq) / (2 * a), t1 = (-b + sq) / (2 * a);
  }
  t0 = std::max(t0, t_min);
  if (t1 <= t0) return false;

  double best = INFINITY;
  auto test_cell = [&](int ix, int iy, int64_t iz) {
    const int64_t zi = floor_div(iz, nz_);
    const double zoff = double(zi) * period_;
    const Vec3d oo{o.x, o.y, o.z - zoff};
    const int cell = cell_index(ix, iy, int(iz - zi * nz_));
    for (int k = cell_start_[size_t(cell)]; k < cell_start_[size_t(cell) + 1]; ++k) {
      const int id = cell_seg_[size_t(k)];
      const Segment& s = seg_[size_t(id)];
      Vec3d D = oo - s.p0;
      double da = dot(d, s.axis), Da = dot(D, s.axis);
      Vec3d dp = d - s.axis * da, Dp = D - s.axis * Da;
      double qa = dot(dp, dp);
      if (qa < 1e-18) continue;
      double qb = 2 * dot(Dp, dp), qc = dot(Dp, Dp) - r_ * r_;
      double disc = qb * qb - 4 * qa * qc;
      if (disc <= 0) continue;
      double t = (-qb - std::sqrt(disc)) / (2 * qa);
      if (t <= t_min || t >= best) continue;
      double ax = Da + t * da;
      if (ax < 0 || ax > s.len) continue;
      best = t;
      hit.t = t;
      hit.segment = id;
      hit.z_offset = zoff;
      hit.normal = normalized(Dp + dp * t);
    }
  };
  // 3D DDA from the entry point (z unwrapped; cells repeat every period).
  const Vec3d p0 = o + d * t0;
  int ix = std::clamp(int(std::floor((p0.x + bound_) / cell_xy_)), 0, nx_ - 1);
  int iy = std::clamp(int(std::floor((p0.y + bound_) / cell_xy_)), 0, nx_ - 1);
  int64_t iz = int64_t(std::floor(p0.z / cell_z_));
  auto axis_setup = [&](double dcomp, double pos, double lo, double size, int64_t idx,
                        int& step, double& tmax, double& tdelta) {
    if (std::fabs(dcomp) < 1e-15) {
      step = 0, tmax = INFINITY, tdelta = INFINITY;
      return;
    }
    step = dcomp > 0 ? 1 : -1;
    double edge = lo + (double(idx) + (step > 0 ? 1 : 0)) * size;
    tmax = t0 + (edge - pos) / dcomp;
    tdelta = size / std::fabs(dcomp);
  };
  int sx, sy, sz;
  double tmx, tmy, tmz, tdx, tdy, tdz;
  axis_setup(d.x, p0.x, -bound_, cell_xy_, ix, sx, tmx, tdx);
  axis_setup(d.y, p0.y, -bound_, cell_xy_, iy, sy, tmy, tdy);
  axis_setup(d.z, p0.z, 0.0, cell_z_, iz, sz, tmz, tdz);
  const int64_t max_steps = int64_t(nx_) * 2 + int64_t(nz_) + 16 +
                            int64_t((t1 - t0) * std::fabs(d.z) / cell_z_);
  for (int64_t step = 0; step < max_steps; ++step) {
    test_cell(ix, iy, iz);
    const double t_leave = std::min({tmx, tmy, tmz});
    if (best <= t_leave) return true;
    if (t_leave >= t1) break;
    if (tmx <= tmy && tmx <= tmz) {
      ix += sx, tmx += tdx;
      if (ix < 0 || ix >= nx_) break;
    } else if (tmy <= tmz) {
      iy += sy, tmy += tdy;
      if (iy < 0 || iy >= nx_) break;
    } else {
      iz += sz, tmz += tdz;
    }
  }
  return best < INFINITY;
}

bool PlyGeometry::intersect_exit(int segment, double z_offset, const Vec3d& o, const Vec3d& d,
                                 Hit& hit) const {
  const Segment& s = seg_[size_t(segment)];
  if (!cylinder_exit(s.p0, s.axis, r_, Vec3d{o.x, o.y, o.z - z_offset}, d, hit.t, hit.normal))
    return false;
  hit.segment = segment;
  hit.z_offset = z_offset;
  return true;
}

// ---------------------------------------------------------------- simulation

namespace {

/// Inside the fiber that `entry` entered, from o along d: bounces off its wall (Fresnel picks
/// internal reflection) until the ray refracts out, adding the path length to `len` and each
/// wall event to `events`; o and d are then where and how it leaves. False when the path
/// reaches max_events first (truncated).
bool trace_inside_fiber(const PlyGeometry& g, const PlyGeometry::Hit& entry, double ior,
                        int max_events, RayRng& rng, Vec3d& o, Vec3d& d, double& len,
                        int& events) {
  for (;;) {
    PlyGeometry::Hit ex;
    if (!g.intersect_exit(entry.segment, entry.z_offset, o, d, ex)) {
      ex.t = 0;  // numerically tangent: leave where we are
      ex.normal = entry.normal;
    }
    len += ex.t;
    Vec3d q = o + d * ex.t;
    double ci = dot(d, ex.normal), cto;  // > 0: leaving through the wall
    if (ci <= 0) {  // rounding put us outside already
      o = q;
      return true;
    }
    double Fi = fresnel_dielectric(ci, 1 / ior, cto);
    events += 1;
    if (events >= max_events) return false;
    if (rng.next() < Fi) {  // internal reflection
      o = q;
      d = reflected(d, ex.normal);
      continue;
    }
    o = q;
    d = refracted(d, ex.normal * -1.0, ci, cto, 1 / ior);
    return true;
  }
}

}  // namespace

PlySimSlice simulate_ply_slice(const PlyGeometry& g, double ior, const PlySimSettings& s,
                               double theta_i, double h, uint64_t slice_index) {
  const int T = s.theta_o_count, P = s.phi_o_count, K = int(s.sigmas.size());
  const size_t bins = size_t(T) * size_t(P);
  PlySimSlice out;
  out.theta_i = theta_i;
  out.h = h;
  out.energy.assign(size_t(K), {});
  std::vector<double> refl(bins, 0), high(bins * size_t(K), 0);
  double unscattered = 0, reflected_w = 0;
  std::vector<double> high_e(size_t(K), 0), trunc_e(size_t(K), 0);
  std::vector<double> sig_um(static_cast<size_t>(K));
  for (int k = 0; k < K; ++k) sig_um[size_t(k)] = s.sigmas[size_t(k)] * 1e-3;  // 1/mm -> 1/um

  const double R_ply = g.bound_radius();
  const double w = s.beam_halfwidth >= 0 ? s.beam_halfwidth
                                         : (s.h_count > 1 ? 1.0 / (s.h_count - 1) : 0.5);
  const double ct = std::cos(theta_i), st = std::sin(theta_i);
  const Vec3d d0{0, -ct, -st};

  struct Path {
    Vec3d o, d;
    double weight = 1, len = 0;
    int events = 0;
    bool pure_refl = false;
  };
  auto escape = [&](const Path& pa) {
    if (pa.events == 0) {
      unscattered += pa.weight;
      return;
    }
    int t, p;
    ply_sim_bin_of(s, pa.d, t, p);
    size_t b = size_t(t) * size_t(P) + size_t(p);
    if (pa.pure_refl) {
      refl[b] += pa.weight;
      reflected_w += pa.weight;
      return;
    }
    for (int k = 0; k < K; ++k) {
      double e = pa.weight * std::exp(-sig_um[size_t(k)] * pa.len);
      high[size_t(k) * bins + b] += e;
      high_e[size_t(k)] += e;
    }
  };

  const int N = s.rays_per_slice;
  for (int r = 0; r < N; ++r) {
    RayRng rng(s.seed, slice_index, uint64_t(r));
    const double x = (h + w * (2 * rng.next() - 1)) * R_ply;
    const double z = rng.next() * g.period();
    if (ct < 1e-6) {  // along the ply axis: the beam never meets the ply
      unscattered += 1;
      continue;
    }
    const double back = (g.bound_radius() * 1.01) / ct;
    Path stack[2];
    int top = 0;
    stack[top++] = Path{Vec3d{x, 0, z} - d0 * back, d0, 1.0, 0.0, 0, false};
    while (top > 0) {
      Path pa = stack[--top];
      for (;;) {
        PlyGeometry::Hit hit;
        if (!g.intersect_entry(pa.o, pa.d, kEps, hit)) {
          escape(pa);
          break;
        }
        if (pa.events >= s.max_events) {
          for (int k = 0; k < K; ++k) trunc_e[size_t(k)] += pa.weight * std::exp(-sig_um[size_t(k)] * pa.len);
          break;
        }
        Vec3d pos = pa.o + pa.d * hit.t;
        double cos_i = -dot(pa.d, hit.normal), cos_t;
        double F = fresnel_dielectric(cos_i, ior, cos_t);
        Vec3d refl_d = reflected(pa.d, hit.normal);
        Vec3d refr_d = refracted(pa.d, hit.normal, cos_i, cos_t, ior);
        bool reflect;
        if (pa.events == 0) {
          // First hit: follow both branches with their Fresnel weights.
          Path rp{pos, refl_d, pa.weight * F, pa.len, 1, true};
          stack[top++] = rp;
          pa.weight *= 1 - F;
          reflect = false;
        } else {
          reflect = rng.next() < F;
        }
        pa.events += 1;
        if (reflect) {
          pa.pure_refl = false;
          pa.o = pos;
          pa.d = refl_d;
          continue;
        }
        pa.pure_refl = false;
        Vec3d o = pos, d = refr_d;
        if (!trace_inside_fiber(g, hit, ior, s.max_events, rng, o, d, pa.len, pa.events)) {
          for (int k = 0; k < K; ++k) trunc_e[size_t(k)] += pa.weight * std::exp(-sig_um[size_t(k)] * pa.len);
          break;
        }
        pa.o = o;
        pa.d = d;
      }
    }
  }

  out.refl.assign(bins, 0);
  out.high.assign(bins * size_t(K), 0);
  for (int t = 0; t < T; ++t) {
    double norm = 1.0 / (double(N) * ply_sim_bin_solid_angle(s, t));
    for (int p = 0; p < P; ++p) {
      size_t b = size_t(t) * size_t(P) + size_t(p);
      out.refl[b] = float(refl[b] * norm);
      for (int k = 0; k < K; ++k) out.high[size_t(k) * bins + b] = float(high[size_t(k) * bins + b] * norm);
    }
  }
  for (int k = 0; k < K; ++k) {
    PlySimEnergy& e = out.energy[size_t(k)];
    e.reflected = reflected_w / N;
    e.unscattered = unscattered / N;
    e.higher_order = high_e[size_t(k)] / N;
    e.truncated = trunc_e[size_t(k)] / N;
    e.absorbed = std::max(0.0, 1 - e.reflected - e.unscattered - e.higher_order - e.truncated);
  }
  return out;
}

PlySimResult simulate_ply_scattering(const PlyParams& p, double ior, const PlySimSettings& s) {
  if (s.theta_i_count < 3 || s.theta_i_count % 2 == 0 || s.h_count < 3 || s.h_count % 2 == 0)
    throw std::invalid_argument("ply simulation: theta_i and h sample counts must be odd and >= 3");
  if (s.sigmas.empty() || s.sigmas[0] != 0)
    throw std::invalid_argument("ply simulation: the first absorption level must be 0");
  PlyGeometry g(p, make_ply_fibers(p, 0, 0));
  PlySimResult res;
  res.settings = s;
  const double tmax = s.theta_i_max_deg * M_PI / 180;
  for (int m = 0; m < s.theta_i_count; ++m)
    res.theta_i.push_back(-tmax + 2 * tmax * m / (s.theta_i_count - 1));
  for (int n = 0; n < s.h_count; ++n) res.h.push_back(-1 + 2.0 * n / (s.h_count - 1));
  const size_t count = size_t(s.theta_i_count) * size_t(s.h_count);
  res.slices.resize(count);
  tbb::parallel_for(size_t(0), count, [&](size_t i) {
    size_t m = i / size_t(s.h_count), n = i % size_t(s.h_count);
    res.slices[i] = simulate_ply_slice(g, ior, s, res.theta_i[m], res.h[n], i);
  });
  res.rays = uint64_t(count) * uint64_t(s.rays_per_slice);
  res.silhouette_radius_um = g.bound_radius();
  return res;
}

}  // namespace loom
