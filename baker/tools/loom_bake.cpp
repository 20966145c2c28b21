// loom-bake: bake a fabric spec into an atlas, inspect an atlas, and probe its BSDF. Each
// subcommand lives in baker/tools/cli/ (command.h); this file adds them and runs the one given.
#include <tbb/global_control.h>

#include <CLI/CLI.hpp>
#include <exception>
#include <iostream>
#include <optional>
#include <string>

#include "cli/command.h"
#include "loom/cli_values.h"
#include "loom_version.h"

int main(int argc, char** argv) {
  namespace cli = loom::cli;
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
  app.set_version_flag("--version", std::string("loom-bake ") + LOOM_VERSION + " (commit " +
                                        LOOM_COMMIT + ")");
  // Like oiiotool's and maketx's: all cores unless told; given before or after the subcommand.
  unsigned threads = 0;
  app.add_option("--threads", threads, "worker threads (default: all cores)")
      ->check(CLI::Range(1u, 4096u));
  bool quiet = false, verbose = false;
  auto* q = app.add_flag("-q,--quiet", quiet,
                         "say nothing on stderr but errors (bake: no progress)");
  app.add_flag("-v,--verbose", verbose,
               "say more on stderr (bake: each stage on a line of its own, with its time)")
      ->excludes(q);
  app.fallthrough();
  app.footer(
      "Exit codes: 0 done; 1 failed (could not read or write, or an internal error); 2 bad "
      "input (command line, spec, value: the field and its allowed range are named, nothing "
      "is written); 3 not a valid atlas.");
  cli::Commands commands;
  cli::add_bake(app, commands);
  cli::add_inspect(app, commands);
  cli::add_check(app, commands);
  cli::add_presets(app, commands);
  cli::add_fibers(app, commands);
  CLI::App& eval = *app.add_subcommand("eval", "probe an evaluator");
  eval.require_subcommand(1);
  for (auto add : {cli::add_eval_bsdf, cli::add_eval_mapping, cli::add_eval_albedo,
                   cli::add_eval_average,
                   cli::add_eval_asg, cli::add_eval_diffraction, cli::add_eval_plysim,
                   cli::add_eval_raywave, cli::add_eval_tables, cli::add_eval_error,
                   cli::add_eval_lobes, cli::add_eval_noise, cli::add_eval_colour,
                   cli::add_eval_fibers, cli::add_eval_truth, cli::add_eval_swatch})
    add(eval, commands);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version exit 0; every bad command line exits 2, like every other bad input.
    return app.exit(e) == 0 ? 0 : 2;
  }
  cli::verbosity() = quiet ? 0 : verbose ? 2 : 1;
  std::optional<tbb::global_control> limit;
  if (threads > 0) limit.emplace(tbb::global_control::max_allowed_parallelism, size_t(threads));
  try {
    for (const cli::Command& c : commands)
      if (c.app->parsed()) return c.run();
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
