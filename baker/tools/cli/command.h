// loom-bake's subcommands: each file of baker/tools/cli/ declares one or a few subcommands (their
// options, bound to a state object the command owns) and what each runs once parsed; main
// (baker/tools/loom_bake.cpp) adds them in the order --help lists them and runs the one given.
#pragma once
#include <CLI/CLI.hpp>
#include <array>
#include <utility>

#include "loom/atlas.h"
#include "loom/shading.h"
#include "loom/spec.h"
#include <functional>
#include <string>
#include <vector>

namespace loom::cli {

/// A parsed subcommand runs `run`, which returns the exit code (0 ok, 2 bad input, 3 not a
/// valid atlas); main turns exceptions into 2 (loom::CliValueError, a bad value) or 1.
struct Command {
  CLI::App* app;
  std::function<int()> run;
};
using Commands = std::vector<Command>;

/// CLI::Range for real numbers, but NaN and infinities are rejected too (every comparison with
/// NaN is false, so CLI::Range lets it through); the number syntax of loom/cli_values.h. The
/// accepted value is handed on in its shortest round-trip form, so that CLI11's own conversion
/// reads exactly the number checked.
CLI::Validator finite_range(double lo, double hi);

/// The help of a spec argument: "spec file or preset name (plain, twill, ...)", every built-in
/// preset named.
std::string spec_help();

/// How much a subcommand says on stderr besides its errors: 0 with -q, 1 by default, 2 with -v
/// (main sets it from the command line; bake: its progress and each stage's time).
int& verbosity();

/// eval bsdf --evaluator average: the repeat-averaged closures at each (wi, wo) pair, at `uv`
/// (scaled by the point's yarn coverage) or, with `average`, over the repeat (eval_average.cpp).
int eval_average_closures(const Atlas& atlas, bool average, std::array<double, 2> uv,
                          const std::vector<std::pair<shading::vec3, shading::vec3>>& pairs);

/// Prints a spec's problems and "nothing was written"; returns 2.
int report_spec_errors(const std::string& what, const std::vector<std::string>& errors);
/// Adds to res the "not yet" of a command that knows one colour per system (`what`) when its
/// valid spec has per-thread yarn sequences (spec.h: thread_sequences_not_yet).
void refuse_thread_sequences(loom::SpecResult& res, const std::string& what);

// The subcommands (one add_* per subcommand, in --help's order).
void add_bake(CLI::App& app, Commands& out);           // bake_commands.cpp
void add_inspect(CLI::App& app, Commands& out);        // inspect_command.cpp
void add_check(CLI::App& app, Commands& out);          // bake_commands.cpp
void add_presets(CLI::App& app, Commands& out);        // bake_commands.cpp
void add_fibers(CLI::App& app, Commands& out);         // fiber_commands.cpp
void add_eval_bsdf(CLI::App& eval, Commands& out);     // eval_bsdf.cpp
void add_eval_mapping(CLI::App& eval, Commands& out);  // eval_bsdf.cpp
void add_eval_albedo(CLI::App& eval, Commands& out);   // eval_bsdf.cpp
void add_eval_average(CLI::App& eval, Commands& out);  // eval_average.cpp
void add_eval_asg(CLI::App& eval, Commands& out);      // eval_plies.cpp
void add_eval_diffraction(CLI::App& eval, Commands& out);  // eval_wave.cpp
void add_eval_plysim(CLI::App& eval, Commands& out);   // eval_plies.cpp
void add_eval_raywave(CLI::App& eval, Commands& out);  // eval_plies.cpp
void add_eval_tables(CLI::App& eval, Commands& out);   // eval_plies.cpp
void add_eval_error(CLI::App& eval, Commands& out);    // eval_bsdf.cpp
void add_eval_lobes(CLI::App& eval, Commands& out);    // eval_plies.cpp
void add_eval_noise(CLI::App& eval, Commands& out);    // eval_wave.cpp
void add_eval_colour(CLI::App& eval, Commands& out);   // eval_wave.cpp
void add_eval_fibers(CLI::App& eval, Commands& out);   // fiber_commands.cpp
void add_eval_truth(CLI::App& eval, Commands& out);    // truth_commands.cpp
void add_eval_swatch(CLI::App& eval, Commands& out);   // truth_commands.cpp

}  // namespace loom::cli
