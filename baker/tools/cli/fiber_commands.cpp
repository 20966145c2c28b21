// loom-bake fibers (the fiber tier's curves of a region) and eval fibers (its look-up structures
// against full realization).
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "command.h"
#include "loom/cli_values.h"
#include "loom/fiber_lookup.h"
#include "loom/fiber_region.h"
#include "loom/spec.h"

using nlohmann::json;

namespace loom::cli {

void add_fibers(CLI::App& app, Commands& out) {
  struct Args {
    std::string spec, region, out;
    uint64_t max = loom::kDefaultMaxFiberVertices;
  };
  auto a = std::make_shared<Args>();
  auto* c = app.add_subcommand(
      "fibers", "realize the fibers of a region of the fabric as curves (fiber tier)");
  c->add_option("spec,--spec", a->spec, spec_help())->required();
  c->add_option("--region", a->region, "X0,Y0,X1,Y1 in um of the fabric plane (x along the warp)")
      ->required();
  c->add_option("-o,--out", a->out, "directory to write (manifest.json and the curves)")
      ->required();
  c->add_option("--max-vertices", a->max, "refuse regions needing more vertices")
      ->check(CLI::Range(uint64_t(2), uint64_t(2000000000)));
  out.push_back({c, [a] {
    auto res = loom::load_spec(a->spec);
    refuse_thread_sequences(res, "fibers");  // the add-on colours the fibers by system
    if (!res.ok()) return report_spec_errors(a->spec, res.errors);
    const auto rv = loom::parse_cli_region("--region", a->region);
    loom::FiberRegion reg{rv[0], rv[1], rv[2], rv[3]};
    auto t0 = std::chrono::steady_clock::now();
    loom::FiberCurves curves;
    try {
      curves = loom::realize_fiber_region(res.spec, reg, a->max);
    } catch (const std::invalid_argument& e) {
      std::cerr << "error: --" << e.what() << "\n";
      return 2;
    }
    loom::write_fiber_curves(curves, res.spec, reg, a->out);
    size_t hairs = 0;
    for (auto h : curves.hair) hairs += h;
    std::cout << json{{"out", a->out},
                      {"yarns", curves.yarns},
                      {"curves", curves.curves()},
                      {"hair_curves", hairs},
                      {"vertices", curves.vertices()},
                      {"bytes", curves.bytes()},
                      {"seconds", std::chrono::duration<double>(
                                      std::chrono::steady_clock::now() - t0)
                                      .count()}}
                     .dump()
              << std::endl;
    return 0;
  }});
}

namespace {

struct EvalFibersArgs {
  std::string spec, only = "both", hairs = "hybrid";
  int yarns = 10, points = 10000, bins = 64;
  uint64_t seed = 1;
};

int eval_fibers(const EvalFibersArgs& a) {
  auto res = loom::load_spec(a.spec);
  if (!res.ok()) return report_spec_errors(a.spec, res.errors);
  using clock = std::chrono::steady_clock;
  auto secs = [](clock::time_point t) {
    return std::chrono::duration<double>(clock::now() - t).count();
  };
  auto patch = loom::make_woven_patch(res.spec, a.yarns);
  const bool do_min = a.only != "realized", do_real = a.only != "minimising";
  if (do_real) {  // refuse a realization that cannot fit rather than run out of memory
    double verts = 0;
    for (const auto& y : patch)
      verts += double(std::max(y.ply.plies, 1)) * y.ply.fibers *
               (y.curve.length() / loom::fiber_step(y.ply) + 2);
    const double gib = verts * 36 / (1u << 30), limit = 12;
    if (gib > limit) {
      std::cerr << fmt::format(
          "error: --yarns: full realization of {} yarns needs about {:.1f} GiB ({:.3g} "
          "vertices), more than the {} GiB allowed; use --only minimising or fewer yarns\n",
          a.yarns, gib, verts, limit);
      return 2;
    }
  }
  auto pts = loom::fiber_test_points(patch, a.points, a.seed);
  loom::FiberLookupOptions fopt;
  fopt.azimuth_bins = a.bins;
  fopt.realization_free_hairs = a.hairs == "realization-free";
  std::unique_ptr<loom::FiberLookup> minimising;
  std::unique_ptr<loom::RealizedFibers> realized;
  json out{{"spec", res.spec.name}, {"yarns", a.yarns}, {"points", a.points},
           {"fibers_per_yarn", res.spec.warp.plies * res.spec.warp.fibers_per_ply},
           {"hairs_method", a.hairs}};
  std::vector<loom::FiberHit> hm, hr;
  if (do_min) {
    auto t0 = clock::now();
    minimising = std::make_unique<loom::FiberLookup>(patch, fopt);
    out["build_seconds_minimising"] = secs(t0);
    t0 = clock::now();
    hm.reserve(pts.size());
    for (auto& p : pts) hm.push_back(minimising->lookup(p));
    out["seconds_minimising"] = secs(t0);
    out["bytes_minimising"] = minimising->bytes();
    out["hairs"] = minimising->hair_count();
  }
  if (do_real) {
    auto t0 = clock::now();
    realized = std::make_unique<loom::RealizedFibers>(patch, fopt);
    out["build_seconds_realized"] = secs(t0);
    t0 = clock::now();
    hr.reserve(pts.size());
    for (auto& p : pts) hr.push_back(realized->lookup(p));
    out["seconds_realized"] = secs(t0);
    out["bytes_realized"] = realized->bytes();
    out["realized_vertices"] = realized->vertex_count();
  }
  const auto& hits = do_min ? hm : hr;
  size_t covered = 0, hair = 0;
  for (auto& h : hits) covered += h.covered, hair += h.covered && h.hair;
  out["covered"] = covered;
  out["covered_by_hair"] = hair;
  if (do_min && do_real) {
    size_t mismatches = 0;
    for (size_t i = 0; i < pts.size(); ++i)
      mismatches += !hm[i].same_fiber(hr[i]) || hm[i].distance != hr[i].distance;
    out["mismatches"] = mismatches;
    out["memory_ratio"] = double(realized->bytes()) / double(minimising->bytes());
    out["time_ratio"] = out["seconds_minimising"].get<double>() /
                        std::max(out["seconds_realized"].get<double>(), 1e-9);
  } else {
    out["mismatches"] = nullptr;
  }
  std::cout << out.dump() << std::endl;
  return 0;
}

}  // namespace

void add_eval_fibers(CLI::App& eval, Commands& out) {
  auto a = std::make_shared<EvalFibersArgs>();
  auto* c = eval.add_subcommand(
      "fibers", "look up seeded points in an N-yarn woven patch both by the fiber tier's "
                "realization-minimising structures and by full realization; print JSON");
  c->add_option("--spec", a->spec, spec_help())->required();
  c->add_option("--yarns", a->yarns, "yarns in the patch (warp and weft together)")
      ->check(CLI::Range(2, loom::kMaxPatchYarns));
  c->add_option("--points", a->points, "seeded points to look up")
      ->check(CLI::Range(1, 100000000));
  c->add_option("--seed", a->seed, "seed of the points");
  c->add_option("--bins", a->bins, "azimuth bins of Algorithm 2")->check(CLI::Range(1, 4096));
  c->add_option("--only", a->only,
                "both | minimising | realized (build and time one of them alone, for "
                "whole-process memory)")
      ->check(CLI::IsMember({"both", "minimising", "realized"}));
  c->add_option("--hairs", a->hairs,
                "hybrid (z-binning, section 4.4.2) | realization-free (Algorithm 3)")
      ->check(CLI::IsMember({"hybrid", "realization-free"}));
  out.push_back({c, [a] { return eval_fibers(*a); }});
}

}  // namespace loom::cli
