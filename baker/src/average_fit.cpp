#include "loom/average_fit.h"

#include <ceres/ceres.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "loom/atlas_bsdf.h"
#include "loom/evaluator.h"
#include "loom/preset_error.h"

namespace loom {

using namespace shading;

namespace {

constexpr int kTheta = LOOM_AVERAGE_THETA, kPhi = LOOM_AVERAGE_PHI,
              kPanels = LOOM_AVERAGE_PANELS;
constexpr float kMinCos = 0.04f;  // the grazing row is fitted slightly above the plane
constexpr double kMaxWeight = 8.0;

/// The table's view (side, row i of cos theta, column j of phi), in the mirrored frame.
vec3 node_view(int i, int j) {
  const float c = std::max(float(i) / (kTheta - 1), kMinCos), s = std::sqrt(1 - c * c);
  const float phi = float(j) * 2.0f * float(M_PI) / kPhi;
  return vec3(s * std::cos(phi), s * std::sin(phi), c);
}

}  // namespace

AverageFitOptions average_fit_options(const std::string& quality) {
  AverageFitOptions o;
  if (quality == "draft") o.points = 16, o.sphere_n = 10;
  if (quality == "preview") o.points = 36, o.sphere_n = 12;
  return o;
}

namespace {

/// 2 n^2 directions spread evenly over the whole sphere (a spherical Fibonacci lattice: no
/// clustering at the poles, where a view along the normal puts its mirror direction).
std::vector<vec3> light_directions(int n) { return fibonacci_sphere(2 * n * n); }

/// The narrowest lobe the fit may use: as wide as the light directions' spacing, so that no
/// closure can carry energy between them unseen by the L1.
double min_lobe_width(int n) { return std::sqrt(4 * M_PI / (2.0 * n * n)); }

/// One view's target: the model averaged over the points, f |cos| at the lights (mirrored to
/// the closures' frame), its grey and the grey albedo.
struct Target {
  std::vector<vec3> L;
  std::vector<std::array<double, 3>> f;
  std::vector<double> grey;
  double dw = 0, albedo = 0;
};

Target average_target(const AtlasBsdf& bsdf, const std::vector<std::pair<float, float>>& uv,
                      vec3 wo, int sphere_n) {
  Target t;
  const std::vector<vec3> lights = light_directions(sphere_n);
  t.dw = 4 * M_PI / double(lights.size());
  t.f.assign(lights.size(), {0.0, 0.0, 0.0});
  for (const auto& [u, v] : uv) {
    const auto f = bsdf.at(u, v, wo);
    for (size_t k = 0; k < lights.size(); ++k) {
      const auto fk = f(lights[k]);
      for (size_t c = 0; c < 3; ++c) t.f[k][c] += fk[c];
    }
  }
  const bool back = wo.z < 0;
  for (size_t k = 0; k < lights.size(); ++k) {
    for (auto& x : t.f[k]) x /= double(uv.size());
    t.L.push_back(average_mirror(lights[k], back));
    t.grey.push_back((t.f[k][0] + t.f[k][1] + t.f[k][2]) / 3.0);
    t.albedo += t.grey.back() * t.dw;
  }
  return t;
}

/// Residuals whose squares sum to the Charbonnier penalty of the relative distance (relative to
/// the model, floored at its mean over the sphere: between the L1, which leaves dim directions
/// to chance, and the pointwise relative error a render shows), plus the albedo on the same
/// directions held to the model's (the lobes are at least as wide as their spacing).
struct Cost {
  const Target& t;
  const std::vector<double>& target;  // grey or one channel
  double albedo, eps;
  std::function<void(const double*, std::vector<double>&)> closures;  // x -> values at t.L
  bool operator()(double const* const* x, double* r) const {
    std::vector<double> c;
    closures(x[0], c);
    double energy = 0;
    for (size_t k = 0; k < t.L.size(); ++k) {
      const double e = (c[k] - target[k]) / (target[k] + albedo / (4 * M_PI));
      r[k] = std::sqrt(t.dw) * e / std::sqrt(std::sqrt(e * e + eps * eps) + eps);
      energy += c[k] * t.dw;
    }
    r[t.L.size()] = 3.0 * (energy / albedo - 1.0);  // the albedo held closely
    return true;
  }
};

void minimise(Cost* cost_fn, std::vector<double>& x, const std::vector<double>& lo,
              const std::vector<double>& hi, int iterations) {
  auto* cost = new ceres::DynamicNumericDiffCostFunction<Cost>(cost_fn);
  cost->AddParameterBlock(int(x.size()));
  cost->SetNumResiduals(int(cost_fn->t.L.size()) + 1);
  ceres::Problem pb;
  for (size_t i = 0; i < x.size(); ++i) x[i] = std::clamp(x[i], lo[i], hi[i]);
  pb.AddResidualBlock(cost, nullptr, x.data());
  for (size_t i = 0; i < x.size(); ++i) {
    pb.SetParameterLowerBound(x.data(), int(i), lo[i]);
    pb.SetParameterUpperBound(x.data(), int(i), hi[i]);
  }
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = iterations;
  so.num_threads = 1;  // views run in parallel
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary sum;
  ceres::Solve(so, &pb, &sum);
}

double relative_l1(const Target& t, const std::vector<double>& target, double albedo,
                   const AverageClosureSet& c, int channel) {
  if (albedo <= 0) return 0;
  double num = 0;
  for (size_t k = 0; k < t.L.size(); ++k) {
    const auto f = c.eval(t.L[k]);
    const double v = channel < 0 ? (f[0] + f[1] + f[2]) / 3.0 : f[size_t(channel)];
    num += std::fabs(v - target[k]) * t.dw;
  }
  return num / albedo;
}

double grey_of(const std::array<float, 3>& w) { return (w[0] + w[1] + w[2]) / 3.0; }

/// A view's alphas and grey weights, from `start`: x = (w_0 .. w_3, a_x, a_y, a_t).
AverageClosures fit_shapes(const Target& t, vec3 V, const AverageClosures& start,
                           const AverageFitOptions& o) {
  constexpr int n = kAverageClosures, na = 3;
  AverageClosures p = start;
  if (!(t.albedo > 1e-9)) return p;
  std::vector<double> x(n + na), lo(n + na, 0.0), hi(n + na, kMaxWeight);
  // A GGX lobe is about 2 alpha wide in the light direction, the refraction a_t / 2.
  const double w = min_lobe_width(o.sphere_n);
  for (int q = 0; q < n; ++q) x[size_t(q)] = grey_of(p.w[size_t(q)]);
  for (int q = 0; q < na; ++q) {
    x[size_t(n + q)] = p.alpha[size_t(q)];
    lo[size_t(n + q)] = q < 2 ? w / 2 : std::min(w / (1 - 1 / LOOM_AVERAGE_ETA), 1.0);
    hi[size_t(n + q)] = 1;
  }
  auto set = [](const double* v, AverageClosures& a) {
    for (int q = 0; q < n; ++q) a.w[size_t(q)].fill(float(v[q]));
    for (int q = 0; q < na; ++q) a.alpha[size_t(q)] = float(v[n + q]);
  };
  minimise(new Cost{t, t.grey, t.albedo, o.charbonnier_eps,
                    [&](const double* v, std::vector<double>& c) {
                      AverageClosures a;
                      set(v, a);
                      const AverageClosureSet s(a, V);
                      c.resize(t.L.size());
                      for (size_t k = 0; k < t.L.size(); ++k) c[k] = grey_of(s.eval(t.L[k]));
                    }},
           x, lo, hi, o.max_iterations);
  set(x.data(), p);
  return p;
}

/// Each colour channel's four weights with p's alphas fixed, from p's weights; returns the
/// relative L1 of the grey.
double fit_weights(const Target& t, vec3 V, AverageClosures& p, const AverageFitOptions& o) {
  constexpr int n = kAverageClosures;
  if (!(t.albedo > 1e-9)) {
    for (auto& w : p.w) w.fill(0.0f);
    return 0;
  }
  const AverageClosureSet shapes(p, V);
  std::array<double, n> E{};
  for (int q = 0; q < n; ++q) E[size_t(q)] = shapes.albedo(q);
  std::vector<std::array<double, n>> B(t.L.size());
  for (size_t k = 0; k < t.L.size(); ++k)
    for (int q = 0; q < n; ++q) B[k][size_t(q)] = shapes.basis(q, t.L[k]);
  const AverageClosures grey = p;
  for (size_t ch = 0; ch < 3; ++ch) {
    std::vector<double> target(t.L.size());
    double albedo = 0;
    for (size_t k = 0; k < t.L.size(); ++k) albedo += (target[k] = t.f[k][ch]) * t.dw;
    if (!(albedo > 1e-9)) {
      for (auto& w : p.w) w[ch] = 0;
      continue;
    }
    // From the grey weights scaled to this channel's albedo.
    std::vector<double> w(n);
    for (int q = 0; q < n; ++q) w[size_t(q)] = grey_of(grey.w[size_t(q)]) * albedo / t.albedo;
    minimise(new Cost{t, target, albedo, o.charbonnier_eps,
                      [&](const double* v, std::vector<double>& c) {
                        c.assign(t.L.size(), 0.0);
                        for (size_t k = 0; k < t.L.size(); ++k)
                          for (int q = 0; q < n; ++q) c[k] += v[q] * B[k][size_t(q)];
                      }},
             w, std::vector<double>(n, 0.0), std::vector<double>(n, kMaxWeight),
             o.max_iterations);
    // The albedo exactly the model's, with each lobe integrated about itself (the lights' grid
    // is coarse for the fit's narrowest lobes).
    double have = 0;
    for (int q = 0; q < n; ++q) have += w[size_t(q)] * E[size_t(q)];
    const double k = have > 1e-12 ? albedo / have : 0.0;
    for (int q = 0; q < n; ++q) p.w[size_t(q)][ch] = float(w[size_t(q)] * k);
  }
  return relative_l1(t, t.grey, t.albedo, AverageClosureSet(p, V), -1);
}

float median(std::vector<float> v) {
  std::nth_element(v.begin(), v.begin() + long(v.size() / 2), v.end());
  return v[v.size() / 2];
}

}  // namespace

AverageFit fit_average_closures(const Atlas& a, const AverageFitOptions& o,
                                const std::function<void(double)>& progress) {
  if (o.points < 1 || o.sphere_n < 4 || o.max_iterations < 1)
    throw std::invalid_argument(
        "fit_average_closures: points >= 1, sphere_n >= 4, iterations >= 1");
  const AtlasBsdf bsdf(a, Evaluator::Model);
  const auto uv = preset_error_sampling(o.points, 1, 2).uv;
  AverageFit out;
  out.table = Image(kPhi + 1, 2 * kPanels * kTheta, 4);
  // The repeat's mean open fraction over every texel (what the shaders' per-point gaps average to).
  const Image& ref = a.map("yarn_info");
  double open = 0;
  for (int iy = 0; iy < ref.height; ++iy)
    for (int ix = 0; ix < ref.width; ++ix)
      open += bsdf.open((ix + 0.5f) / ref.width, (iy + 0.5f) / ref.height);
  out.gap_mean = float(open / (double(ref.width) * ref.height));

  // Pass 1, chains (side, phi column), each from the normal (row kTheta - 1) down to grazing,
  // each view starting from the one before: every view's own shapes.
  const int n_views = 2 * kPhi * kTheta;
  auto index = [](int side, int j, int i) { return size_t((side * kPhi + j) * kTheta + i); };
  std::vector<Target> targets(static_cast<size_t>(n_views));
  std::vector<AverageClosures> fitted(static_cast<size_t>(n_views));
  // Progress after d of the two passes' 2 n_views fits (pass 1 the first 0.8), reported each
  // quarter only: a line each in the bake's --progress output (and a restart each in
  // AtlasCli.KilledBakesLeaveACompleteAtlasOrNone).
  std::atomic<int> done{0};
  auto fraction = [&](int d) {
    return d <= n_views ? 0.8 * d / n_views : 0.8 + 0.2 * (d - n_views) / n_views;
  };
  auto report = [&](int d) {
    if (progress && int(4 * fraction(d)) != int(4 * fraction(d - 1))) progress(fraction(d));
  };
  tbb::parallel_for(0, 2 * kPhi, [&](int chain) {
    const int side = chain / kPhi, j = chain % kPhi;
    AverageClosures p;
    for (int i = kTheta - 1; i >= 0; --i) {
      const vec3 V = node_view(i, j);
      Target& t = targets[index(side, j, i)];
      t = average_target(bsdf, uv, average_mirror(V, side == 1), o.sphere_n);
      if (i == kTheta - 1) {  // a first guess: half diffuse, half glossy on each side
        double up = 0, down = 0;
        for (size_t k = 0; k < t.L.size(); ++k) (t.L[k].z > 0 ? up : down) += t.grey[k] * t.dw;
        const float u = float(0.5 * up), d = float(0.5 * down);
        p.w[0].fill(u), p.w[2].fill(u);
        p.w[1].fill(d), p.w[3].fill(d);
      }
      fitted[index(side, j, i)] = p = fit_shapes(t, V, p, o);
      report(++done);
    }
  });
  // Pass 2: one set of alphas per row (the medians of pass 1), so that the shaders'
  // interpolation between views mixes closures of the same shapes; each view's weights
  // refitted with them.
  for (int side = 0; side < 2; ++side)
    for (int i = 0; i < kTheta; ++i)
      for (int q = 0; q < kAverageClosures; ++q) {
        std::vector<float> alphas;
        for (int j = 0; j < kPhi; ++j) alphas.push_back(fitted[index(side, j, i)].alpha[size_t(q)]);
        const float m = median(alphas);
        for (int j = 0; j < kPhi; ++j) fitted[index(side, j, i)].alpha[size_t(q)] = m;
      }
  std::vector<double> l1(static_cast<size_t>(n_views), 0.0);
  tbb::parallel_for(0, n_views, [&](int k) {
    const int side = k / (kPhi * kTheta), j = (k / kTheta) % kPhi, i = k % kTheta;
    AverageClosures& p = fitted[size_t(k)];
    l1[size_t(k)] = fit_weights(targets[size_t(k)], node_view(i, j), p, o);
    for (int q = 0; q < kPanels; ++q) {
      const int row = (side * kPanels + q) * kTheta + i;
      const float v[4] = {p.w[size_t(q)][0], p.w[size_t(q)][1], p.w[size_t(q)][2],
                          p.alpha[size_t(q)]};
      for (int c = 0; c < 4; ++c) {
        out.table.px(j, row)[c] = v[c];
        if (j == 0) out.table.px(kPhi, row)[c] = v[c];  // the wrap column
      }
    }
    report(++done);
  });
  for (double e : l1) {
    out.fit_l1_mean += e / double(l1.size());
    out.fit_l1_worst = std::max(out.fit_l1_worst, e);
  }
  return out;
}

nlohmann::json average_manifest(const AverageFit& f, const AverageFitOptions& o) {
  return {{"texture", "average_closures"},
          {"theta", kTheta},
          {"phi", kPhi},
          {"panels", kPanels},
          {"gap_mean", f.gap_mean},
          {"points", o.points},
          {"sphere_n", o.sphere_n},
          {"fit_relative_l1", {{"mean", f.fit_l1_mean}, {"worst", f.fit_l1_worst}}}};
}

AverageError average_closures_error(const Atlas& a, int points, int views, int sphere_n) {
  if (points < 1 || views < 1 || sphere_n < 4)
    throw std::invalid_argument("average_closures_error: points, views >= 1, sphere_n >= 4");
  const Image& table = a.map("average_closures");
  const AtlasBsdf model(a, Evaluator::Model), closures(a, Evaluator::Closures);
  const auto uv = preset_error_sampling(points, 1, 2).uv;
  const std::vector<vec3> V = fibonacci_views(views);
  struct PerView {
    double l1 = 0, energy = 0, texel_l1 = 0;
    bool lit = false;
  };
  std::vector<PerView> per(V.size());
  tbb::parallel_for(size_t(0), V.size(), [&](size_t v) {
    const Target t = average_target(model, uv, V[v], sphere_n);
    const Target tc = average_target(closures, uv, V[v], sphere_n);
    const bool back = V[v].z < 0;
    const AverageClosureSet c(read_average_closures(table, V[v]),
                              normalize(average_mirror(V[v], back)));
    double num = 0, num_texel = 0, m = 0, have = 0;
    for (size_t k = 0; k < t.L.size(); ++k) {
      const double f = c.eval(t.L[k])[1], g = t.f[k][1];  // green, as mapping_error
      num += std::fabs(f - g) * t.dw, m += g * t.dw, have += f * t.dw;
      num_texel += std::fabs(tc.f[k][1] - g) * t.dw;
    }
    if (m > 1e-9) per[v] = {num / m, std::fabs(have / m - 1.0), num_texel / m, true};
  });
  AverageError e;
  for (const PerView& p : per) {
    if (!p.lit) continue;
    ++e.views;
    e.l1_mean += p.l1, e.energy_mean += p.energy, e.texel_closures_l1_mean += p.texel_l1;
    e.l1_worst = std::max(e.l1_worst, p.l1);
  }
  if (e.views == 0) throw std::runtime_error("average_closures_error: no view receives light");
  e.l1_mean /= e.views, e.energy_mean /= e.views, e.texel_closures_l1_mean /= e.views;
  return e;
}

}  // namespace loom
