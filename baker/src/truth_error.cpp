#include "loom/truth_error.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "loom/atlas_bsdf.h"
#include "loom/evaluator.h"
#include "loom/preset_error.h"
#include "loom/swatch.h"

namespace loom {

using namespace shading;

void add_bin_averages(const std::function<std::array<float, 3>(vec3)>& f, int res, int sub,
                      double weight, std::vector<double>& bins) {
  const double w = weight / (double(sub) * sub);
  for (int row = 0; row < res; ++row)
    for (int a = 0; a < sub; ++a) {
      const double z = -1 + (row + (a + 0.5) / sub) * 2.0 / res, r = std::sqrt(1 - z * z);
      for (int col = 0; col < res; ++col) {
        double* b = &bins[(size_t(row) * size_t(res) + size_t(col)) * 3];
        for (int c = 0; c < sub; ++c) {
          const double phi = -M_PI + (col + (c + 0.5) / sub) * 2 * M_PI / res;
          const auto v = f(vec3(float(r * std::cos(phi)), float(r * std::sin(phi)), float(z)));
          for (int k = 0; k < 3; ++k) b[k] += w * v[size_t(k)];
        }
      }
    }
}

std::array<double, 3> hemisphere_sum(const std::vector<double>& bins, int res, bool upper) {
  std::array<double, 3> s{0, 0, 0};
  const double dw = 4 * M_PI / (double(res) * res);
  for (int row = upper ? res / 2 : 0; row < (upper ? res : res / 2); ++row)
    for (int col = 0; col < res; ++col)
      for (int k = 0; k < 3; ++k)
        s[size_t(k)] += bins[(size_t(row) * size_t(res) + size_t(col)) * 3 + size_t(k)] * dw;
  return s;
}

double relative_l1(const std::vector<double>& a, const std::vector<double>& b) {
  double num = 0, den = 0;
  for (size_t k = 0; k < a.size(); ++k) num += std::fabs(a[k] - b[k]), den += b[k];
  return den > 0 ? num / den : (num > 0 ? INFINITY : 0.0);
}

TruthTally combine_halves(const TruthResult& a, const TruthResult& b) {
  if (a.density.size() != b.density.size())
    throw std::invalid_argument("combine_halves: tallies of different resolutions");
  TruthTally t;
  t.density.resize(a.density.size());
  double noise = 0, total = 0;
  for (size_t k = 0; k < t.density.size(); ++k) {
    t.density[k] = 0.5 * (double(a.density[k]) + double(b.density[k]));
    noise += 0.5 * std::fabs(double(a.density[k]) - double(b.density[k]));
    total += t.density[k];
  }
  t.noise_l1 = total > 0 ? noise / total : 0;
  return t;
}

namespace {

double rgb_sum(const std::array<double, 3>& v) { return v[0] + v[1] + v[2]; }

/// The repeat-averaged tally of one evaluator for view V, and the mean open fraction.
std::vector<double> atlas_bins(const AtlasBsdf& bsdf, const PresetErrorSampling& sp, vec3 V,
                               int res, int sub) {
  const size_t n = sp.uv.size(), len = size_t(res) * size_t(res) * 3;
  std::vector<std::vector<double>> per(n);
  tbb::parallel_for(size_t(0), n, [&](size_t p) {
    per[p].assign(len, 0.0);
    add_bin_averages(bsdf.at(sp.uv[p].first, sp.uv[p].second, V), res, sub, 1.0 / double(n),
                     per[p]);
  });
  std::vector<double> out(len, 0.0);  // summed in a fixed order: the same on any thread count
  for (const auto& v : per)
    for (size_t k = 0; k < len; ++k) out[k] += v[k];
  return out;
}

}  // namespace

TruthError truth_error(const Atlas& a, const FabricSpec& spec, const TruthErrorSettings& s) {
  if (s.views < 1 || s.points < 1 || s.sub < 1 || s.truth.res < 2 || s.truth.res % 2 ||
      s.truth.rays < 2)
    throw std::invalid_argument("truth_error: views, points, sub >= 1, res even >= 2, rays >= 2");
  const auto one = truth_tile(spec, 1);
  const auto size = a.manifest.at("repeat").at("size_um");
  for (int k = 0; k < 2; ++k) {
    const double want = one[size_t(k) + 2] - one[size_t(k)], got = size.at(size_t(k)).get<double>();
    if (!(std::fabs(got - want) <= 1e-3 * want))
      throw std::runtime_error(fmt::format(
          "the atlas's weave repeat is {:.1f} x {:.1f} um, the spec's {:.1f} x {:.1f} um: not the "
          "same fabric", size.at(0).get<double>(), size.at(1).get<double>(), one[2] - one[0],
          one[3] - one[1]));
  }
  if (auto e = thread_sequences_not_yet(spec, "eval error --truth"); !e.empty())
    throw std::invalid_argument(e);
  // The fibers' colours as the atlas resolved them (its OCIO config, if any).
  FabricSpec fabric = spec;
  const auto& colours = a.manifest.at("yarn_colours_linear");
  fabric.warp.color_linear = colours.at("warp").get<std::array<double, 3>>();
  fabric.weft.color_linear = colours.at("weft").get<std::array<double, 3>>();
  const auto scene = make_truth_scene(fabric, s.truth.min_yarns);
  // The fibers absorb what the atlas's colours stand for: a ray-wave atlas's own absorption
  // (its colour reading applied at bake time), else the spec's reading (swatch.h).
  std::vector<FiberMaterial> fibers = scene->materials();
  if (a.manifest.value("tier", "") == "raywave") {
    for (size_t k = 0; k < fibers.size() && k < 2; ++k) {
      const auto mm = a.manifest.at("raywave").at("yarns").at(k == 0 ? "warp" : "weft")
                          .at("absorption").at("sigma_rgb_per_mm").get<std::array<double, 3>>();
      for (size_t c = 0; c < 3; ++c) fibers[k].sigma_per_um[c] = mm[c] * 1e-3;
    }
  } else {
    fibers = reading_materials(*scene, fabric);
  }
  const AtlasBsdf model(a, Evaluator::Model), closures(a, Evaluator::Closures);
  const PresetErrorSampling sp = preset_error_sampling(s.points, 1, 2);
  double open = 0;
  for (const auto& [u, v] : sp.uv) open += model.open(u, v);
  open /= double(sp.uv.size());

  const int res = s.truth.res;
  TruthError out;
  double log_r[2] = {0, 0}, log_t[2] = {0, 0};
  for (const vec3 V : fibonacci_views(s.views)) {
    TruthView tv;
    tv.view = V;
    tv.open = open;
    // The truth as two halves of independent seeds (header comment: noise_l1).
    TruthSettings half = s.truth;
    half.rays = s.truth.rays / 2;
    const Vec3d wi{V.x, V.y, V.z};
    const TruthResult ta = scene->tally(scene->paths(wi, half), fibers);
    half.seed = s.truth.seed + 0x9e3779b97f4a7c15ull;
    const TruthResult tb = scene->tally(scene->paths(wi, half), fibers);
    const TruthTally truth = combine_halves(ta, tb);
    tv.noise_l1 = truth.noise_l1;
    for (size_t c = 0; c < 3; ++c) {
      tv.truth_reflect[c] = 0.5 * (ta.reflect[c] + tb.reflect[c]);
      tv.truth_transmit[c] = 0.5 * (ta.transmit[c] + tb.transmit[c]);
    }
    tv.truth_direct = 0.5 * (ta.direct + tb.direct);
    const bool up = V.z > 0;
    const double truth_a = rgb_sum(tv.truth_reflect) + rgb_sum(tv.truth_transmit);
    int e = 0;
    for (const AtlasBsdf* b : {&model, &closures}) {
      const std::vector<double> m = atlas_bins(*b, sp, V, res, s.sub);
      TruthView::Side& side = e == 0 ? tv.model : tv.closures;
      side.relative_l1 = relative_l1(m, truth.density);
      side.reflect = hemisphere_sum(m, res, up);
      side.transmit = hemisphere_sum(m, res, !up);
      for (double& t : side.transmit) t += open;
      TruthComparison& c = e == 0 ? out.model : out.closures;
      c.relative_l1 += side.relative_l1;
      const double atlas_a = rgb_sum(side.reflect) + rgb_sum(side.transmit);
      c.albedo_error += std::fabs(atlas_a - truth_a) / std::max(truth_a, 1e-12);
      log_r[e] += std::log(std::max(rgb_sum(side.reflect), 1e-12) /
                           std::max(rgb_sum(tv.truth_reflect), 1e-12));
      log_t[e] += std::log(std::max(rgb_sum(side.transmit), 1e-12) /
                           std::max(rgb_sum(tv.truth_transmit), 1e-12));
      ++e;
    }
    out.noise_l1 += tv.noise_l1;
    out.views.push_back(tv);
  }
  const double n = double(out.views.size());
  int e = 0;
  for (TruthComparison* c : {&out.model, &out.closures}) {
    c->relative_l1 /= n, c->albedo_error /= n;
    c->reflect_ratio = std::exp(log_r[e] / n), c->transmit_ratio = std::exp(log_t[e] / n);
    ++e;
  }
  out.noise_l1 /= n;
  return out;
}

}  // namespace loom
