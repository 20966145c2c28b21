#include "loom/double_layer.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <stdexcept>

namespace loom {
namespace {


/// The layer's h-averaged outgoing energies per simulated theta_i sample and level, weighted by
/// bin solid angle (so they are energies, not densities), and the unscattered fractions.
struct LayerData {
  int M = 0, K = 0, T = 0, P = 0;
  std::vector<double> energy;       // [(k * M + m) * bins + b]
  std::vector<double> unscattered;  // [k * M + m]
  std::vector<Vec3d> dir;           // ply-space bin centres
};

LayerData layer_data(const PlySimResult& sim) {
  const PlySimSettings& st = sim.settings;
  LayerData d;
  d.M = int(sim.theta_i.size());
  d.K = int(st.sigmas.size());
  d.T = st.theta_o_count;
  d.P = st.phi_o_count;
  const size_t bins = size_t(d.T) * size_t(d.P);
  const int N = int(sim.h.size());
  d.energy.assign(size_t(d.K * d.M) * bins, 0.0);
  d.unscattered.assign(size_t(d.K * d.M), 0.0);
  for (int t = 0; t < d.T; ++t)
    for (int p = 0; p < d.P; ++p) d.dir.push_back(ply_sim_bin_direction(st, t, p));
  for (int k = 0; k < d.K; ++k)
    for (int m = 0; m < d.M; ++m) {
      double* e = &d.energy[size_t(k * d.M + m) * bins];
      for (int n = 0; n < N; ++n) {
        const PlySimSlice& sl = sim.slice(m, n);
        d.unscattered[size_t(k * d.M + m)] += sl.energy[size_t(k)].unscattered / N;
        for (int t = 0; t < d.T; ++t) {
          const double om = ply_sim_bin_solid_angle(st, t) / N;
          for (int p = 0; p < d.P; ++p) {
            const size_t b = size_t(t) * size_t(d.P) + size_t(p);
            e[b] += om * (double(sl.refl[b]) + double(sl.high[size_t(k) * bins + b]));
          }
        }
      }
    }
  return d;
}

/// A layer with its data, and the backward/forward integrals R, T over the upper hemisphere on
/// a grid, for the bottom layer of Eq. S.20 (bilinear in theta, periodic in phi).
class LayerModel {
 public:
  LayerModel(const Layer& l) : layer_(l), data_(layer_data(*l.sim)) {}

  /// Scatter a unit beam from surface direction xi (towards the light) off the layer at level k:
  /// out(direction of travel, energy) for every outgoing bin (h-averaged) and for the
  /// unscattered forward delta. Energies sum to 1 - absorbed - truncated.
  void scatter(const Vec3d& xi_in, int k, const std::function<void(const Vec3d&, double)>& out) const {
    const Vec3d a = normalized(layer_.axis), xi = normalized(xi_in);
    const double s = std::clamp(dot(xi, a), -1.0, 1.0);
    Vec3d yp = xi - a * s;
    if (dot(yp, yp) < 1e-18) yp = std::fabs(a.z) < 0.9 ? Vec3d{0, 0, 1} : Vec3d{1, 0, 0};
    yp = normalized(yp - a * dot(yp, a));
    const Vec3d xp = cross(yp, a);
    const std::vector<double>& g = layer_.sim->theta_i;
    double u = (std::asin(s) - g.front()) / (g.back() - g.front()) * (data_.M - 1);
    u = std::clamp(u, 0.0, double(data_.M - 1));
    const int m0 = std::min(int(u), data_.M - 1), m1 = std::min(m0 + 1, data_.M - 1);
    const double w1 = u - m0, w0 = 1 - w1;
    const size_t bins = data_.dir.size();
    const double* e0 = &data_.energy[size_t(k * data_.M + m0) * bins];
    const double* e1 = &data_.energy[size_t(k * data_.M + m1) * bins];
    for (size_t b = 0; b < bins; ++b) {
      const double e = w0 * e0[b] + w1 * e1[b];
      if (e <= 0) continue;
      const Vec3d& d = data_.dir[b];
      out(xp * d.x + yp * d.y + a * d.z, e);
    }
    const double un = w0 * data_.unscattered[size_t(k * data_.M + m0)] +
                      w1 * data_.unscattered[size_t(k * data_.M + m1)];
    if (un > 0) out(xi * -1, un);
  }

  /// Backward (same side as xi) and forward energies for light from xi.
  std::pair<double, double> back_forward(const Vec3d& xi, int k) const {
    double B = 0, F = 0;
    const double side = xi.z >= 0 ? 1 : -1;
    scatter(xi, k, [&](const Vec3d& d, double e) {
      double z = d.z * side;
      if (z > 0) B += e;
      else if (z < 0) F += e;
      else B += e / 2, F += e / 2;
    });
    return {B, F};
  }

  void build_hemisphere(int rows, int cols) {
    rows_ = rows, cols_ = cols;
    const int K = data_.K;
    R_.assign(size_t(K * rows * cols), 0.0);
    T_.assign(size_t(K * rows * cols), 0.0);
    tbb::parallel_for(0, K * rows, [&](int kr) {
      const int k = kr / rows, r = kr % rows;
      for (int c = 0; c < cols; ++c) {
        auto [B, F] = back_forward(grid_dir(r, c), k);
        R_[size_t((k * rows + r) * cols + c)] = B;
        T_[size_t((k * rows + r) * cols + c)] = F;
      }
    });
  }
  /// Bilinear look-up of R, T for xi in the upper hemisphere (theta from the normal).
  std::pair<double, double> hemisphere(const Vec3d& xi, int k) const {
    const double th = std::acos(std::clamp(xi.z, -1.0, 1.0));
    double ph = std::atan2(xi.y, xi.x);
    if (ph < 0) ph += 2 * M_PI;
    const double u = std::clamp(th / (M_PI / 2) * rows_ - 0.5, 0.0, double(rows_ - 1));
    const double v = ph / (2 * M_PI) * cols_ - 0.5;
    const int r0 = std::min(int(u), rows_ - 1), r1 = std::min(r0 + 1, rows_ - 1);
    const double fr = u - r0;
    const int c0f = int(std::floor(v));
    const double fc = v - c0f;
    const int c0 = ((c0f % cols_) + cols_) % cols_, c1 = (c0 + 1) % cols_;
    auto at = [&](const std::vector<double>& X, int r, int c) {
      return X[size_t((k * rows_ + r) * cols_ + c)];
    };
    auto lerp2 = [&](const std::vector<double>& X) {
      return (1 - fr) * ((1 - fc) * at(X, r0, c0) + fc * at(X, r0, c1)) +
             fr * ((1 - fc) * at(X, r1, c0) + fc * at(X, r1, c1));
    };
    return {lerp2(R_), lerp2(T_)};
  }
  int levels() const { return data_.K; }

 private:
  Vec3d grid_dir(int r, int c) const {
    const double th = (r + 0.5) * (M_PI / 2) / rows_, ph = (c + 0.5) * 2 * M_PI / cols_;
    return {std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th)};
  }
  Layer layer_;
  LayerData data_;
  int rows_ = 0, cols_ = 0;
  std::vector<double> R_, T_;
};

DoubleLayerFactors factors(const LayerModel& top, const LayerModel& bottom, const Vec3d& xi, int k) {
  DoubleLayerFactors f;
  top.scatter(xi, k, [&](const Vec3d& d, double e) {
    if (d.z > 0) {
      f.Bt += e;
    } else if (d.z < 0) {
      f.Ft += e;
      // The bottom layer lit from -d (towards the top layer, +z side).
      auto [R, T] = bottom.hemisphere(d * -1, k);
      f.Bb += e * R;
      f.Fb += e * T;
    } else {
      f.Bt += e / 2, f.Ft += e / 2;
    }
  });
  // Eq. S.20 with B_tb = B_b / F_t, F_tb = F_b / F_t.
  if (f.Ft > 1e-12) {
    const double Btb = std::clamp(f.Bb / f.Ft, 0.0, 1.0), Ftb = std::clamp(f.Fb / f.Ft, 0.0, 1.0);
    const double series = f.Ft * Ftb / std::max(1 - Btb * Btb, 1e-9);
    f.Ftotal = series;
    f.Btotal = f.Bt + Btb * series;
  } else {
    f.Btotal = f.Bt;
    f.Ftotal = 0;
  }
  return f;
}

constexpr int kHemiRows = 32, kHemiCols = 64;

}  // namespace

DoubleLayerSettings double_layer_settings(Quality q) {
  switch (q) {
    case Quality::Draft: return {8, 16};
    case Quality::Preview: return {12, 24};
    case Quality::Final: return {16, 32};
    case Quality::Reference: return {24, 48};
  }
  return {};
}

DoubleLayerFactors double_layer_factors(const Layer& top, const Layer& bottom, const Vec3d& xi,
                                        int k) {
  LayerModel t(top), b(bottom);
  b.build_hemisphere(kHemiRows, kHemiCols);
  return factors(t, b, xi, k);
}

DoubleLayerTable double_layer_table(const Layer& top, const Layer& bottom,
                                    const DoubleLayerSettings& s) {
  if (s.theta_count < 1 || s.phi_count < 1)
    throw std::invalid_argument("double_layer: table sizes must be positive");
  LayerModel t(top), b(bottom);
  b.build_hemisphere(kHemiRows, kHemiCols);
  DoubleLayerTable out;
  out.settings = s;
  out.sigmas = top.sim->settings.sigmas;
  const int K = std::min(t.levels(), b.levels());
  out.values.assign(size_t(K * s.theta_count * s.phi_count), {});
  tbb::parallel_for(0, K * s.theta_count, [&](int kt) {
    const int k = kt / s.theta_count, r = kt % s.theta_count;
    for (int c = 0; c < s.phi_count; ++c) {
      const double th = (r + 0.5) * (M_PI / 2) / s.theta_count,
                   ph = (c + 0.5) * 2 * M_PI / s.phi_count;
      Vec3d xi{std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th)};
      out.values[size_t((k * s.theta_count + r) * s.phi_count + c)] = factors(t, b, xi, k);
    }
  });
  return out;
}

std::pair<double, double> double_layer_brute_force(const Layer& top, const Layer& bottom,
                                                   const Vec3d& xi, int k, int rows,
                                                   double tolerance) {
  // Directions of travel on a grid of equal solid angle: 2 rows uniform in z, 4 rows in phi.
  LayerModel t(top), b(bottom);
  const int R = 2 * rows, C = 4 * rows;
  auto cell = [&](const Vec3d& d) {
    int r = std::clamp(int((d.z + 1) / 2 * R), 0, R - 1);
    double ph = std::atan2(d.y, d.x);
    if (ph < 0) ph += 2 * M_PI;
    int c = std::clamp(int(ph / (2 * M_PI) * C), 0, C - 1);
    return r * C + c;
  };
  auto centre = [&](int id) {
    const int r = id / C, c = id % C;
    const double z = -1 + 2 * (r + 0.5) / R, s = std::sqrt(std::max(0.0, 1 - z * z));
    const double ph = 2 * M_PI * (c + 0.5) / C;
    return Vec3d{s * std::cos(ph), s * std::sin(ph), z};
  };
  std::vector<double> down(size_t(R * C), 0.0), up(size_t(R * C), 0.0);
  double B = 0, F = 0;
  t.scatter(xi, k, [&](const Vec3d& d, double e) {
    if (d.z > 0) B += e;
    else down[size_t(cell(d))] += e;
  });
  for (int bounce = 0; bounce < 10000; ++bounce) {
    std::fill(up.begin(), up.end(), 0.0);
    for (int id = 0; id < R * C; ++id) {
      if (down[size_t(id)] <= 0) continue;
      const double w = down[size_t(id)];
      Vec3d d = centre(id);
      if (d.z >= 0) d.z = -1e-6;  // a cell on the equator still travels down
      b.scatter(d * -1, k, [&](const Vec3d& d2, double e) {
        if (d2.z < 0) F += w * e;
        else up[size_t(cell(d2))] += w * e;
      });
    }
    std::fill(down.begin(), down.end(), 0.0);
    double between = 0;
    for (int id = 0; id < R * C; ++id) {
      if (up[size_t(id)] <= 0) continue;
      const double w = up[size_t(id)];
      Vec3d d = centre(id);
      if (d.z <= 0) d.z = 1e-6;
      t.scatter(d * -1, k, [&](const Vec3d& d2, double e) {
        if (d2.z > 0) B += w * e;
        else down[size_t(cell(d2))] += w * e, between += w * e;
      });
    }
    if (between < tolerance) break;
  }
  return {B, F};
}

}  // namespace loom
