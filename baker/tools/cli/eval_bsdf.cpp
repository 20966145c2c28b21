// loom-bake eval bsdf, mapping, albedo, error: an atlas's BSDF (model or closures) at a point or
// averaged over the repeat, the closure-mapping error, the ray-wave directional albedo, and the
// error against the same fabric at another preset.
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "command.h"
#include "loom/atlas.h"
#include "loom/average_fit.h"
#include "loom/cli_values.h"
#include "loom/evaluator.h"
#include "loom/preset_error.h"
#include "loom/raywave_bsdf.h"
#include "loom/shading.h"
#include "loom/spec.h"
#include "loom/truth_error.h"

using nlohmann::json;

namespace loom::cli {

namespace {

struct BsdfArgs {
  std::string atlas, uv, evaluator = "model", backend = "nodes";
  std::vector<std::string> wi, wo;
  bool average = false;
};

loom::shading::vec3 unit_direction(const char* flag, const std::string& s) {
  const auto w = loom::parse_cli_direction(flag, s);
  return loom::shading::normalize(loom::shading::vec3{float(w[0]), float(w[1]), float(w[2])});
}

int eval_bsdf(const BsdfArgs& a) {
  std::array<double, 2> uv{};
  if (!a.average) {
    if (a.uv.empty()) {
      std::cerr << "error: --uv: expected U,V (two finite numbers), or give --average\n";
      return 2;
    }
    uv = loom::parse_cli_uv("--uv", a.uv);
  }
  if (a.wi.size() != a.wo.size()) {
    std::cerr << fmt::format("error: --wi and --wo: {} and {} directions; give one --wo for "
                             "each --wi\n", a.wi.size(), a.wo.size());
    return 2;
  }
  std::vector<std::pair<loom::shading::vec3, loom::shading::vec3>> pairs;
  for (size_t k = 0; k < a.wi.size(); ++k)
    pairs.emplace_back(unit_direction("--wi", a.wi[k]), unit_direction("--wo", a.wo[k]));
  auto atlas = loom::load_atlas(a.atlas);
  if (a.evaluator == "average") return eval_average_closures(atlas, a.average, uv, pairs);
  auto e = a.evaluator == "closures" ? loom::Evaluator::Closures : loom::Evaluator::Model;
  if (atlas.manifest.value("tier", "") == "raywave") {
    // The ray-wave BSDF (baker/include/loom/raywave_bsdf.h): f_cos is Cycles' eval (f times
    // the cosine), the quantity the ply scattering density gives directly.
    const loom::RaywaveData rd = loom::load_raywave(atlas);
    for (const auto& [vi, vo] : pairs) {
      const std::array<float, 3> fc =
          a.average ? loom::raywave_eval_average(atlas, rd, vi, vo, e)
                    : loom::raywave_eval(rd,
                                         loom::sample_surface(atlas, float(uv[0]), float(uv[1])),
                                         vi, vo, e);
      const float c = std::max(std::fabs(vi.z), 1e-6f);
      // One mixture for both backends (--backend is not used): the microfacet normals are
      // lifted alike by SVM and OSL; SVM's Translucent BSDF would lift its normal where the
      // shading normal differs from the geometric one, which the emulator's tangent frame
      // (flat geometry) does not have.
      std::cout << json{{"f", {fc[0] / c, fc[1] / c, fc[2] / c}},
                        {"f_cos", fc},
                        {"evaluator", a.evaluator},
                        {"backend", "any (flat geometry)"},
                        {"tier", "raywave"}}
                       .dump()
                << std::endl;
    }
    return 0;
  }
  auto be = a.backend == "osl" ? loom::Backend::Osl : loom::Backend::Nodes;
  for (const auto& [vi, vo] : pairs) {
    std::array<float, 3> f =
        a.average ? loom::eval_bsdf_average(atlas, vi, vo, e, be)
                  : loom::eval_bsdf(atlas, loom::sample_surface(atlas, float(uv[0]), float(uv[1])),
                                    vi, vo, e, be);
    json out = {{"f", f}, {"evaluator", a.evaluator}};
    if (e == loom::Evaluator::Closures) out["backend"] = a.backend;
    std::cout << out.dump() << std::endl;
  }
  return 0;
}

struct MappingArgs {
  std::string atlas;
  int texels = 64, views = 24;
  bool by_kind = false;
};

int eval_mapping(const MappingArgs& a) {
  auto atlas = loom::load_atlas(a.atlas);
  const bool rw = atlas.manifest.value("tier", "") == "raywave";
  auto e = rw ? loom::raywave_mapping_error(atlas, loom::load_raywave(atlas), a.texels, a.views)
              : loom::mapping_error(atlas, a.texels, a.views);
  json out = {{"mean_relative_l1", e.mean_l1},
              {"worst_relative_l1", e.worst_l1},
              {"mean_energy_error", e.mean_energy},
              {"worst_energy_error", e.worst_energy},
              {"texels", e.texels},
              {"pairs", e.views},
              {"tier", rw ? "raywave" : "surface"}};
  if (a.by_kind) {
    if (!rw) {
      std::cerr << "error: --by-kind: a ray-wave atlas's closures only\n";
      return 2;
    }
    const auto k =
        loom::raywave_mapping_by_kind(atlas, loom::load_raywave(atlas), a.texels, a.views);
    auto one = [](const loom::MappingError& m) {
      return json{{"mean_relative_l1", m.mean_l1},
                  {"mean_energy_error", m.mean_energy},
                  {"pairs", m.views}};
    };
    out["by_kind"] = {{"reflection", one(k.reflection)},
                      {"refraction", one(k.refraction)},
                      {"translucent", one(k.translucent)},
                      {"residual", one(k.residual)},
                      {"layer_diffuse", one(k.layer_diffuse)}};
  }
  std::cout << out.dump() << std::endl;
  return 0;
}

}  // namespace

void add_eval_bsdf(CLI::App& eval, Commands& out) {
  auto a = std::make_shared<BsdfArgs>();
  auto* c = eval.add_subcommand("bsdf", "BSDF value f (no cosine) at a surface point");
  c->add_option("--atlas", a->atlas, "atlas directory")->required();
  c->add_option("--uv", a->uv, "U,V texture coordinate (one repeat = [0,1)^2, wrapped)");
  c->add_flag("--average", a->average, "average f over the whole weave repeat instead of --uv");
  c->add_option("--wi", a->wi,
                "X,Y,Z towards the light (tangent frame, x warp, z normal); several --wi "
                "and as many --wo: one JSON line per (wi, wo) pair, the atlas read once")
      ->required()
      ->allow_extra_args(false);
  c->add_option("--wo", a->wo, "X,Y,Z towards the viewer (tangent frame)")
      ->required()
      ->allow_extra_args(false);
  c->add_option("--evaluator", a->evaluator,
                "model | closures | average (the repeat-averaged closures, average_closures.h: "
                "at --uv scaled by the point's yarn coverage, as the shaders far away)")
      ->check(CLI::IsMember({"model", "closures", "average"}));
  c->add_option("--backend", a->backend,
                "closures as built by: nodes (node mode, SVM) | osl (the OSL shader)")
      ->check(CLI::IsMember({"nodes", "osl"}));
  out.push_back({c, [a] { return eval_bsdf(*a); }});
}

void add_eval_mapping(CLI::App& eval, Commands& out) {
  auto a = std::make_shared<MappingArgs>();
  auto* c = eval.add_subcommand(
      "mapping", "closure-mapping error: model vs the Cycles closure mixture, over the sphere");
  c->add_option("--atlas", a->atlas, "atlas directory")->required();
  c->add_option("--texels", a->texels, "texels sampled over the repeat")
      ->check(CLI::Range(1, 4096));
  c->add_flag("--by-kind", a->by_kind,
              "ray-wave atlases: also the error of each kind of closure (reflection, "
              "refraction and translucent lobes, energy residual, the double layer's light "
              "from the forward light: diffuse BTDF and light returned backwards)");
  c->add_option("--views", a->views, "view directions over the hemisphere")
      ->check(CLI::Range(1, 1024));
  out.push_back({c, [a] { return eval_mapping(*a); }});
}

void add_eval_albedo(CLI::App& eval, Commands& out) {
  struct Args {
    std::string atlas, wo, evaluator = "model";
    int texels = 64;
  };
  auto a = std::make_shared<Args>();
  auto* c = eval.add_subcommand(
      "albedo", "directional albedo of a ray-wave atlas: energy reflected and transmitted");
  c->add_option("--atlas", a->atlas, "atlas directory")->required();
  c->add_option("--wo", a->wo, "X,Y,Z towards the viewer (tangent frame)")->required();
  c->add_option("--evaluator", a->evaluator, "model | closures")
      ->check(CLI::IsMember({"model", "closures"}));
  c->add_option("--texels", a->texels, "texels sampled over the repeat")
      ->check(CLI::Range(1, 4096));
  out.push_back({c, [a] {
    const loom::shading::vec3 vo = unit_direction("--wo", a->wo);
    auto atlas = loom::load_atlas(a->atlas);
    if (atlas.manifest.value("tier", "") != "raywave") {
      std::cerr << "error: --atlas: eval albedo needs a ray-wave atlas (this one is \""
                << atlas.manifest.value("tier", "?") << "\")\n";
      return 2;
    }
    const auto r = loom::raywave_albedo(
        atlas, loom::load_raywave(atlas), vo,
        a->evaluator == "closures" ? loom::Evaluator::Closures : loom::Evaluator::Model,
        a->texels);
    std::cout << json{{"reflect", r.reflect},
                      {"transmit", r.transmit},
                      {"gap_transmit", r.gap},
                      {"gap_diffracted", r.diffracted},
                      {"evaluator", a->evaluator},
                      {"wo", {vo.x, vo.y, vo.z}}}
                     .dump()
              << std::endl;
    return 0;
  }});
}

namespace {

struct ErrorArgs {
  std::string atlas, reference;
  bool truth = false;
  int points = 64, views = 12, sphere = 48;
  loom::TruthErrorSettings t;
};

json comparison(const loom::TruthComparison& c) {
  return {{"relative_l1", c.relative_l1},
          {"albedo_error", c.albedo_error},
          {"reflect_ratio", c.reflect_ratio},
          {"transmit_ratio", c.transmit_ratio}};
}

int eval_error_truth(const ErrorArgs& a, const loom::Atlas& at) {
  // The fabric is the one the atlas was baked from: its canonical spec, in the manifest.
  const auto spec = loom::parse_spec(at.manifest.value("spec", json::object()));
  if (!spec.ok()) {
    std::cerr << "error: --atlas: " << a.atlas << ": the manifest's spec does not load:\n";
    for (const auto& e : spec.errors) std::cerr << "  " << e << "\n";
    return 2;
  }
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  const loom::TruthError e = loom::truth_error(at, spec.spec, a.t);
  json views = json::array();
  for (const auto& v : e.views) {
    auto side = [](const loom::TruthView::Side& s) {
      return json{{"relative_l1", s.relative_l1}, {"reflect", s.reflect}, {"transmit", s.transmit}};
    };
    views.push_back({{"view", {v.view.x, v.view.y, v.view.z}},
                     {"truth", {{"reflect", v.truth_reflect},
                                {"transmit", v.truth_transmit},
                                {"direct", v.truth_direct},
                                {"noise_l1", v.noise_l1}}},
                     {"open", v.open},
                     {"model", side(v.model)},
                     {"closures", side(v.closures)}});
  }
  std::cout << json{{"model", comparison(e.model)},
                    {"closures", comparison(e.closures)},
                    {"noise_l1", e.noise_l1},
                    {"views", views},
                    {"rays_per_view", a.t.truth.rays},
                    {"res", a.t.truth.res},
                    {"points", a.t.points},
                    {"tier", at.manifest.value("tier", "")},
                    {"quality", at.manifest.value("quality", "")},
                    {"seconds", std::chrono::duration<double>(clock::now() - t0).count()}}
                   .dump()
            << std::endl;
  return 0;
}

}  // namespace

void add_eval_error(CLI::App& eval, Commands& out) {
  auto a = std::make_shared<ErrorArgs>();
  auto* c = eval.add_subcommand(
      "error", "error of an atlas's BSDF against the same fabric at another preset (e.g. "
               "reference), by the C++ model: relative L1 over the sphere (preset_error.h); "
               "with --truth, of its model and closures against the fibers (truth_error.h)");
  c->add_option("--atlas", a->atlas, "atlas to measure")->required();
  auto* ref = c->add_option("--reference", a->reference,
                            "atlas of the same fabric and tier to compare with");
  auto* tru = c->add_flag("--truth", a->truth,
                          "compare with light traced through the fibers of the fabric the "
                          "atlas was baked from (eval truth), model and closures");
  ref->excludes(tru);
  auto* pts = c->add_option("--points", a->points,
                            "points of the weave repeat (an n x n lattice, n = "
                            "round(sqrt(points))); default 64, 256 with --truth")
                  ->check(CLI::Range(1, 4096));
  auto* vws = c->add_option("--views", a->views,
                            "view directions over the sphere; default 12, 6 with --truth")
                  ->check(CLI::Range(1, 1024));
  c->add_option("--sphere", a->sphere, "light directions: N x 2N over the sphere (not --truth)")
      ->check(CLI::Range(2, 512));
  a->t.truth.res = 24;
  c->add_option("--rays", a->t.truth.rays, "--truth: rays per view (default 200000)")
      ->check(CLI::Range(uint64_t(2), uint64_t(1) << 40));
  c->add_option("--res", a->t.truth.res,
                "--truth: bins per side over the sphere, even (default 24)")
      ->check(CLI::Range(2, 512) & CLI::Validator(
                                       [](std::string& v) {
                                         return std::stoi(v) % 2 ? std::string("must be even")
                                                                 : std::string();
                                       },
                                       "EVEN"));
  c->add_option("--seed", a->t.truth.seed, "--truth: seed of the rays");
  c->add_option("--min-yarns", a->t.truth.min_yarns,
                "--truth: yarns across the traced tile in each direction, at least")
      ->check(CLI::Range(1, 256));
  out.push_back({c, [a, pts, vws] {
    if (a->reference.empty() && !a->truth) {
      std::cerr << "error: --reference or --truth: give one (what to compare the atlas with)\n";
      return 2;
    }
    const auto at = loom::load_atlas(a->atlas);
    if (a->truth) {
      a->t.points = pts->count() ? a->points : 256;
      a->t.views = vws->count() ? a->views : 6;
      return eval_error_truth(*a, at);
    }
    const auto r = loom::load_atlas(a->reference);
    const auto e = loom::preset_error(at, r, a->points, a->views, a->sphere);
    std::cout << json{{"average_relative_l1", e.average},
                      {"pointwise_mean_relative_l1", e.pointwise_mean},
                      {"pointwise_worst_relative_l1", e.pointwise_worst},
                      {"energy_error", e.energy},
                      {"points", e.points},
                      {"views", e.views},
                      {"tier", at.manifest.value("tier", "")},
                      {"quality", at.manifest.value("quality", "")},
                      {"reference_quality", r.manifest.value("quality", "")}}
                     .dump()
              << std::endl;
    return 0;
  }});
}

}  // namespace loom::cli
