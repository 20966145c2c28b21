#include "loom/asg_fit.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <stdexcept>
#include <thread>

#include "asg_fit_grid.h"
#include "loom/shading.h"

namespace loom {
namespace {

namespace sh = shading;
constexpr int kQ = 6;  // parameters per lobe

AsgLobe lobe_from(const double* q) { return {q[0], q[1], q[2], q[3], q[4], q[5]}; }

/// One slice of a block (S.4 with S.5): residuals sqrt(Omega_b) (sum_l G_l(q_l) - f_b), with
/// q_l = sum_c w_c q_{c,l} over the corner parameter blocks that carry weight.
class SliceCost final : public ceres::CostFunction {
 public:
  SliceCost(const FitGrid& g, const double* data, std::vector<double> w, int lobes)
      : g_(g), data_(data), w_(std::move(w)), L_(lobes) {
    set_num_residuals(int(g.bins()));
    for (size_t c = 0; c < w_.size(); ++c) mutable_parameter_block_sizes()->push_back(kQ * L_);
  }
  bool Evaluate(double const* const* params, double* residuals, double** jac) const override {
    std::vector<double> q(size_t(kQ * L_), 0.0);
    for (size_t c = 0; c < w_.size(); ++c)
      for (int i = 0; i < kQ * L_; ++i) q[size_t(i)] += w_[c] * params[c][i];
    const int P = kQ * L_;
    std::vector<double> grad(static_cast<size_t>(P));
    std::vector<float> trig(size_t(6 * L_));  // sin, cos of theta_z, phi_z, phi_xy per lobe
    for (int l = 0; l < L_; ++l)
      for (int i = 0; i < 3; ++i) {
        trig[size_t(6 * l + 2 * i)] = float(std::sin(q[size_t(kQ * l + i)]));
        trig[size_t(6 * l + 2 * i + 1)] = float(std::cos(q[size_t(kQ * l + i)]));
      }
    for (size_t b = 0; b < g_.bins(); ++b) {
      const double sw = std::sqrt(g_.weight[b]);
      double sum = 0;
      for (int l = 0; l < L_; ++l) {
        const double* ql = &q[size_t(kQ * l)];
        const float* tr = &trig[size_t(6 * l)];
        sh::vec3 ga, gs;
        sum += sh::asg_eval_grad_trig(tr[0], tr[1], tr[2], tr[3], tr[4], tr[5], float(ql[3]),
                                      float(ql[4]), float(ql[5]), g_.dir[b], ga, gs);
        double* gl = &grad[size_t(kQ * l)];
        gl[0] = ga.x, gl[1] = ga.y, gl[2] = ga.z, gl[3] = gs.x, gl[4] = gs.y, gl[5] = gs.z;
      }
      residuals[b] = sw * (sum - data_[b]);
      if (!jac) continue;
      for (size_t c = 0; c < w_.size(); ++c) {
        if (!jac[c]) continue;
        double* row = jac[c] + b * size_t(P);
        for (int i = 0; i < P; ++i) row[i] = sw * w_[c] * grad[size_t(i)];
      }
    }
    return true;
  }

 private:
  const FitGrid& g_;
  const double* data_;
  std::vector<double> w_;
  int L_;
};

/// Bounds of a free parameter block. The azimuths stay within half a turn of their start
/// (phi_z within pi, phi_xy within pi/2, its period): unbounded, an optimiser may move a corner's
/// angle by whole turns, which leaves the fitted slices unchanged but makes S.7's bilinear
/// interpolation sweep the lobe round the ply between them.
/// The side of the ply a lobe must stay on (asg_fit.h, AsgFitSettings::split_sides): the first
/// Lb lobes backward (centre towards the beam's source in the ply's cross-section, sin phi_z > 0,
/// as omega_i = (0, cos theta_i, sin theta_i)), the others forward (sin phi_z < 0); Lb = 0: free.
/// Returns the interval of phi_z (unwrapped next to `phi`) for lobe l.
void side_interval(int l, int Lb, double phi, double& lo, double& hi) {
  if (Lb == 0) {
    lo = phi - M_PI, hi = phi + M_PI;
    return;
  }
  constexpr double eps = 1e-3;
  const double base = l < Lb ? 0.0 : -M_PI;  // back (0, pi), forward (-pi, 0), mod 2 pi
  const double k = std::floor((phi - base) / (2 * M_PI));
  lo = base + 2 * M_PI * k + eps, hi = base + 2 * M_PI * k + M_PI - eps;
}

/// Backward lobes of L when the sides are split (side_interval).
int back_lobes(int L, bool split) { return split && L >= 2 ? L / 2 : 0; }

void set_bounds(ceres::Problem& pb, double* q, int L, int Lb, double mu_max, double c_max) {
  for (int l = 0; l < L; ++l) {
    pb.SetParameterLowerBound(q, kQ * l + 0, -M_PI / 2);
    pb.SetParameterUpperBound(q, kQ * l + 0, M_PI / 2);
    double lo, hi;
    side_interval(l, Lb, q[kQ * l + 1], lo, hi);
    pb.SetParameterLowerBound(q, kQ * l + 1, lo);
    pb.SetParameterUpperBound(q, kQ * l + 1, hi);
    pb.SetParameterLowerBound(q, kQ * l + 2, q[kQ * l + 2] - M_PI / 2);
    pb.SetParameterUpperBound(q, kQ * l + 2, q[kQ * l + 2] + M_PI / 2);
    for (int i : {3, 4}) {
      pb.SetParameterLowerBound(q, kQ * l + i, 0.0);
      pb.SetParameterUpperBound(q, kQ * l + i, mu_max);
    }
    pb.SetParameterLowerBound(q, kQ * l + 5, 0.0);
    pb.SetParameterUpperBound(q, kQ * l + 5, c_max);
  }
}

void clamp_to_bounds(double* q, int L, int Lb, double mu_max, double c_max) {
  for (int l = 0; l < L; ++l) {
    double* ql = q + kQ * l;
    ql[0] = std::clamp(ql[0], -M_PI / 2 + 1e-9, M_PI / 2 - 1e-9);
    if (Lb > 0) {  // onto the lobe's side: the nearer end of its interval
      double lo, hi;
      side_interval(l, Lb, ql[1], lo, hi);
      if (ql[1] < lo || ql[1] > hi) {
        const double a = ql[1] < lo ? lo : hi;  // same turn; also try the other turns' ends
        double best = a;
        for (double cand : {lo, hi, lo + 2 * M_PI, hi - 2 * M_PI})
          if (std::fabs(cand - ql[1]) < std::fabs(best - ql[1])) best = cand;
        side_interval(l, Lb, best, lo, hi);
        ql[1] = std::clamp(best, lo, hi);
      }
    }
    ql[3] = std::clamp(ql[3], 0.0, mu_max);
    ql[4] = std::clamp(ql[4], 0.0, mu_max);
    ql[5] = std::clamp(ql[5], 0.0, c_max);
  }
}

ceres::Solver::Options solver_options(const AsgFitSettings& s) {
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
  o.max_num_iterations = s.max_iterations;
  o.num_threads = s.threads > 0 ? s.threads : int(std::max(1u, std::thread::hardware_concurrency()));
  o.logging_type = ceres::SILENT;
  o.minimizer_progress_to_stdout = false;
  o.function_tolerance = 1e-7;
  return o;
}

/// Greedy start for L lobes on one slice: the peak of what remains, half-maximum widths along
/// the azimuth (x0 of S.2) and the elevation (y0), subtract, repeat.
void greedy_init(const FitGrid& g, const double* f, int L, int Lb, double mu_max, double* q) {
  std::vector<double> r(f, f + g.bins());
  const double dth = M_PI / g.rows, dph = 2 * M_PI / g.cols;
  for (int l = 0; l < L; ++l) {
    double* ql = q + kQ * l;
    // With split sides, the peak of what remains on the lobe's own side.
    const int half = Lb == 0 ? 0 : (l < Lb ? 1 : -1);
    size_t best = 0;
    double peak = -1;
    for (size_t b = 0; b < g.bins(); ++b)
      if ((half == 0 || (half > 0) == (g.dir[b].y > 0)) && r[b] > peak) peak = r[b], best = b;
    const sh::vec3 d = g.dir[best];
    ql[0] = std::asin(std::clamp(double(d.z), -1.0, 1.0));
    ql[1] = std::atan2(double(d.y), double(d.x));
    ql[2] = 0;
    if (!(peak > 0)) {
      if (half != 0) ql[0] = 0, ql[1] = half * M_PI / 2;
      ql[3] = ql[4] = 1, ql[5] = 0;
      continue;
    }
    const int row = int(best) / g.cols, col = int(best) % g.cols;
    int up = 0, side = 0;
    while (row + up + 1 < g.rows && r[size_t((row + up + 1) * g.cols + col)] > peak / 2) ++up;
    while (side + 1 < g.cols / 2 && r[size_t(row * g.cols + (col + side + 1) % g.cols)] > peak / 2)
      ++side;
    double d_el = std::max((up + 0.5) * dth, 0.5 * dth);
    double d_az = std::max((side + 0.5) * dph * std::cos(ql[0]), 0.5 * dth);
    ql[3] = std::clamp(std::log(2.0) / std::pow(std::sin(std::min(d_az, 1.5)), 2), 0.0, mu_max);
    ql[4] = std::clamp(std::log(2.0) / std::pow(std::sin(std::min(d_el, 1.5)), 2), 0.0, mu_max);
    ql[5] = peak;
    for (size_t b = 0; b < g.bins(); ++b)
      r[b] = std::max(0.0, r[b] - sh::asg_eval(float(ql[0]), float(ql[1]), float(ql[2]),
                                               float(ql[3]), float(ql[4]), float(ql[5]), g.dir[b]));
  }
}

/// Fit the lobes q of one slice alone (a start for the block fit); returns the final cost.
double single_slice_fit(const FitGrid& g, const double* f, int L, int Lb,
                        const AsgFitSettings& s, double c_max, double* q) {
  clamp_to_bounds(q, L, Lb, s.mu_max, c_max);
  ceres::Problem pb;
  pb.AddResidualBlock(new SliceCost(g, f, {1.0}, L), nullptr, q);
  set_bounds(pb, q, L, Lb, s.mu_max, c_max);
  ceres::Solver::Summary sum;
  ceres::Solve(solver_options(s), &pb, &sum);
  return sum.final_cost;
}

/// Reorder lobes b to follow lobes a (greedy nearest centres) and unwrap b's phi_z (period 2 pi)
/// and phi_xy (period pi: the ASG is unchanged by x, y -> -x, -y) to lie nearest a's.
void match_lobes(const double* a, double* b, int L, int Lb) {
  std::vector<double> out(size_t(kQ * L));
  std::vector<char> used(size_t(L), 0);
  for (int l = 0; l < L; ++l) {
    const double* al = a + kQ * l;
    sh::vec3 za, zb, x, y;
    sh::asg_frame(float(al[0]), float(al[1]), float(al[2]), x, y, za);
    int best = -1;
    double best_d = -2;
    for (int m = 0; m < L; ++m) {
      if (used[size_t(m)] || (Lb > 0 && (m < Lb) != (l < Lb))) continue;  // same side only
      const double* bm = b + kQ * m;
      sh::asg_frame(float(bm[0]), float(bm[1]), float(bm[2]), x, y, zb);
      double d = sh::dot(za, zb);
      if (d > best_d) best_d = d, best = m;
    }
    used[size_t(best)] = 1;
    double* o = &out[size_t(kQ * l)];
    std::copy(b + kQ * best, b + kQ * best + kQ, o);
    o[1] += 2 * M_PI * std::round((al[1] - o[1]) / (2 * M_PI));
    o[2] += M_PI * std::round((al[2] - o[2]) / M_PI);
  }
  std::copy(out.begin(), out.end(), b);
}

/// The sizes of a fit: M x N slices (theta_i, h), L lobes (Lb of them backward), Mb x Nb blocks,
/// rows x cols corner nodes, K absorption levels.
struct FitShape {
  int M = 0, N = 0, L = 0, Lb = 0, Mb = 0, Nb = 0, rows = 0, cols = 0, K = 1;
  size_t slice(int m, int n) const { return size_t(m) * size_t(N) + size_t(n); }
};

/// A slice's four corner nodes and their weights (S.5).
struct SliceNodes {
  int node[4];
  double w[4];
};

/// The corner nodes' lobes, block by block in raster order (asg_fit.h: shared corners).
std::vector<double> fit_corners(const FitGrid& g, const FitShape& z, const AsgFitSettings& s,
                                double c_max) {
  const int L = z.L, Lb = z.Lb, Mb = z.Mb, Nb = z.Nb, rows = z.rows, cols = z.cols;
  auto slice_index = [&](int m, int n) { return z.slice(m, n); };
  std::vector<double> nodes(size_t(rows * cols * kQ * L), 0.0);
  std::vector<char> fitted(size_t(rows * cols), 0);
  auto node = [&](int i, int j) { return &nodes[size_t((i * cols + j) * kQ * L)]; };
  const auto opts = solver_options(s);

  // The first corner: greedy start and a single-slice fit; every other corner starts from it.
  greedy_init(g, g.slice(slice_index(0, 0), 0), L, Lb, s.mu_max, node(0, 0));
  single_slice_fit(g, g.slice(slice_index(0, 0), 0), L, Lb, s, c_max, node(0, 0));
  for (int bm = 0; bm < Mb; ++bm)
    for (int bn = 0; bn < Nb; ++bn) {
      const int ci[4][2] = {{bm, bn}, {bm, bn + 1}, {bm + 1, bn}, {bm + 1, bn + 1}};
      // Unfitted corners get two starts, and the joint block fit runs from both: the fitted
      // neighbour's lobes (keeps lobe correspondence and unwrapped angles continuous), and a
      // fresh greedy start on the corner's own slice, matched to the neighbour's lobes. The
      // block keeps whichever ends with the lower cost.
      std::vector<double*> blocks;
      for (auto& c : ci) blocks.push_back(node(c[0], c[1]));
      std::vector<int> free_corners;
      std::vector<const double*> neighbour;
      for (int c = 0; c < 4; ++c) {
        const int i = ci[c][0], j = ci[c][1];
        if (fitted[size_t(i * cols + j)]) continue;
        if (i == 0 && j == 0) {
          free_corners.push_back(c);
          neighbour.push_back(nullptr);  // its own greedy single-slice fit, made above
          continue;
        }
        const int cand[4][2] = {{i - 1, j}, {i, j - 1}, {i - 1, j - 1}, {0, 0}};
        const double* nb = node(0, 0);
        for (auto& n : cand) {
          if (n[0] < 0 || n[1] < 0) continue;
          if (fitted[size_t(n[0] * cols + n[1])] || (n[0] == 0 && n[1] == 0)) {
            nb = node(n[0], n[1]);
            break;
          }
        }
        free_corners.push_back(c);
        neighbour.push_back(nb);
      }
      auto block_fit = [&](std::vector<std::vector<double>>& q) {
        ceres::Problem pb;
        std::vector<double*> ptr = blocks;
        for (size_t f = 0; f < free_corners.size(); ++f) ptr[size_t(free_corners[f])] = q[f].data();
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b) {
            auto w = asg_corner_weights(a / 2.0, b / 2.0);
            std::vector<double> wv;
            std::vector<double*> pv;
            for (int c = 0; c < 4; ++c)
              if (w[size_t(c)] > 0) wv.push_back(w[size_t(c)]), pv.push_back(ptr[size_t(c)]);
            pb.AddResidualBlock(
                new SliceCost(g, g.slice(slice_index(2 * bm + a, 2 * bn + b), 0), wv, L), nullptr,
                pv);
          }
        for (int c = 0; c < 4; ++c) {
          bool is_free = std::find(free_corners.begin(), free_corners.end(), c) != free_corners.end();
          if (!is_free) {
            pb.SetParameterBlockConstant(ptr[size_t(c)]);
          } else {
            clamp_to_bounds(ptr[size_t(c)], L, Lb, s.mu_max, c_max);
            set_bounds(pb, ptr[size_t(c)], L, Lb, s.mu_max, c_max);
          }
        }
        ceres::Solver::Summary sum;
        ceres::Solve(opts, &pb, &sum);
        return sum.final_cost;
      };
      std::vector<std::vector<double>> qa, qb;
      for (size_t f = 0; f < free_corners.size(); ++f) {
        const int c = free_corners[f];
        const double* fs = g.slice(slice_index(2 * ci[c][0], 2 * ci[c][1]), 0);
        std::vector<double> greedy(size_t(kQ * L));
        greedy_init(g, fs, L, Lb, s.mu_max, greedy.data());
        if (neighbour[f]) {
          qa.emplace_back(neighbour[f], neighbour[f] + kQ * L);
          match_lobes(neighbour[f], greedy.data(), L, Lb);
          qb.push_back(greedy);
        } else {
          qa.emplace_back(node(0, 0), node(0, 0) + kQ * L);
          qb.push_back(qa.back());
        }
      }
      if (!free_corners.empty()) {
        double ea = block_fit(qa);
        double eb = block_fit(qb);
        const auto& q = eb < ea ? qb : qa;
        for (size_t f = 0; f < free_corners.size(); ++f)
          std::copy(q[f].begin(), q[f].end(), blocks[size_t(free_corners[f])]);
      }
      for (auto& c : ci) fitted[size_t(c[0] * cols + c[1])] = 1;
    }
  return nodes;
}

/// Each slice's corners (S.5).
std::vector<SliceNodes> slice_corners(const FitShape& z) {
  const int M = z.M, N = z.N, Mb = z.Mb, Nb = z.Nb, cols = z.cols;
  auto slice_index = [&](int m, int n) { return z.slice(m, n); };
  // Each slice's corner nodes and S.5's weights (a slice on a block border belongs to both
  // blocks and has the same lobes in each: the corners are shared).
  const size_t S = size_t(M) * size_t(N);
  std::vector<SliceNodes> at(S);
  for (int m = 0; m < M; ++m)
    for (int n = 0; n < N; ++n) {
      const int bm = std::min(m / 2, Mb - 1), bn = std::min(n / 2, Nb - 1);
      const auto w = asg_corner_weights((m - 2 * bm) / 2.0, (n - 2 * bn) / 2.0);
      const int cn[4][2] = {{bm, bn}, {bm, bn + 1}, {bm + 1, bn}, {bm + 1, bn + 1}};
      SliceNodes& sn = at[slice_index(m, n)];
      for (int c = 0; c < 4; ++c) {
        sn.node[c] = cn[c][0] * cols + cn[c][1];
        sn.w[c] = w[size_t(c)];
      }
    }
  return at;
}

/// Scales the corners' amplitudes c so that no slice's lobes hold more than its data.
void cap_lobe_energy(const FitGrid& g, const FitShape& z, const std::vector<SliceNodes>& at,
                     std::vector<double>& nodes) {
  const size_t S = size_t(z.M) * size_t(z.N), B = g.bins();
  const int L = z.L;
  // Energy cap: no slice's lobes hold more than the slice's data at sigma = 0 (asg_fit.h).
  {
    auto lobe_energy = [&](size_t sl) {  // sum_l asg_integral of S.7's interpolated lobes
      double e = 0;
      for (int l = 0; l < L; ++l) {
        double mu1 = 0, mu2 = 0, c = 0;
        for (int k = 0; k < 4; ++k) {
          const double* q = &nodes[size_t((at[sl].node[k] * L + l) * kQ)];
          mu1 += at[sl].w[k] * q[3];
          mu2 += at[sl].w[k] * q[4];
          c += at[sl].w[k] * q[5];
        }
        e += sh::asg_integral(float(mu1), float(mu2), float(c));
      }
      return e;
    };
    std::vector<double> data(S, 0.0);
    std::vector<std::pair<double, size_t>> order;
    for (size_t sl = 0; sl < S; ++sl) {
      const double* f = g.slice(sl, 0);
      for (size_t b = 0; b < B; ++b) data[sl] += g.weight[b] * f[b];
      const double e = lobe_energy(sl);
      if (e > data[sl]) order.emplace_back(data[sl] > 0 ? e / data[sl] : HUGE_VAL, sl);
    }
    std::sort(order.begin(), order.end(), std::greater<>());
    for (const auto& [ratio, sl] : order) {
      const double e = lobe_energy(sl);  // earlier scalings may have brought it down already
      if (!(e > data[sl])) continue;
      const double scale = std::max(0.0, data[sl] / e);
      for (int k = 0; k < 4; ++k)
        if (at[sl].w[k] > 0)
          for (int l = 0; l < L; ++l) nodes[size_t((at[sl].node[k] * L + l) * kQ + 5)] *= scale;
    }
  }

}

/// G_l of S.9 on every bin of every slice: G[(slice * bins + bin) * L + l].
std::vector<double> lobe_values(const FitGrid& g, const FitShape& z,
                                const std::vector<SliceNodes>& at, const std::vector<double>& nodes) {
  const size_t S = size_t(z.M) * size_t(z.N), B = g.bins();
  const int M = z.M, N = z.N, L = z.L;
  auto slice_index = [&](int m, int n) { return z.slice(m, n); };
  // Lobe values G_l on every bin of every slice.
  std::vector<double> G(S * B * size_t(L));
  for (int m = 0; m < M; ++m)
    for (int n = 0; n < N; ++n) {
      const SliceNodes& sn = at[slice_index(m, n)];
      std::vector<double> q(size_t(kQ * L), 0.0);
      for (int c = 0; c < 4; ++c)
        for (int i = 0; i < kQ * L; ++i)
          q[size_t(i)] += sn.w[c] * nodes[size_t(sn.node[c] * kQ * L + i)];
      double* Gs = &G[slice_index(m, n) * B * size_t(L)];
      for (size_t bin = 0; bin < B; ++bin)
        for (int l = 0; l < L; ++l) {
          const double* ql = &q[size_t(kQ * l)];
          Gs[bin * size_t(L) + size_t(l)] =
              sh::asg_eval(float(ql[0]), float(ql[1]), float(ql[2]), float(ql[3]), float(ql[4]),
                           float(ql[5]), g.dir[bin]);
        }
    }
  return G;
}

/// The scale-downs s_{l,k} of the absorption levels k >= 1 (S.9), into t.scale.
void fit_scale_downs(const FitGrid& g, const FitShape& z, const std::vector<SliceNodes>& at,
                     const std::vector<double>& G, AsgTable& t) {
  const size_t S = size_t(z.M) * size_t(z.N), B = g.bins();
  const int L = z.L, rows = z.rows, cols = z.cols, K = z.K;
  // Scale-downs (S.9) at the corner nodes, interpolated like the lobes (S.7's weights).
  const int U = rows * cols * L;  // unknowns of one level: node-major, then lobe
  t.scale.assign(size_t(U * K), 1.0);
  if (K > 1) {
    // Normal equations of sum_slices sum_bins Omega (sum_{c,l} w_c s_{c,l} G_l - f)^2: the Gram
    // matrix of the lobes per slice (the same at every level), spread over the slice's corners.
    std::vector<double> A(size_t(U) * size_t(U), 0.0);
    std::vector<double> gram(size_t(L * L));
    for (size_t sl = 0; sl < S; ++sl) {
      std::fill(gram.begin(), gram.end(), 0.0);
      const double* Gs = &G[sl * B * size_t(L)];
      for (size_t bin = 0; bin < B; ++bin)
        for (int l = 0; l < L; ++l)
          for (int l2 = 0; l2 < L; ++l2)
            gram[size_t(l * L + l2)] += g.weight[bin] * Gs[bin * size_t(L) + size_t(l)] *
                                        Gs[bin * size_t(L) + size_t(l2)];
      const SliceNodes& sn = at[sl];
      for (int c = 0; c < 4; ++c)
        for (int c2 = 0; c2 < 4; ++c2) {
          const double ww = sn.w[c] * sn.w[c2];
          if (ww == 0) continue;
          for (int l = 0; l < L; ++l)
            for (int l2 = 0; l2 < L; ++l2)
              A[size_t(sn.node[c] * L + l) * size_t(U) + size_t(sn.node[c2] * L + l2)] +=
                  ww * gram[size_t(l * L + l2)];
        }
    }
    std::vector<double> rhs(static_cast<size_t>(U));
    for (int k = 1; k < K; ++k) {
      std::fill(rhs.begin(), rhs.end(), 0.0);
      for (size_t sl = 0; sl < S; ++sl) {
        const double* f = g.slice(sl, k);
        const double* Gs = &G[sl * B * size_t(L)];
        for (int l = 0; l < L; ++l) {
          double r = 0;
          for (size_t bin = 0; bin < B; ++bin) r += g.weight[bin] * Gs[bin * size_t(L) + size_t(l)] * f[bin];
          for (int c = 0; c < 4; ++c) rhs[size_t(at[sl].node[c] * L + l)] += at[sl].w[c] * r;
        }
      }
      // Bounded least squares 0 <= s_k <= s_{k-1} by projected Gauss-Seidel, from s_{k-1}.
      const double* prev = &t.scale[size_t((k - 1) * U)];
      double* sk = &t.scale[size_t(k * U)];
      std::copy(prev, prev + U, sk);
      for (int sweep = 0; sweep < 1000; ++sweep) {
        double change = 0;
        for (int u = 0; u < U; ++u) {
          const double* Au = &A[size_t(u) * size_t(U)];
          const double diag = Au[u];
          if (!(diag > 1e-300)) continue;  // a lobe with no support keeps s_{k-1}
          double r = rhs[size_t(u)];
          for (int v = 0; v < U; ++v)
            if (v != u) r -= Au[v] * sk[v];
          const double next = std::clamp(r / diag, 0.0, prev[u]);
          change = std::max(change, std::fabs(next - sk[u]));
          sk[u] = next;
        }
        if (change < 1e-10) break;
      }
    }
  }
}

/// t's fit errors: per block (f_0) and per level.
void fit_errors(const FitGrid& g, const FitShape& z, const std::vector<SliceNodes>& at,
                const std::vector<double>& G, AsgTable& t) {
  const int U = z.rows * z.cols * z.L;  // unknowns of one level
  const size_t S = size_t(z.M) * size_t(z.N), B = g.bins();
  const int L = z.L, Mb = z.Mb, Nb = z.Nb, K = z.K;
  auto slice_index = [&](int m, int n) { return z.slice(m, n); };
  // Fit errors: per block over its nine slices (f_0), and per level over all slices.
  auto scale_at = [&](size_t sl, int k, int l) {
    double v = 0;
    for (int c = 0; c < 4; ++c) v += at[sl].w[c] * t.scale[size_t(k * U + at[sl].node[c] * L + l)];
    return v;
  };
  auto slice_error = [&](size_t sl, int k, double& e, double& n) {
    const double* f = g.slice(sl, k);
    const double* Gs = &G[sl * B * size_t(L)];
    for (size_t bin = 0; bin < B; ++bin) {
      double mdl = 0;
      for (int l = 0; l < L; ++l) mdl += scale_at(sl, k, l) * Gs[bin * size_t(L) + size_t(l)];
      e += g.weight[bin] * (mdl - f[bin]) * (mdl - f[bin]);
      n += g.weight[bin] * f[bin] * f[bin];
    }
  };
  t.block_nrmse.assign(size_t(Mb * Nb), 0.0);
  for (int bm = 0; bm < Mb; ++bm)
    for (int bn = 0; bn < Nb; ++bn) {
      double e = 0, n = 0;
      for (int sl = 0; sl < 9; ++sl) slice_error(slice_index(2 * bm + sl / 3, 2 * bn + sl % 3), 0, e, n);
      t.block_nrmse[size_t(bm * Nb + bn)] = n > 0 ? std::sqrt(e / n) : 0.0;
    }
  std::vector<double> err_k(size_t(K), 0.0), norm_k(size_t(K), 0.0);
  for (int k = 0; k < K; ++k)
    for (size_t sl = 0; sl < S; ++sl) slice_error(sl, k, err_k[size_t(k)], norm_k[size_t(k)]);
  for (int k = 0; k < K; ++k)
    t.nrmse_per_sigma.push_back(norm_k[size_t(k)] > 0 ? std::sqrt(err_k[size_t(k)] / norm_k[size_t(k)]) : 0.0);
  t.nrmse = t.nrmse_per_sigma[0];
}

AsgTable fit(const PlySimResult& sim, const AsgFitSettings& settings, bool refl) {
  const int M = int(sim.theta_i.size()), N = int(sim.h.size()), L = settings.lobes;
  if (M < 3 || N < 3 || M % 2 == 0 || N % 2 == 0)
    throw std::invalid_argument("asg_fit: the theta_i and h sample counts must be odd and >= 3");
  if (L < 1) throw std::invalid_argument("asg_fit: at least one lobe");
  const FitGrid g = make_grid(sim, refl);
  // No lobe narrower than the grid it is fitted on (asg_resolvable_mu).
  AsgFitSettings s = settings;
  s.mu_max = std::min(s.mu_max, asg_resolvable_mu(g.rows, g.cols));
  FitShape z;
  z.M = M, z.N = N, z.L = L, z.Lb = back_lobes(L, s.split_sides);
  z.Mb = (M - 1) / 2, z.Nb = (N - 1) / 2, z.rows = z.Mb + 1, z.cols = z.Nb + 1, z.K = g.K;
  double data_max = 0;
  for (size_t sl = 0; sl < sim.slices.size(); ++sl)
    for (size_t b = 0; b < g.bins(); ++b) data_max = std::max(data_max, g.slice(sl, 0)[b]);
  const double c_max = std::max(10 * data_max, 1e-6);

  std::vector<double> nodes = fit_corners(g, z, s, c_max);
  const std::vector<SliceNodes> at = slice_corners(z);
  cap_lobe_energy(g, z, at, nodes);
  AsgTable t;
  t.lobes = L;
  t.theta_i = sim.theta_i;
  t.h = sim.h;
  t.sigmas = refl ? std::vector<double>{0.0} : sim.settings.sigmas;
  for (int i = 0; i < z.rows * z.cols * L; ++i) t.nodes.push_back(lobe_from(&nodes[size_t(i * kQ)]));

  const std::vector<double> G = lobe_values(g, z, at, nodes);
  fit_scale_downs(g, z, at, G, t);
  fit_errors(g, z, at, G, t);
  return t;
}

}  // namespace

AsgFitSettings asg_fit_settings(Quality q, bool refl) {
  AsgFitSettings s;
  switch (q) {
    case Quality::Draft: s.lobes = refl ? 1 : 2, s.max_iterations = 20; break;
    case Quality::Preview: s.lobes = refl ? 1 : 3, s.max_iterations = 30; break;
    case Quality::Final: s.lobes = refl ? 2 : 4, s.max_iterations = 50; break;
    case Quality::Reference: s.lobes = refl ? 2 : 6, s.max_iterations = 100; break;
  }
  return s;
}

double asg_resolvable_mu(int rows, int cols) {
  const double d = std::max(M_PI / rows, 2 * M_PI / cols);
  return 2 / (d * d);
}

AsgTable asg_fit_high(const PlySimResult& sim, const AsgFitSettings& s) { return fit(sim, s, false); }
AsgTable asg_fit_refl(const PlySimResult& sim, const AsgFitSettings& s) { return fit(sim, s, true); }

}  // namespace loom
