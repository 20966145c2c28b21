#include "loom/preset_error.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <vector>

#include "loom/atlas_bsdf.h"

namespace loom {

using namespace shading;

namespace {

/// A jittered lattice point of the repeat: cell (i, j) of side x side, offset by a fixed hash.
float jitter(unsigned i, unsigned j, unsigned c) {
  unsigned h = i * 73856093u ^ j * 19349663u ^ c * 83492791u;
  h ^= h >> 13;
  h *= 0x5bd1e995u;
  h ^= h >> 15;
  return float(h & 0xffffu) / 65536.0f;
}

}  // namespace

PresetErrorSampling preset_error_sampling(int points, int views, int sphere_n) {
  PresetErrorSampling s;
  const int side = std::max(1, int(std::lround(std::sqrt(double(points)))));
  for (int j = 0; j < side; ++j)
    for (int i = 0; i < side; ++i)
      s.uv.emplace_back((i + jitter(unsigned(i), unsigned(j), 0)) / side,
                        (j + jitter(unsigned(i), unsigned(j), 1)) / side);
  s.views = fibonacci_views(views);
  s.lights = sphere_grid(sphere_n);
  s.dw = sphere_grid_dw(sphere_n);
  return s;
}

PresetError preset_error(const Atlas& a, const Atlas& reference, int points, int views,
                         int sphere_n) {
  if (points < 1 || views < 1 || sphere_n < 2)
    throw std::runtime_error("preset_error: points and views must be >= 1, sphere_n >= 2");
  const std::string ta = a.manifest.value("tier", ""), tr = reference.manifest.value("tier", "");
  if (ta != tr)
    throw std::runtime_error("the atlas is of tier \"" + ta + "\" and the reference of \"" + tr +
                             "\": a preset is compared with the same tier's reference");
  if (a.manifest.value("repeat", nlohmann::json()) !=
      reference.manifest.value("repeat", nlohmann::json()))
    throw std::runtime_error("the atlas and the reference have different weave repeats: not the "
                             "same fabric");
  const AtlasBsdf fa(a, Evaluator::Model), fr(reference, Evaluator::Model);
  const PresetErrorSampling sampling = preset_error_sampling(points, views, sphere_n);
  const auto& uv = sampling.uv;
  const auto& V = sampling.views;
  const auto& L = sampling.lights;
  const size_t np = uv.size(), nl = L.size();
  // f_a and f_r for every (view, point, L), green: points x L per view, views in parallel.
  struct PerView {
    double pw_sum = 0, pw_worst = 0, avg = 0, energy = 0;
    int counted = 0;
    bool any = false;
  };
  std::vector<PerView> per(V.size());
  tbb::parallel_for(size_t(0), V.size(), [&](size_t k) {
    std::vector<double> mean_a(nl, 0.0), mean_r(nl, 0.0);
    PerView& o = per[k];
    for (size_t p = 0; p < np; ++p) {
      const auto ga = fa.at(uv[p].first, uv[p].second, V[k]);
      const auto gr = fr.at(uv[p].first, uv[p].second, V[k]);
      double num = 0, den = 0;
      for (size_t l = 0; l < nl; ++l) {
        const double x = ga(L[l])[1], y = gr(L[l])[1];
        mean_a[l] += x, mean_r[l] += y;
        num += std::fabs(x - y), den += y;
      }
      if (den * sampling.dw < 1e-6) continue;  // an open gap in the reference: nothing to compare
      const double e = num / den;
      o.pw_sum += e, o.pw_worst = std::max(o.pw_worst, e), ++o.counted;
    }
    double num = 0, den = 0, ea = 0;
    for (size_t l = 0; l < nl; ++l)
      num += std::fabs(mean_a[l] - mean_r[l]), den += mean_r[l], ea += mean_a[l];
    if (den > 0) o.avg = num / den, o.energy = std::fabs(ea - den) / den, o.any = true;
  });
  PresetError out;
  out.points = int(np);
  int counted = 0, views_used = 0;
  for (const PerView& o : per) {
    out.pointwise_mean += o.pw_sum, counted += o.counted;
    out.pointwise_worst = std::max(out.pointwise_worst, o.pw_worst);
    if (o.any) out.average += o.avg, out.energy += o.energy, ++views_used;
  }
  // Nothing compared is no agreement: say so rather than print zeros.
  if (views_used == 0)
    throw std::runtime_error("the reference sends no light to any of the " +
                             std::to_string(V.size()) + " views: use more --views");
  if (counted == 0)
    throw std::runtime_error("every one of the " + std::to_string(np) +
                             " points is an open gap in the reference: use more --points");
  out.pointwise_mean /= counted;
  out.average /= views_used, out.energy /= views_used;
  out.views = views_used;
  return out;
}

}  // namespace loom
