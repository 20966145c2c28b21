// loom-bake: bake a fabric spec into an atlas, inspect an atlas, and probe its BSDF.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fmt/format.h>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include "loom/asg_residual.h"
#include "loom/absorption.h"
#include "loom/aperture_diffraction.h"
#include "loom/atlas.h"
#include "loom/bake.h"
#include "loom/cli_values.h"
#include "loom/evaluator.h"
#include "loom/fiber_lookup.h"
#include "loom/fiber_region.h"
#include "loom/raywave_bsdf.h"
#include "loom/ply_scattering.h"
#include "loom/ply_tables.h"
#include "loom/shading.h"
#include "loom/spec.h"
#include "loom/ply_maps.h"
#include "loom/preset_error.h"
#include "loom/weave.h"

using nlohmann::json;
namespace fs = std::filesystem;

namespace {

/// Index of the grid value nearest to x (the first of equals).
size_t nearest_node(const std::vector<double>& g, double x) {
  size_t best = 0;
  for (size_t i = 1; i < g.size(); ++i)
    if (std::fabs(g[i] - x) < std::fabs(g[best] - x)) best = i;
  return best;
}

/// The ray simulation of the grid slice of an atlas's ply tables nearest to (theta_i, h),
/// identical to the bake's (same seed), at sigma = 0 and `sigma`: what eval raywave --raw and
/// eval lobes --raw compare the fit with. For a multi-ply yarn this is one ply's scattering
/// while the tables hold the yarn's (Eq. S.13).
struct NearestSlice {
  loom::PlySimSlice slice;
  loom::PlySimSettings settings;
  double theta_i = 0, h = 0;
  bool multi_ply = false;
  /// Simulated f_refl + f_high (at `sigma`) in the bin of direction w.
  double value(const loom::Vec3d& w, double* refl = nullptr, double* high = nullptr) const {
    int bt, bp;
    loom::ply_sim_bin_of(settings, w, bt, bp);
    const size_t bins = size_t(settings.theta_o_count) * size_t(settings.phi_o_count);
    const size_t b = size_t(bt) * size_t(settings.phi_o_count) + size_t(bp);
    const double r = slice.refl[b], hh = slice.high[(settings.sigmas.size() - 1) * bins + b];
    if (refl) *refl = r;
    if (high) *high = hh;
    return r + hh;
  }
};

NearestSlice simulate_nearest_slice(const loom::Atlas& atlas, const loom::AsgTable& high,
                                    const std::string& yarn, double theta_i, double h,
                                    double sigma) {
  auto res = loom::parse_spec(atlas.manifest.value("spec", json()));
  if (!res.ok()) throw std::runtime_error("the atlas's spec does not parse: " + res.errors[0]);
  const loom::YarnSpec& y = yarn == "weft" ? res.spec.weft : res.spec.warp;
  NearestSlice out;
  out.settings = loom::ply_sim_settings(res.spec.quality);
  const size_t m = nearest_node(high.theta_i, theta_i), hn = nearest_node(high.h, h);
  out.settings.sigmas = {0.0};
  if (sigma > 0) out.settings.sigmas.push_back(sigma);
  auto p = loom::ply_params_from_yarn(y);
  loom::PlyGeometry g(p, loom::make_ply_fibers(p, 0, 0));
  out.slice = loom::simulate_ply_slice(g, y.ior, out.settings, high.theta_i[m], high.h[hn],
                                       m * high.h.size() + hn);
  out.theta_i = high.theta_i[m], out.h = high.h[hn], out.multi_ply = y.plies > 1;
  return out;
}

/// CLI::Range for real numbers, but NaN and infinities are rejected too (every comparison with
/// NaN is false, so CLI::Range lets it through); the number syntax of loom/cli_values.h. The
/// accepted value is handed on in its shortest round-trip form, so that CLI11's own conversion
/// reads exactly the number checked.
CLI::Validator finite_range(double lo, double hi) {
  return CLI::Validator(
      [lo, hi](std::string& s) -> std::string {
        try {
          s = fmt::format("{}", loom::parse_cli_number_in("", s, lo, hi));
        } catch (const loom::CliValueError& e) {
          return e.what();
        }
        return "";
      },
      fmt::format("in [{}, {}]", lo, hi));
}

int report_spec_errors(const std::string& what, const std::vector<std::string>& errors) {
  for (auto& e : errors) std::cerr << "error: " << e << "\n";
  std::cerr << fmt::format("loom-bake: {} has {} problem{}; nothing was written\n", what,
                           errors.size(), errors.size() == 1 ? "" : "s");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "loom-bake: physically based woven cloth for Cycles.\n"
      "Bakes a fabric spec (JSON, schema loom.fabric/1, or a preset name) into an atlas of\n"
      "tiled, mip-mapped textures plus manifest.json, which Loom's OSL shaders and node groups\n"
      "read. Examples:\n"
      "  loom-bake bake plain -o /tmp/plain.atlas\n"
      "  loom-bake bake my_fabric.json -o out.atlas --quality final --progress=json\n"
      "  loom-bake inspect out.atlas\n"
      "  loom-bake eval bsdf --atlas out.atlas --uv 0.3,0.6 --wi 0,0.5,0.866 --wo 0,0,1"};
  app.require_subcommand(1);

  std::string spec_arg, out_dir, quality, ocio, progress_mode = "auto";
  bool force = false;
  auto* bake = app.add_subcommand("bake", "bake a spec (file or preset name) into an atlas");
  bake->add_option("spec", spec_arg, "spec file or preset name (plain, twill, satin, basket)")
      ->required();
  bake->add_option("-o,--output", out_dir, "atlas directory to create (published atomically)")
      ->required();
  bake->add_option("--quality", quality, "override model.quality: draft|preview|final|reference");
  bake->add_option("--ocio-config", ocio,
                   "OpenColorIO config for colour conversion (e.g. Blender's); default: $OCIO "
                   "or Loom's built-in sRGB -> linear Rec.709");
  bake->add_option("--progress", progress_mode, "progress output: auto|text|json|none");
  bake->add_flag("--force", force,
                 "re-bake from scratch even if the destination holds this spec's atlas, and "
                 "re-simulate a ray-wave spec whose tables another atlas holds");
  std::vector<std::string> reuse_dirs;
  bake->add_option("--reuse", reuse_dirs,
                   "ray-wave atlas whose colour-independent tables (ply tables, double layer, "
                   "diffraction, noise) a colour-only change may copy; the destination and its "
                   "siblings are always looked at");

  std::string inspect_dir;
  bool inspect_json = false;
  auto* inspect = app.add_subcommand("inspect", "validate an atlas and print a summary");
  inspect->add_option("atlas", inspect_dir, "atlas directory")->required();
  inspect->add_flag("--json", inspect_json, "print the manifest summary as JSON");

  std::string check_arg, check_quality;
  auto* check = app.add_subcommand("check", "validate a spec and print its canonical form");
  check->add_option("spec", check_arg, "spec file or preset name")->required();
  check->add_option("--quality", check_quality, "override model.quality");
  bool check_geometry = false;
  check->add_flag("--geometry", check_geometry,
                  "print {\"spec\": canonical spec, \"repeat_um\": [x, y], \"warp_yarns\", "
                  "\"weft_yarns\"} (the weave repeat's size and yarn counts)");

  auto* presets = app.add_subcommand("presets", "list the built-in presets, or print one");
  std::string preset_name;
  presets->add_option("name", preset_name, "preset to print as JSON");

  auto* fibers_cmd = app.add_subcommand(
      "fibers", "realize the fibers of a region of the fabric as curves (fiber tier)");
  std::string fr_spec, fr_region, fr_out;
  uint64_t fr_max = loom::kDefaultMaxFiberVertices;
  fibers_cmd->add_option("--spec", fr_spec, "fabric spec file or preset name")->required();
  fibers_cmd->add_option("--region", fr_region,
                         "X0,Y0,X1,Y1 in um of the fabric plane (x along the warp)")
      ->required();
  fibers_cmd->add_option("--out", fr_out, "directory to write (manifest.json and the curves)")
      ->required();
  fibers_cmd->add_option("--max-vertices", fr_max, "refuse regions needing more vertices")
      ->check(CLI::Range(uint64_t(2), uint64_t(2000000000)));

  auto* eval = app.add_subcommand("eval", "probe an evaluator");
  eval->require_subcommand(1);
  auto* bsdf = eval->add_subcommand("bsdf", "BSDF value f (no cosine) at a surface point");
  std::string atlas_dir, uv_s, evaluator = "model";
  std::vector<std::string> wi_s, wo_s;
  bool average = false;
  bsdf->add_option("--atlas", atlas_dir, "atlas directory")->required();
  bsdf->add_option("--uv", uv_s, "U,V texture coordinate (one repeat = [0,1)^2, wrapped)");
  bsdf->add_flag("--average", average, "average f over the whole weave repeat instead of --uv");
  bsdf->add_option("--wi", wi_s,
                   "X,Y,Z towards the light (tangent frame, x warp, z normal); several --wi "
                   "and as many --wo: one JSON line per (wi, wo) pair, the atlas read once")
      ->required()
      ->allow_extra_args(false);
  bsdf->add_option("--wo", wo_s, "X,Y,Z towards the viewer (tangent frame)")
      ->required()
      ->allow_extra_args(false);
  bsdf->add_option("--evaluator", evaluator, "model | closures")
      ->check(CLI::IsMember({"model", "closures"}));
  std::string backend = "nodes";
  bsdf->add_option("--backend", backend,
                   "closures as built by: nodes (node mode, SVM) | osl (the OSL shader)")
      ->check(CLI::IsMember({"nodes", "osl"}));

  auto* mapping = eval->add_subcommand(
      "mapping", "closure-mapping error: model vs the Cycles closure mixture, over the sphere");
  std::string mapping_atlas;
  int mapping_texels = 64, mapping_views = 24;
  mapping->add_option("--atlas", mapping_atlas, "atlas directory")->required();
  mapping->add_option("--texels", mapping_texels, "texels sampled over the repeat")
      ->check(CLI::Range(1, 4096));
  bool mapping_by_kind = false;
  mapping->add_flag("--by-kind", mapping_by_kind,
                    "ray-wave atlases: also the error of each kind of closure (reflection, "
                    "refraction and translucent lobes, energy residual, the double layer's light "
                    "from the forward light: diffuse BTDF and light returned backwards)");
  mapping->add_option("--views", mapping_views, "view directions over the hemisphere")
      ->check(CLI::Range(1, 1024));

  auto* albedo = eval->add_subcommand(
      "albedo", "directional albedo of a ray-wave atlas: energy reflected and transmitted");
  std::string albedo_atlas, albedo_wo_s, albedo_evaluator = "model";
  int albedo_texels = 64;
  albedo->add_option("--atlas", albedo_atlas, "atlas directory")->required();
  albedo->add_option("--wo", albedo_wo_s, "X,Y,Z towards the viewer (tangent frame)")->required();
  albedo->add_option("--evaluator", albedo_evaluator, "model | closures")
      ->check(CLI::IsMember({"model", "closures"}));
  albedo->add_option("--texels", albedo_texels, "texels sampled over the repeat")
      ->check(CLI::Range(1, 4096));

  auto* asg = eval->add_subcommand(
      "asg", "one ASG lobe (Eq. S.1, S.2) at a direction, and its integral over the sphere");
  std::string asg_lobe_s, asg_v_s;
  asg->add_option("--lobe", asg_lobe_s, "THETA_Z,PHI_Z,PHI_XY,MU1,MU2,C (angles in radians)")
      ->required();
  asg->add_option("--v", asg_v_s, "X,Y,Z direction in ply space (normalised)")->required();

  auto* diffraction = eval->add_subcommand(
      "diffraction",
      "Gaussian-beam aperture diffraction (Eq. S.34, S.35) for one wavelength and direction pair");
  std::string dif_aperture_s, dif_wi_s, dif_wo_s;
  double dif_waist = 10, dif_lambda = 550;
  diffraction
      ->add_option("--aperture", dif_aperture_s,
                   "XW,XE,YS,YN: the rectangle [XW, XE] x [YS, YN] in um, relative to the beam "
                   "centre (inf and -inf allowed)")
      ->required();
  diffraction->add_option("--waist", dif_waist, "beam waist w_0 in um (Eq. S.25)")
      ->check(finite_range(1e-3, 1e6));
  diffraction->add_option("--lambda", dif_lambda, "wavelength in nm")->check(finite_range(1.0, 1e5));
  diffraction->add_option("--wi", dif_wi_s, "X,Y,Z towards the light, aperture frame (z normal)")
      ->required();
  diffraction->add_option("--wo", dif_wo_s, "X,Y,Z towards the receiver on the far side")
      ->required();

  auto* plysim = eval->add_subcommand(
      "plysim", "simulate one (theta_i, h) slice of ply scattering and print energy fractions");
  std::string plysim_spec, plysim_yarn = "warp", plysim_quality;
  double plysim_theta = 0, plysim_h = 0, plysim_sigma = 0;
  int plysim_rays = 0;
  uint64_t plysim_seed = 1;
  plysim->add_option("--spec", plysim_spec, "fabric spec file or preset name")->required();
  plysim->add_option("--yarn", plysim_yarn, "warp | weft")->check(CLI::IsMember({"warp", "weft"}));
  plysim->add_option("--theta-i", plysim_theta, "incident angle from the ply's normal plane, "
                                                "degrees [-90, 90]")
      ->required()
      ->check(finite_range(-90.0, 90.0));
  plysim->add_option("--h", plysim_h, "beam offset across the ply, [-1, 1]")
      ->required()
      ->check(finite_range(-1.0, 1.0));
  plysim->add_option("--sigma", plysim_sigma, "fiber absorption, 1/mm, [0, 1e6]")
      ->check(finite_range(0.0, 1e6));
  plysim->add_option("--rays", plysim_rays, "rays (default: the quality preset's per slice)")
      ->check(CLI::Range(1, 100000000));
  plysim->add_option("--quality", plysim_quality, "draft | preview | final | reference");
  plysim->add_option("--seed", plysim_seed, "random seed");

  auto* raywave = eval->add_subcommand(
      "raywave", "the fitted ply scattering of a ray-wave atlas (Eq. S.8, S.12) at one direction");
  std::string rw_atlas, rw_wo_s, rw_yarn = "warp";
  double rw_theta = 0, rw_h = 0, rw_sigma = 0;
  bool rw_raw = false;
  // --atlas, --theta-i, --h, --sigma, --yarn: where in an atlas's ply tables a probe looks.
  auto add_slice_options = [](CLI::App* sub, std::string& atlas, double& theta, double& h,
                              double& sigma, std::string& yarn) {
    sub->add_option("--atlas", atlas, "ray-wave atlas directory")->required();
    sub->add_option("--theta-i", theta, "incident angle, degrees [-90, 90]")
        ->required()
        ->check(finite_range(-90.0, 90.0));
    sub->add_option("--h", h, "offset across the ply, [-1, 1]")
        ->required()
        ->check(finite_range(-1.0, 1.0));
    sub->add_option("--sigma", sigma, "fiber absorption, 1/mm, [0, 1e6]")
        ->check(finite_range(0.0, 1e6));
    sub->add_option("--yarn", yarn, "warp | weft")->check(CLI::IsMember({"warp", "weft"}));
  };
  add_slice_options(raywave, rw_atlas, rw_theta, rw_h, rw_sigma, rw_yarn);
  raywave->add_option("--wo", rw_wo_s, "X,Y,Z outgoing direction in ply space")->required();
  raywave->add_flag("--raw", rw_raw,
                    "also re-run the simulation of the nearest grid slice (identical to the "
                    "bake's: same seed) and print its value in the bin of --wo");

  auto* tables = eval->add_subcommand(
      "tables", "error of a ray-wave atlas's fitted ply scattering against another (e.g. the "
                "reference preset's): relative L1 over the sphere");
  std::string tables_atlas, tables_ref, tables_yarn = "warp";
  tables->add_option("--atlas", tables_atlas, "ray-wave atlas to measure")->required();
  tables->add_option("--reference", tables_ref, "ray-wave atlas to compare with")->required();
  tables->add_option("--yarn", tables_yarn, "warp | weft")->check(CLI::IsMember({"warp", "weft"}));

  auto* error = eval->add_subcommand(
      "error", "error of an atlas's BSDF against the same fabric at another preset (e.g. "
               "reference), by the C++ model: relative L1 over the sphere (preset_error.h)");
  std::string error_atlas, error_ref;
  int error_points = 64, error_views = 12, error_sphere = 48;
  error->add_option("--atlas", error_atlas, "atlas to measure")->required();
  error->add_option("--reference", error_ref, "atlas of the same fabric and tier to compare with")
      ->required();
  error->add_option("--points", error_points,
                    "points of the weave repeat (an n x n lattice, n = round(sqrt(points)))")
      ->check(CLI::Range(1, 4096));
  error->add_option("--views", error_views, "view directions over the sphere")
      ->check(CLI::Range(1, 1024));
  error->add_option("--sphere", error_sphere, "light directions: N x 2N over the sphere")
      ->check(CLI::Range(2, 512));

  auto* lobes = eval->add_subcommand(
      "lobes", "each fitted lobe of a ray-wave atlas (Eq. S.1, S.7, S.11) at (theta_i, h, "
               "sigma) on an (elevation, azimuth) grid of ply-space directions, for plots");
  std::string lobes_atlas, lobes_yarn = "warp";
  double lobes_theta = 0, lobes_h = 0, lobes_sigma = 0;
  int lobes_res = 48;
  bool lobes_raw = false;
  add_slice_options(lobes, lobes_atlas, lobes_theta, lobes_h, lobes_sigma, lobes_yarn);
  lobes->add_option("--res", lobes_res, "grid rows (elevation); columns (azimuth) 2x, [4, 512]")
      ->check(CLI::Range(4, 512));
  lobes->add_flag("--raw", lobes_raw,
                  "also the simulated scattering of the nearest grid slice on the same grid");
  bool lobes_snap = false;
  lobes->add_flag("--snap", lobes_snap,
                  "evaluate the lobes at the tables' grid slice (theta_i, h) nearest to the one "
                  "asked, where the simulation is (to compare the two)");

  auto* noise = eval->add_subcommand(
      "noise", "statistics of a ray-wave atlas's speckle noise tiles (Eq. S.37, S.38)");
  std::string noise_atlas;
  bool noise_stats = false;
  noise->add_option("--atlas", noise_atlas, "ray-wave atlas")->required();
  noise->add_flag("--stats", noise_stats,
                  "per tile, instance and band: mean (1 by construction), variance, min, max")
      ->required();

  auto* colour = eval->add_subcommand(
      "colour", "a colour through a ray-wave atlas's absorption data: sigma(lambda) (Eq. S.42) "
                "and the RGB the ply reflects with it");
  std::string colour_rgb_s, colour_atlas, colour_yarn = "warp";
  colour->add_option("--rgb", colour_rgb_s, "R,G,B scene-linear, each in [0, 1]")->required();
  colour->add_option("--atlas", colour_atlas, "ray-wave atlas")->required();
  colour->add_option("--yarn", colour_yarn, "warp | weft (whose ply model)")
      ->check(CLI::IsMember({"warp", "weft"}));

  auto* fibers = eval->add_subcommand(
      "fibers", "look up seeded points in an N-yarn woven patch both by the fiber tier's "
                "realization-minimising structures and by full realization; print JSON");
  std::string fibers_spec, fibers_only = "both", fibers_hairs = "hybrid";
  int fibers_yarns = 10, fibers_points = 10000, fibers_bins = 64;
  uint64_t fibers_seed = 1;
  fibers->add_option("--spec", fibers_spec, "fabric spec file or preset name")->required();
  fibers->add_option("--yarns", fibers_yarns, "yarns in the patch (warp and weft together)")
      ->check(CLI::Range(2, loom::kMaxPatchYarns));
  fibers->add_option("--points", fibers_points, "seeded points to look up")
      ->check(CLI::Range(1, 100000000));
  fibers->add_option("--seed", fibers_seed, "seed of the points");
  fibers->add_option("--bins", fibers_bins, "azimuth bins of Algorithm 2")
      ->check(CLI::Range(1, 4096));
  fibers->add_option("--only", fibers_only,
                     "both | minimising | realized (build and time one of them alone, for "
                     "whole-process memory)")
      ->check(CLI::IsMember({"both", "minimising", "realized"}));
  fibers->add_option("--hairs", fibers_hairs,
                     "hybrid (z-binning, section 4.4.2) | realization-free (Algorithm 3)")
      ->check(CLI::IsMember({"hybrid", "realization-free"}));

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version exit 0; every bad command line exits 2, like every other bad input.
    return app.exit(e) == 0 ? 0 : 2;
  }

  try {
    if (*bake) {
      if (ocio.empty() && std::getenv("OCIO")) ocio = std::getenv("OCIO");
      auto res = loom::load_spec(spec_arg, quality);
      if (!res.ok()) return report_spec_errors(spec_arg, res.errors);
      if (progress_mode != "auto" && progress_mode != "text" && progress_mode != "json" &&
          progress_mode != "none") {
        std::cerr << "error: --progress: \"" << progress_mode
                  << "\" is not one of auto, text, json, none\n";
        return 2;
      }
      if (progress_mode == "auto") progress_mode = isatty(2) ? "text" : "none";
      loom::BakeOptions opt;
      opt.ocio_config = ocio;
      opt.force = force;
      for (const auto& d : reuse_dirs) opt.reuse_from.emplace_back(d);
      if (progress_mode == "json") {
        opt.progress = [](const std::string& stage, double f) {
          std::cout << json{{"stage", stage}, {"fraction", f}}.dump() << std::endl;
        };
      } else if (progress_mode == "text") {
        opt.progress = [](const std::string& stage, double f) {
          std::cerr << fmt::format("\r{:<12} {:3.0f}%", stage, 100 * f) << std::flush;
          if (f >= 1.0) std::cerr << "\n";
        };
      }
      auto r = loom::bake_atlas(res.spec, out_dir, opt);
      std::cout << json{{"atlas", r.dir.string()},
                        {"reused", r.reused},
                        {"reused_simulation", r.reused_simulation.string()},
                        {"seconds", r.seconds},
                        {"bytes", r.bytes}}
                       .dump()
                << std::endl;
      return 0;
    }
    if (*check) {
      auto res = loom::load_spec(check_arg, check_quality);
      if (!res.ok()) return report_spec_errors(check_arg, res.errors);
      if (check_geometry) {
        const loom::Weave w = loom::make_weave(res.spec.weave);
        const loom::SurfaceGeometry g(res.spec);  // (the repeat as the maps are baked)
        std::cout << json{{"spec", loom::canonical_spec(res.spec)},
                          {"repeat_um", {g.repeat_x(), g.repeat_y()}},
                          {"warp_yarns", w.rows()},
                          {"weft_yarns", w.cols()}}
                         .dump(2)
                  << std::endl;
        return 0;
      }
      std::cout << loom::canonical_spec(res.spec).dump(2) << std::endl;
      return 0;
    }
    if (*presets) {
      if (preset_name.empty()) {
        for (auto& p : loom::preset_names()) std::cout << p << "\n";
        return 0;
      }
      try {
        std::cout << loom::preset(preset_name).dump(2) << std::endl;
      } catch (const std::out_of_range&) {
        std::cerr << "error: no preset named \"" << preset_name << "\"\n";
        return 2;
      }
      return 0;
    }
    if (*inspect) {
      json m;
      auto errors = loom::validate_atlas(inspect_dir, &m);
      if (!errors.empty()) {
        for (auto& e : errors) std::cerr << "error: " << e << "\n";
        std::cerr << fmt::format("loom-bake: {} is not a valid atlas ({} problem{})\n",
                                 inspect_dir, errors.size(), errors.size() == 1 ? "" : "s");
        return 3;
      }
      // The summary's fields are for people, not for the evaluators, so validate_atlas does not
      // require them: one that is missing or of another type shows as null (JSON) or as
      // "(no <field>)", never as an exception.
      auto at = [&m](const char* ptr) {
        const json::json_pointer p(ptr);
        return m.contains(p) ? m.at(p) : json();
      };
      auto text = [&at](const char* ptr, const char* field) {
        const json v = at(ptr);
        if (v.is_string()) return v.get<std::string>();
        if (v.is_number_integer()) return std::to_string(v.get<long long>());
        return fmt::format("(no {})", field);
      };
      json summary = {{"atlas", fs::absolute(inspect_dir).string()},
                      {"valid", true},
                      {"schema", at("/schema")},
                      {"baker_version", at("/baker_version")},
                      {"spec_sha256", at("/spec_sha256")},
                      {"name", at("/spec/name")},
                      {"tier", at("/tier")},
                      {"quality", at("/quality")},
                      {"repeat", at("/repeat")},
                      {"colour", at("/colour")}};
      json tex = json::object();
      for (auto& [name, t] : m["textures"].items()) tex[name] = t["size"];
      summary["textures"] = tex;
      if (inspect_json) {
        std::cout << summary.dump(2) << std::endl;
      } else {
        std::cout << fmt::format("{}: valid {} atlas \"{}\" ({}, {}), {} x {} yarn repeat\n",
                                 summary["atlas"].get<std::string>(), text("/schema", "schema"),
                                 text("/spec/name", "spec.name"), text("/tier", "tier"),
                                 text("/quality", "quality"),
                                 text("/repeat/warp_yarns", "repeat.warp_yarns"),
                                 text("/repeat/weft_yarns", "repeat.weft_yarns"));
        for (auto& [name, t] : m["textures"].items())
          std::cout << fmt::format("  {:<16} {:>5} x {:<5} {}\n", name, t["size"][0].get<int>(),
                                   t["size"][1].get<int>(),
                                   t["channels"].dump());
      }
      return 0;
    }
    if (*mapping) {
      auto atlas = loom::load_atlas(mapping_atlas);
      const bool rw = atlas.manifest.value("tier", "") == "raywave";
      auto e = rw ? loom::raywave_mapping_error(atlas, loom::load_raywave(atlas), mapping_texels,
                                                mapping_views)
                  : loom::mapping_error(atlas, mapping_texels, mapping_views);
      json out = {{"mean_relative_l1", e.mean_l1},
                  {"worst_relative_l1", e.worst_l1},
                  {"mean_energy_error", e.mean_energy},
                  {"worst_energy_error", e.worst_energy},
                  {"texels", e.texels},
                  {"pairs", e.views},
                  {"tier", rw ? "raywave" : "surface"}};
      if (mapping_by_kind) {
        if (!rw) {
          std::cerr << "error: --by-kind: a ray-wave atlas's closures only\n";
          return 2;
        }
        const auto k = loom::raywave_mapping_by_kind(atlas, loom::load_raywave(atlas),
                                                     mapping_texels, mapping_views);
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
    if (*albedo) {
      const auto wo = loom::parse_cli_direction("--wo", albedo_wo_s);
      auto atlas = loom::load_atlas(albedo_atlas);
      if (atlas.manifest.value("tier", "") != "raywave") {
        std::cerr << "error: --atlas: eval albedo needs a ray-wave atlas (this one is \""
                  << atlas.manifest.value("tier", "?") << "\")\n";
        return 2;
      }
      const loom::shading::vec3 vo = loom::shading::normalize(
          loom::shading::vec3{float(wo[0]), float(wo[1]), float(wo[2])});
      const auto r = loom::raywave_albedo(
          atlas, loom::load_raywave(atlas), vo,
          albedo_evaluator == "closures" ? loom::Evaluator::Closures : loom::Evaluator::Model,
          albedo_texels);
      std::cout << json{{"reflect", r.reflect},
                        {"transmit", r.transmit},
                        {"gap_transmit", r.gap},
                        {"gap_diffracted", r.diffracted},
                        {"evaluator", albedo_evaluator},
                        {"wo", {vo.x, vo.y, vo.z}}}
                       .dump()
                << std::endl;
      return 0;
    }
    if (*asg) {
      const auto q = loom::parse_cli_asg_lobe("--lobe", asg_lobe_s);
      const auto v = loom::parse_cli_direction("--v", asg_v_s);
      namespace sh = loom::shading;
      sh::vec3 dir = sh::normalize(sh::vec3(float(v[0]), float(v[1]), float(v[2])));
      float val = sh::asg_eval(float(q[0]), float(q[1]), float(q[2]), float(q[3]), float(q[4]),
                               float(q[5]), dir);
      float integral = sh::asg_integral(float(q[3]), float(q[4]), float(q[5]));
      std::cout << json{{"value", val}, {"integral", integral}}.dump() << std::endl;
      return 0;
    }
    if (*diffraction) {
      const auto A = loom::parse_cli_aperture("--aperture", dif_aperture_s);
      const auto wi = loom::parse_cli_direction("--wi", dif_wi_s);
      const auto wo = loom::parse_cli_direction("--wo", dif_wo_s);
      const loom::Aperture ap{A[0], A[1], A[2], A[3]};
      const double lambda_um = dif_lambda * 1e-3;
      const std::array<double, 3> xi{wi[0], wi[1], wi[2]}, xo{wo[0], wo[1], wo[2]};
      const auto K = loom::aperture_K(ap, (wi[0] + wo[0]) / lambda_um, (wi[1] + wo[1]) / lambda_um,
                                      dif_waist);
      const double I = loom::aperture_intensity(ap, dif_waist, lambda_um, xi, xo);
      std::cout << json{{"intensity", I},
                        {"K", {K.real(), K.imag()}},
                        {"f", {(wi[0] + wo[0]) / lambda_um, (wi[1] + wo[1]) / lambda_um}},
                        {"beam_power", loom::beam_power(dif_waist)},
                        {"aperture_power", loom::aperture_power(ap, dif_waist)},
                        {"units", "lengths um, f 1/um, K um^2, intensity um^2 (Eq. S.35)"}}
                       .dump()
                << std::endl;
      return 0;
    }
    if (*colour) {
      const auto rgb = loom::parse_cli_rgb01("--rgb", colour_rgb_s);
      auto atlas = loom::load_atlas(colour_atlas);
      const json& m = atlas.manifest;
      const json y = m.contains("raywave") ? m["raywave"]["yarns"].value(colour_yarn, json())
                                           : json();
      if (!y.is_object() || !y.contains("absorption")) {
        std::cerr << "error: " << colour_atlas
                  << ": no absorption data (bake a ray-wave spec; this atlas has tier "
                  << m.value("tier", "?") << ")\n";
        return 2;
      }
      const json& a = y["absorption"];
      loom::AbsorptionCurve curve;
      curve.sigma_per_mm = a["curve"]["sigma_per_mm"].get<std::vector<double>>();
      curve.energy = a["curve"]["energy"].get<std::vector<double>>();
      loom::AbsorptionFit fit;
      fit.a = a["s42"]["a_mm"], fit.b = a["s42"]["b"];
      const double sigma_max = y["high"]["sigma_per_mm"].back();
      // The atlas's own colour configuration (a config file, or the built-in one).
      std::string cfg = m.contains("colour") ? m["colour"].value("config", "") : "";
      if (cfg.rfind("loom-builtin", 0) == 0) cfg.clear();
      const loom::ColourConverter cc(cfg);
      const loom::SpectralUpsampler up(cc, 5.0);
      const auto ya = loom::yarn_absorption({rgb[0], rgb[1], rgb[2]}, up, fit, curve, sigma_max);
      json samples = json::array();
      for (size_t k = 0; k < ya.lambda_nm.size(); k += 4)  // every 20 nm
        samples.push_back({{"lambda_nm", ya.lambda_nm[k]},
                           {"reflectance", ya.spectrum(ya.lambda_nm[k])},
                           {"sigma_per_mm", ya.sigma_per_mm[k]},
                           {"sigma_s42_per_mm", ya.sigma_s42_per_mm[k]}});
      std::cout << json{{"rgb", rgb},
                        {"sigma", samples},
                        {"sigma_rgb_per_mm", ya.sigma_rgb},
                        {"rgb_spectrum", ya.rgb_spectrum},
                        {"rgb_reconstructed", ya.rgb_ply},
                        {"rgb_reconstructed_s42", ya.rgb_s42},
                        {"s42", {{"a_mm", fit.a}, {"b", fit.b}}}}
                       .dump()
                << std::endl;
      return 0;
    }
    if (*noise) {
      auto atlas = loom::load_atlas(noise_atlas);
      const json& m = atlas.manifest;
      const json* nj = m.contains("raywave") ? &m["raywave"] : nullptr;
      if (!nj || !nj->contains("noise") || (*nj)["noise"]["files"].empty()) {
        std::cerr << "error: " << noise_atlas
                  << ": no speckle noise tiles (bake a ray-wave spec with wave.noise on)\n";
        return 2;
      }
      const json& n = (*nj)["noise"];
      const int H = n["theta_count"], inst = n["instances"];
      json out = json::object();
      for (auto& [which, file] : n["files"].items()) {
        const auto& img = atlas.map(file.get<std::string>());
        json per = json::array();
        for (int j = 0; j < inst; ++j) {
          json bands = json::array();
          for (int c = 0; c < img.channels; ++c) {
            double sum = 0, sum2 = 0, lo = INFINITY, hi = -INFINITY;
            for (int y = j * H; y < (j + 1) * H; ++y)
              for (int x = 0; x < img.width; ++x) {
                const double v = img.px(x, y)[c];
                sum += v, sum2 += v * v, lo = std::min(lo, v), hi = std::max(hi, v);
              }
            const double cnt = double(H) * img.width, mean = sum / cnt;
            bands.push_back({{"band_nm", n["band_nm"][size_t(c)]},
                             {"mean", mean},
                             {"variance", sum2 / cnt - mean * mean},
                             {"min", lo},
                             {"max", hi}});
          }
          per.push_back({{"instance", j}, {"bands", bands}});
        }
        out[which] = per;
      }
      std::cout << out.dump() << std::endl;
      return 0;
    }
    if (*error) {
      const auto a = loom::load_atlas(error_atlas), r = loom::load_atlas(error_ref);
      const auto e = loom::preset_error(a, r, error_points, error_views, error_sphere);
      std::cout << json{{"average_relative_l1", e.average},
                        {"pointwise_mean_relative_l1", e.pointwise_mean},
                        {"pointwise_worst_relative_l1", e.pointwise_worst},
                        {"energy_error", e.energy},
                        {"points", e.points},
                        {"views", e.views},
                        {"tier", a.manifest.value("tier", "")},
                        {"quality", a.manifest.value("quality", "")},
                        {"reference_quality", r.manifest.value("quality", "")}}
                       .dump()
                << std::endl;
      return 0;
    }
    if (*lobes) {
      const auto atlas = loom::load_atlas(lobes_atlas);
      const auto t = loom::load_ply_tables(atlas, lobes_yarn);
      double th = lobes_theta * M_PI / 180, lh = lobes_h;
      if (lobes_snap)
        th = t.high.theta_i[nearest_node(t.high.theta_i, th)],
        lh = t.high.h[nearest_node(t.high.h, lh)];
      const auto high = loom::asg_table_lobes(t.high, th, lh, lobes_sigma);
      const auto refl = loom::asg_table_lobes(t.refl, th, lh, 0);
      // Ply space: z along the ply axis (the ASG frame of Eq. S.2); elevation from the ply's
      // normal plane, as in eval tables. Row r at elevation -90 + 180 (r + 0.5) / res.
      const int rows = lobes_res, cols = 2 * lobes_res;
      std::vector<loom::Vec3d> dirs;
      for (int r = 0; r < rows; ++r) {
        const double el = -M_PI / 2 + M_PI * (r + 0.5) / rows;
        for (int c = 0; c < cols; ++c) {
          const double az = -M_PI + 2 * M_PI * (c + 0.5) / cols;
          dirs.push_back({std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)});
        }
      }
      auto grid = [&](const std::vector<loom::AsgLobe>& ls) {
        json rowsj = json::array();
        for (int r = 0; r < rows; ++r) {
          json row = json::array();
          for (int c = 0; c < cols; ++c)
            row.push_back(loom::asg_mixture_eval(ls, dirs[size_t(r) * size_t(cols) + size_t(c)]));
          rowsj.push_back(row);
        }
        return rowsj;
      };
      auto each = [&](const std::vector<loom::AsgLobe>& ls) {
        json out = json::array();
        for (const auto& l : ls)
          out.push_back({{"theta_z", l.theta_z}, {"phi_z", l.phi_z}, {"phi_xy", l.phi_xy},
                         {"mu1", l.mu1}, {"mu2", l.mu2}, {"c", l.c},
                         {"values", grid({l})}});
        return out;
      };
      std::vector<loom::AsgLobe> all = high;
      all.insert(all.end(), refl.begin(), refl.end());
      json out = {{"theta_i_deg", th * 180 / M_PI}, {"h", lh}, {"sigma_per_mm", lobes_sigma},
                  {"yarn", lobes_yarn},
                  {"grid", {{"rows", rows}, {"cols", cols},
                            {"elevation", "row r: -90 + 180 (r + 0.5) / rows degrees"},
                            {"azimuth", "column c: -180 + 360 (c + 0.5) / cols degrees"}}},
                  {"high", each(high)}, {"refl", each(refl)}, {"total", grid(all)}};
      if (lobes_raw) {
        const NearestSlice sl =
            simulate_nearest_slice(atlas, t.high, lobes_yarn, th, lh, lobes_sigma);
        json rowsj = json::array();
        for (int r = 0; r < rows; ++r) {
          json row = json::array();
          for (int c = 0; c < cols; ++c)
            row.push_back(sl.value(dirs[size_t(r) * size_t(cols) + size_t(c)]));
          rowsj.push_back(row);
        }
        out["raw"] = {{"values", rowsj},
                      {"theta_i_deg", sl.theta_i * 180 / M_PI},
                      {"h", sl.h},
                      {"model", sl.multi_ply ? "single ply (the tables are multi-ply)"
                                             : "single ply"}};
      }
      std::cout << out.dump() << std::endl;
      return 0;
    }
    if (*tables) {
      auto a = loom::load_atlas(tables_atlas), r = loom::load_atlas(tables_ref);
      auto ta = loom::load_ply_tables(a, tables_yarn), tr = loom::load_ply_tables(r, tables_yarn);
      // f = f_refl + f_high over 9 x 9 (theta_i, h) inside the grids, the reference's absorption
      // levels, and a 32 x 64 (theta_o, phi_o) midpoint grid weighted by solid angle.
      json per_sigma = json::array();
      double num_all = 0, den_all = 0;
      for (double sg : tr.high.sigmas) {
        double num = 0, den = 0;
        for (int i = 0; i < 9; ++i)
          for (int j = 0; j < 9; ++j) {
            const double th = tr.high.theta_i.front() +
                              (tr.high.theta_i.back() - tr.high.theta_i.front()) * (i + 0.5) / 9;
            const double h = -1 + 2 * (j + 0.5) / 9;
            auto la = loom::asg_table_lobes(ta.high, th, h, sg), lr = loom::asg_table_lobes(tr.high, th, h, sg);
            auto ra = loom::asg_table_lobes(ta.refl, th, h, 0), rr = loom::asg_table_lobes(tr.refl, th, h, 0);
            for (int t = 0; t < 32; ++t) {
              const double el = -M_PI / 2 + M_PI * (t + 0.5) / 32, w = std::cos(el);
              for (int q = 0; q < 64; ++q) {
                const double az = -M_PI + 2 * M_PI * (q + 0.5) / 64;
                loom::Vec3d v{std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)};
                const double fa = loom::asg_mixture_eval(la, v) + loom::asg_mixture_eval(ra, v);
                const double fr = loom::asg_mixture_eval(lr, v) + loom::asg_mixture_eval(rr, v);
                num += w * std::fabs(fa - fr);
                den += w * std::fabs(fr);
              }
            }
          }
        per_sigma.push_back({{"sigma_per_mm", sg}, {"relative_l1", den > 0 ? num / den : 0.0}});
        num_all += num, den_all += den;
      }
      std::cout << json{{"relative_l1", den_all > 0 ? num_all / den_all : 0.0},
                        {"per_sigma", per_sigma},
                        {"yarn", tables_yarn},
                        {"lobes", {{"atlas", ta.high.lobes}, {"reference", tr.high.lobes}}}}
                       .dump()
                << std::endl;
      return 0;
    }
    if (*raywave) {
      const auto wo = loom::parse_cli_direction("--wo", rw_wo_s);
      const loom::Vec3d w{wo[0], wo[1], wo[2]};
      auto atlas = loom::load_atlas(rw_atlas);
      auto t = loom::load_ply_tables(atlas, rw_yarn);
      const double th = rw_theta * M_PI / 180;
      double high = loom::asg_table_eval(t.high, th, rw_h, rw_sigma, w);
      double refl = loom::asg_table_eval(t.refl, th, rw_h, 0, w);
      json out = {{"value", refl + high}, {"refl", refl}, {"high", high}, {"yarn", rw_yarn},
                  {"lobes", {{"high", t.high.lobes}, {"refl", t.refl.lobes}}}};
      {  // The energy the lobes miss at this (theta_i, h, sigma) (asg_residual.h).
        double hb, hf, rb, rf;
        loom::asg_residual_at(t.high, th, rw_h, rw_sigma, hb, hf);
        loom::asg_residual_at(t.refl, th, rw_h, 0, rb, rf);
        out["residual_energy"] = {{"backward", hb + rb}, {"forward", hf + rf}};
      }
      if (rw_raw) {
        const NearestSlice sl = simulate_nearest_slice(atlas, t.high, rw_yarn, th, rw_h, rw_sigma);
        double raw_refl, raw_high;
        const double raw = sl.value(w, &raw_refl, &raw_high);
        out["raw"] = {{"value", raw}, {"refl", raw_refl}, {"high", raw_high},
                      {"model", sl.multi_ply ? "single ply (the tables are multi-ply)"
                                             : "single ply"},
                      {"theta_i_deg", sl.theta_i * 180 / M_PI}, {"h", sl.h},
                      {"rays", sl.settings.rays_per_slice}};
      }
      std::cout << out.dump() << std::endl;
      return 0;
    }
    if (*fibers_cmd) {
      auto res = loom::load_spec(fr_spec);
      if (!res.ok()) return report_spec_errors(fr_spec, res.errors);
      const auto rv = loom::parse_cli_region("--region", fr_region);
      loom::FiberRegion reg{rv[0], rv[1], rv[2], rv[3]};
      auto t0 = std::chrono::steady_clock::now();
      loom::FiberCurves curves;
      try {
        curves = loom::realize_fiber_region(res.spec, reg, fr_max);
      } catch (const std::invalid_argument& e) {
        std::cerr << "error: --" << e.what() << "\n";
        return 2;
      }
      loom::write_fiber_curves(curves, res.spec, reg, fr_out);
      size_t hairs = 0;
      for (auto h : curves.hair) hairs += h;
      std::cout << json{{"out", fr_out},
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
    }
    if (*fibers) {
      auto res = loom::load_spec(fibers_spec);
      if (!res.ok()) return report_spec_errors(fibers_spec, res.errors);
      using clock = std::chrono::steady_clock;
      auto secs = [](clock::time_point a) {
        return std::chrono::duration<double>(clock::now() - a).count();
      };
      auto patch = loom::make_woven_patch(res.spec, fibers_yarns);
      const bool do_min = fibers_only != "realized", do_real = fibers_only != "minimising";
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
              fibers_yarns, gib, verts, limit);
          return 2;
        }
      }
      auto pts = loom::fiber_test_points(patch, fibers_points, fibers_seed);
      loom::FiberLookupOptions fopt;
      fopt.azimuth_bins = fibers_bins;
      fopt.realization_free_hairs = fibers_hairs == "realization-free";
      std::unique_ptr<loom::FiberLookup> minimising;
      std::unique_ptr<loom::RealizedFibers> realized;
      json out{{"spec", res.spec.name}, {"yarns", fibers_yarns}, {"points", fibers_points},
               {"fibers_per_yarn", res.spec.warp.plies * res.spec.warp.fibers_per_ply},
               {"hairs_method", fibers_hairs}};
      std::vector<loom::FiberHit> a, b;
      if (do_min) {
        auto t0 = clock::now();
        minimising = std::make_unique<loom::FiberLookup>(patch, fopt);
        out["build_seconds_minimising"] = secs(t0);
        t0 = clock::now();
        a.reserve(pts.size());
        for (auto& p : pts) a.push_back(minimising->lookup(p));
        out["seconds_minimising"] = secs(t0);
        out["bytes_minimising"] = minimising->bytes();
        out["hairs"] = minimising->hair_count();
      }
      if (do_real) {
        auto t0 = clock::now();
        realized = std::make_unique<loom::RealizedFibers>(patch, fopt);
        out["build_seconds_realized"] = secs(t0);
        t0 = clock::now();
        b.reserve(pts.size());
        for (auto& p : pts) b.push_back(realized->lookup(p));
        out["seconds_realized"] = secs(t0);
        out["bytes_realized"] = realized->bytes();
        out["realized_vertices"] = realized->vertex_count();
      }
      const auto& hits = do_min ? a : b;
      size_t covered = 0, hair = 0;
      for (auto& h : hits) covered += h.covered, hair += h.covered && h.hair;
      out["covered"] = covered;
      out["covered_by_hair"] = hair;
      if (do_min && do_real) {
        size_t mismatches = 0;
        for (size_t i = 0; i < pts.size(); ++i)
          mismatches += !a[i].same_fiber(b[i]) || a[i].distance != b[i].distance;
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
    if (*plysim) {
      auto res = loom::load_spec(plysim_spec, plysim_quality);
      if (!res.ok()) return report_spec_errors(plysim_spec, res.errors);
      const loom::YarnSpec& y = plysim_yarn == "weft" ? res.spec.weft : res.spec.warp;
      auto p = loom::ply_params_from_yarn(y);
      auto st = loom::ply_sim_settings(res.spec.quality);
      if (plysim_rays > 0) st.rays_per_slice = plysim_rays;
      st.sigmas = {0.0};
      if (plysim_sigma > 0) st.sigmas.push_back(plysim_sigma);
      st.seed = plysim_seed;
      loom::PlyGeometry g(p, loom::make_ply_fibers(p, 0, 0));
      auto sl = loom::simulate_ply_slice(g, y.ior, st, plysim_theta * M_PI / 180, plysim_h, 0);
      const auto& e = sl.energy.back();
      std::cout << json{{"reflected", e.reflected},
                        {"higher_order", e.higher_order},
                        {"absorbed", e.absorbed},
                        {"unscattered", e.unscattered},
                        {"truncated", e.truncated},
                        {"rays", st.rays_per_slice},
                        {"sigma_per_mm", plysim_sigma},
                        {"yarn", plysim_yarn}}
                       .dump()
                << std::endl;
      return 0;
    }
    if (*bsdf) {
      std::array<double, 2> uv{};
      if (!average) {
        if (uv_s.empty()) {
          std::cerr << "error: --uv: expected U,V (two finite numbers), or give --average\n";
          return 2;
        }
        uv = loom::parse_cli_uv("--uv", uv_s);
      }
      if (wi_s.size() != wo_s.size()) {
        std::cerr << fmt::format("error: --wi and --wo: {} and {} directions; give one --wo for "
                                 "each --wi\n", wi_s.size(), wo_s.size());
        return 2;
      }
      std::vector<std::pair<loom::shading::vec3, loom::shading::vec3>> pairs;
      for (size_t k = 0; k < wi_s.size(); ++k) {
        const auto wi = loom::parse_cli_direction("--wi", wi_s[k]);
        const auto wo = loom::parse_cli_direction("--wo", wo_s[k]);
        pairs.emplace_back(
            loom::shading::normalize(loom::shading::vec3{float(wi[0]), float(wi[1]), float(wi[2])}),
            loom::shading::normalize(loom::shading::vec3{float(wo[0]), float(wo[1]), float(wo[2])}));
      }
      auto atlas = loom::load_atlas(atlas_dir);
      auto e = evaluator == "closures" ? loom::Evaluator::Closures : loom::Evaluator::Model;
      if (atlas.manifest.value("tier", "") == "raywave") {
        // The ray-wave BSDF (baker/include/loom/raywave_bsdf.h): f_cos is Cycles' eval (f times
        // the cosine), the quantity the ply scattering density gives directly.
        const loom::RaywaveData rd = loom::load_raywave(atlas);
        for (const auto& [vi, vo] : pairs) {
          const std::array<float, 3> fc =
              average ? loom::raywave_eval_average(atlas, rd, vi, vo, e)
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
                            {"evaluator", evaluator},
                            {"backend", "any (flat geometry)"},
                            {"tier", "raywave"}}
                           .dump()
                    << std::endl;
        }
        return 0;
      }
      auto be = backend == "osl" ? loom::Backend::Osl : loom::Backend::Nodes;
      for (const auto& [vi, vo] : pairs) {
        std::array<float, 3> f =
            average ? loom::eval_bsdf_average(atlas, vi, vo, e, be)
                    : loom::eval_bsdf(atlas,
                                      loom::sample_surface(atlas, float(uv[0]), float(uv[1])), vi,
                                      vo, e, be);
        json out = {{"f", f}, {"evaluator", evaluator}};
        if (e == loom::Evaluator::Closures) out["backend"] = backend;
        std::cout << out.dump() << std::endl;
      }
      return 0;
    }
  } catch (const loom::CliValueError& ex) {
    // A bad value on the command line (loom/cli_values.h): like every other bad input.
    std::cerr << "error: " << ex.what() << "\n";
    return 2;
  } catch (const std::exception& ex) {
    std::cerr << "loom-bake: " << ex.what() << "\n";
    return 1;
  }
  return 0;
}
