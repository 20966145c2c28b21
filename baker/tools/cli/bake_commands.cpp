// loom-bake bake, check, presets: a spec into an atlas, a spec's canonical form, the presets.
#include <fmt/format.h>
#include <unistd.h>

#include <tbb/global_control.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <map>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <mutex>
#include <thread>
#include <nlohmann/json.hpp>

#include "command.h"
#include "loom/atlas_writer.h"
#include "loom/bake.h"
#include "loom/cli_values.h"
#include "loom/ply_maps.h"
#include "loom/spec.h"
#include "loom/weave.h"

using nlohmann::json;
namespace fs = std::filesystem;

namespace loom::cli {

namespace {

/// The bakes a command line asks for: (spec, atlas directory). One spec file or preset bakes
/// into -o; several, or a folder (its *.json and *.wif, sorted), each into -o/<name> (the spec
/// file's stem or the preset's name). Problems (an empty folder, two specs of one name) go to
/// `errors`.
std::vector<std::pair<std::string, fs::path>> bake_jobs(const std::vector<std::string>& specs,
                                                        const fs::path& out,
                                                        std::vector<std::string>& errors) {
  std::vector<std::string> all;
  for (const std::string& s : specs) {
    if (!fs::is_directory(s)) {
      all.push_back(s);
      continue;
    }
    std::vector<std::string> found;
    for (const auto& e : fs::directory_iterator(s)) {
      std::string ext = e.path().extension().string();
      for (char& ch : ext) ch = char(std::tolower(static_cast<unsigned char>(ch)));
      if (e.is_regular_file() && (ext == ".json" || ext == ".wif"))
        found.push_back(e.path().string());
    }
    std::sort(found.begin(), found.end());
    if (found.empty()) errors.push_back(fmt::format("{}: a folder without specs (*.json, *.wif)", s));
    all.insert(all.end(), found.begin(), found.end());
  }
  std::vector<std::pair<std::string, fs::path>> jobs;
  if (all.size() == 1 && specs.size() == 1 && !fs::is_directory(specs[0])) {
    jobs.push_back({all[0], out});
    return jobs;
  }
  std::map<std::string, std::string> by_name;
  for (const std::string& s : all) {
    const std::string name = fs::exists(s) ? fs::path(s).stem().string() : s;
    auto [it, fresh] = by_name.emplace(name, s);
    if (!fresh)
      errors.push_back(fmt::format("{} and {}: both would bake into {}; give them different "
                                   "names",
                                   it->second, s, (out / name).string()));
    jobs.push_back({s, out / name});
  }
  return jobs;
}

}  // namespace

void add_bake(CLI::App& app, Commands& out) {
  struct Args {
    std::vector<std::string> specs;
    std::string out_dir, quality, ocio, progress = "auto";
    bool force = false;
    std::vector<std::string> reuse;
  };
  auto a = std::make_shared<Args>();
  auto* c = app.add_subcommand(
      "bake", "bake a spec (file or preset name) into an atlas; several, or a folder of them, "
              "each into its own atlas");
  c->add_option("spec,--spec", a->specs,
                spec_help() + "; several specs, or a folder (its *.json and *.wif), bake up to "
                              "--threads at once, each into -o/<name>")
      ->required();
  c->add_option("-o,--output", a->out_dir,
                "atlas directory to create (published atomically); with several specs the "
                "folder their atlases go into")
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
    std::vector<std::string> problems;
    const auto jobs = bake_jobs(a->specs, a->out_dir, problems);
    const bool batch = jobs.size() != 1 || jobs[0].second != fs::path(a->out_dir);
    const std::string what = batch ? fmt::format("{} specs", jobs.size()) : a->specs[0];
    // With --progress=json every failure is also a JSON line on stdout, where the progress goes:
    // {"error": what, "errors": [each problem], "exit": code} (stderr keeps the text), with
    // "spec" in a batch.
    auto fail = [&](const std::vector<std::string>& errors, int code, const std::string& spec) {
      if (mode == "json") {
        json j{{"error", errors.size() == 1 ? errors[0]
                                            : fmt::format("{}: {} problems", spec, errors.size())},
               {"errors", errors},
               {"exit", code}};
        if (batch) j["spec"] = spec;
        std::cout << j.dump() << std::endl;
      }
      return code;
    };
    // Every spec and destination is checked before any work: bad input writes nothing.
    std::vector<loom::FabricSpec> parsed;
    for (const auto& [spec, dir] : jobs) {
      auto res = loom::load_spec(spec, a->quality);
      for (const auto& e : res.errors) problems.push_back(batch ? spec + ": " + e : e);
      parsed.push_back(res.spec);
      try {  // a destination that is not an atlas is bad input (exit 2)
        loom::check_bake_destination(dir);
      } catch (const std::runtime_error& e) {
        problems.push_back(std::string("-o: ") + e.what());
      }
    }
    if (batch && fs::exists(a->out_dir) && !fs::is_directory(a->out_dir))
      problems.push_back(fmt::format("-o: {} exists and is not a folder", a->out_dir));
    if (!problems.empty()) return fail(problems, report_spec_errors(what, problems), what);
    // A batch bakes up to --threads specs at once (much of a bake runs on one core), each
    // spreading its own loops over the same threads; output lines are written whole, one at a
    // time, and carry "spec" (JSON) or the spec's name (-v).
    const size_t parallel =
        batch ? std::min(jobs.size(), tbb::global_control::active_value(
                                          tbb::global_control::max_allowed_parallelism))
              : 1;
    std::mutex io;
    std::atomic<size_t> next{0};
    int worst = 0;  // (written under io)
    auto bake_one = [&](size_t k) {
      const auto& [spec, dir] = jobs[k];
      const std::string tag = batch ? spec : "";
      // -v's stage lines: the stage reporting now and when it began.
      using Clock = std::chrono::steady_clock;
      auto stage_now =
          std::make_shared<std::pair<std::string, Clock::time_point>>("", Clock::now());
      auto end_stage = [&io, tag](std::pair<std::string, Clock::time_point>& st) {
        const auto now = Clock::now();
        if (!st.first.empty()) {
          std::lock_guard lock(io);
          std::cerr << fmt::format("loom-bake: {}{} done ({:.2f} s)\n",
                                   tag.empty() ? "" : tag + ": ", st.first,
                                   std::chrono::duration<double>(now - st.second).count());
        }
        st.second = now;
      };
      loom::BakeOptions opt;
      opt.ocio_config = a->ocio;
      opt.force = a->force;
      for (const auto& d : a->reuse) opt.reuse_from.emplace_back(d);
      if (mode == "json") {
        opt.progress = [&io, tag](const std::string& stage, double f) {
          json j{{"stage", stage}, {"fraction", f}};
          if (!tag.empty()) j["spec"] = tag;
          std::lock_guard lock(io);
          std::cout << j.dump() << std::endl;
        };
      } else if (mode == "lines") {  // -v: each stage once, when the next begins (the last at
                                     // the end), with its time from its first report to there
        opt.progress = [stage_now, end_stage](const std::string& stage, double) {
          if (stage != stage_now->first) end_stage(*stage_now), stage_now->first = stage;
        };
      } else if (mode == "text" && parallel == 1) {  // (several at once: start and end lines)
        opt.progress = [](const std::string& stage, double f) {
          std::cerr << fmt::format("\r{:<12} {:3.0f}%", stage, 100 * f) << std::flush;
          if (f >= 1.0) std::cerr << "\n";
        };
      }
      if (batch && mode != "none" && mode != "json") {
        std::lock_guard lock(io);
        std::cerr << fmt::format("loom-bake: {} -> {}\n", spec, dir.string());
      }
      loom::BakeResult r;
      try {
        r = loom::bake_atlas(parsed[k], dir, opt);
      } catch (const std::exception& e) {
        // (main reports these on stderr: a bad value exits 2, anything else 1)
        const int code = dynamic_cast<const loom::CliValueError*>(&e) ? 2 : 1;
        std::lock_guard lock(io);
        fail({e.what()}, code, spec);
        if (!batch) throw;
        std::cerr << "error: " << spec << ": " << e.what() << "\n";
        worst = std::max(worst, code);
        return;  // the others still bake
      }
      if (mode == "lines") end_stage(*stage_now);
      json done{{"atlas", r.dir.string()},
                {"reused", r.reused},
                {"reused_simulation", r.reused_simulation.string()},
                {"seconds", r.seconds},
                {"bytes", r.bytes}};
      if (batch) done["spec"] = spec;
      std::lock_guard lock(io);
      std::cout << done.dump() << std::endl;
    };
    if (parallel == 1) {
      for (size_t k = 0; k < jobs.size(); ++k) bake_one(k);
    } else {
      std::vector<std::thread> workers;
      for (size_t w = 0; w < parallel; ++w)
        workers.emplace_back([&] {
          for (size_t k; (k = next++) < jobs.size();) bake_one(k);
        });
      for (auto& t : workers) t.join();
    }
    return worst;
  }});
}

void add_check(CLI::App& app, Commands& out) {
  struct Args {
    std::string spec, quality;
    bool geometry = false;
  };
  auto a = std::make_shared<Args>();
  auto* c = app.add_subcommand("check", "validate a spec and print its canonical form");
  c->add_option("spec,--spec", a->spec, spec_help())->required();
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
