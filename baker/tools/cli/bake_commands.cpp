// loom-bake bake, check, presets: a spec into an atlas, a spec's canonical form, the presets.
#include <fmt/format.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "command.h"
#include "loom/atlas_writer.h"
#include "loom/bake.h"
#include "loom/cli_values.h"
#include "loom/ply_maps.h"
#include "loom/spec.h"
#include "loom/weave.h"

using nlohmann::json;

namespace loom::cli {

void add_bake(CLI::App& app, Commands& out) {
  struct Args {
    std::string spec, out_dir, quality, ocio, progress = "auto";
    bool force = false;
    std::vector<std::string> reuse;
  };
  auto a = std::make_shared<Args>();
  auto* c = app.add_subcommand("bake", "bake a spec (file or preset name) into an atlas");
  c->add_option("spec", a->spec, spec_help())
      ->required();
  c->add_option("-o,--output", a->out_dir, "atlas directory to create (published atomically)")
      ->required();
  c->add_option("--quality", a->quality, "override model.quality: draft|preview|final|reference");
  c->add_option("--ocio-config", a->ocio,
                "OpenColorIO config for colour conversion (e.g. Blender's); default: $OCIO "
                "or Loom's built-in sRGB -> linear Rec.709");
  c->add_option("--progress", a->progress,
                "progress output: auto|text|json|none (auto: text on a terminal, else none; "
                "none with -q; a line per stage with its time with -v)");
  c->add_flag("--force", a->force,
              "re-bake from scratch even if the destination holds this spec's atlas, and "
              "re-simulate a ray-wave spec whose tables another atlas holds");
  c->add_option("--reuse", a->reuse,
                "ray-wave atlas whose colour-independent tables (ply tables, double layer, "
                "diffraction, noise) a colour-only change may copy; the destination and its "
                "siblings are always looked at");
  out.push_back({c, [a] {
    if (a->ocio.empty() && std::getenv("OCIO")) a->ocio = std::getenv("OCIO");
    std::string& mode = a->progress;
    if (mode != "auto" && mode != "text" && mode != "json" && mode != "none") {
      std::cerr << "error: --progress: \"" << mode << "\" is not one of auto, text, json, none\n";
      return 2;
    }
    if (mode == "auto")
      mode = verbosity() == 2 ? "lines" : isatty(2) ? "text" : "none";
    if (verbosity() == 0 && mode != "json") mode = "none";  // -q: nothing on stderr but errors
    // With --progress=json every failure is also a JSON line on stdout, where the progress goes:
    // {"error": what, "errors": [each problem], "exit": code} (stderr keeps the text).
    auto fail = [&](const std::vector<std::string>& errors, int code) {
      if (mode == "json")
        std::cout << json{{"error", errors.size() == 1 ? errors[0]
                                                       : fmt::format("{}: {} problems", a->spec,
                                                                     errors.size())},
                          {"errors", errors},
                          {"exit", code}}
                         .dump()
                  << std::endl;
      return code;
    };
    auto res = loom::load_spec(a->spec, a->quality);
    if (!res.ok()) return fail(res.errors, report_spec_errors(a->spec, res.errors));
    // -v's stage lines: the stage reporting now and when it began.
    using Clock = std::chrono::steady_clock;
    auto stage_now = std::make_shared<std::pair<std::string, Clock::time_point>>("", Clock::now());
    auto end_stage = [](std::pair<std::string, Clock::time_point>& s) {
      const auto now = Clock::now();
      if (!s.first.empty())
        std::cerr << fmt::format("loom-bake: {} done ({:.2f} s)\n", s.first,
                                 std::chrono::duration<double>(now - s.second).count());
      s.second = now;
    };
    loom::BakeOptions opt;
    opt.ocio_config = a->ocio;
    opt.force = a->force;
    for (const auto& d : a->reuse) opt.reuse_from.emplace_back(d);
    if (mode == "json") {
      opt.progress = [](const std::string& stage, double f) {
        std::cout << json{{"stage", stage}, {"fraction", f}}.dump() << std::endl;
      };
    } else if (mode == "lines") {  // -v: each stage once, when the next begins (the last at
                                   // the end), with its time from its first report to there
      opt.progress = [stage_now, end_stage](const std::string& stage, double) {
        if (stage != stage_now->first) end_stage(*stage_now), stage_now->first = stage;
      };
    } else if (mode == "text") {
      opt.progress = [](const std::string& stage, double f) {
        std::cerr << fmt::format("\r{:<12} {:3.0f}%", stage, 100 * f) << std::flush;
        if (f >= 1.0) std::cerr << "\n";
      };
    }
    try {  // a destination that is not an atlas is bad input (exit 2), found before any work
      loom::check_bake_destination(a->out_dir);
    } catch (const std::runtime_error& e) {
      std::cerr << "error: -o: " << e.what() << "\n";
      return fail({std::string("-o: ") + e.what()}, 2);
    }
    loom::BakeResult r;
    try {
      r = loom::bake_atlas(res.spec, a->out_dir, opt);
    } catch (const loom::CliValueError& e) {  // (main reports these on stderr, exit 2 and 1)
      fail({e.what()}, 2);
      throw;
    } catch (const std::exception& e) {
      fail({e.what()}, 1);
      throw;
    }
    if (mode == "lines") end_stage(*stage_now);
    std::cout << json{{"atlas", r.dir.string()},
                      {"reused", r.reused},
                      {"reused_simulation", r.reused_simulation.string()},
                      {"seconds", r.seconds},
                      {"bytes", r.bytes}}
                     .dump()
              << std::endl;
    return 0;
  }});
}

void add_check(CLI::App& app, Commands& out) {
  struct Args {
    std::string spec, quality;
    bool geometry = false;
  };
  auto a = std::make_shared<Args>();
  auto* c = app.add_subcommand("check", "validate a spec and print its canonical form");
  c->add_option("spec", a->spec, spec_help())->required();
  c->add_option("--quality", a->quality, "override model.quality");
  c->add_flag("--geometry", a->geometry,
              "print {\"spec\": canonical spec, \"repeat_um\": [x, y], \"warp_yarns\", "
              "\"weft_yarns\"} (the weave repeat's size and yarn counts)");
  out.push_back({c, [a] {
    auto res = loom::load_spec(a->spec, a->quality);
    if (!res.ok()) return report_spec_errors(a->spec, res.errors);
    if (a->geometry) {
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
  }});
}

void add_presets(CLI::App& app, Commands& out) {
  auto name = std::make_shared<std::string>();
  auto* c = app.add_subcommand("presets", "list the built-in presets, or print one");
  c->add_option("name", *name, "preset to print as JSON");
  out.push_back({c, [name] {
    if (name->empty()) {
      for (auto& p : loom::preset_names()) std::cout << p << "\n";
      return 0;
    }
    try {
      std::cout << loom::preset(*name).dump(2) << std::endl;
    } catch (const std::out_of_range&) {
      std::cerr << "error: no preset named \"" << *name << "\"\n";
      return 2;
    }
    return 0;
  }});
}

}  // namespace loom::cli
