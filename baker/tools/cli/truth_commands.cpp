// loom-bake eval truth (light traced through the fibers of a tile of the fabric: fiber_truth.h)
// and eval swatch (the colour the fibers show as a swatch, and the absorption that makes it the
// picked one: swatch.h).
#include <fmt/format.h>
#include <OpenImageIO/imageio.h>
#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "command.h"
#include "loom/atlas.h"
#include "loom/atlas_swatch.h"
#include "loom/cli_values.h"
#include "loom/colour.h"
#include "loom/delta_e.h"
#include "loom/fiber_truth.h"
#include "loom/spec.h"
#include "loom/spectral_upsampling.h"
#include "loom/swatch.h"
#include "loom/truth_error.h"

using nlohmann::json;

namespace loom::cli {

namespace {

struct EvalTruthArgs {
  std::string spec, wi, out;
  loom::TruthSettings s;
};

/// The tally as a float RGB OpenEXR image (res x res, the first scanline is cos theta_o = -1),
/// written beside its place and renamed into it, so that a failed write leaves nothing.
bool write_truth_image(const loom::TruthResult& r, const loom::Vec3d& wi, const std::string& path) {
  namespace fs = std::filesystem;
  const fs::path dst(path), tmp = dst.parent_path() / (".tmp-" + dst.filename().string());
  auto out = OIIO::ImageOutput::create(dst.filename().string());
  if (!out) return false;
  OIIO::ImageSpec spec(r.res, r.res, 3, OIIO::TypeDesc::FLOAT);
  spec.attribute("loom:layout", "f(wi, wo) |cos theta_o| per sr; rows: cos theta_o from -1 "
                                "(first scanline) to 1; columns: phi_o = atan2(y, x) from -pi; "
                                "the light through the gaps (a delta at -wi) is not in it");
  spec.attribute("loom:wi", fmt::format("{},{},{}", wi.x, wi.y, wi.z));
  if (!out->open(tmp.string(), spec) ||
      !out->write_image(OIIO::TypeDesc::FLOAT, r.density.data()) || !out->close()) {
    std::error_code ec;
    fs::remove(tmp, ec);
    return false;
  }
  std::error_code ec;
  fs::rename(tmp, dst, ec);
  return !ec;
}

int eval_truth(const EvalTruthArgs& a) {
  auto res = loom::load_spec(a.spec);
  refuse_thread_sequences(res, "eval truth");
  if (!res.ok()) return report_spec_errors(a.spec, res.errors);
  loom::resolve_yarn_colours(res.spec, loom::ColourConverter(""));  // as bake does by default
  const auto w = loom::parse_cli_direction("--wi", a.wi);
  const loom::Vec3d wi{w[0], w[1], w[2]};
  if (!(std::fabs(wi.z) >= 1e-3)) {
    std::cerr << "error: --wi: the light must not lie in the cloth's plane (|z| >= 1e-3 of a "
                 "unit vector; got "
              << a.wi << ")\n";
    return 2;
  }
  if (!a.out.empty() && !OIIO::ImageOutput::create(a.out)) {
    std::cerr << "error: --out: " << a.out << ": not an image format OpenImageIO writes (use .exr)\n";
    return 2;
  }
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  // Two halves of independent seeds: together the result, apart its Monte Carlo relative L1
  // over the bins (truth_error.h: noise_l1).
  const auto scene = loom::make_truth_scene(res.spec, a.s.min_yarns);
  loom::TruthSettings h = a.s;
  h.rays = std::max<uint64_t>(a.s.rays / 2, 1);
  loom::TruthPaths pa = scene->paths(wi, h);
  h.seed = a.s.seed + 0x9e3779b97f4a7c15ull;
  h.rays = std::max<uint64_t>(a.s.rays - a.s.rays / 2, 1);
  const loom::TruthPaths pb = scene->paths(wi, h);
  // The fibers absorb what the spec's colours stand for, in its colour reading (swatch.h).
  const auto fibers = loom::reading_materials(*scene, res.spec);
  const double noise =
      loom::combine_halves(scene->tally(pa, fibers), scene->tally(pb, fibers)).noise_l1;
  pa.paths.insert(pa.paths.end(), pb.paths.begin(), pb.paths.end());
  const loom::TruthResult r = scene->tally(pa, fibers);
  const double secs = std::chrono::duration<double>(clock::now() - t0).count();
  if (!a.out.empty() && !write_truth_image(r, wi, a.out)) {
    std::cerr << "error: --out: cannot write " << a.out << "\n";
    return 1;
  }
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  std::cout << json{{"spec", res.spec.name},
                    {"wi", {wi.x, wi.y, wi.z}},
                    {"reflect", r.reflect},
                    {"transmit", r.transmit},
                    {"absorbed", r.absorbed},
                    {"reflect_se", r.reflect_se},
                    {"transmit_se", r.transmit_se},
                    {"absorbed_se", r.absorbed_se},
                    {"direct", r.direct},
                    {"truncated", r.truncated},
                    {"noise_l1", noise},
                    {"colour_reading", loom::to_string(res.spec.colour_reading)},
                    {"sigma_per_um", {{"warp", fibers[0].sigma_per_um},
                                      {"weft", fibers[fibers.size() > 1 ? 1 : 0].sigma_per_um}}},
                    {"rays", r.rays},
                    {"res", r.res},
                    {"tile_um", r.tile_um},
                    {"z_um", {r.z_lo_um, r.z_hi_um}},
                    {"curves", r.curves},
                    {"segments", r.segments},
                    {"seconds", secs},
                    {"peak_rss_mib", double(ru.ru_maxrss) / 1024.0},
                    {"out", a.out.empty() ? json(nullptr) : json(a.out)}}
                   .dump()
            << std::endl;
  return 0;
}

}  // namespace

void add_eval_truth(CLI::App& eval, Commands& out) {
  auto a = std::make_shared<EvalTruthArgs>();
  auto* c = eval.add_subcommand(
      "truth", "trace light through the explicit fibers of a periodic tile of the fabric (the "
               "fiber-level ground truth); print JSON: reflect, transmit, absorbed (RGB "
               "fractions of the incident power) with their Monte Carlo standard errors, and "
               "noise_l1, the tally's Monte Carlo relative L1 over the bins");
  c->add_option("--spec", a->spec, spec_help())->required();
  c->add_option("--wi", a->wi, "X,Y,Z: direction towards the light in the cloth's frame (x along "
                               "the warp, z the normal; z < 0 lights the back)")
      ->required();
  c->add_option("--rays", a->s.rays, "rays traced (16 bytes of memory each)")
      ->check(CLI::Range(uint64_t(2), uint64_t(1) << 28));
  c->add_option("--res", a->s.res, "tally bins per side over the sphere")
      ->check(CLI::Range(1, 4096));
  c->add_option("--seed", a->s.seed, "seed of the rays");
  c->add_option("--min-yarns", a->s.min_yarns, "yarns across the tile in each direction, at least")
      ->check(CLI::Range(1, 256));
  c->add_option("-o,--out", a->out, "write the tally (f |cos theta_o| per sr, RGB) as OpenEXR");
  out.push_back({c, [a] { return eval_truth(*a); }});
}

namespace {

struct SwatchArgs {
  std::string spec, atlas;
  loom::SwatchSettings s;
};

/// The swatch an atlas renders (atlas_swatch.h), model and closures, against its picked colour.
int eval_atlas_swatch(const SwatchArgs& a) {
  const auto atlas = loom::load_atlas(a.atlas);
  if (const auto sp = loom::parse_spec(atlas.manifest.value("spec", json::object())); sp.ok())
    if (auto e = loom::thread_sequences_not_yet(sp.spec, "eval swatch"); !e.empty())
      return report_spec_errors(a.atlas, {e});
  const loom::SpectralUpsampler lab_of(loom::ColourConverter(""));  // its CIELAB
  auto lab = [&](const std::array<double, 3>& c) { return lab_of.lab(c); };
  const auto& cols = atlas.manifest.at("yarn_colours_linear");
  const auto warp = cols.at("warp").get<std::array<double, 3>>();
  const auto weft = cols.at("weft").get<std::array<double, 3>>();
  loom::AtlasSwatchSettings st;
  st.card = a.s.card;
  st.light_deg = a.s.light_deg;
  json out{{"atlas", a.atlas},
           {"tier", atlas.manifest.value("tier", "")},
           {"picked", {{"warp", warp}, {"weft", weft}}},
           {"below", a.s.card < 0 ? json("folded to opacity") : json(a.s.card)}};
  for (const auto e : {loom::Evaluator::Model, loom::Evaluator::Closures}) {
    const loom::Swatch sw = loom::atlas_swatch(atlas, e, st);
    json j{{"rho", sw.rho},
           {"lab", lab(sw.rho)},
           {"reflect", sw.reflect},
           {"transmit", sw.transmit},
           {"below", sw.below}};
    // One picked colour to compare with when warp and weft are one colour.
    j["delta_e_2000"] = warp == weft ? json(loom::delta_e_2000(lab(warp), lab(sw.rho))) : json(nullptr);
    out[e == loom::Evaluator::Model ? "model" : "closures"] = j;
  }
  std::cout << out.dump() << std::endl;
  return 0;
}

int eval_swatch(const SwatchArgs& a) {
  if (a.spec.empty() == a.atlas.empty()) {
    std::cerr << "error: --spec or --atlas: give one (the fibers of a spec, or what an atlas "
                 "renders)\n";
    return 2;
  }
  if (!a.atlas.empty()) return eval_atlas_swatch(a);
  auto res = loom::load_spec(a.spec);
  refuse_thread_sequences(res, "eval swatch");
  if (!res.ok()) return report_spec_errors(a.spec, res.errors);
  const loom::ColourConverter cc("");
  loom::resolve_yarn_colours(res.spec, cc);  // as bake does by default
  const loom::SpectralUpsampler lab_of(cc);  // its CIELAB
  auto lab = [&](const std::array<double, 3>& c) { return lab_of.lab(c); };
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  const auto scene = loom::make_truth_scene(res.spec, a.s.truth.min_yarns);
  const loom::SwatchPaths paths(*scene, a.s);
  // Today's reading of a colour (the ply's albedo, absorption.h), yarn by yarn as it is baked.
  const auto ply = loom::truth_materials(res.spec);
  json yarns = json::object();
  for (int i = 0; i < 2; ++i) {
    const loom::YarnSpec& y = i == 0 ? res.spec.warp : res.spec.weft;
    if (i == 1 && y.color_linear == res.spec.warp.color_linear) break;  // one colour: one answer
    std::vector<loom::FiberMaterial> as_ply = scene->materials();
    for (size_t k = 0; k < as_ply.size(); ++k)
      as_ply[k].sigma_per_um = ply[size_t(i)].sigma_per_um;
    const loom::Swatch now = paths.swatch(as_ply);
    const loom::SwatchSolve sol = paths.solve(y.color_linear);
    const loom::Lab picked = lab(y.color_linear);
    auto side = [&](const loom::Swatch& sw) {
      return json{{"rho", sw.rho},
                  {"lab", lab(sw.rho)},
                  {"delta_e_2000", loom::delta_e_2000(picked, lab(sw.rho))},
                  {"reflect", sw.reflect},
                  {"transmit", sw.transmit},
                  {"up_reflect", sw.up_reflect},
                  {"up_transmit", sw.up_transmit},
                  {"below", sw.below}};
    };
    json solved = side(sol.swatch);
    solved["sigma_per_um"] = sol.sigma_per_um;
    solved["clamped"] = sol.clamped;
    json now_j = side(now);
    now_j["sigma_per_um"] = ply[size_t(i)].sigma_per_um;
    yarns[i == 0 ? (res.spec.weft.color_linear == y.color_linear ? "warp_and_weft" : "warp")
                 : "weft"] = {{"picked", y.color_linear},
                              {"picked_lab", picked},
                              {"as_ply_albedo", now_j},
                              {"solved", solved}};
  }
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  std::cout << json{{"spec", res.spec.name},
                    {"yarns", yarns},
                    {"light_deg", a.s.light_deg},
                    {"below", a.s.card < 0 ? json("folded to opacity") : json(a.s.card)},
                    {"rays", a.s.truth.rays},
                    {"seconds", std::chrono::duration<double>(clock::now() - t0).count()},
                    {"peak_rss_mib", double(ru.ru_maxrss) / 1024.0}}
                   .dump()
            << std::endl;
  return 0;
}

}  // namespace

void add_eval_swatch(CLI::App& eval, Commands& out) {
  auto a = std::make_shared<SwatchArgs>();
  auto* c = eval.add_subcommand(
      "swatch", "the colour a spec's cloth shows as a swatch folded to opacity, light at 8 degrees "
                "(swatch.h), traced through its fibers: today's reading of the yarn colour "
                "(the ply's albedo) and the absorption that makes the swatch the picked colour, "
                "each with Delta E 2000 to it; with --atlas, the swatch the atlas renders; print "
                "JSON");
  c->add_option("--spec", a->spec, spec_help());
  c->add_option("--atlas", a->atlas,
                "instead of --spec: the swatch the atlas renders, by its model and by its "
                "closures (atlas_swatch.h)");
  a->s.truth.rays = 100000;
  c->add_option("--rays", a->s.truth.rays, "rays of each of the two traces (default 100000)")
      ->check(CLI::Range(uint64_t(100), uint64_t(1) << 32));
  c->add_option("--card", a->s.card,
                "lay the cloth on a card of this reflectance (1: ideal white) instead of "
                "folding it to opacity")
      ->check(finite_range(0, 1));
  c->add_option("--seed", a->s.truth.seed, "seed of the rays");
  c->add_option("--min-yarns", a->s.truth.min_yarns,
                "yarns across the traced tile in each direction, at least")
      ->check(CLI::Range(1, 256));
  out.push_back({c, [a] { return eval_swatch(*a); }});
}

}  // namespace loom::cli
